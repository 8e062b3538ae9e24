#!/usr/bin/env python3
"""Per-kernel GPU time per step from an Nsight Compute summary (``ncu --print-summary per-kernel --csv``).

Made for the LF profile (docs/lf_model.md, "Speed"); works for any run whose step count is known::

    ncu --metrics gpu__time_duration.sum --print-summary per-kernel --csv \\
        python3 scripts/bench_lf.py --device cuda:0 --duration 1.0 > ncu_lf.csv
    python3 scripts/ncu_summary.py ncu_lf.csv --steps 99 --markdown table.md

ncu runs every kernel alone (serialised, caches flushed between replays), so the sum exceeds the graph-replayed
step time; it ranks the kernels, it does not time the step.
"""

from __future__ import annotations

import argparse
import csv
import re
import sys
from pathlib import Path


def summarise(text: str, steps: int) -> list[tuple[str, int, float, float, str]]:
    """Rows (kernel, invocations, mean µs per invocation, µs per step, grid × block), largest first."""
    lines = text.splitlines()
    head = next((k for k, line in enumerate(lines) if line.startswith('"Process ID"')), None)
    if head is None:
        raise ValueError("no ncu per-kernel summary table (run ncu with --print-summary per-kernel --csv)")
    rows = []
    for r in csv.DictReader(lines[head:]):
        if r.get("Metric Name") != "gpu__time_duration.sum":
            continue
        n = int(r["Invocations"].replace(",", ""))
        mean_ns = float(r["Average"].replace(",", ""))
        name = r["Kernel Name"]
        warp = re.match(r"(.+)_[0-9a-f]{8}_cuda_kernel_forward", name)
        name = warp.group(1) if warp else re.sub(r"<.*", "", name).replace("void ", "")[:60]
        rows.append((name, n, mean_ns / 1e3, n * mean_ns / 1e3 / steps, f"{r['Grid Size']} × {r['Block Size']}"))
    return sorted(rows, key=lambda x: -x[3])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("csv", help="ncu output (stdout of the profiled run, with the CSV summary at its end)")
    ap.add_argument("--steps", type=int, required=True, help="steps the profiled run took")
    ap.add_argument("--markdown", help="also write the table here")
    args = ap.parse_args(argv)
    try:
        rows = summarise(Path(args.csv).read_text(), args.steps)
    except (OSError, ValueError) as e:
        print(f"ncu_summary: {e}", file=sys.stderr)
        return 2
    total = sum(r[3] for r in rows)
    out = ["| kernel | launches | µs per launch | µs per step | grid × block |", "|---|---|---|---|---|"]
    out += [f"| `{k}` | {n} | {m:.2f} | {s:.1f} | {g} |" for k, n, m, s, g in rows]
    out.append(f"| **sum** | | | **{total:.0f}** | |")
    text = "\n".join(out)
    print(text)
    if args.markdown:
        Path(args.markdown).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
