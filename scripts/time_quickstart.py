#!/usr/bin/env python3
"""Time the README's quick start on a fresh clone of this checkout's HEAD: its install-and-run command as written,
then the main job once more with the kernels compiled.

Clones the repository into a temporary folder and runs the README's first ``bash`` block under "Quick start" there
(a new virtual environment, ``pip install -e ".[test]"``, the main job) with an empty Warp kernel cache, so the
first run compiles the kernels as on a new machine (the command is run in its two parts, the install and the main
job, each timed); then runs the main job once more. Reported: the install's wall time, the first and the second
run of the main job, the machine, the date and the commit. Examples::

    python3 scripts/time_quickstart.py --json docs/benchmarks/quickstart.json --markdown docs/benchmarks/quickstart.md
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from time_tests import _machine, check_outputs, fresh_clone, report

from aca_warp.common.argtypes import positive


def quickstart_command(readme: str) -> str:
    """The first ``bash`` block after the README's "Quick start" heading, as one shell line."""
    section = readme.split("## Quick start", 1)[1]
    block = re.search(r"```bash\n(.*?)```", section, flags=re.DOTALL)
    if block is None:
        raise ValueError("README.md: no bash block under 'Quick start'")
    return " ".join(line.strip() for line in block.group(1).splitlines() if line.strip())


def _timed(command: str, cwd: Path, env: dict[str, str], timeout: float) -> float:
    t = time.perf_counter()
    subprocess.run(["bash", "-c", command], cwd=cwd, env=env, check=True, timeout=timeout, capture_output=True)
    return time.perf_counter() - t


def run(timeout: float) -> dict:
    """Clone, run the quick start, run its main job again; the figures."""
    with tempfile.TemporaryDirectory(prefix="aca_warp_quickstart_") as tmp:
        clone, commit = fresh_clone(Path(tmp), "aca_warp")
        command = quickstart_command((clone / "README.md").read_text())
        setup, job = command.rsplit(" && ", 1)
        env = {**os.environ, "WARP_CACHE_PATH": str(Path(tmp) / "warp-cache")}
        install = _timed(setup, clone, env, timeout)  # the command as written, in its two parts
        first = _timed(f". .venv/bin/activate && {job}", clone, env, timeout)
        (clone / re.search(r"-o (\S+)", job).group(1)).unlink()  # the main job does not overwrite its output
        second = _timed(f". .venv/bin/activate && {job}", clone, env, timeout)
    return {
        "command": command,
        "commit": commit,
        "date": time.strftime("%Y-%m-%d %H:%M", time.localtime()),
        "machine": _machine(),
        "install_s": round(install, 1),
        "first_run_s": round(first, 1),
        "second_run_s": round(second, 1),
    }


def markdown(r: dict) -> str:
    return (
        "# Quick start: install and main job\n\n"
        f"`{r['command']}` on a fresh clone (commit {r['commit']}), {r['date']}, on {r['machine']}, with an empty "
        "kernel cache. Written by `python3 scripts/time_quickstart.py`.\n\n"
        "| install | main job, first run (kernels compiled on the way) | main job, second run |\n|---|---|---|\n"
        f"| {r['install_s']} s | {r['first_run_s']} s | {r['second_run_s']} s |\n"
    )


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--timeout", type=positive, default=1800.0, help="give up on a step after this many seconds")
    p.add_argument("--json", type=Path)
    p.add_argument("--markdown", type=Path)
    args = p.parse_args()
    check_outputs(p, args.json, args.markdown)
    report(run(args.timeout), markdown, args.json, args.markdown)
    return 0


if __name__ == "__main__":
    sys.exit(main())
