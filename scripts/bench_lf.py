#!/usr/bin/env python3
"""Benchmark the LF automaton over the default multi-timescale schedule (preset ``multiscale``).

Prints and writes (JSON, optionally Markdown): device, Warp version, precision, problem size (cells, rings,
patch slots, mean alive patches), kernel load/compile time separately from the run, LF steps/s and
element-steps/s (cells + patch slots per step), the contact-solve passes per loaded step (mean, max), the
merge-candidate rebuilds (and the steps with births or merges, which cause them, and with deaths only), and two
checks of the final state: the contact force balance |ΣF_N − F_N| / F_N and the debris mass balance over the
last step. Targets: ≥ 100 LF steps/s on one
CPU core, ≥ 2000 on a GPU. Examples::

    python3 scripts/bench_lf.py                           # CPU, whole schedule (~5500 steps)
    python3 scripts/bench_lf.py --device cuda:0 --json $OUT/bench_lf_gpu.json --markdown $OUT/bench_lf_gpu.md
    python3 scripts/bench_lf.py --duration 5 --save ref_cpu.h5                     # CPU reference run file
    python3 scripts/bench_lf.py --duration 5 --device cuda:0 --compare ref_cpu.h5  # GPU against it

``--compare`` checks the same scene on this device against a reference LF run file (another device): the
global time series and every snapshot's patch arrays, relative to their scale.

``--activity`` (CUDA only) then runs the schedule twice more under Warp's activity timing
(``wp.timing_begin``, CUDA events around every launch): once as benchmarked (graph replay; the neighbourhood
rebuilds are eager launches) and once eagerly (every kernel timed). The JSON gets, per pass, the wall time, the
GPU time of every named activity (count, total [ms]) and their sum; wall minus that sum is host time, launch
latency and work Warp does not time (the hash-grid build's sort). Timing adds per-launch overhead, so these
passes are slower than the benchmark and are not its result.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

from aca_warp.common.argtypes import positive
from aca_warp.common.devices import get_device
from aca_warp.common.errors import AcaError
from aca_warp.common.files import check_output_path

wp.config.log_level = wp.LOG_WARNING


def compare(path: Path, ref: Path) -> dict:
    """Largest deviations of ``path`` from ``ref``: global series (relative to each series' max |value|) and per
    snapshot patch count and patch arrays (sorted by position, relative to their max)."""
    import h5py

    res: dict = {}
    with h5py.File(path, "r") as a, h5py.File(ref, "r") as b:
        for k in ("mu", "torque", "friction_radius", "patch_count", "coverage", "disc_temperature_max"):
            x, y = a["global"][k][()], b["global"][k][()]
            n = min(len(x), len(y))
            res[f"global/{k}"] = float(np.max(np.abs(x[:n] - y[:n])) / max(np.max(np.abs(y[:n])), 1e-300))
        for name in b["snapshots"]:
            if name not in a["snapshots"]:
                continue
            pa, pb = a["snapshots"][name]["patches"], b["snapshots"][name]["patches"]
            res[f"{name}/count"] = [int(len(pa["x"])), int(len(pb["x"]))]
            if len(pa["x"]) == len(pb["x"]):
                oa = np.lexsort((pa["y"][()], pa["x"][()]))
                ob = np.lexsort((pb["y"][()], pb["x"][()]))
                for k in ("x", "y", "area", "normal_force", "temperature"):
                    x, y = pa[k][()][oa], pb[k][()][ob]
                    res[f"{name}/{k}"] = float(np.max(np.abs(x - y)) / max(np.max(np.abs(y)), 1e-300))
    return res


def activity(scene, device: str, duration: float | None, graph: bool) -> dict:
    """One timed pass over the schedule: wall [s], GPU time per activity name {name: [count, ms]}, their sum."""
    from aca_warp.lf.solver import LFSimulation

    sim = LFSimulation(scene, device=device, duration=duration, graph=None if graph else False)
    sim.step()
    sim.run(steps=1)  # captures the graphs of a loaded step before timing
    wp.timing_begin(cuda_filter=wp.TIMING_ALL)
    t0 = time.perf_counter()
    sim.run()
    results = wp.timing_end()
    wall = time.perf_counter() - t0
    per: dict[str, list[float]] = {}
    for r in results:
        c = per.setdefault(r.name, [0, 0.0])
        c[0] += 1
        c[1] += r.elapsed
    per = dict(sorted(per.items(), key=lambda kv: -kv[1][1]))
    gpu_ms = sum(v[1] for v in per.values())
    return {"graph": sim.use_graph, "steps": sim.step_index - 2, "wall_s": wall, "gpu_ms": gpu_ms, "activities": per}


def _parse() -> argparse.Namespace:
    """The command line, with its combinations checked."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu", help="Warp device (default cpu)")
    ap.add_argument("--scene", default="multiscale", help="LF preset or TOML file (default multiscale)")
    ap.add_argument("--duration", type=positive, help="simulated time [s] (default: the whole schedule)")
    ap.add_argument("--eager", action="store_true", help="no graph capture (launch every kernel from Python)")
    ap.add_argument("--json", default="bench_lf.json", help="output JSON file")
    ap.add_argument("--markdown", help="also write a Markdown table here")
    ap.add_argument("--save", help="also write the run (an LF run file with snapshots) here")
    ap.add_argument("--compare", metavar="REF.h5", help="compare with a reference LF run file of the same scene")
    ap.add_argument("--activity", action="store_true", help="CUDA: also time every GPU activity (two more passes)")
    args = ap.parse_args()
    if args.activity and not args.device.startswith("cuda"):
        ap.error("--activity times CUDA activity; it needs a CUDA --device")
    return args


def _summary(sim, scene, compile_s: float, wall: float) -> dict:
    """The result of a finished run: machine, sizes, times [s] and rates, and checks on the final state (the
    relative force balance of the contact solve, contact-solve passes, rebuilds, the debris inventory [kg])."""
    from aca_warp.kernels.lf_types import G_LOAD

    from aca_warp.common.files import machine

    steps = sim.step_index - 1
    h = sim.history()
    passes = h["contact_passes"][h["normal_force"] > 0]  # contact-solve passes per loaded step
    changed = (h["births"] + h["merges"]) > 0  # steps after which the merge candidates are rebuilt
    # checks on the final state
    inv0 = sim.inventory()
    sim_load = sim.table.load[-1]
    sim.resolve()
    g = sim.glob.numpy()
    fn = sim.cell_fn.numpy().sum() + sim.patch_fn.numpy()[sim.alive.numpy() != 0].sum()
    force_err = abs(fn - g[G_LOAD]) / g[G_LOAD] if sim_load > 0 else 0.0
    mach = machine(sim.device)
    return {
        "device": mach["device"],
        "device_name": mach["device_name"],
        "warp": wp.config.version,
        "precision": "fp64",
        "graph": sim.use_graph,
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
        "contact_passes_mean_max": [float(np.mean(passes)), float(np.max(passes))] if passes.size else [0.0, 0.0],
        "neighbour_rebuilds": sim.rebuilds,
        "steps_with_births_or_merges": int(np.sum(changed)),
        "steps_with_deaths_only": int(np.sum((h["deaths"] > 0) & ~changed)),
        "debris_inventory_kg": inv0,
    }


def _print_summary(out: dict) -> None:
    """One line per field; with --activity the GPU activities of each mode, the 15 largest."""
    for k, v in out.items():
        if k == "activity":
            for kind, a in v.items():
                gpu_s = a["gpu_ms"] / 1e3
                print(f"activity {kind}: wall {a['wall_s']:.2f} s, GPU {gpu_s:.2f} s over {a['steps']} steps")
                for name, (n, ms) in list(a["activities"].items())[:15]:
                    print(f"    {name:40s} {n:7d} × {1e3 * ms / max(n, 1):8.1f} µs = {ms:9.1f} ms")
            continue
        print(f"{k:32s} {v}")


def _markdown(out: dict) -> str:
    """The Markdown table of one run."""
    return (
        f"Machine: {out['device_name']}. Warp {out['warp']}, fp64, scene {out['scene']} "
        f"({out['cells']} cells, {out['rings']} rings, {out['patch_slots']} patch slots, mean "
        f"{out['mean_alive_patches']:.0f} alive patches).\n\n"
        "| device | steps | compile [s] | run [s] | LF steps/s | element-steps/s | force balance err |\n"
        "|---|---|---|---|---|---|---|\n"
        f"| {out['device']} | {out['steps']} | {out['compile_s']:.2f} | {out['run_s']:.2f} | "
        f"{out['steps_per_s']:.0f} | {out['element_steps_per_s']:.3g} | {out['contact_force_balance_rel_err']:.1e} |\n"
    )


def main() -> int:
    args = _parse()

    from aca_warp.kernels import lf_contact, lf_patches, lf_record, lf_thermal, lf_wear

    from aca_warp.lf.scene import load_lf_scene
    from aca_warp.lf.solver import LFSimulation

    try:  # every refusal before the first compile: nothing run, nothing written
        get_device(args.device)
        scene = load_lf_scene(args.scene)
        if args.compare and not Path(args.compare).is_file():
            raise AcaError(f"--compare: no run file {args.compare}")
        for out in (args.json, args.markdown, args.save):
            if out:
                check_output_path(out, overwrite=True)
    except AcaError as e:
        print(f"bench_lf.py: error: {e}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    for module in (lf_contact, lf_thermal, lf_wear, lf_patches, lf_record):
        wp.load_module(module, device=args.device)
    compile_s = time.perf_counter() - t0
    sim = LFSimulation(scene, device=args.device, duration=args.duration, graph=False if args.eager else None)
    sim.step()  # first step: hash grid, scans, allocations
    writer = None
    if args.save or args.compare:
        from aca_warp.lf.io import LFRunWriter

        path = args.save or str(Path(args.json).with_suffix(".h5"))
        writer = LFRunWriter(path, sim, overwrite=True)
    wall = sim.run(on_snapshot=writer.snapshot if writer else None)
    if writer is not None:
        writer.close(complete=True, status="complete")
    out = _summary(sim, scene, compile_s, wall)
    if args.compare:
        out["compare"] = compare(writer.path, Path(args.compare))
    if args.activity:
        modes = (("graph", True), ("eager", False))
        out["activity"] = {kind: activity(scene, args.device, args.duration, graph) for kind, graph in modes}
    _print_summary(out)
    Path(args.json).write_text(json.dumps(out, indent=1))
    if args.markdown:
        Path(args.markdown).write_text(_markdown(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
