#!/usr/bin/env python3
"""Two steps of strang's default stepping side by side in every regime of the statistical work-precision.

Reads a folder of merged result files, one regime each (``FOLDER/<regime>/wps_*_<regime>.json``), and in each the
rows of strang in fp32 with the crossings averaged (growth events every 5 µs where the pads grow; no fast math) at
the steps asked (``--steps``, as the rows' ``dt`` holds them). Prints, per regime, whether each row keeps every
measure (rule ``--rule`` σ between seeds, criterion ``resolution``), its stepping wall time, and the measures a row
does not keep or keeps within resolution only, with error/σ and the upper end of the 95 % interval of the bias/σ;
then, per regime and measure, error/σ and verdict of each row (``--full``). ``--markdown``: the first table as
Markdown. Example (the study of three steps a 1 µs sample)::

    python3 scripts/step_rows.py docs/figures/work_precision_statistics/three_steps --steps 2.5e-7 3.33334e-7
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from default_row_changes import merged

from aca_warp.studies import work_precision_stats_rule as rule


def stepping_rows(regime: dict[str, Any], steps: list[float]) -> list[dict[str, Any]]:
    """The regime's usable fp32 rows with the crossings averaged at each of ``steps`` [s] (growth every 5 µs where a
    row has growth events; no fast math); KeyError naming a step without one."""
    out = []
    for dt in steps:
        rows = [s for s in regime["settings"] if s["role"] == "grid" and rule.usable(s) and s["precision"] == "fp32"
                and s.get("crossing") == "mean" and not s.get("fast_math") and s.get("growth_dt") in (None, 5e-6)
                and s.get("dt") is not None and abs(s["dt"] - dt) <= 1e-9 * dt]  # fmt: skip
        if not rows:
            raise KeyError(f"{regime.get('name', '?')} has no fp32 row at {dt:g} s with the crossings averaged")
        grown = [s for s in rows if s.get("growth_dt") == 5e-6]
        out.append((grown or rows)[0])
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folder", type=Path, help="folder of merged result files, one subfolder per regime")
    ap.add_argument("--steps", type=float, nargs="+", required=True, metavar="S", help="steps as the rows ask them [s]")
    ap.add_argument("--rule", type=float, default=rule.DEFAULT_RULE, help="the rule, in σ between seeds (0.25)")
    ap.add_argument("--markdown", action="store_true", help="the per-regime table as Markdown")
    ap.add_argument("--full", action="store_true", help="every measure's error/σ and verdict too")
    args = ap.parse_args(argv)
    if not args.folder.is_dir():
        ap.error(f"{args.folder} is not a folder")
    files = merged(args.folder)
    if not files:
        ap.error(f"no regime folder with a merged result file in {args.folder}")
    steps = " | ".join(f"{dt:.3g} s" for dt in args.steps)
    if args.markdown:
        print(f"| regime | seeds | keeps every measure: {steps} | stepping wall [s]: {steps} | "
              f"not strictly kept at {args.steps[-1]:.3g} s: error/σ (95 % bound/σ), verdict |")  # fmt: skip
        print("|---|---|---|---|---|")
    for name, path in files.items():
        regime = rule.load_results(path)["regimes"][name]
        rows = stepping_rows(regime, args.steps)
        verdicts = [{m: rule.verdict(regime, r, m, args.rule, "resolution") for m in regime["measures"]} for r in rows]
        every = ["yes" if all(rule.kept(v) for v in vs.values()) else "no" for vs in verdicts]
        last = []
        for m, v in verdicts[-1].items():
            if v != "keeps":
                c = rule.compare_setting(regime, rows[-1], m)
                last.append(f"{rule.MEASURES[m].label} {c.ratio:.2f} ({c.bound_ratio:.2f}), {v}")
        n = rule.compare_setting(regime, rows[0], regime["measures"][0]).n
        walls = " / ".join(f"{r['wall_s']:.2f}" for r in rows)
        if args.markdown:
            print(f"| {name} | {n} | {' / '.join(every)} | {walls} | {'; '.join(last) or '–'} |")
        else:
            print(f"{name} ({n} seeds): keeps every measure {' / '.join(every)}; wall {walls} s; "
                  f"at {args.steps[-1]:.3g} s not strictly kept: {'; '.join(last) or 'none'}")  # fmt: skip
        if args.full:
            for m in regime["measures"]:
                cells = []
                for r, vs in zip(rows, verdicts, strict=True):
                    c = rule.compare_setting(regime, r, m)
                    cells.append(f"{c.ratio:6.3f} ({c.bound_ratio:5.2f}) {vs[m]:17s}")
                print(f"  {m:15s} " + " | ".join(cells))
    return 0


if __name__ == "__main__":
    sys.exit(main())
