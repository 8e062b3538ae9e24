#!/usr/bin/env python3
"""Benchmark the LF automaton over the default multi-timescale schedule (preset ``multiscale``).

Prints and writes (JSON, optionally Markdown): device, Warp version, precision, problem size (cells, rings,
patch slots, mean alive patches), kernel load/compile time separately from the run, LF steps/s and
element-steps/s (cells + patch slots per step), and two checks of the final state: the contact force balance
|ΣF_N − F_N| / F_N and the debris mass balance over the last step. Targets (issue 5): ≥ 100 LF steps/s on one
CPU core, ≥ 2000 on a GPU. Examples::

    python3 scripts/bench_lf.py                           # CPU, whole schedule (~5500 steps)
    python3 scripts/bench_lf.py --device cuda:0 --json $OUT/bench_lf_gpu.json --markdown $OUT/bench_lf_gpu.md
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

wp.config.log_level = wp.LOG_WARNING


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu", help="Warp device (default cpu)")
    ap.add_argument("--scene", default="multiscale", help="LF preset or TOML file (default multiscale)")
    ap.add_argument("--duration", type=float, help="simulated time [s] (default: the whole schedule)")
    ap.add_argument("--json", default="bench_lf.json", help="output JSON file")
    ap.add_argument("--markdown", help="also write a Markdown table here")
    args = ap.parse_args()

    import aca_warp.kernels.lf as K

    from aca_warp.io import machine
    from aca_warp.lf.scene import load_lf_scene
    from aca_warp.lf.solver import LFSimulation

    wp.init()
    t0 = time.perf_counter()
    wp.load_module(K, device=args.device)
    compile_s = time.perf_counter() - t0
    scene = load_lf_scene(args.scene)
    sim = LFSimulation(scene, device=args.device, duration=args.duration)
    sim.step()  # first step: hash grid, scans, allocations
    wall = sim.run()
    steps = sim.step_index - 1
    h = sim.history()
    # checks on the final state
    inv0 = sim.inventory()
    sim_load = sim.table.load[-1]
    sim.resolve()
    g = sim.glob.numpy()
    fn = sim.cell_fn.numpy().sum() + sim.patch_fn.numpy()[sim.alive.numpy() != 0].sum()
    force_err = abs(fn - g[K.G_LOAD]) / g[K.G_LOAD] if sim_load > 0 else 0.0
    mach = machine(sim.device)
    out = {
        "device": mach["device"],
        "device_name": mach["device_name"],
        "warp": wp.config.version,
        "precision": "fp64",
        "scene": scene.name,
        "steps": steps,
        "simulated_s": sim.step_index * scene.lf.dt,
        "cells": sim.n_cells,
        "rings": sim.n_r,
        "patch_slots": sim.capacity,
        "mean_alive_patches": float(np.mean(h["patch_count"])),
        "compile_s": compile_s,
        "run_s": wall,
        "steps_per_s": steps / wall,
        "element_steps_per_s": steps * (sim.n_cells + sim.capacity) / wall,
        "contact_force_balance_rel_err": float(force_err),
        "debris_inventory_kg": inv0,
    }
    for k, v in out.items():
        print(f"{k:32s} {v}")
    Path(args.json).write_text(json.dumps(out, indent=1))
    if args.markdown:
        Path(args.markdown).write_text(
            f"Machine: {out['device_name']}. Warp {out['warp']}, fp64, scene {out['scene']} "
            f"({out['cells']} cells, {out['rings']} rings, {out['patch_slots']} patch slots, mean "
            f"{out['mean_alive_patches']:.0f} alive patches).\n\n"
            "| device | steps | compile [s] | run [s] | LF steps/s | element-steps/s | force balance err |\n"
            "|---|---|---|---|---|---|---|\n"
            f"| {out['device']} | {steps} | {compile_s:.2f} | {wall:.2f} | {out['steps_per_s']:.0f} | "
            f"{out['element_steps_per_s']:.3g} | {force_err:.1e} |\n"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
