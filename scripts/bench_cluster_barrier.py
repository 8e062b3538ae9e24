#!/usr/bin/env python3
"""The floor under one pad's on-chip step on a thread-block cluster: the cost of the barrier alone.

The on-chip HF kernel (kernels/hf_onchip.py) ends each step's friction phase with a barrier of all blocks that
advance the pad (a block barrier for one block, ``barrier.cluster`` for a cluster of K blocks), after each thread
has stored its patches' new displacements into the shared-memory copy of every block of the cluster. This script
times that skeleton alone, per step: a loop of ``steps`` rounds, each (optionally) storing one value per thread
into the u copy of every block of the cluster (``--remote``: the kernel's ``put_u_at``), then the barrier, then
reading one value back (so that the rounds form a chain as in the kernel). No physics: what it measures is the
least time a step on K blocks can take, to set beside the one-pad target (1.5 µs per step) and the
kernel's ablation profile ("loop only" / "no friction, no gather" rows of docs/onchip.md).

Prints a Markdown table (ns per round: barrier only, with the stores into the K copies) and writes JSON rows::

    python3 scripts/bench_cluster_barrier.py --device cuda:0 --clusters 1 2 4 8 16 --blocks 128 224 512 \\
        --json $OUT/barrier.json --markdown $OUT/barrier.md

Clusters above 8 blocks are "non-portable" (H100/H200: up to 16); a size the device cannot launch is reported as
such. On the CPU a cluster is one block and the numbers mean nothing (the script says so and exits).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import warp as wp
from aca_warp.kernels.tiles import (
    block_sync,
    cluster_sync,
    mbarrier_ops,
    tile_load_rows,
    tile_store_rows,
    tile_store_rows_async,
    tile_store_rows_remote,
)

from aca_warp.common.devices import get_device
from aca_warp.common.errors import SceneError

MODES = ("barrier", "stores", "async")
KEYS = ("ns_barrier", "ns_barrier_and_stores", "ns_async_stores_and_wait")


def barrier_kernel(cluster: int, block_dim: int, mode: str) -> Any:
    """A kernel of ``steps`` rounds; ``out[block, lane]`` the sum of the values read back. ``mode``:

    * ``barrier``: barrier, one read;
    * ``stores``: each thread stores its value into the u copy of every block of the cluster (``st.shared::cluster``,
      the kernel's ``put_u_at``), barrier, one read;
    * ``async``: the same stores, into the other blocks by ``st.async`` (each completing bytes of the receiving
      block's mbarrier of that round's parity) and into the own copy directly; then a block barrier and a wait
      for the bytes of the round (``mbarrier_ops``) instead of the cluster barrier.
    """
    K = wp.constant(cluster)
    MODE = wp.constant(MODES.index(mode))
    NBYTES = wp.constant((cluster - 1) * block_dim * 4)  # bytes the other blocks store into one block per round
    put = tile_store_rows_remote(wp.float32, 2, block_dim)
    put_async = tile_store_rows_async(wp.float32, 2, block_dim, 2)
    put_local = tile_store_rows(wp.float32, 2, block_dim)
    get = tile_load_rows(wp.float32, 2, block_dim)
    init, expect, wait = mbarrier_ops(2)
    sync = block_sync if cluster == 1 else cluster_sync

    @wp.kernel(enable_backward=False, module="unique", launch_bounds=(block_dim, 1), cluster_dim=cluster)
    def rounds(steps: int, out: wp.array2d[wp.float32]):
        blk, lane = wp.tid()
        rank = blk % K
        t = wp.tile_zeros(shape=(2, block_dim), dtype=wp.float32, storage="shared")
        bars = wp.tile_zeros(shape=2, dtype=wp.int64, storage="shared")
        init(bars, lane)
        sync()  # every block's mbarriers are set before any block stores into it
        x = wp.float32(lane)
        acc = wp.float32(0.0)
        for s in range(steps):
            row = s % 2
            if MODE == 1:
                for q in range(K):
                    put(t, row, lane, x, q)
            if MODE == 2:
                put_local(t, row, lane, x)
                for q in range(K):
                    if q != rank:
                        put_async(t, row, lane, x, q, bars, row)
                if lane == 0:
                    expect(bars, row, NBYTES)
                block_sync()
                wait(bars, row, (s // 2) % 2)
            else:
                sync()
            acc += get(t, row, (lane + 1) % block_dim)
            x = x + wp.float32(1.0)
        sync()  # no block leaves while another may still store into it
        out[blk, lane] = acc

    return rounds


def time_rounds(kernel: Any, cluster: int, block_dim: int, steps: int, repeats: int, device: Any) -> float:
    """Median seconds per round of one cluster (``repeats`` timed launches after a warm-up)."""
    out = wp.zeros((cluster, block_dim), dtype=wp.float32, device=device)
    wp.launch_tiled(kernel, dim=[cluster], block_dim=block_dim, inputs=[steps, out], device=device)
    wp.synchronize_device(device)
    times = []
    for _ in range(repeats):
        t0 = wp.Event(device, enable_timing=True)
        t1 = wp.Event(device, enable_timing=True)
        wp.record_event(t0)
        wp.launch_tiled(kernel, dim=[cluster], block_dim=block_dim, inputs=[steps, out], device=device)
        wp.record_event(t1)
        wp.synchronize_device(device)
        times.append(wp.get_event_elapsed_time(t0, t1) * 1e-3 / steps)
    return float(np.median(times))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--device", default="cuda:0", help="a CUDA device of compute capability 9.0+ (default cuda:0)")
    p.add_argument("--clusters", type=int, nargs="+", default=[1, 2, 4, 8, 16], help="blocks per cluster")
    p.add_argument("--blocks", type=int, nargs="+", default=[128, 224, 512], help="threads per block")
    p.add_argument("--steps", type=int, default=20_000, help="rounds per launch (default 20000)")
    p.add_argument("--repeats", type=int, default=5, help="timed launches per case (median; default 5)")
    p.add_argument("--json", type=Path, help="write the rows as JSON here")
    p.add_argument("--markdown", type=Path, help="write the table as Markdown here")
    a = p.parse_args(argv)
    if a.steps < 1 or a.repeats < 1:
        p.error("--steps and --repeats must be ≥ 1")
    if any(k < 1 or k > 16 for k in a.clusters):
        p.error("--clusters: 1 to 16 blocks")
    if any(b < 32 or b > 1024 or b % 32 for b in a.blocks):
        p.error("--blocks: multiples of 32 from 32 to 1024")
    try:
        dev = get_device(a.device)
    except SceneError as e:
        p.error(str(e))
    if dev.is_cpu or dev.arch < 90:
        print(f"{dev}: clusters need a CUDA device of compute capability 9.0+; nothing to measure", file=sys.stderr)
        return 2
    rows = []
    for b in a.blocks:
        for k in a.clusters:
            row: dict[str, Any] = {"device": dev.name, "warp_version": wp.config.version, "cluster": k, "threads": b}
            for mode, key in zip(MODES, KEYS, strict=True):
                kern = barrier_kernel(k, b, mode)
                try:
                    row[key] = 1e9 * time_rounds(kern, k, b, a.steps, a.repeats, dev)
                except Exception as exc:  # a cluster size the device cannot launch
                    row[key] = None
                    row["error"] = f"{type(exc).__name__}: {exc}"[:200]
            rows.append(row)
            print(row, flush=True)
    lines = [
        f"Barrier rounds on {dev.name} (Warp {wp.config.version}; `scripts/bench_cluster_barrier.py`, median of "
        f"{a.repeats} launches of {a.steps} rounds, one cluster)",
        "",
        "| threads per block | blocks per cluster | ns per round: barrier | barrier + stores into every copy "
        "| st.async stores + mbarrier wait |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        cells = " | ".join(f"{r[k]:.0f}" if r.get(k) is not None else "not launchable" for k in KEYS)
        lines.append(f"| {r['threads']} | {r['cluster']} | {cells} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if a.json:
        a.json.write_text(json.dumps(rows, indent=1))
    if a.markdown:
        a.markdown.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
