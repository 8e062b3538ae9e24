#!/usr/bin/env python3
"""Where the start of a local sweep's cluster goes: a fresh process's imports and Warp/CUDA start, and a local Dask
cluster's start, client, kernel warm-up and close, each ``--repeat`` times.

* ``fresh``: a new Python process (as a Dask worker or a preparation-pool process is) times, one after the other:
  import NumPy, import Warp, ``wp.init()``, the device's context with a first allocation, the sweep's modules, the
  loads of the HF kernel modules from the kernel cache, import Dask distributed;
* ``cluster``: :func:`~aca_warp.sweep.cluster.local_cluster` on ``--device`` with its default workers (one per GPU,
  or ``--workers`` CPU processes), its client, :func:`~aca_warp.sweep.cluster.warm_workers` (and the load as each
  worker timed it) and the close.

The first repeat loads the kernels into the cache if they are not there (compiling them: minutes); later ones load
them. Prints the JSON and writes it with ``--json``.

    python3 scripts/sweep_start_parts.py --device cuda:0 --repeat 3 \
        --json docs/benchmarks/sweep/cluster_start_h200/parts.json
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import time
from pathlib import Path

FRESH = r"""
import json, sys, time
T = {}
t = time.perf_counter()
def mark(k):
    global t
    n = time.perf_counter(); T[k] = round(n - t, 4); t = n
import numpy; mark("import numpy")
import warp as wp; wp.config.quiet = True; mark("import warp")
wp.init(); mark("wp.init")
d = wp.get_device(sys.argv[1]); a = wp.zeros(1, device=d); wp.synchronize_device(d); mark("context + first alloc")
import aca_warp.kernels.hf, aca_warp.kernels.neighbours; from aca_warp.sweep import shard, prepare
mark("import aca_warp sweep")
wp.load_module(aca_warp.kernels.hf, device=d); wp.synchronize_device(d); mark("load kernels.hf")
wp.load_module(aca_warp.kernels.neighbours, device=d); wp.synchronize_device(d); mark("load kernels.neighbours")
import distributed; mark("import distributed")
print("JSON" + json.dumps(T))
"""


def fresh(device: str) -> dict[str, float]:
    """The start of a new process, part by part [s]."""
    out = subprocess.run([sys.executable, "-c", FRESH, device], capture_output=True, text=True, check=True).stdout
    return json.loads(out.split("JSON", 1)[1])


def cluster(device: str, workers: int | None) -> dict[str, object]:
    """A local cluster's start, client, warm-up and close [s]."""
    from distributed import Client

    from aca_warp.sweep.cluster import local_cluster, warm_workers

    times: dict[str, object] = {}
    t = time.perf_counter()
    made, dev = local_cluster("cpu" if device == "cpu" else device, workers, threads=2)
    times["local_cluster"] = time.perf_counter() - t
    t = time.perf_counter()
    client = Client(made)
    times["client"] = time.perf_counter() - t
    t = time.perf_counter()
    times["warm (per worker, inside)"] = list(warm_workers(client, dev).values())
    times["warm_workers"] = time.perf_counter() - t
    t = time.perf_counter()
    client.close()
    made.close()
    times["close"] = time.perf_counter() - t
    return times


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--device", default="cpu", help="cpu (default) or cuda:N: the device the workers run on")
    ap.add_argument("--workers", type=int, default=None, help="CPU worker processes (default: one per core)")
    ap.add_argument("--repeat", type=int, default=2, help="times each part is measured (default 2)")
    ap.add_argument("--json", type=Path, help="write the results here")
    args = ap.parse_args(argv)
    from aca_warp.common.files import host_cpu
    from aca_warp.studies.report import command_line, write_json

    if args.repeat < 1:
        ap.error("--repeat must be at least 1")
    if args.workers is not None and args.workers < 1:
        ap.error("--workers must be at least 1")
    if args.json is not None and not args.json.parent.is_dir():
        ap.error(f"--json: folder {args.json.parent} does not exist")
    doc = {
        "date": time.strftime("%Y-%m-%d"),
        "host": host_cpu(),
        "platform": platform.platform(),
        "command": command_line("sweep_start_parts.py", argv if argv is not None else sys.argv[1:]),
        "fresh": [fresh(args.device) for _ in range(args.repeat)],
        "cluster": [cluster(args.device, args.workers) for _ in range(args.repeat)],
    }
    print(json.dumps(doc, indent=1))
    if args.json is not None:
        write_json(args.json, doc)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
