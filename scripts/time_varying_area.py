#!/usr/bin/env python3
"""Time the varying-area record through the command line at several fixed steps.

Runs ``aca-warp hf varying_area --duration D --dt STEP --precision fp32 --device DEV -o OUT/va_STEP.h5`` once per
step (each in its own process, as a user runs it, after a 10 µs run of every case has compiled the kernels into
Warp's cache; without ``--crossing``: at every step the preset's default treatment of zero-slip crossings,
``mean``), with ``--math exact fast`` also with ``--fast-math`` (``OUT/va_STEP_fast.h5``; docs/onchip.md,
"Fast math"), with ``--growth-dt`` once per spacing of the growth events (``default``: no option, the command's
default spacing, 5e-6 s for ``strang``, which the row records as read back from the run file; a number S:
``--growth-dt S``, ``OUT/va_STEP_gS.h5``; the paper's clock is 2.02e-7), and writes the wall time of each command
with the run's summary line to ``OUT/time_varying_area.json`` and a Markdown table beside it. Which step and spacing the
statistics allow is the statistical work-precision's question (docs/work_precision_statistics.md, regime ``va``);
this script only measures what each costs.

``--checkouts FIRST SECOND`` times two checkouts of aca_warp side by side instead of the installed package: each
command runs with that checkout's code (a package view as in ``scripts/compare_checkouts.py``, its own kernel
cache, warmed up by a 10 µs run of the same case first), the checkouts alternating case by case and ``--repeat``
times, and each case's two run files (the last repeat's) are compared dataset by dataset. Example (one GPU; the
paper's record is 0.36 s)::

    python3 scripts/time_varying_area.py --device cuda:0 --steps 1e-7 2.5e-7 5e-7 --out out/va_time
    python3 scripts/time_varying_area.py --device cuda:0 --steps 5e-8 --math exact fast --out out/va_fast
    python3 scripts/time_varying_area.py --device cuda:0 --steps 5e-8 1e-7 --growth-dt default 2.02e-7 --out out/va_g
    python3 scripts/time_varying_area.py --device cuda:0 --steps default 5e-8 --out out/va_default  # the defaults
    python3 scripts/time_varying_area.py --device cuda:0 --steps 5e-8 --checkouts build/base . --repeat 2
    python3 scripts/time_varying_area.py --dry-run --steps 5e-8        # print the commands only
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from aca_warp.cli import Parser
from aca_warp.common.argtypes import positive, step_or_default

# runs the CLI with the package of the view in argv[1] (scripts/compare_checkouts.py's package view)
CHILD = (
    "import sys; sys.path.insert(0, sys.argv[1]); import aca_warp; "
    "assert aca_warp.__file__.startswith(sys.argv[1]), aca_warp.__file__; "
    "from aca_warp.cli import main; sys.exit(main(sys.argv[2:]))"
)


@dataclass(frozen=True)
class Case:
    """One timed case: the fixed step [s] (None: no ``--dt``, the command's default), CUDA fast math or not, and the
    growth events' spacing [s] (None: no ``--growth-dt``, the command's default)."""

    step: float | None
    fast: bool = False
    growth_dt: float | None = None

    def fields(self) -> dict:
        """The case as a result row's fields."""
        return {"step_s": self.step, "fast_math": self.fast, "growth_dt_s": self.growth_dt}


def spacing(text: str) -> float | None:
    """``--growth-dt`` value: ``default`` (no option: None) or a positive number of seconds."""
    if text == "scene":
        raise argparse.ArgumentTypeError("'scene' is no spacing: give the scene's interval (2.02e-7 s for the preset)")
    return None if text == "default" else positive(text)


def settings_used(path: Path) -> dict[str, float | None]:
    """The step and the spacing of growth events a run file says its run took [s], as ``step_used_s`` and
    ``growth_dt_used_s`` (None where it names none, or is unreadable)."""
    import h5py

    from aca_warp.common.errors import SceneError
    from aca_warp.common.files import attr_value

    try:
        with h5py.File(path, "r") as f:
            options = attr_value(f.attrs["run_options"])  # as the hf command's summary line reads them
            return {"step_used_s": options.get("dt"), "growth_dt_used_s": options.get("growth_dt")}
    except (OSError, KeyError, AttributeError, SceneError):  # no file, no options, options that are not JSON
        return {"step_used_s": None, "growth_dt_used_s": None}


def run_file(out: Path, case: Case, checkout: int | None = None) -> Path:
    """The run file of one case (of checkout 0 or 1 with ``--checkouts``)."""
    growth = "" if case.growth_dt is None else f"_g{case.growth_dt:g}"
    kept = "" if checkout is None else f"_c{checkout}"
    step = "default" if case.step is None else f"{case.step:g}"
    return out / f"va_{step}{growth}{'_fast' if case.fast else ''}{kept}.h5"


def command(case: Case, duration: float, device: str, out: Path, checkout: int | None = None) -> list[str]:
    """The command line timed for one case (``checkout``: its run file's)."""
    return [
        "aca-warp", "hf", "varying_area", "--duration", f"{duration:g}",
        *([] if case.step is None else ["--dt", f"{case.step:g}"]),
        "--precision", "fp32", "--device", device, "--overwrite", "-o", str(run_file(out, case, checkout)),
        *(["--fast-math"] if case.fast else []),
        *([] if case.growth_dt is None else ["--growth-dt", f"{case.growth_dt:g}"]),
    ]  # fmt: skip


def in_view(cmd: list[str], view: Path) -> list[str]:
    """``cmd`` (an ``aca-warp`` command line) run with the package of a checkout's view instead of the installed one."""
    return [sys.executable, "-c", CHILD, str(view), *cmd[1:]]


def time_one(cmd: list[str], env: dict[str, str] | None = None) -> dict:
    """Wall time [s], exit code and the last output line of one command (in environment ``env``, default this one)."""
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    lines = (proc.stdout + proc.stderr).strip().splitlines()
    return {
        "command": " ".join(cmd),
        "wall_s": round(wall, 2),
        "exit": proc.returncode,
        "summary": lines[-1] if lines else "",
    }


def machine_of(run_file: Path) -> str:
    """The device and host a run file says it ran on (its ``device_name`` and ``host`` attributes), else this host."""
    try:
        import h5py

        with h5py.File(run_file, "r") as f:
            return f"{f.attrs['device_name']}; host {f.attrs['host']}"
    except (OSError, KeyError):
        return f"{platform.node()} ({platform.processor() or platform.machine()})"


def _events(row: dict) -> str:
    """The growth events' spacing of a row, in words: the one asked, or the command's default with the spacing its
    run file names ("default (scene)" where it names none or could not be read; "scene": a row of a result file
    written before the rows named it, at the scene's own clock, then the command's default)."""
    g, used = row.get("growth_dt_s"), row.get("growth_dt_used_s")
    if g is not None:
        return f"{g:g}"
    return "scene" if "growth_dt_used_s" not in row else f"default ({'scene' if used is None else f'{used:g}'})"


def _step(row: dict) -> str:
    """The step of a row, in words: the one asked, or the command's default with the step its run file names."""
    if row["step_s"] is not None:
        return f"{row['step_s']:g}"
    used = row.get("step_used_s")
    return f"default ({'?' if used is None else f'{used:g}'})"


def markdown(doc: dict) -> str:
    """The table of ``doc`` (one row per case)."""
    two = "checkouts" in doc
    rows = [
        f"| {_step(r)} | {'fast' if r.get('fast_math') else 'exact'} | {_events(r)} "
        + (f"| {r['checkout']} " if two else "")
        + f"| {r['wall_s']:.1f} | {r['exit']} | {r['summary']} |"
        for r in doc["rows"]
    ]
    head = [
        f"# Varying-area record through the CLI ({doc['duration_s']:g} s)",
        "",
        f"{doc['date']}, {doc['machine']}, device {doc['device']}; written by `python3 scripts/time_varying_area.py`.",
        *([f"Checkouts: 0 = `{doc['checkouts'][0]}`, 1 = `{doc['checkouts'][1]}`."] if two else []),
        "",
        "| step [s] | math | growth events every [s] | "
        + ("checkout | " if two else "")
        + "wall [s] | exit | summary |",
        "|---|---|---|" + ("---|" if two else "") + "---|---|---|",
    ]
    same = [
        f"* {_step(c)} s, {'fast' if c['fast_math'] else 'exact'}, events {_events(c)}: "
        + ("the two records bit-identical" if c["identical"] else f"records differ: {c['differ']}")
        for c in doc.get("comparisons", [])
    ]
    return "\n".join(head + rows + ([""] + same if same else [])) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cuda:0", help="Warp device of the runs (default cuda:0)")
    ap.add_argument("--steps", type=step_or_default, nargs="+", default=[1e-7, 2.5e-7, 5e-7], metavar="S",
                    help="fixed steps to time [s] (default 1e-7 2.5e-7 5e-7); default: no --dt, the command's default "
                    "step, which the row records as read back from the run file")  # fmt: skip
    ap.add_argument("--duration", type=positive, default=0.36, metavar="S", help="record length [s] (default 0.36)")
    ap.add_argument("--out", default="out/va_time", help="folder of the run files and the results")
    ap.add_argument("--math", nargs="+", choices=("exact", "fast"), default=["exact"],
                    help="exact (default) and/or fast: each step also with --fast-math (fp32 on CUDA)")  # fmt: skip
    ap.add_argument("--growth-dt", type=spacing, nargs="+", default=[None], metavar="S",
                    help="spacings of the growth events [s] (aca-warp hf --growth-dt), each step with each; default "
                    "(the default): no option, the command's default spacing; the paper's clock: 2.02e-7")  # fmt: skip
    ap.add_argument("--checkouts", type=Path, nargs=2, metavar=("FIRST", "SECOND"),
                    help="time these two checkouts of aca_warp side by side (run files compared)")  # fmt: skip
    ap.add_argument("--repeat", type=int, default=1, choices=range(1, 11), metavar="N",
                    help="with --checkouts: runs of each checkout per case, alternating (1-10, default 1)")  # fmt: skip
    ap.add_argument("--dry-run", action="store_true", help="print the commands and exit")
    args = ap.parse_args(argv)
    if args.checkouts:
        from compare_checkouts import refuse_bad_checkouts

        refuse_bad_checkouts(ap, args.checkouts)
    elif args.repeat != 1:
        ap.error("--repeat needs --checkouts")
    out = Path(args.out)
    cases = [Case(s, m == "fast", g) for s in args.steps for g in args.growth_dt for m in args.math]
    ks = (0, 1) if args.checkouts else (None,)
    cmds = [command(c, args.duration, args.device, out, k) for c in cases for k in ks]
    if args.dry_run:  # the commands, for this machine or another: the device is not looked up
        print("\n".join(" ".join(c) for c in cmds))
        return 0
    from aca_warp.common.devices import get_device
    from aca_warp.common.errors import AcaError
    from aca_warp.common.files import check_output_folder

    try:
        if get_device(args.device).is_cpu and "fast" in args.math:
            ap.error("--math fast: fast math applies to CUDA devices only")
        check_output_folder(out)
    except AcaError as e:
        ap.error(str(e))
    out.mkdir(parents=True, exist_ok=True)
    if args.checkouts:
        rows, extra = time_checkouts(args, cases, out)
    else:
        rows, extra = [], {}
        with tempfile.TemporaryDirectory(prefix="va_warm_") as tmp:
            for case in cases:  # the warm-up: every kernel compiled into the cache before any case is timed
                if (w := time_one(command(case, 1e-5, args.device, Path(tmp))))["exit"] != 0:
                    raise SystemExit(f"the warm-up of {' '.join(command(case, 1e-5, args.device, Path(tmp)))} "
                                     f"failed: {w['summary']}")  # fmt: skip
        for case, cmd in zip(cases, cmds, strict=True):
            rows.append(case.fields() | time_one(cmd) | settings_used(run_file(out, case)))
            report(rows[-1], out)
    doc = {
        "date": time.strftime("%Y-%m-%d %H:%M"),
        "machine": machine_of(run_file(out, cases[0], 0 if args.checkouts else None)),
        "device": args.device,
        "duration_s": args.duration,
        "rows": rows,
        **extra,
    }
    (out / "time_varying_area.json").write_text(json.dumps(doc, indent=1) + "\n")
    (out / "time_varying_area.md").write_text(markdown(doc))
    ok = all(r["exit"] == 0 for r in rows) and all(c["identical"] for c in extra.get("comparisons", []))
    return 0 if ok else 1


def report(row: dict, out: Path) -> None:
    """Print one timed row (its run file named as under ``out``)."""
    row["summary"] = row["summary"].replace(f"{out}/", "")
    what = f"dt {_step(row)} s, events {_events(row)}{' fast math' if row['fast_math'] else ''}"
    who = f" [checkout {row['checkout']}]" if "checkout" in row else ""
    print(f"{what}{who}: {row['wall_s']:.1f} s  {row['summary']}", flush=True)


def time_checkouts(args: argparse.Namespace, cases: list[Case], out: Path) -> tuple[list, dict]:
    """The cases run from the two checkouts, alternating, ``--repeat`` times, each checkout warmed up first per case;
    the rows and {"checkouts", "comparisons"} (each case's two last run files compared dataset by dataset)."""
    from compare_checkouts import package_view

    rows = []
    with tempfile.TemporaryDirectory(prefix="va_checkouts_") as tmp:
        views = [package_view(c, Path(tmp) / f"view{k}") for k, c in enumerate(args.checkouts)]
        envs = [{**os.environ, "WARP_CACHE_PATH": str(Path(tmp) / f"cache{k}")} for k in range(2)]
        for case in cases:
            for k in range(2):  # the warm-up: the same kernels compiled into each checkout's cache
                warm = command(case, 1e-5, args.device, Path(tmp), k)
                if (w := time_one(in_view(warm, views[k]), envs[k]))["exit"] != 0:
                    raise SystemExit(f"checkout {k} ({args.checkouts[k]}) failed its warm-up: {w['summary']}")
        for r in range(args.repeat):
            for case in cases:
                for k in range(2):
                    cmd = command(case, args.duration, args.device, out, k)
                    row = time_one(in_view(cmd, views[k]), envs[k])
                    row["command"] = " ".join(cmd)  # as a user would type it in that checkout
                    used = settings_used(run_file(out, case, k))
                    rows.append(case.fields() | {"checkout": k, "repeat": r} | row | used)
                    report(rows[-1], out)
    comparisons = []
    for case in cases:
        files = [run_file(out, case, k) for k in range(2)]
        last = [r for r in rows if r["repeat"] == args.repeat - 1 and all(r[k] == v for k, v in case.fields().items())]
        if any(r["exit"] != 0 for r in last):
            comparisons.append(case.fields() | settings_used(files[1]) | {"identical": False, "differ": "a run failed"})
            continue
        comparisons.append(case.fields() | settings_used(files[1]) | compare_runs(*files))
    return rows, {"checkouts": [str(c) for c in args.checkouts], "comparisons": comparisons}


def compare_runs(first: Path, second: Path) -> dict:
    """{"identical": every dataset in both run files and bit for bit the same, "differ": the datasets that differ or
    are in one file only}."""
    from compare_checkouts import compare, same_results

    c = compare(first, second)
    return {"identical": same_results(c), "differ": sorted({*c["different"], *c["only_first"], *c["only_second"]})}


if __name__ == "__main__":
    raise SystemExit(main())
