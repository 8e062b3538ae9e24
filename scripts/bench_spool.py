#!/usr/bin/env python3
"""How a prepared shard reaches a local Dask worker: by value through the cluster, or through the pool's spool file.

A sweep's preparation pool makes each shard's models on the host (``aca_warp.sweep.prepare``); a prepared shard of
256 hf1 pads is ≈ 100 MB. Handed to a task by value it is pickled in the client, sent through the scheduler to the
worker over the local cluster's TLS connections and unpickled there; handed as a :class:`SpooledShard` the task
reads it from a file of the user's private spool folder. This script prepares one shard of ``--pads`` hf1 pads on
the CPU, starts the sweep's local cluster (one worker, loopback, TLS) and measures, ``--repeat`` times each in turn,
the time from ``client.submit`` until the task holds the prepared shard, both ways (the spool file written as the
pool writes it, before the clock starts; the pool's own transfer of a shard by value into the client is not counted).

    python scripts/bench_spool.py --pads 256 --repeat 3 --json docs/benchmarks/sweep/bench_spool_cpu.json
"""

from __future__ import annotations

import argparse
import json
import platform
import shutil
import statistics
import sys
import time
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_sweep import power_of_two  # noqa: E402

from aca_warp.common.argtypes import int_at_least  # noqa: E402
from aca_warp.common.errors import AcaError  # noqa: E402
from aca_warp.common.files import check_output_path  # noqa: E402


def _held(prepared: object) -> float:
    """Dask task: the prepared shard as the task holds it (a spooled one read from its file); the time it did."""
    from aca_warp.sweep.prepare import SpooledShard

    if isinstance(prepared, SpooledShard):
        prepared.load()
    return time.time()


def measure(pads: int, repeat: int) -> dict:
    import pickle

    from bench_sweep import sweep_doc  # the bench's hf1 product sweep
    from distributed import Client

    from aca_warp.common.devices import init_warp
    from aca_warp.common.files import host_cpu

    init_warp()
    from aca_warp.sweep import hf1_product_doc, load_spec, local_cluster
    from aca_warp.sweep.prepare import _spool_folder, _spooled, prepare_shard

    spec = load_spec(sweep_doc(hf1_product_doc, pads, None, pads, 1e-5, "fp32"))
    t = time.perf_counter()
    prepared = prepare_shard(spec.doc, str(spec.base_dir), 0, device="cpu")
    prepare_s = time.perf_counter() - t
    size = len(pickle.dumps(prepared, protocol=pickle.HIGHEST_PROTOCOL))
    spool = _spool_folder()  # the folder a sweep's pool writes its files into
    cluster, _ = local_cluster("cpu", 1, threads=2)
    client = Client(cluster)
    times: dict[str, list[float]] = {"by value": [], "spool file": []}
    try:
        client.submit(_held, None, pure=False).result()  # the worker warm: imports done
        for _ in range(repeat):
            t = time.time()
            with warnings.catch_warnings():  # Dask's note on large graphs: the hand-over measured here
                warnings.filterwarnings("ignore", message="Sending large graph", category=UserWarning)
                fut = client.submit(_held, prepared, pure=False)
            times["by value"].append(fut.result() - t)
            handle = _spooled(lambda _i: prepared, spool, 0)  # the file as the pool writes it
            t = time.time()
            times["spool file"].append(client.submit(_held, handle, pure=False).result() - t)
    finally:
        client.close()
        cluster.close()
        shutil.rmtree(spool, ignore_errors=True)
    return {
        "date": time.strftime("%Y-%m-%d"),
        "machine": f"{host_cpu()}, {platform.platform()}",
        "command": " ".join(["python", "scripts/bench_spool.py", *sys.argv[1:]]),
        "pads": pads,
        "patches": int(sum(s.patches.count for s in prepared.scenes)),
        "pickle_MB": size / 1e6,
        "prepare_s": prepare_s,
        "submit_to_held_s": times,
        "median_s": {k: statistics.median(v) for k, v in times.items()},
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--pads", type=power_of_two, default=256, help="hf1 pads in the shard (a power of two; default 256)"
    )
    ap.add_argument("--repeat", type=int_at_least(1), default=3, help="hand-overs of each kind, in turn (default 3)")
    ap.add_argument("--json", type=Path, help="write the result there (JSON)")
    args = ap.parse_args(argv)
    if args.json:
        try:
            check_output_path(args.json, overwrite=True)
        except AcaError as e:
            ap.error(str(e))
    doc = measure(args.pads, args.repeat)
    med = doc["median_s"]
    print(
        f"{doc['date']}, {doc['machine']}: a prepared shard of {doc['pads']} hf1 pads ({doc['patches']} patches, "
        f"{doc['pickle_MB']:.1f} MB pickled): submit to held, median of {args.repeat}: by value "
        f"{med['by value']:.3f} s, from the spool file {med['spool file']:.3f} s"
    )
    if args.json:
        args.json.write_text(json.dumps(doc, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
