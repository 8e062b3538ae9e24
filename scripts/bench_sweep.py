#!/usr/bin/env python3
"""Multi-GPU sweep throughput: the same 2048-pad hf1 sweep on one GPU and on two GPUs through Dask.

For each worker count (default 1 and 2) a local Dask cluster is started (one single-threaded worker process per
GPU, pinned through ``CUDA_VISIBLE_DEVICES``), the kernels are loaded on every worker (compile or cache), and
then the sweep runs into a fresh directory. Reported per configuration: cluster start-up, per-worker kernel
load, sweep wall time, patch-steps/s over the sweep wall time (cluster already up), and the ratio against the
first configuration. The sweep: hf1 (1758 patches) × friction.M (16 values) × load.normal_force (16) ×
patches.seed (8) = 2048 pads, ``strang``, fp32, dt = 1e-8 s, 1 µs samples, shards of 256 pads.

On a machine with two GPUs (target: ≥ 1.8×)::

    NCCL_NVLS_ENABLE=0 python scripts/bench_sweep.py --device cuda --json bench_sweep.json

Quick CPU check (two worker processes, tiny pads)::

    python scripts/bench_sweep.py --device cpu --workers 1 2 --patches 50 --pads 64 --shard-size 16 --duration 2e-5
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NCCL_NVLS_ENABLE", "0")  # never use NVLink multicast (shared machines)

import numpy as np  # noqa: E402
import warp as wp  # noqa: E402

wp.config.log_level = wp.LOG_WARNING

from aca_warp.common.files import machine  # noqa: E402
from aca_warp.sweep import hf1_product_doc, load_spec, local_cluster, run_sweep, warm_workers  # noqa: E402


def sweep_doc(pads: int, patches: int | None, shard_size: int, duration: float, precision: str) -> dict:
    """A product sweep of ``pads`` hf1 pads: M × F_N × seed, factors as equal as possible (pads = 2^k best)."""
    seeds = 8 if pads >= 512 else max(1, min(8, pads // 4))
    rest = max(1, pads // seeds)
    n_m = int(np.sqrt(rest))
    n_f = rest // n_m
    if n_m * n_f * seeds != pads:
        raise SystemExit(f"--pads {pads}: choose a power of two (the sweep is a product M x F_N x seed)")
    return hf1_product_doc(
        f"bench-{pads}", n_m, n_f, seeds, shard_size=shard_size, duration=duration, precision=precision, patches=patches
    )


def _parse() -> argparse.Namespace:
    """The command line."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cuda", help="cuda (GPUs 0..N-1 for N workers) or cpu (default cuda)")
    ap.add_argument("--workers", nargs="+", type=int, default=[1, 2], help="worker counts to compare (default 1 2)")
    ap.add_argument("--pads", type=int, default=2048, help="pads in the sweep (a power of two; default 2048)")
    ap.add_argument("--patches", type=int, help="patches per pad (default: hf1's 1758)")
    ap.add_argument("--shard-size", type=int, default=256, help="pads per shard (default 256)")
    ap.add_argument("--duration", type=float, default=1e-3, help="simulated time per pad [s] (default 1e-3)")
    ap.add_argument("--precision", default="fp32", choices=("fp32", "fp64"))
    ap.add_argument("--dir", help="scratch folder for the sweep outputs (default: a temporary one, removed)")
    ap.add_argument("--json", default="bench_sweep.json", help="output JSON file")
    return ap.parse_args()


def _measure(spec, n: int, device_arg: str, scratch: Path) -> dict | None:
    """Start a local cluster of ``n`` workers, load the kernels on each and run the sweep into ``scratch``/w<n>;
    the row of times [s] and rates, or None (after a message) when a shard failed or stopped on a fault."""
    from distributed import Client

    device = "cpu" if device_arg == "cpu" else ",".join(f"cuda:{i}" for i in range(n))
    t0 = time.perf_counter()
    cluster, worker_device = local_cluster(device, n)
    client = Client(cluster)
    client.wait_for_workers(n)
    start_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    loads = warm_workers(client, worker_device)
    warm_s = time.perf_counter() - t0
    out = scratch / f"w{n}"
    shutil.rmtree(out, ignore_errors=True)
    try:
        res = run_sweep(spec, out, device=worker_device, client=client, log=lambda s: print("  " + s, flush=True))
    finally:
        client.close()
        cluster.close()
    if res.failed or res.faults:
        print(f"workers={n}: failed shards {res.failed}, faults {res.faults}", file=sys.stderr)
        return None
    rate = res.patch_steps / res.wall_time
    names = sorted({s["device_name"] for s in res.summaries})
    return {
        "workers": n,
        "device": device,
        "device_names": names,
        "cluster_start_s": start_s,
        "kernel_load_s": warm_s,
        "kernel_load_per_worker_s": loads,
        "sweep_wall_s": res.wall_time,
        "patch_steps": res.patch_steps,
        "patch_steps_per_s": rate,
        "shard_compile_s": [s["compile_time"] for s in res.summaries],
        "shard_wall_s": [s["wall_time"] for s in res.summaries],
        "shard_task_s": [s["task_time"] for s in res.summaries],
    }


def main() -> int:
    args = _parse()
    from distributed import Client  # noqa: F401 (fails here, before any work, where Dask is missing)

    spec = load_spec(sweep_doc(args.pads, args.patches, args.shard_size, args.duration, args.precision))
    scratch = Path(args.dir or tempfile.mkdtemp(prefix="aca_bench_sweep_"))
    rows = []
    print(
        f"sweep: {spec.pad_count} pads x {spec.base.patches.count} patches, {spec.shard_count} shards of "
        f"{spec.shard_size}, {spec.duration:g} s, {spec.integrator} {spec.precision}",
        flush=True,
    )
    for n in args.workers:
        row = _measure(spec, n, args.device, scratch)
        if row is None:
            return 3
        rows.append(row)
        start_s, warm_s, wall, rate = (
            row[k] for k in ("cluster_start_s", "kernel_load_s", "sweep_wall_s", "patch_steps_per_s")
        )
        print(
            f"workers={n} ({row['device']}): start {start_s:.1f} s, kernels {warm_s:.1f} s, sweep {wall:.1f} s, "
            f"{rate:.3g} patch-steps/s, ratio {rate / rows[0]['patch_steps_per_s']:.2f}",
            flush=True,
        )
    base = rows[0]["patch_steps_per_s"]
    for r in rows:
        r["ratio_vs_first"] = r["patch_steps_per_s"] / base
    doc = {
        "machine": machine(wp.get_device("cpu" if args.device == "cpu" else "cuda:0")),
        "warp_version": wp.__version__,
        "pads": spec.pad_count,
        "patches_per_pad": spec.base.patches.count,
        "shard_size": spec.shard_size,
        "duration_s": spec.duration,
        "integrator": spec.integrator,
        "precision": spec.precision,
        "results": rows,
    }
    Path(args.json).write_text(json.dumps(doc, indent=1))
    if not args.dir:
        shutil.rmtree(scratch, ignore_errors=True)
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
