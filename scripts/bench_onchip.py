#!/usr/bin/env python3
"""Benchmark the on-chip HF engine against the general per-step path (``strang``, hf1 pads).

Per case (engine, precision, pads, blocks per pad (a thread-block cluster), block size, CSR on chip): µs per
step, steps/s, patch-steps/s, compile time, and the
error against the general path in fp64 on the same window: max |Δμ| over the samples and the max |Δu|
relative to max |u| at the end (pad 0; every pad of a batch is the same scene). Results go to a JSON file
and a Markdown table. Examples::

    python scripts/bench_onchip.py --device cpu --pads 1 --duration 1e-6        # smoke test
    python scripts/bench_onchip.py --device cuda:0 --pads 1 1024 --json $OUT/onchip.json --markdown $OUT/onchip.md
    python scripts/bench_onchip.py --device cuda:0 --pads 1 16 132 1024 --clusters 1 2 4 8 --json $OUT/c.json
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import warp as wp

wp.config.log_level = wp.LOG_WARNING

from aca_warp.common.argtypes import int_between  # noqa: E402
from aca_warp.common.devices import get_device, init_warp  # noqa: E402
from aca_warp.common.errors import AcaError  # noqa: E402
from aca_warp.common.files import check_output_path, machine  # noqa: E402
from aca_warp.hf.loop import EngineTuning, run_hf  # noqa: E402
from aca_warp.hf.model import build_model  # noqa: E402
from aca_warp.hf.onchip_layout import MAX_BLOCK, MAX_CLUSTER, block_config, shared_bytes  # noqa: E402
from aca_warp.hf.options import RunOptions  # noqa: E402
from aca_warp.hf.state import initial_state  # noqa: E402
from aca_warp.scene import Record, preset  # noqa: E402


def onchip_bytes(model, block_dim, csr_shared, cluster) -> int:
    """Shared memory per block [bytes] of the on-chip run as the on-chip engine configures it."""
    _, threads, csr = block_config(model, cluster, block_dim, csr_shared)
    return shared_bytes(model, csr, cluster, threads)


def run_case(scene, device, precision, engine, pads, dt, duration, block_dim=None, csr_shared=None, cluster=1):
    """Warm up (compile, capture) on a short window, then time ``duration`` [s]; returns a result row."""
    model = build_model([scene] * pads, device=device, precision=precision)
    state = initial_state(model)
    tuning = EngineTuning()
    if engine != "general":
        tuning = EngineTuning(block_dim=block_dim, csr_shared=csr_shared, cluster=cluster or None)
    options = RunOptions(engine=engine, dt=dt)
    tc = time.perf_counter()
    warm = run_hf(model, state, options.with_duration(scene.record.sample_dt * 2), tuning=tuning)
    compile_s = time.perf_counter() - tc
    state = initial_state(model)
    res = run_hf(model, state, options.with_duration(duration), tuning=tuning)
    c = res.collect()
    n = model.patch_count
    row = {
        **machine(model.device),
        "warp_version": wp.__version__,
        "engine": engine,
        "precision": precision,
        "pads": pads,
        "patches": n,
        "cluster": res.blocks_per_pad if engine == "onchip" else None,
        "cluster_asked": (cluster or "default") if engine == "onchip" else None,
        "block_dim": block_dim,
        "csr_shared": csr_shared,
        "shared_bytes": onchip_bytes(model, block_dim, csr_shared, res.blocks_per_pad) if engine == "onchip" else 0,
        "dt": res.dt,
        "steps": res.steps,
        "compile_s": compile_s - warm.wall_time,
        "wall_s": res.wall_time,
        "us_per_step": 1e6 * res.wall_time / res.steps,
        "steps_per_s": res.steps / res.wall_time,
        "patch_steps_per_s": n * res.steps / res.wall_time,
    }
    u, _ = state.numpy()
    return row, c.globals[:, 0, 0], u[: n // pads].astype(np.float64)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    init_warp()  # quietly: no CUDA-driver note on a machine without a GPU, not even for --help
    ap.add_argument("--device", default="cuda:0" if wp.is_cuda_available() else "cpu")
    ap.add_argument("--scene", default="hf1")
    ap.add_argument("--pads", nargs="+", type=int, default=[1, 1024])
    ap.add_argument("--precisions", nargs="+", default=["fp32", "fp64"], choices=["fp32", "fp64"])
    ap.add_argument(
        "--clusters", nargs="+", type=int_between(0, MAX_CLUSTER), default=[1],
        help="blocks per pad to try (default 1; 0: the on-chip engine's default, default_cluster)",
    )  # fmt: skip
    ap.add_argument(
        "--blocks",
        nargs="+",
        type=int_between(0, MAX_BLOCK),
        default=[0],
        help="threads per block to try (0, the default: the on-chip engine's)",
    )
    ap.add_argument(
        "--csr", nargs="+", choices=["auto", "on", "off"], default=["auto"], help="neighbour lists in shared memory"
    )
    ap.add_argument("--dt", type=float, default=1e-8)
    ap.add_argument("--duration", type=float, default=2e-4, help="timed window for one pad [s]")
    ap.add_argument("--batch-duration", type=float, default=2e-5, help="timed window for batches [s]")
    ap.add_argument("--general", action="store_true", help="also time the general path at every batch size")
    ap.add_argument("--json", default="bench_onchip.json")
    ap.add_argument("--markdown", default=None)
    args = ap.parse_args()
    for name in ("duration", "batch_duration", "dt"):
        if not getattr(args, name) > 0:
            ap.error(f"--{name.replace('_', '-')} must be > 0")
    if min(args.duration, args.batch_duration) < 1e-6:
        ap.error("--duration and --batch-duration must hold at least one 1 µs sample (≥ 1e-6 s)")
    if min(args.pads) < 1:
        ap.error("--pads must be ≥ 1")
    try:
        get_device(args.device)
        scene = preset(args.scene).replace(record=Record(sample_dt=1e-6))
        for out in (args.json, args.markdown):
            if out:
                check_output_path(out, overwrite=True)
    except AcaError as e:
        ap.error(str(e))
    rows = []
    for pads in args.pads:
        dur = args.duration if pads == 1 else args.batch_duration
        _, mu_ref, u_ref = run_case(scene, args.device, "fp64", "general", 1, args.dt, dur)
        cases = [("general", p) for p in args.precisions] if (args.general or pads == 1) else []
        cases = [(*c, None, None, 1) for c in cases]
        csr = {"auto": None, "on": True, "off": False}
        for p in args.precisions:
            for kc in args.clusters:
                for b in args.blocks:
                    for cs in args.csr:
                        cases.append(("onchip", p, b or None, csr[cs], kc))
        for engine, p, b, cs, kc in cases:
            try:
                row, mu, u = run_case(scene, args.device, p, engine, pads, args.dt, dur, b, cs, kc)
            except Exception as e:  # noqa: BLE001  (report and go on: e.g. shared memory exceeded)
                print(f"{engine} {p} pads={pads} cluster={kc} block={b} csr={cs}: {type(e).__name__}: {e}", flush=True)
                continue
            k = min(len(mu), len(mu_ref))
            row["mu_err_vs_general_fp64"] = float(np.abs(mu[:k] - mu_ref[:k]).max())
            row["u_rel_err_vs_general_fp64"] = float(np.abs(u - u_ref).max() / np.abs(u_ref).max())
            rows.append(row)
            Path(args.json).write_text(json.dumps(rows, indent=1))  # after every case: a cut-off run keeps its rows
            print(
                f"{row['device_name']}: {engine:7s} {p} pads={pads:5d} cluster={row['cluster']} block={b} csr={cs} "
                f"{row['us_per_step']:.3f} us/step {row['patch_steps_per_s']:.3g} patch-steps/s "
                f"compile {row['compile_s']:.2f} s  dmu {row['mu_err_vs_general_fp64']:.2e} "
                f"du {row['u_rel_err_vs_general_fp64']:.2e}",
                flush=True,
            )
    Path(args.json).write_text(json.dumps(rows, indent=1))
    if args.markdown:
        lines = [
            f"Device: {rows[0]['device_name']}, Warp {rows[0]['warp_version']}, scene {args.scene}, dt {args.dt:g} s",
            "",
            "| engine | precision | pads | blocks per pad | block | CSR in smem | µs/step | patch-steps/s "
            "| max abs dμ vs fp64 general | rel. du vs fp64 general |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in rows:
            on = r["engine"] == "onchip"
            smem = {True: "yes", False: "no", None: "auto"}[r["csr_shared"]] if on else "-"
            lines.append(
                f"| {r['engine']} | {r['precision']} | {r['pads']} | {r['cluster'] or '-'} | "
                f"{(r['block_dim'] or 'auto') if on else '-'} | {smem} | {r['us_per_step']:.3g} | "
                f"{r['patch_steps_per_s']:.3g} | {r['mu_err_vs_general_fp64']:.2g} | "
                f"{r['u_rel_err_vs_general_fp64']:.2g} |"
            )
        Path(args.markdown).write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
