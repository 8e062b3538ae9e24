"""Command line ``aca-warp COMMAND ...``: the top-level parser and the entry point.

Each command registers its own parser from its package (``add_parsers(sub)`` in aca_warp.hf.commands,
aca_warp.lf.commands, aca_warp.analysis.commands, aca_warp.sweep, aca_warp.bench) and sets ``handler``; nothing
imports this module. Parsing imports no simulation code, so ``--help`` and argument errors answer at once.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from aca_warp import __version__
from aca_warp.common.errors import AcaError

EPILOG = """\
SCENE is a preset (hf1, hf2, hf3, hf4, varying_area) or a TOML scene file (docs/scenes.md).
Example:  aca-warp hf hf1 --duration 1e-3 -o run.h5
Units are SI throughout: seconds, metres, newtons. Exit codes: 0 done, 2 bad input (nothing written),
3 the run stopped on a fault or an unphysical result (the file holds everything before it, marked incomplete),
4 the output could not be written (disk full, file-size limit; the .partial keeps its last checkpoint),
130 interrupted (docs/faults.md).
"""


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``aca-warp``."""
    from aca_warp.analysis.commands import add_parsers as add_analysis
    from aca_warp.bench import add_parsers as add_bench
    from aca_warp.hf.commands import add_parsers as add_hf
    from aca_warp.lf.commands import add_parsers as add_lf
    from aca_warp.sweep import add_parsers as add_sweep

    p = argparse.ArgumentParser(
        prog="aca-warp",
        description="Abstract Cellular Automaton of the brake pad-disc "
        "boundary layer (Merlis & Ostermeyer 2019) in NVIDIA Warp.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=EPILOG,
    )
    p.add_argument("--version", action="version", version=f"aca-warp {__version__}")
    p.add_argument(
        "--verbose", action="store_true", help="show Warp's own messages (start-up, module loads, CUDA driver)"
    )
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in (add_hf, add_lf, add_analysis, add_sweep, add_bench):
        add(sub)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``aca-warp`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.verbose:
        os.environ["ACA_WARP_VERBOSE"] = "1"
    from aca_warp.common.devices import init_warp

    init_warp()
    try:
        return args.handler(args)
    except AcaError as e:
        print(f"aca-warp: error: {e}", file=sys.stderr)
        return e.exit_code  # 2 bad input, 3 unphysical, 4 output not writable (docs/faults.md)
    except KeyboardInterrupt:
        if args.command == "hf":
            print("aca-warp: interrupted; the run file holds the samples so far, marked incomplete", file=sys.stderr)
        else:
            print("aca-warp: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
