#!/usr/bin/env python3
"""Benchmark the HF step (thin wrapper of ``aca_warp.bench``, the logic behind ``aca-warp bench``).

Reports, per case: device, Warp version, precision, integrator, pads, patches, compile time (separate from
run time), per-stage times, steps/s, patch-steps/s, ns per patch-step, achieved memory bandwidth against the
device peak, and the error of μ(t) against a reference run (fp64, ``strang`` at a quarter of the step) over the
timed window. Results go to a JSON file and, if asked, a Markdown table. This script keeps the plural options
of its first version and runs every integrator by default; ``aca-warp bench`` runs ``strang``. Examples::

    python scripts/bench_hf.py                                  # CPU, hf1, every integrator, fp32 + fp64
    python scripts/bench_hf.py --device cuda:0 --pads 1 1024    # GPU: one pad and 1024 batched pads
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import warp as wp

wp.config.log_level = wp.LOG_WARNING

from aca_warp.bench import markdown, run_bench  # noqa: E402
from aca_warp.errors import AcaError  # noqa: E402
from aca_warp.hf import INTEGRATORS  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu", help="Warp device (default cpu)")
    ap.add_argument("--scene", default="hf1", help="preset or TOML scene (default hf1)")
    ap.add_argument("--patches", type=int, help="patches per pad (default: the scene's)")
    ap.add_argument("--integrators", nargs="+", default=list(INTEGRATORS), choices=INTEGRATORS)
    ap.add_argument("--precisions", nargs="+", default=["fp64", "fp32"], choices=["fp32", "fp64"])
    ap.add_argument("--pads", nargs="+", type=int, default=[1], help="batch sizes (default 1)")
    ap.add_argument("--dt", type=float, default=1e-8, help="fixed step [s] (default 1e-8)")
    ap.add_argument("--duration", type=float, default=2e-5, help="timed simulated window per case [s]")
    ap.add_argument("--no-reference", action="store_true", help="skip the fp64 dt/4 reference (no μ error)")
    ap.add_argument("--no-stages", action="store_true", help="skip the per-stage timings")
    ap.add_argument("--json", default="bench_hf.json", help="output JSON file")
    ap.add_argument("--markdown", default=None, help="also write a Markdown table here")
    args = ap.parse_args()
    try:
        out = run_bench(
            device=args.device,
            scene=args.scene,
            patches=args.patches,
            precisions=tuple(args.precisions),
            integrators=tuple(args.integrators),
            pads=tuple(args.pads),
            dt=args.dt,
            duration=args.duration,
            reference=not args.no_reference,
            stages=not args.no_stages,
            log=lambda s: print(s, flush=True),
        )
    except AcaError as e:
        print(f"bench_hf: error: {e}", file=sys.stderr)
        return 2
    Path(args.json).write_text(json.dumps(out, indent=1))
    if args.markdown:
        Path(args.markdown).write_text(markdown(out))
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
