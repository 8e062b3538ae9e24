#!/usr/bin/env python3
"""The CWT of μ of the §3.2 growth runs (Fig. 11) as a figure, from a validation results file.

The ensemble mean of every pad's stored CWT (window means, amplitude-true and energy-normalised, each window scaled
to its largest value) of ``va_full`` and ``va_full_rest``, with the median first line of Σu̇'s STFT (white) and the
median CWT ridge within §4's 20–80 kHz (red), the lines the §3.2 rows read. Example::

    python3 scripts/validation_cwt_figure.py docs/validation/seeds32/results.json.gz docs/figures/validation/va_cwt.png
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("results", type=Path, help="a validation results file (results.json or .json.gz)")
    p.add_argument("out", type=Path, help="the PNG to write")
    args = p.parse_args(argv)
    import aca_warp.studies.validation  # noqa: F401  (registers the experiments)
    from aca_warp.studies.validation.area_figure import cwt_figure
    from aca_warp.studies.validation.results import read_results

    if not args.results.is_file():
        p.error(f"no such results file: {args.results}")
    results, _, _ = read_results(args.results)
    try:
        path = cwt_figure(results, args.out)
    except ValueError as e:
        print(f"validation_cwt_figure: {e}", file=sys.stderr)
        return 2
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
