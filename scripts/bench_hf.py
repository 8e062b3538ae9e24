#!/usr/bin/env python3
"""Benchmark the HF step: patch-steps/s per integrator and precision, one pad and batched pads.

Reports, per case: device, Warp version, precision, integrator, pads, patches, compile time (separate from
run time), steps/s, patch-steps/s, ns per patch-step, and the error of μ(t) against a reference run
(fp64, ``strang`` at a quarter of the step) over the timed window. Results go to a JSON file and a
Markdown table. Examples::

    python scripts/bench_hf.py                                  # CPU, hf1, every integrator, fp32 + fp64
    python scripts/bench_hf.py --device cuda:0 --pads 1 1024    # GPU: one pad and 1024 batched pads
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import warp as wp

wp.config.log_level = wp.LOG_WARNING

from aca_warp.hf import INTEGRATORS, run_hf  # noqa: E402
from aca_warp.io import machine  # noqa: E402
from aca_warp.model import build_model  # noqa: E402
from aca_warp.scene import Record, preset  # noqa: E402
from aca_warp.state import initial_state  # noqa: E402


def run_case(
    scene, device: str, precision: str, integrator: str, pads: int, dt: float, duration: float, warmup: float
) -> dict:
    """Time one configuration; returns a result row."""
    t0 = time.perf_counter()
    model = build_model([scene] * pads, device=device, precision=precision)
    build_time = time.perf_counter() - t0
    state = initial_state(model)
    rec = Record(sample_dt=scene.record.sample_dt)
    warm = run_hf(model, state, duration=warmup, integrator=integrator, dt=dt, record=rec)  # compiles, captures
    res = run_hf(model, state, duration=duration, integrator=integrator, dt=dt, record=rec)
    mu = res.collect().globals[:, 0, 0]
    n = model.patch_count
    return {
        "device": str(model.device),
        "device_name": model.device.name,
        "warp_version": wp.__version__,
        "precision": precision,
        "integrator": integrator,
        "pads": pads,
        "patches": n,
        "patches_per_pad": n // pads,
        "dt": res.dt,
        "steps": res.steps,
        "rejected": res.rejected,
        "compile_time_s": warm.compile_time,
        "model_build_s": build_time,
        "wall_s": res.wall_time,
        "steps_per_s": res.steps / res.wall_time,
        "patch_steps_per_s": n * res.steps / res.wall_time,
        "ns_per_patch_step": 1e9 * res.wall_time / (n * res.steps),
        "mu": mu,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu", help="Warp device (default cpu)")
    ap.add_argument("--scene", default="hf1", help="preset (default hf1)")
    ap.add_argument("--integrators", nargs="+", default=list(INTEGRATORS), choices=INTEGRATORS)
    ap.add_argument("--precisions", nargs="+", default=["fp64", "fp32"], choices=["fp32", "fp64"])
    ap.add_argument("--pads", nargs="+", type=int, default=[1], help="batch sizes (default 1)")
    ap.add_argument("--dt", type=float, default=1e-8, help="fixed step [s] (default 1e-8)")
    ap.add_argument("--duration", type=float, default=2e-5, help="timed simulated window per case [s]")
    ap.add_argument("--json", default="bench_hf.json", help="output JSON file")
    ap.add_argument("--markdown", default=None, help="also write a Markdown table here")
    args = ap.parse_args()
    dev = wp.get_device(args.device)
    scene = preset(args.scene).replace(record=Record(sample_dt=1e-6))
    rows = []
    refs: dict[int, np.ndarray] = {}
    for pads in args.pads:
        for prec in args.precisions:
            for integ in args.integrators:
                r = run_case(scene, args.device, prec, integ, pads, args.dt, args.duration, warmup=2e-6)
                if pads not in refs:  # reference: fp64 strang at dt/4 over the same two windows
                    ref = run_case(scene, args.device, "fp64", "strang", 1, args.dt / 4, args.duration, 2e-6)
                    refs[pads] = ref["mu"]
                mu = r.pop("mu")
                r["mu_rel_error_max"] = float(np.max(np.abs(mu - refs[pads]) / np.abs(refs[pads]).max()))
                rows.append(r)
                print(
                    f"{dev.name:>24s} {prec} {integ:>17s} pads={pads:5d} {r['patch_steps_per_s']:.3g} patch-steps/s "
                    f"{r['ns_per_patch_step']:.3g} ns/patch-step, compile {r['compile_time_s']:.2f} s, "
                    f"mu err {r['mu_rel_error_max']:.2e}",
                    flush=True,
                )
    out = {"machine": machine(dev), "scene": args.scene, "duration_s": args.duration, "results": rows}
    Path(args.json).write_text(json.dumps(out, indent=1))
    if args.markdown:
        lines = [
            f"Machine: {out['machine']['device_name']}. Scene {args.scene}, "
            f"timed window {args.duration:g} s simulated, "
            f"dt = {args.dt:g} s (adaptive: tolerance 1e-4). μ error: max |μ − μ_ref| / max|μ_ref| against "
            "fp64 strang at dt/4.",
            "",
            "| device | precision | integrator | pads | patches | steps/s | patch-steps/s | ns/patch-step "
            "| compile [s] | μ error |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in rows:
            lines.append(
                f"| {r['device_name']} | {r['precision']} | {r['integrator']} | {r['pads']} | {r['patches']} "
                f"| {r['steps_per_s']:.3g} | {r['patch_steps_per_s']:.3g} | {r['ns_per_patch_step']:.3g} "
                f"| {r['compile_time_s']:.2f} | {r['mu_rel_error_max']:.1e} |"
            )
        Path(args.markdown).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
