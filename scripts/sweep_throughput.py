#!/usr/bin/env python3
"""Sweep throughput on one device: the in-shard kernel rate against the sweep's wall rate, overlapped and sequential.

One product sweep of hf1 pads (friction.M × load.normal_force × patches.seed, ``strang``, dt 1e-8 s) runs twice into
fresh directories on the device given: once ``sequential`` (one shard after another: build, run, write) and once
``overlapped`` (while one shard steps, the next waits ready and the last finishes its file, samples written behind
the run; docs/sweeps.md, "Overlap"). Reported per mode:

* in-shard rate: patch-steps / seconds inside stepping, summed over the shards (``timings.kernel`` of each shard:
  the run loop less its sink; no model building, set-up or writing);
* wall rate: patch-steps / the sweep call's wall time (every build, set-up, kernel and write; the Dask cluster's
  start and a warm-up sweep that compiles or loads the kernels are not counted);
* ratio: the overlapped wall rate against the sequential in-shard rate (the kernel alone; target ≥ 0.9), and each
  mode's wall rate against its own in-shard rate.

Paths: on CUDA a local Dask cluster on the one GPU (one worker process; overlapped: two shard tasks in its threads
that take the GPU in turns), as ``aca-warp sweep --device cuda:N`` runs; on the CPU this process (overlapped: two
shard tasks in threads), as ``--workers 0``; ``--path`` chooses. Writes JSON and one Markdown line.

One H100 (2048 hf1 pads of 1758 patches in 8 shards of 256, 2 ms simulated each; a few minutes)::

    python scripts/sweep_throughput.py --device cuda:0 --json sweep_throughput.json --md sweep_throughput.md

CPU (tiny settings, about a minute)::

    python scripts/sweep_throughput.py --device cpu
"""

from __future__ import annotations

import argparse
import datetime
import math
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("NCCL_NVLS_ENABLE", "0")  # never use NVLink multicast (shared machines)

import warp as wp  # noqa: E402
from bench_sweep import write_outputs  # noqa: E402

from aca_warp.common.devices import init_warp  # noqa: E402
from aca_warp.common.files import machine  # noqa: E402
from aca_warp.sweep import PIPELINE_DEPTH, SweepSpec, hf1_product_doc, load_spec, local_cluster, run_sweep  # noqa: E402

# (pads, patches per pad, shard size, duration [s]) when not given: the GPU figure's sweep, and a tiny CPU one
DEFAULTS = {"cuda": (2048, None, 256, 2e-3), "cpu": (16, 40, 4, 1.5e-3)}
MODES = ("sequential", "overlapped")


def sweep_doc(pads: int, patches: int | None, shard_size: int, duration: float, precision: str) -> dict:
    """A product sweep of ``pads`` hf1 pads: M × F_N × seed (pads a power of two, factors as equal as possible)."""
    if pads < 1 or pads & (pads - 1):
        raise SystemExit(f"--pads {pads}: choose a power of two (the sweep is a product M x F_N x seed)")
    seeds = min(8, pads)
    rest = pads // seeds
    n_m = 2 ** (int(math.log2(rest)) // 2)
    n_f = rest // n_m
    return hf1_product_doc(
        f"throughput-{pads}",
        n_m,
        n_f,
        seeds,
        shard_size=shard_size,
        duration=duration,
        precision=precision,
        patches=patches,
    )


class Runner:
    """Runs a sweep in one mode on one device: through a local Dask cluster (started once, kept for the warm-up and
    the timed sweep) or in this process."""

    def __init__(self, device: str, mode: str, path: str) -> None:
        self.device, self.overlap, self.path = device, mode == "overlapped", path
        self.cluster = self.client = None
        self.start_s = 0.0
        if path == "dask":
            from distributed import Client

            t0 = time.perf_counter()
            threads = PIPELINE_DEPTH if self.overlap else 1
            self.cluster, self.worker_device = local_cluster(device, 1 if device == "cpu" else None, threads=threads)
            self.client = Client(self.cluster)
            self.client.wait_for_workers(len(self.cluster.worker_spec))
            self.start_s = time.perf_counter() - t0
        else:
            self.worker_device = device

    def run(self, spec: SweepSpec, out: Path) -> Any:
        shutil.rmtree(out, ignore_errors=True)
        if self.client is not None:
            return run_sweep(spec, out, device=self.worker_device, client=self.client, overlap=self.overlap)
        return run_sweep(spec, out, device=self.device, workers=0, overlap=self.overlap)

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
            self.cluster.close()


def measure(runner: Runner, spec: SweepSpec, warm: SweepSpec, scratch: Path, mode: str) -> dict:
    """Warm-up sweep (kernels compiled or loaded in every worker), then the timed sweep; the mode's figures."""
    t0 = time.perf_counter()
    runner.run(warm, scratch / f"{mode}-warm")
    warm_s = time.perf_counter() - t0
    res = runner.run(spec, scratch / mode)
    if res.failed or res.faults:
        raise SystemExit(f"{mode}: failed shards {res.failed}, faults {res.faults}")
    kernel = sum(s["timings"]["kernel"] for s in res.summaries)
    phases = sorted({k for s in res.summaries for k in s["timings"]} - {"run_start", "run_end"})  # not durations
    return {
        "mode": mode,
        "path": runner.path,
        "workers": res.workers,
        "cluster_start_s": runner.start_s,
        "warm_up_s": warm_s,
        "wall_s": res.wall_time,
        "patch_steps": res.patch_steps,
        "kernel_s": kernel,
        "in_shard_rate": res.patch_steps / kernel,
        "wall_rate": res.patch_steps / res.wall_time,
        "wall_over_in_shard": kernel / res.wall_time,
        "device_names": sorted({s["device_name"] for s in res.summaries}),
        "phase_totals_s": {k: sum(s["timings"].get(k, 0.0) for s in res.summaries) for k in phases},
        "shards": [{"index": s["index"], "batches": s["batches"], **s["timings"]} for s in res.summaries],
    }


def parse_args() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cuda:0", help="one device: cuda:N or cpu (default cuda:0)")
    ap.add_argument("--path", choices=("dask", "inprocess"), help="default: dask on CUDA, inprocess on the CPU")
    ap.add_argument("--pads", type=int, help="pads (a power of two; default 2048 on CUDA, 16 on the CPU)")
    ap.add_argument("--patches", type=int, help="patches per pad (default: hf1's 1758 on CUDA, 40 on the CPU)")
    ap.add_argument("--shard-size", type=int, help="pads per shard (default 256 on CUDA, 4 on the CPU)")
    ap.add_argument("--duration", type=float, help="simulated time per pad [s] (default 2e-3 on CUDA, 1.5e-3 on CPU)")
    ap.add_argument("--precision", default="fp32", choices=("fp32", "fp64"))
    ap.add_argument("--modes", nargs="+", choices=MODES, default=list(MODES), help="modes to run, in this order")
    ap.add_argument("--dir", help="scratch folder for the sweep outputs (default: a temporary one, removed)")
    ap.add_argument("--json", default="sweep_throughput.json", help="output JSON file")
    ap.add_argument("--md", default="sweep_throughput.md", help="output Markdown file (one line)")
    args = ap.parse_args()
    if args.device != "cpu" and not (args.device.startswith("cuda:") and args.device[5:].isdigit()):
        ap.error("--device: one device, cuda:N or cpu")
    kind = "cpu" if args.device == "cpu" else "cuda"
    pads, patches, shard, duration = DEFAULTS[kind]
    args.pads = args.pads or pads
    args.patches = args.patches if args.patches is not None else patches
    args.shard_size = args.shard_size or shard
    args.duration = args.duration or duration
    args.path = args.path or ("dask" if kind == "cuda" else "inprocess")
    return args


def markdown_line(doc: dict) -> str:
    """One line: device, sweep, and per mode the wall rate against the in-shard rate."""
    by = {r["mode"]: r for r in doc["results"]}
    parts = [
        f"{m}: {r['wall_s']:.1f} s wall, {r['wall_rate']:.3g} patch-steps/s over the wall against "
        f"{r['in_shard_rate']:.3g} in-shard ({100 * r['wall_over_in_shard']:.0f} %)"
        for m, r in by.items()
    ]
    if "target_ratio" in doc:
        parts.append(f"overlapped wall / sequential in-shard **{100 * doc['target_ratio']:.0f} %** (target ≥ 90 %)")
    s = doc["sweep"]
    return (
        f"{doc['date']}, {doc['machine']['device_name']} ({doc['machine']['device']}, {doc['path']}), Warp "
        f"{doc['warp_version']}: {s['pads']} pads × {s['patches_per_pad']} patches, {s['shards']} shards of "
        f"{s['shard_size']}, {s['duration_s']:g} s, {s['integrator']} {s['precision']}; " + "; ".join(parts) + "."
    )


def main() -> int:
    args = parse_args()
    init_warp()
    spec = load_spec(sweep_doc(args.pads, args.patches, args.shard_size, args.duration, args.precision))
    warm_pads = min(args.pads, 2 * args.shard_size)  # a shard for each of up to two workers
    warm = load_spec(sweep_doc(warm_pads, args.patches, args.shard_size, 20 * 1e-6, args.precision))
    scratch = Path(args.dir or tempfile.mkdtemp(prefix="aca_sweep_throughput_"))
    print(
        f"sweep: {spec.pad_count} pads x {spec.base.patches.count} patches, {spec.shard_count} shards of "
        f"{spec.shard_size}, {spec.duration:g} s, {spec.integrator} {spec.precision}, {args.device} ({args.path})",
        flush=True,
    )
    rows = []
    try:
        for mode in args.modes:
            runner = Runner(args.device, mode, args.path)
            try:
                row = measure(runner, spec, warm, scratch, mode)
            finally:
                runner.close()
            rows.append(row)
            print(
                f"{mode}: {row['wall_s']:.2f} s wall ({row['kernel_s']:.2f} s stepping), in-shard "
                f"{row['in_shard_rate']:.3g} patch-steps/s, wall {row['wall_rate']:.3g} "
                f"({100 * row['wall_over_in_shard']:.0f} %)",
                flush=True,
            )
    finally:
        if not args.dir:
            shutil.rmtree(scratch, ignore_errors=True)
    doc: dict[str, Any] = {
        "date": datetime.date.today().isoformat(),
        "machine": machine(wp.get_device(args.device)),
        "warp_version": wp.__version__,
        "path": args.path,
        "command": " ".join([Path(sys.argv[0]).as_posix(), *sys.argv[1:]]),
        "sweep": {
            "pads": spec.pad_count,
            "patches_per_pad": spec.base.patches.count,
            "shard_size": spec.shard_size,
            "shards": spec.shard_count,
            "duration_s": spec.duration,
            "integrator": spec.integrator,
            "precision": spec.precision,
            "dt_s": spec.dt,
        },
        "results": rows,
    }
    by = {r["mode"]: r for r in rows}
    if set(by) == set(MODES):
        doc["target_ratio"] = by["overlapped"]["wall_rate"] / by["sequential"]["in_shard_rate"]
        doc["overlapped_over_sequential_wall"] = by["overlapped"]["wall_rate"] / by["sequential"]["wall_rate"]
    write_outputs(doc, markdown_line(doc), args.json, args.md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
