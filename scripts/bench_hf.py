#!/usr/bin/env python3
"""Benchmark the HF step (thin wrapper of ``aca_warp.bench``, the logic behind ``aca-warp bench``).

Reports, per case: device, Warp version, precision, integrator, pads, patches, compile time (separate from
run time), per-stage times, steps/s, patch-steps/s, ns per patch-step, achieved memory bandwidth against the
device peak, and the error of μ(t) against a reference run (fp64, ``strang`` at a quarter of the step) over the
timed window. Results go to a JSON file and, if asked, a Markdown table. This script keeps the plural options
of its first version (``--integrators``, ``--precisions``) and runs every integrator by default; ``aca-warp
bench`` runs ``strang``; every other option is ``aca-warp bench``'s (``--engine``, ``--pads``, …). Examples::

    python scripts/bench_hf.py                                  # CPU, hf1, every integrator, fp32 + fp64
    python scripts/bench_hf.py --device cuda:0 --pads 1 1024    # GPU: one pad and 1024 batched pads
"""

from __future__ import annotations

import sys

from aca_warp.cli import main as cli_main
from aca_warp.hf.options import INTEGRATORS

RENAMED = {"--integrators": "--integrator", "--precisions": "--precision"}  # this script's plural options


def main(argv: list[str]) -> int:
    """``aca-warp bench`` with every integrator and ``--json bench_hf.json`` (this script's own file, replaced by
    the next run) unless the arguments say otherwise."""
    if {"-h", "--help"} & set(argv):
        print(__doc__)
    args = [RENAMED.get(a, a) for a in argv]
    own = (
        []
        if any(a == "--json" or a.startswith("--json=") for a in args)
        else ["--json", "bench_hf.json", "--overwrite"]
    )
    return cli_main(["bench", "--integrator", *INTEGRATORS, *own, *args])


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
