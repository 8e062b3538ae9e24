#!/usr/bin/env python3
"""Time the test suite as the README runs it, on a fresh clone of this checkout's HEAD.

Clones the repository (its committed HEAD) into a temporary folder, makes a virtual environment there over the
system's packages with the clone installed (``pip install --no-deps -e .``: the dependencies are the system's, as
``pip install -e ".[test]"`` leaves them on a machine that has them), and runs the README's command
``python3 -m pytest -q -n auto tests`` in it. Reported: the tests passed, skipped and failed, the wall time, the CPU
time of the suite and every process it waited for (user + sys: the figure that does not depend on what else loads
the machine), the machine, the date, the load average before and after, and whether Warp's kernel cache was warm
(the one ``aca-warp`` and the tests share, ``~/.cache/warp`` or ``WARP_CACHE_PATH``) or, with ``--cold``, an empty
one (kernels compiled on the way, as on a new machine or after a Warp upgrade), and how many kernel modules were
added to that cache during the run (a "warm" cache misses the modules whose source changed since it was filled:
their compiles are in the CPU time, seconds each). With ``--durations N`` pytest also
times every test (``--durations=0``): the N slowest tests and the N files of the largest total are listed (the time a
file takes sets when its worker can finish: every file runs on one worker), and every file's total is kept in the JSON,
from which the tests' conftest.py orders the files, longest first. With ``--beside`` a second fresh clone runs the
same command at the same moment (both started together, each with its own virtual environment): the suite as it
runs on a machine that another suite (another CI job, a second checkout) shares; the timed suite's wall and CPU time
are reported as before, the other's under ``beside``. Examples::

    python3 scripts/time_tests.py --durations 15 --json docs/benchmarks/test_suite.json \
        --markdown docs/benchmarks/test_suite.md
    python3 scripts/time_tests.py --cold -n 2          # a new machine's first run, two workers
    python3 scripts/time_tests.py --beside             # with a second copy of the suite running beside it
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from aca_warp.common.argtypes import int_at_least, positive

REPO = Path(__file__).resolve().parent.parent


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


def fresh_clone(tmp: Path, name: str) -> tuple[Path, str]:
    """A fresh clone of this checkout's HEAD under ``tmp/name``; (clone, its short commit)."""
    clone = tmp / name
    subprocess.run(["git", "clone", "--quiet", "--no-hardlinks", str(REPO), str(clone)], check=True)
    commit = subprocess.run(["git", "-C", str(clone), "rev-parse", "--short", "HEAD"], check=True,
                            capture_output=True, text=True).stdout.strip()  # fmt: skip
    return clone, commit


def _clone(tmp: Path, name: str, args: argparse.Namespace) -> tuple[Path, str, list[str], dict[str, str]]:
    """A fresh clone (:func:`fresh_clone`) with its virtual environment; (clone, commit, the suite's command, its
    environment)."""
    clone, commit = fresh_clone(tmp, name)
    venv = clone / ".venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], check=True)
    python = str(venv / "bin" / "python")
    subprocess.run([python, "-m", "pip", "install", "-q", "--no-deps", "-e", str(clone)], check=True)
    env = {**os.environ, "PATH": f"{venv / 'bin'}{os.pathsep}{os.environ.get('PATH', '')}"}
    if args.cold:
        env["WARP_CACHE_PATH"] = str(tmp / "warp_cache")
    command = [python, "-m", "pytest", "-q", "-n", args.n, "tests"] + (["--durations=0"] if args.durations else [])
    return clone, commit, command, env


def cached_modules(env: dict[str, str]) -> int:
    """Kernel modules in the Warp kernel cache the suite uses (``WARP_CACHE_PATH``, else ``~/.cache/warp``; one folder
    per compiled module under the Warp version's folder)."""
    root = Path(env.get("WARP_CACHE_PATH") or Path.home() / ".cache" / "warp")
    return sum(1 for d in root.glob("*/*") if d.is_dir())


def _suites(runs: list[tuple[Path, list[str], dict[str, str]]], timeout: float) -> list[dict]:
    """Start every (folder, command, environment) of ``runs`` at the same moment and wait for all; per run its exit
    code, output (stdout and stderr), wall time [s] and CPU time [s] (user + sys of the command and every process it
    waited for: ``os.wait4``'s resource use, the figure that does not depend on what else loads the machine)."""
    logs = [tempfile.TemporaryFile("w+") for _ in runs]
    t0 = time.perf_counter()
    procs = [subprocess.Popen(cmd, cwd=cwd, env=env, stdout=log, stderr=subprocess.STDOUT, text=True)
             for (cwd, cmd, env), log in zip(runs, logs, strict=True)]  # fmt: skip
    out: list[dict] = [{} for _ in runs]
    waiting = {p.pid: k for k, p in enumerate(procs)}
    deadline = t0 + timeout
    while waiting:
        pid, status, usage = os.wait4(-1, os.WNOHANG)
        if pid == 0:
            if time.perf_counter() > deadline:
                for k in waiting.values():
                    procs[k].kill()
                deadline = float("inf")  # the killed ones are reaped on the next turns
            time.sleep(0.2)
            continue
        if pid not in waiting:
            continue
        k = waiting.pop(pid)
        procs[k].returncode = os.waitstatus_to_exitcode(status)
        out[k] = {
            "exit_code": procs[k].returncode,
            "wall_s": time.perf_counter() - t0,
            "cpu_s": usage.ru_utime + usage.ru_stime,
        }
    for k, log in enumerate(logs):
        log.seek(0)
        out[k]["output"] = log.read()
        log.close()
    return out


def run(args: argparse.Namespace) -> dict:
    """Clone, install, run the suite (with ``--beside``: a second clone's suite started at the same moment); the
    figures of the run."""
    with tempfile.TemporaryDirectory(prefix="aca_warp_suite_") as tmp:
        clone, commit, command, env = _clone(Path(tmp), "aca_warp", args)
        runs = [(clone, command, env)]
        if args.beside:
            other, _, other_command, other_env = _clone(Path(tmp), "beside", args)
            runs.append((other, other_command, other_env))
        started = time.strftime("%Y-%m-%d %H:%M")
        load_before, modules_before = os.getloadavg(), cached_modules(env)
        done = _suites(runs, args.timeout)
        load_after, compiled = os.getloadavg(), cached_modules(env) - modules_before
    figures = [_figures(d) for d in done]
    beside = {"beside": figures[1]} if args.beside else {}
    return {
        "command": f"python3 -m pytest -q -n {args.n} tests",
        "commit": commit,
        "date": started,
        "machine": _machine(),
        "cores": os.cpu_count(),
        "kernel_cache": "cold (empty)" if args.cold else "warm (Warp's cache of this machine)",
        "kernels_compiled": compiled,
        **figures[0],
        "load_before": load_before[0],
        "load_after": load_after[0],
        **beside,
        **(durations(done[0]["output"], args.durations) if args.durations else {}),
    }


def _figures(done: dict) -> dict:
    """Exit code, counts, failed tests, wall and CPU time of one suite's run (its output's tail on stderr when it
    failed)."""
    if done["exit_code"] != 0:
        sys.stderr.write(done["output"][-6000:])
    out = done["output"]
    return {"exit_code": done["exit_code"], **counts(out), "failures": failures(out), "wall_s": done["wall_s"],
            "cpu_s": done["cpu_s"]}  # fmt: skip


def _machine() -> str:
    try:
        sys.path.insert(0, str(REPO))
        from aca_warp.common.files import host_cpu

        return host_cpu()
    except ImportError:
        return f"{os.cpu_count()} cores"


def markdown(r: dict) -> str:
    def minutes(s: float) -> str:
        whole = round(s)  # 299.6 s reads 5 min 0 s, not 4 min 60 s
        return f"{whole // 60} min {whole % 60} s"

    n = r.get("kernels_compiled", 0)
    compiled = f", {n} kernel modules added to it during the run (compiled by the suite or other work)" if n else ""

    def table(title: str, rows: list) -> str:
        lines = "".join(f"| `{name}` | {seconds:.1f} |\n" for name, seconds in rows)
        return f"\n| {title} | s |\n|---|---|\n{lines}"

    return (
        "# Test suite: count and time\n\n"
        f"`{r['command']}` on a fresh clone (commit {r['commit']}), {r['date']}, on {r['machine']}; kernel cache "
        f"{r['kernel_cache']}{compiled}; load average {r['load_before']:.2g} before, {r['load_after']:.2g} after "
        "(the wall time depends on it, the CPU time hardly). Written by `python3 scripts/time_tests.py`.\n\n"
        "| passed | skipped | failed | wall | CPU (user + sys) |\n|---|---|---|---|---|\n"
        f"| {r['passed']} | {r['skipped']} | {r['failed'] + r['errors']} | {minutes(r['wall_s'])} | "
        f"{minutes(r['cpu_s'])} |\n"
        + ("\nFailed: " + ", ".join(f"`{t}`" for t in r["failures"]) + "\n" if r.get("failures") else "")
        + (
            f"\nBeside a second copy of the suite (a fresh clone of the same commit, started at the same moment): "
            f"that one {r['beside']['passed']} passed, {r['beside']['failed'] + r['beside']['errors']} failed, "
            f"{minutes(r['beside']['wall_s'])} wall, {minutes(r['beside']['cpu_s'])} CPU"
            + "".join(f"; failed there: `{t}`" for t in r["beside"].get("failures", []))
            + ".\n"
            if r.get("beside")
            else ""
        )
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


def check_outputs(p: argparse.ArgumentParser, *paths: Path | None) -> None:
    """Refuse (``p.error``, exit 2) an output path given in a missing folder or naming a folder, before any work."""
    from aca_warp.common.errors import AcaError
    from aca_warp.common.files import check_output_path

    try:
        for path in paths:
            if path is not None:
                check_output_path(path, overwrite=True)
    except AcaError as e:
        p.error(str(e))


def workers(text: str) -> str:
    """pytest-xdist's ``-n``: ``auto`` or a count >= 0."""
    return text if text == "auto" else str(int_at_least(0)(text))


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cold", action="store_true", help="an empty kernel cache (kernels compiled during the run)")
    p.add_argument("-n", type=workers, default="auto", help="pytest-xdist workers (default auto: one per core)")
    p.add_argument("--timeout", type=positive, default=3600.0, help="give up after this many seconds (default 3600)")
    p.add_argument(
        "--durations", type=int_at_least(0), default=0, metavar="N", help="list the N slowest tests and files"
    )
    p.add_argument("--json", type=Path)
    p.add_argument("--markdown", type=Path)
    p.add_argument(
        "--beside",
        action="store_true",
        help="a second fresh clone runs the same suite at the same moment (shared cores)",
    )
    args = p.parse_args(argv)
    check_outputs(p, args.json, args.markdown)
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    r = run(args)
    report(r, markdown, args.json, args.markdown)
    return 0 if r["exit_code"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
