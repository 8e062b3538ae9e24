#!/usr/bin/env python3
"""How much the draw of seeds decides each verdict: the rows of a validation results file read on all its seeds and on
each of its disjoint draws of --size seeds (the validation's eight by default), beside other results files'
verdicts (--against, a column per file, and a line per file counting the rows it reads as all the seeds do).
Prints a markdown table (--split-only: of the rows whose draws disagree); exit 2 for a file that is not a results
file or holds fewer than two draws. Example (the 32-seed ensemble of every experiment against the eight-seed files
of two code versions)::

    python3 scripts/validation_draws.py docs/validation/seeds32/results.json.gz --size 8 \
        --against docs/validation/results.json docs/validation/rerun_twice/results.json
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", type=Path, help="a validation results.json (or .json.gz) of many seeds")
    ap.add_argument("--size", type=int, default=8, help="seeds per draw (8: the validation's)")
    ap.add_argument("--against", type=Path, nargs="+", default=[],
                    help="other results files, each of whose verdicts make a column (named by the file, and by its "
                         "folder where two files share a name)")  # fmt: skip
    ap.add_argument("--split-only", action="store_true", help="list only the rows whose draws disagree (or failed)")
    args = ap.parse_args(argv)
    import aca_warp.studies.validation  # noqa: F401  (registers the experiments)
    from aca_warp.studies.validation.draws import draw_verdicts, render, verdicts_by_statement
    from aca_warp.studies.validation.results import read_results

    try:
        results, _, cfg = read_results(args.results)
        against, labels = [], []
        names = [p.name for p in args.against]
        for path in args.against:
            other, _, ocfg = read_results(path)
            name = f"{path.parent.name}/{path.name}" if names.count(path.name) > 1 else path.name
            against.append(verdicts_by_statement(other, ocfg))
            labels.append(f"{name} ({ocfg.seeds} seeds)")
        table = draw_verdicts(results, cfg, args.size, against)
    except ValueError as e:
        print(f"validation_draws.py: error: {e}", file=sys.stderr)
        return 2
    print("\n".join(render(table, cfg, args.size, labels, args.split_only)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
