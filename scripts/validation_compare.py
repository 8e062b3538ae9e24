#!/usr/bin/env python3
"""Two validation results files side by side: every number the rows read, experiment by experiment, and the rows
whose verdict or value text differ. Exit 0 when everything is the same, 1 when something differs, 2 for a file that
is not a results file. Example (does a rerun regenerate the committed file?)::

    python3 scripts/validation.py --device cuda:0 --out DIR --results RERUN
    python3 scripts/validation_compare.py docs/validation/results.json RERUN/results.json

With --partial the first file holds some experiments only, e.g. one group run at another stepping, and the page's
verdicts are compared as if they replaced the second file's::

    python3 scripts/validation_compare.py --partial docs/validation/ms_short_reference_step/results.json \
        docs/validation/results.json
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("first", type=Path, help="a validation results.json")
    ap.add_argument("second", type=Path, help="another one")
    ap.add_argument("--partial", action="store_true",
                    help="the first file holds some experiments only: the others are taken from the second, and only "
                         "its own are compared entry by entry")  # fmt: skip
    args = ap.parse_args(argv)
    import aca_warp.studies.validation  # noqa: F401  (registers the experiments)
    from aca_warp.studies.validation.compare import report

    try:
        lines, same = report(args.first, args.second, args.partial)
    except ValueError as e:
        print(f"validation_compare.py: error: {e}", file=sys.stderr)
        return 2
    print("\n".join(lines))
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
