#!/usr/bin/env python3
"""The validation page's figures, from a validation results file, written into a folder:

* ``first_peaks.png`` (§3.1, Fig. 8, Table 1): the first velocity peak of HF1–HF4 by every reading the paper leaves
  open, from equilibrium and from rest, mean and 95 % interval over the seeds against the paper's 73 and 32.8 kHz,
  and the exponent of f ∝ A^b each reading gives against −1/4;
* ``va_cwt.png`` (§3.2, Fig. 11): the ensemble mean of every growth pad's stored CWT of μ (``va_full``,
  ``va_full_rest``; window means, amplitude-true and energy-normalised, each window scaled to its largest value),
  with the median first line of Σu̇'s STFT (white) and the median CWT ridge within §4's 20–80 kHz (red).

* ``verdicts.png``: how many rows carry each verdict, per section of the paper, from the primary start and from rest
  at the paper's length (the rows measured there, beside the primary's verdicts on the same rows).

A figure whose data the file does not hold is reported and not written; the others are (exit status 2 then).
Example::

    python3 scripts/validation_figures.py docs/validation/seeds32/results.json.gz docs/figures/validation
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

FIGURES = {"verdicts": "verdicts.png", "peaks": "first_peaks.png", "cwt": "va_cwt.png"}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("results", type=Path, help="a validation results file (results.json or .json.gz)")
    p.add_argument("out", type=Path, help="the folder to write the PNGs into (created if missing)")
    p.add_argument("--only", nargs="+", choices=sorted(FIGURES), default=list(FIGURES),
                   help="the figures to write (default: all)")  # fmt: skip
    args = p.parse_args(argv)
    import aca_warp.studies.validation  # noqa: F401  (registers the experiments)
    from aca_warp.studies.validation.area_figure import cwt_figure
    from aca_warp.studies.validation.peaks_figure import peaks_figure
    from aca_warp.studies.validation.results import read_results
    from aca_warp.studies.validation.verdicts_figure import verdicts_figure

    if not args.results.is_file():
        p.error(f"no such results file: {args.results}")
    if args.out.exists() and not args.out.is_dir():
        p.error(f"not a folder: {args.out}")
    results, _, cfg = read_results(args.results)
    draw = {
        "verdicts": lambda r, path: verdicts_figure(r, cfg, path),
        "peaks": peaks_figure,
        "cwt": cwt_figure,
    }
    status = 0
    for name in args.only:
        try:
            path = draw[name](results, args.out / FIGURES[name])
        except ValueError as e:
            print(f"validation_figures: {FIGURES[name]} not written: {e}", file=sys.stderr)
            status = 2
            continue
        print(f"wrote {path}")
    return status


if __name__ == "__main__":
    sys.exit(main())
