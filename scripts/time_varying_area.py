#!/usr/bin/env python3
"""Time the varying-area record through the command line at several fixed steps.

Runs ``aca-warp hf varying_area --duration D --dt STEP --precision fp32 --device DEV -o OUT/va_STEP.h5`` once per
step (each in its own process, as a user runs it, kernels cached after the first), with ``--math exact fast`` also
with ``--fast-math`` (``OUT/va_STEP_fast.h5``; docs/onchip.md, "Fast math"), and writes the wall time of each
command with the run's summary line to ``OUT/time_varying_area.json`` and a Markdown table beside it. Which step the
statistics allow is the statistical work-precision's question (docs/work_precision_statistics.md, regime ``va``);
this script only measures what each step costs. Example (one GPU; the paper's record is 0.36 s)::

    python3 scripts/time_varying_area.py --device cuda:0 --steps 1e-7 2.5e-7 5e-7 --out out/va_time
    python3 scripts/time_varying_area.py --device cuda:0 --steps 5e-8 --math exact fast --out out/va_fast
    python3 scripts/time_varying_area.py --dry-run --steps 5e-8        # print the commands only
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import time
from pathlib import Path

from aca_warp.cli import Parser
from aca_warp.common.argtypes import positive


def run_file(out: Path, step: float, fast: bool) -> Path:
    """The run file of one step [s], with or without fast math."""
    return out / f"va_{step:g}{'_fast' if fast else ''}.h5"


def command(step: float, duration: float, device: str, out: Path, fast: bool = False) -> list[str]:
    """The command line timed for one step [s] (``fast``: with CUDA fast math)."""
    return [
        "aca-warp", "hf", "varying_area", "--duration", f"{duration:g}", "--dt", f"{step:g}",
        "--precision", "fp32", "--device", device, "--overwrite", "-o", str(run_file(out, step, fast)),
        *(["--fast-math"] if fast else []),
    ]  # fmt: skip


def time_one(cmd: list[str]) -> dict:
    """Wall time [s], exit code and the last output line of one command."""
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
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


def markdown(doc: dict) -> str:
    """The table of ``doc`` (one row per step)."""
    rows = [
        f"| {r['step_s']:g} | {'fast' if r.get('fast_math') else 'exact'} | {r['wall_s']:.1f} | {r['exit']} "
        f"| {r['summary']} |"
        for r in doc["rows"]
    ]
    head = [
        f"# Varying-area record through the CLI ({doc['duration_s']:g} s)",
        "",
        f"{doc['date']}, {doc['machine']}, device {doc['device']}; written by `python3 scripts/time_varying_area.py`.",
        "",
        "| step [s] | math | wall [s] | exit | summary |",
        "|---|---|---|---|---|",
    ]
    return "\n".join(head + rows) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cuda:0", help="Warp device of the runs (default cuda:0)")
    ap.add_argument("--steps", type=positive, nargs="+", default=[1e-7, 2.5e-7, 5e-7], metavar="S",
                    help="fixed steps to time [s] (default 1e-7 2.5e-7 5e-7)")  # fmt: skip
    ap.add_argument("--duration", type=positive, default=0.36, metavar="S", help="record length [s] (default 0.36)")
    ap.add_argument("--out", default="out/va_time", help="folder of the run files and the results")
    ap.add_argument("--math", nargs="+", choices=("exact", "fast"), default=["exact"],
                    help="exact (default) and/or fast: each step also with --fast-math (fp32 on CUDA)")  # fmt: skip
    ap.add_argument("--dry-run", action="store_true", help="print the commands and exit")
    args = ap.parse_args(argv)
    out = Path(args.out)
    cases = [(s, m == "fast") for s in args.steps for m in args.math]
    cmds = [command(s, args.duration, args.device, out, fast) for s, fast in cases]
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
    rows = []
    for (step, fast), cmd in zip(cases, cmds, strict=True):
        row = time_one(cmd)
        row["summary"] = row["summary"].replace(f"{out}/", "")  # the run file as named under --out
        rows.append({"step_s": step, "fast_math": fast} | row)
        what = f"dt {step:g} s{' fast math' if fast else ''}"
        print(f"{what}: {rows[-1]['wall_s']:.1f} s  {rows[-1]['summary']}", flush=True)
    doc = {
        "date": time.strftime("%Y-%m-%d %H:%M"),
        "machine": machine_of(run_file(out, *cases[0])),
        "device": args.device,
        "duration_s": args.duration,
        "rows": rows,
    }
    (out / "time_varying_area.json").write_text(json.dumps(doc, indent=1) + "\n")
    (out / "time_varying_area.md").write_text(markdown(doc))
    return 0 if all(r["exit"] == 0 for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
