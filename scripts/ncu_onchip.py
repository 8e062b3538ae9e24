"""Per-step and per-patch instruction figures of the on-chip HF kernel from Nsight Compute CSV files.

Each input is the ``--csv`` output of one ``ncu`` run on one launch of the on-chip kernel (``-k regex:onchip_strang
--launch-skip 1 --launch-count 1``: the warm-up launch skipped, the timed one profiled), with at least the metrics
``smsp__inst_executed.sum``, ``smsp__thread_inst_executed.sum`` (optional), ``smsp__issue_active.avg.pct_of_peak_
sustained_active``, ``l1tex__data_pipe_lsu_wavefronts_mem_shared_op_ld.sum`` and
``l1tex__data_bank_conflicts_pipe_lsu_mem_shared_op_ld.sum``, and the kernel time (``gpu__time_duration.sum`` or
the SpeedOfLight section's ``Duration``). The table gives, per case: µs per step, warp instructions per step and per
patch-step, thread instructions per patch-step, issue-slot use, shared-memory load wavefronts per step and the
share of them that are bank conflicts, and the ceiling of patch-steps/s at full issue on the profiled device
(``--sms`` SMs × 4 schedulers × ``--clock`` Hz, one warp instruction per scheduler and cycle).

Example (the files of docs/benchmarks/onchip_h100/ncu_*.csv, made on an H100 as docs/onchip.md shows)::

    python scripts/ncu_onchip.py --steps 2000 --patches 1758 \\
        "docs/benchmarks/onchip_h100/ncu_p1024_k1.csv=1024 pads, one block each:1024" \\
        "docs/benchmarks/onchip_h100/ncu_split_full.csv=one pad, one block"

``FILE=LABEL[:PADS]``: PADS (default 1) pads advanced by the launch.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

INST = "smsp__inst_executed.sum"
THREAD_INST = "smsp__thread_inst_executed.sum"
ISSUE = "smsp__issue_active.avg.pct_of_peak_sustained_active"
WAVES = "l1tex__data_pipe_lsu_wavefronts_mem_shared_op_ld.sum"
CONFLICTS = "l1tex__data_bank_conflicts_pipe_lsu_mem_shared_op_ld.sum"
_TIME_UNITS = {"ns": 1e-9, "nsecond": 1e-9, "us": 1e-6, "usecond": 1e-6, "ms": 1e-3, "msecond": 1e-3}


def read_metrics(path: Path) -> dict[str, float]:
    """Metric name → value of the (single) kernel launch in an ``ncu --csv`` file; times in seconds."""
    lines = [line for line in path.read_text().splitlines() if line.startswith('"')]
    rows = list(csv.reader(lines))
    if not rows or "Metric Name" not in rows[0]:
        raise ValueError(f"{path}: not an ncu --csv file with metric rows")
    head = rows[0]
    launches = {r[head.index("ID")] for r in rows[1:]}
    if len(launches) != 1:
        raise ValueError(f"{path}: {len(launches)} kernel launches, expected one (use --launch-count 1)")
    out: dict[str, float] = {}
    for r in rows[1:]:
        d = dict(zip(head, r, strict=False))
        try:
            value = float(d["Metric Value"].replace(",", ""))
        except ValueError:
            continue
        name = d["Metric Name"]
        if name in ("gpu__time_duration.sum", "Duration"):
            value *= _TIME_UNITS.get(d["Metric Unit"], float("nan"))
            name = "time_s"
        out[name] = value
    missing = [m for m in (INST, ISSUE, WAVES, CONFLICTS, "time_s") if m not in out]
    if missing:
        raise ValueError(f"{path}: missing metrics {missing}")
    return out


def summary_row(m: dict[str, float], steps: int, patches: int, pads: int, sms: int, clock: float) -> dict[str, float]:
    """Per-step figures of one launch of ``steps`` steps of ``pads`` pads of ``patches`` patches."""
    pad_steps = steps * pads
    warp = m[INST] / pad_steps
    return {
        "us_per_step": 1e6 * m["time_s"] / steps,
        "warp_inst_per_pad_step": warp,
        "warp_inst_per_patch_step": warp / patches,
        "thread_inst_per_patch_step": m.get(THREAD_INST, float("nan")) / pad_steps / patches,
        "issue_active_pct": m[ISSUE],
        "smem_load_wavefronts_per_pad_step": m[WAVES] / pad_steps,
        "bank_conflict_share": m[CONFLICTS] / m[WAVES] if m[WAVES] else 0.0,
        "ceiling_patch_steps_per_s": sms * 4 * clock / (warp / patches),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("inputs", nargs="+", help="FILE=LABEL[:PADS] per profiled launch")
    ap.add_argument("--steps", type=int, required=True, help="steps of each profiled launch")
    ap.add_argument("--patches", type=int, required=True, help="patches per pad")
    ap.add_argument("--sms", type=int, default=132, help="SMs of the device (default: H100 SXM, 132)")
    ap.add_argument("--clock", type=float, default=1.98e9, help="SM clock [Hz] (default 1.98e9)")
    args = ap.parse_args(argv)
    print(
        "| case | µs/step | warp instr. per pad-step | per patch-step | thread instr. per patch-step | issue slots "
        "busy | smem load wavefronts per pad-step | bank conflicts | patch-steps/s at full issue |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for spec in args.inputs:
        path, _, label = spec.partition("=")
        label, _, pads = label.rpartition(":") if ":" in label else (label, "", "1")
        try:
            row = summary_row(read_metrics(Path(path)), args.steps, args.patches, int(pads), args.sms, args.clock)
        except (OSError, ValueError) as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        print(
            f"| {label or path} | {row['us_per_step']:.2f} | {row['warp_inst_per_pad_step']:.0f} | "
            f"{row['warp_inst_per_patch_step']:.1f} | {row['thread_inst_per_patch_step']:.0f} | "
            f"{row['issue_active_pct']:.1f} % | {row['smem_load_wavefronts_per_pad_step']:.0f} | "
            f"{100 * row['bank_conflict_share']:.0f} % | {row['ceiling_patch_steps_per_s']:.2e} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
