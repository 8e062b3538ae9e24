#!/usr/bin/env python3
"""Time the test suite as the README runs it, on a fresh clone of this checkout's HEAD.

Clones the repository (its committed HEAD) into a temporary folder, makes a virtual environment there over the
system's packages with the clone installed (``pip install --no-deps -e .``: the dependencies are the system's, as
``pip install -e ".[test]"`` leaves them on a machine that has them), and runs the README's command
``python3 -m pytest -q -n auto tests`` in it. Reported: the tests passed, skipped and failed, the wall time, the CPU
time of the suite and every process it waited for (user + sys: the figure that does not depend on what else loads
the machine), the machine, the date, the load average before and after, and whether Warp's kernel cache was warm
(the one ``aca-warp`` and the tests share, ``~/.cache/warp`` or ``WARP_CACHE_PATH``) or, with ``--cold``, an empty
one (kernels compiled on the way, as on a new machine or after a Warp upgrade). With ``--durations N`` pytest also
times every test (``--durations=0``): the N slowest tests and the N files of the largest total are listed (the time a
file takes sets when its worker can finish: every file runs on one worker), and every file's total is kept in the JSON,
from which the tests' conftest.py orders the files, longest first. Examples::

    python3 scripts/time_tests.py --durations 15 --json docs/benchmarks/test_suite.json \
        --markdown docs/benchmarks/test_suite.md
    python3 scripts/time_tests.py --cold -n 2          # a new machine's first run, two workers
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def cpu_of_children() -> float:
    """CPU time [s] (user + sys) of every child process waited for so far."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def counts(text: str) -> dict[str, int]:
    """passed, skipped, failed, errors of pytest's last summary line."""
    last = [line for line in text.splitlines() if re.search(r"\d+ (passed|failed)", line)]
    found = dict.fromkeys(("passed", "skipped", "failed", "errors"), 0)
    for n, what in re.findall(r"(\d+) (passed|skipped|failed|errors?)", last[-1] if last else ""):
        found["errors" if what.startswith("error") else what] = int(n)
    return found


def failures(text: str) -> list[str]:
    """The ids of the tests that failed or errored, from pytest's short summary (``-ra``)."""
    return re.findall(r"^(?:FAILED|ERROR) (\S+)", text, flags=re.MULTILINE)


def durations(text: str, n: int) -> dict:
    """The ``n`` slowest tests (setup + call + teardown [s]), the ``n`` files of the largest total [s] and every
    file's total (``file_seconds``: the order in which tests/conftest.py hands files to the workers), from pytest's
    ``--durations=0`` section."""
    per_test: dict[str, float] = {}
    for seconds, test in re.findall(r"^(\d+\.\d+)s (?:setup|call|teardown) +(\S+)", text, flags=re.MULTILINE):
        per_test[test] = per_test.get(test, 0.0) + float(seconds)
    per_file: dict[str, float] = {}
    for test, seconds in per_test.items():
        per_file[test.split("::")[0]] = per_file.get(test.split("::")[0], 0.0) + seconds
    slowest = sorted(per_test.items(), key=lambda kv: -kv[1])[:n]
    files = sorted(per_file.items(), key=lambda kv: -kv[1])[:n]
    return {
        "slowest_tests": [[t, round(s, 2)] for t, s in slowest],
        "slowest_files": [[f, round(s, 2)] for f, s in files],
        "file_seconds": {f: round(s, 2) for f, s in sorted(per_file.items(), key=lambda kv: -kv[1])},
    }


def run(args: argparse.Namespace) -> dict:
    """Clone, install, run the suite; the figures of the run."""
    with tempfile.TemporaryDirectory(prefix="aca_warp_suite_") as tmp:
        clone = Path(tmp) / "aca_warp"
        subprocess.run(["git", "clone", "--quiet", "--no-hardlinks", str(REPO), str(clone)], check=True)
        commit = subprocess.run(["git", "-C", str(clone), "rev-parse", "--short", "HEAD"], check=True,
                                capture_output=True, text=True).stdout.strip()  # fmt: skip
        venv = clone / ".venv"
        subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], check=True)
        python = str(venv / "bin" / "python")
        subprocess.run([python, "-m", "pip", "install", "-q", "--no-deps", "-e", str(clone)], check=True)
        env = {**os.environ, "PATH": f"{venv / 'bin'}{os.pathsep}{os.environ.get('PATH', '')}"}
        if args.cold:
            env["WARP_CACHE_PATH"] = str(Path(tmp) / "warp_cache")
        command = [python, "-m", "pytest", "-q", "-n", args.n, "tests"]
        timing = ["--durations=0"] if args.durations else []
        started = time.strftime("%Y-%m-%d %H:%M")
        load_before, cpu0, t0 = os.getloadavg(), cpu_of_children(), time.perf_counter()
        done = subprocess.run(
            command + timing, cwd=clone, env=env, capture_output=True, text=True, timeout=args.timeout
        )
        wall, cpu, load_after = time.perf_counter() - t0, cpu_of_children() - cpu0, os.getloadavg()
    if done.returncode != 0:
        sys.stderr.write(done.stdout[-3000:] + done.stderr[-3000:])
    return {
        "command": f"python3 -m pytest -q -n {args.n} tests",
        "commit": commit,
        "date": started,
        "machine": _machine(),
        "cores": os.cpu_count(),
        "kernel_cache": "cold (empty)" if args.cold else "warm (Warp's cache of this machine)",
        "exit_code": done.returncode,
        **counts(done.stdout),
        "failures": failures(done.stdout),
        "wall_s": wall,
        "cpu_s": cpu,
        "load_before": load_before[0],
        "load_after": load_after[0],
        **(durations(done.stdout, args.durations) if args.durations else {}),
    }


def _machine() -> str:
    try:
        sys.path.insert(0, str(REPO))
        from aca_warp.common.files import host_cpu

        return host_cpu()
    except ImportError:
        return f"{os.cpu_count()} cores"


def markdown(r: dict) -> str:
    def minutes(s: float) -> str:
        return f"{int(s // 60)} min {s % 60:.0f} s"

    def table(title: str, rows: list) -> str:
        lines = "".join(f"| `{name}` | {seconds:.1f} |\n" for name, seconds in rows)
        return f"\n| {title} | s |\n|---|---|\n{lines}"

    return (
        "# Test suite: count and time\n\n"
        f"`{r['command']}` on a fresh clone (commit {r['commit']}), {r['date']}, on {r['machine']}; kernel cache "
        f"{r['kernel_cache']}; load average {r['load_before']:.2g} before, {r['load_after']:.2g} after (the wall "
        "time depends on it, the CPU time hardly). Written by `python3 scripts/time_tests.py`.\n\n"
        "| passed | skipped | failed | wall | CPU (user + sys) |\n|---|---|---|---|---|\n"
        f"| {r['passed']} | {r['skipped']} | {r['failed'] + r['errors']} | {minutes(r['wall_s'])} | "
        f"{minutes(r['cpu_s'])} |\n"
        + ("\nFailed: " + ", ".join(f"`{t}`" for t in r["failures"]) + "\n" if r.get("failures") else "")
        + (
            "\nTime of each test (setup + call + teardown; under `-n` the workers share the cores, so a test takes "
            "longer than alone) and of each file (its tests together, on one worker):\n"
            + table("slowest tests", r["slowest_tests"])
            + table("slowest files", r["slowest_files"])
            if r.get("slowest_tests")
            else ""
        )
    )


def report(r: dict, page: Callable[[dict], str], json_path: Path | None, markdown_path: Path | None) -> None:
    """Print the figures ``r``; write them as JSON and, made by ``page``, as Markdown where paths are given."""
    print(json.dumps(r, indent=1))
    if json_path:
        json_path.write_text(json.dumps(r, indent=1) + "\n")
    if markdown_path:
        markdown_path.write_text(page(r))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cold", action="store_true", help="an empty kernel cache (kernels compiled during the run)")
    p.add_argument("-n", default="auto", help="pytest-xdist workers (default auto: one per core)")
    p.add_argument("--timeout", type=float, default=3600.0, help="give up after this many seconds (default 3600)")
    p.add_argument("--durations", type=int, default=0, metavar="N", help="list the N slowest tests and files")
    p.add_argument("--json", type=Path)
    p.add_argument("--markdown", type=Path)
    args = p.parse_args()
    r = run(args)
    report(r, markdown, args.json, args.markdown)
    return 0 if r["exit_code"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
