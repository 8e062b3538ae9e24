#!/usr/bin/env python3
"""How a change of the kernels moved the statistics of strang's default stepping, against a change of rounding.

Reads two folders of the statistical work-precision's merged result files, one regime each
(``FOLDER/<regime>/wps_*_<regime>.json``): BEFORE, whose files hold strang's default row (2.5e-7 s, the crossings
averaged, growth events every 5 µs where the pads grow) and its fast-math twin on the same kernels, and AFTER, the
same parts continued with the default row made again on other kernels. Prints, per regime and measure, the error of
the ensemble mean over σ between seeds and the rule's verdict (``--rule``, criterion ``resolution``) of the default
row before, of fast math before (rounding alone changed) and of the default row after; then the rms and the largest
change of error/σ from the default row before, for fast math and for the change, over every regime and measure.

    python3 scripts/default_row_changes.py docs/figures/work_precision_statistics/fast_mean \\
        docs/figures/work_precision_statistics/step_sample
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from aca_warp.studies import work_precision_stats_rule as rule

STEP = "dt=2.5e-07"


def default_row(regime: dict[str, Any], fast: bool) -> dict[str, Any]:
    """The regime's usable row of strang's default stepping (``fast``: its fast-math twin); KeyError if none."""
    rows = [s for s in regime["settings"] if s["role"] == "grid" and rule.usable(s)
            and s["label"].startswith("strang@fp32:") and STEP in s["label"] and s["label"].endswith(":mean")
            and (":fast" in s["label"]) == fast]  # fmt: skip
    grown = [s for s in rows if "growth_dt=5e-06" in s["label"]]
    if not (grown or rows):
        raise KeyError(f"{regime.get('name', '?')} has no {'fast-math ' if fast else ''}row of the default stepping")
    return (grown or rows)[0]


def merged(folder: Path) -> dict[str, Path]:
    """The merged result file of each regime folder of ``folder`` (the one directly in it, not a part's)."""
    out = {}
    for sub in sorted(p for p in folder.iterdir() if p.is_dir()):
        files = sorted(sub.glob(f"wps_*_{sub.name}.json"))
        if files:
            out[sub.name] = files[0]
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("before", type=Path, help="folder of the merged files with the default and fast-math rows")
    ap.add_argument("after", type=Path, help="folder of the same regimes with the default row made again")
    ap.add_argument("--rule", type=float, default=rule.DEFAULT_RULE, help="the rule, in σ between seeds (0.25)")
    args = ap.parse_args(argv)
    for folder in (args.before, args.after):
        if not folder.is_dir():
            ap.error(f"{folder} is not a folder")
    before, after = merged(args.before), merged(args.after)
    common = [r for r in before if r in after]
    if not common:
        ap.error(f"no regime has a merged file in both {args.before} and {args.after}")
    d_fast: list[float] = []
    d_new: list[float] = []
    print(
        f"error/σ and verdict (rule {args.rule:g} σ, criterion resolution): default before | fast math before | "
        "default after"
    )
    for name in common:
        b, a = (rule.load_results(p)["regimes"][name] for p in (before[name], after[name]))
        rows = [(b, default_row(b, False)), (b, default_row(b, True)), (a, default_row(a, False))]
        print(f"{name}: {rows[2][1]['label']}")
        for m in b["measures"]:
            errs, verdicts = [], []
            for reg, row in rows:
                c = rule.compare_setting(reg, row, m)
                errs.append(c.error / c.sigma if c.sigma else math.nan)
                verdicts.append(rule.verdict(reg, row, m, args.rule, "resolution"))
            moved = "  (kept before, not after)" if rule.kept(verdicts[0]) and not rule.kept(verdicts[2]) else ""
            print(f"  {m:15s} " + " | ".join(f"{e:6.3f} {v:17s}" for e, v in zip(errs, verdicts, strict=True)) + moved)
            d_fast.append(errs[1] - errs[0])
            d_new.append(errs[2] - errs[0])

    def rms(x: list[float]) -> float:
        return math.sqrt(sum(v * v for v in x) / len(x))

    print(
        f"change of error/σ from the default row before, over {len(d_new)} regime-measures: fast math (rounding) "
        f"rms {rms(d_fast):.3f}, largest {max(map(abs, d_fast)):.3f}, mean {sum(d_fast) / len(d_fast):+.3f}; "
        f"after rms {rms(d_new):.3f}, largest {max(map(abs, d_new)):.3f}, mean {sum(d_new) / len(d_new):+.3f}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
