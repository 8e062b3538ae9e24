#!/usr/bin/env python3
"""The measured stepping of a validation results file, batch by batch, as a Markdown table with its sums.

Every figure comes from the results file (``run``: steps, stepping wall, µs per step, blocks per pad; ``plan``: the
simulated time and the estimate the run logged beside its batch); the experiments a file took from earlier calls
(``--with``) are lettered A, B, … by the call that ran them, in the order its meta records them. Example::

    python3 scripts/validation_cost.py docs/validation/results.json
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def table(path: Path) -> list[str]:
    """The Markdown lines of the table and the sums (all, and per section group) for results file ``path``."""
    import aca_warp.studies.validation  # noqa: F401  (registers the experiments)
    from aca_warp.studies.validation.cost import measured
    from aca_warp.studies.validation.results import read_results

    results, meta, _ = read_results(path)
    rows = measured(results, meta.get("with"))
    lines = [
        "| share | batch | pads × patches | run | stepping | steps | stepping wall | µs per step | blocks per pad "
        "| estimate |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lo, hi = r["patches"]
        blocks = "–" if r["blocks_per_pad"] is None else r["blocks_per_pad"]  # results files that did not record them
        estimate = "–" if r["estimate_s"] is None else f"{r['estimate_s']:.0f} s"
        lines.append(
            f"| {r['share']} | `{r['batch']}` | {r['pads']} × {lo if lo == hi else f'{lo}–{hi}'} | "
            f"{1e3 * r['duration_s']:.3g} ms | {r['stepping']} | {r['steps'] / 1e6:.2f} M | {r['wall_s']:.1f} s | "
            f"{r['us_per_step']:.2f} | {blocks} | {estimate} |"
        )
    total = sum(r["wall_s"] for r in rows)
    hf = sum(r["wall_s"] for r in rows if not r["section"].startswith("§3.3"))
    lines += [
        "",
        f"Stepping: {total:.1f} s in {len(rows)} batches ({hf:.1f} s for §3.1/§3.2, {total - hf:.1f} s for §3.3).",
    ]
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", type=Path, help="a validation results.json")
    args = ap.parse_args(argv)
    if not args.results.is_file():
        print(f"validation_cost: no results file {args.results}", file=sys.stderr)
        return 2
    try:
        print("\n".join(table(args.results)))
    except (ValueError, KeyError) as e:
        print(f"validation_cost: {args.results} is not a validation results file ({e})", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
