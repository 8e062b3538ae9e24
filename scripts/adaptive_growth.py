#!/usr/bin/env python3
"""The adaptive integrator on a growing scene against strang: the ``varying_area`` preset (1758 patches, growth
events every 2.02e-7 s, docs/model.md §2.10) from rest over its first ``--duration`` (default 20 µs), with strang
at ``--dt`` (default 1e-8 s) and adaptive at each ``--tols`` (default 1e-5 and 1e-6), in ``--precision`` (default
fp64) on ``--engine`` (default ``auto``: both integrators on chip, on CUDA and on the CPU; ``general`` for the per-step
kernels).

Prints a markdown table, one row per run: wall time of the stepping loop (compilation and graph captures
excluded), accepted steps (adaptive: trials of the pad) and rejected trials, mean step (simulated time per
accepted step), the mean patch area at the end, and the largest |Δμ| over the samples against the strang run and
against the tightest adaptive run; for each tolerance also the steps of the same run with the growth off (what
landing on the events costs). The machine is named in the line above the table.

Example (docs/numerics.md, "Growth events")::

    python scripts/adaptive_growth.py --duration 2e-5 --tols 1e-5 1e-6
    python scripts/adaptive_growth.py --device cuda:0 --duration 1e-4 --tols 1e-5 --engine onchip --precision fp32
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

import numpy as np
import warp as wp

from aca_warp.common.argtypes import positive
from aca_warp.common.devices import get_device
from aca_warp.common.errors import SceneError
from aca_warp.common.files import machine
from aca_warp.hf.loop import run_hf
from aca_warp.hf.model import build_model
from aca_warp.hf.options import ENGINES, RunOptions
from aca_warp.hf.state import initial_state
from aca_warp.scene import preset


def one_run(args: argparse.Namespace, growth: bool = True, **options: Any) -> dict[str, Any]:
    """One run of the varying_area preset (``growth`` False: its growth off) over ``args.duration`` [s] on
    ``args.device``, ``args.engine``, in ``args.precision``: its figures and μ at every sample."""
    scene = preset("varying_area")
    model = build_model([scene if growth else scene.replace(growth=None)], device=args.device, precision=args.precision)
    opts = RunOptions(duration=args.duration, engine=args.engine, **options)
    res = run_hf(model, initial_state(model), opts)
    if not res.complete:
        raise RuntimeError(f"{options}: stopped at {res.sim_time:.3g} s: {res.fault}")
    return {
        "wall": res.wall_time,
        "steps": res.steps,
        "rejected": res.rejected,
        "mean_step": res.sim_time / res.steps,
        "area": float(model.host("area").mean()),
        "mu": res.collect().globals[:, 0, 0],
        "engine": res.engine,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=positive, default=2e-5, help="simulated time [s]")
    ap.add_argument("--dt", type=positive, default=1e-8, help="strang step [s]")
    ap.add_argument("--tols", type=positive, nargs="+", default=[1e-5, 1e-6], help="adaptive tolerances")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--engine", default="auto", choices=ENGINES, help="HF engine (default auto)")
    ap.add_argument("--precision", default="fp64", choices=["fp32", "fp64"])
    args = ap.parse_args(argv)
    try:
        get_device(args.device)
    except SceneError as e:
        ap.error(str(e))
    runs = {f"strang {args.dt:g} s": one_run(args, integrator="strang", dt=args.dt)}
    for tol in args.tols:
        runs[f"adaptive tol {tol:g}"] = one_run(args, integrator="adaptive", tolerance=tol)
        still = one_run(args, False, integrator="adaptive", tolerance=tol)
        runs[f"adaptive tol {tol:g}"]["still"] = still["steps"]
    strang = runs[f"strang {args.dt:g} s"]["mu"]
    tightest = runs[f"adaptive tol {min(args.tols):g}"]["mu"]
    m = machine(wp.get_device(args.device))
    print(f"varying_area, first {args.duration:g} s from rest, {args.precision}, engine {args.engine}, "
          f"{m['device']}: {m['device_name']}, host {m['host']}\n")  # fmt: skip
    print("| run | engine | wall [s] | steps | rejected | steps, growth off | mean step [s] | mean area [m²] "
          f"| max abs Δμ vs strang | max abs Δμ vs tol {min(args.tols):g} |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, r in runs.items():
        d_strang, d_tight = np.abs(r["mu"] - strang).max(), np.abs(r["mu"] - tightest).max()
        print(f"| {name} | {r['engine']} | {r['wall']:.2f} | {r['steps']} | {r['rejected']} | {r.get('still', '')} "
              f"| {r['mean_step']:.3g} | {r['area']:.6g} | {d_strang:.2g} | {d_tight:.2g} |")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
