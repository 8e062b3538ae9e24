#!/usr/bin/env python3
"""Where a sweep shard's turn on its device goes before its first step, function by function (cProfile), for
consecutive shards in one process as a sweep worker runs them.

The bench's product sweep (hf1, M × F_N × 8 patch layouts, ``scripts/bench_sweep.py``'s ``product``); each of
``--shards`` shards runs as a shard task runs it, by one of three ``--path``s:

* ``prepared``: made by the preparation pool (:func:`~aca_warp.sweep.prepare.prepare_shard` with the device, here
  beforehand), the task uploads it (``upload``) and sets the run up with the pool's checks (``setup``);
* ``built``: the task builds the model on the device (``build``: ``build_model`` and ``initial_state``) and the run
  makes its checks from the device arrays (``setup``), as a shard the pool has not made runs;
* ``host``: the task makes the model on the host as the pool does (``build``: ``prepare_batch``), uploads it and
  sets the run up with those checks.

Then the run (``run``: its loop, samples dropped). Every phase ends with the device synchronised; ``build`` and
``setup`` are profiled, and the functions with the largest cumulative time are listed per shard. With ``--warm-up``
every shard first runs for 1 µs from the pool's batch (a warm worker: the bench's warm-up sweep runs before its timed
sweep). With ``--release-threshold`` the device's CUDA memory pool keeps that much freed memory instead of returning it
to the driver (Warp leaves the threshold at CUDA's default, 0 B).

    python3 scripts/profile_shard_turn.py --device cuda:0 --shards 4 --dt 1e-8 --json turn.json
    python3 scripts/profile_shard_turn.py --device cuda:0 --shards 4 --dt 1e-8 --release-threshold 0.5
"""

from __future__ import annotations

import argparse
import cProfile
import dataclasses
import io
import json
import pstats
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any


def _top(profile: cProfile.Profile, n: int) -> list[dict]:
    """The ``n`` functions of ``profile`` with the largest cumulative time [s]."""
    stats = pstats.Stats(profile, stream=io.StringIO())
    rows = []
    for (file, line, name), (_cc, calls, _tt, cum, _callers) in stats.stats.items():  # type: ignore[attr-defined]
        rows.append({"function": f"{Path(file).name}:{line}({name})", "calls": calls, "cumulative_s": cum})
    rows.sort(key=lambda r: -r["cumulative_s"])
    return rows[:n]


class _Clock:
    """Wall time per phase [s], each call ending with the device synchronised; profiled calls in one profile."""

    def __init__(self, dev: Any) -> None:
        self.dev, self.profile = dev, cProfile.Profile()
        self.phases: dict[str, float] = {}

    def __call__(self, name: str, fn: Callable[..., Any], *args: Any, profiled: bool = True, **kw: Any) -> Any:
        import warp as wp

        t = time.perf_counter()
        if profiled:
            self.profile.enable()
        try:
            out = fn(*args, **kw)
            wp.synchronize_device(self.dev)
        finally:
            self.profile.disable()
        self.phases[name] = self.phases.get(name, 0.0) + time.perf_counter() - t
        return out


def main() -> int:
    from aca_warp.common.argtypes import int_at_least

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cuda:0", help="device of the runs (default cuda:0)")
    ap.add_argument("--shards", type=int_at_least(1), default=4, help="consecutive shards to run (default 4)")
    ap.add_argument("--shard-size", type=int_at_least(1), default=256, help="pads per shard (default 256)")
    ap.add_argument("--duration", type=float, default=1e-3, help="simulated time per pad [s] (default 1e-3)")
    ap.add_argument("--dt", type=float, default=None, help="strang's step [s] (default: the sweep's default step)")
    ap.add_argument(
        "--release-threshold",
        type=float,
        default=None,
        help="the CUDA memory pool's release threshold: a fraction of the device's memory (< 1) or bytes (default: "
        "left as Warp leaves it)",
    )
    ap.add_argument(
        "--path", choices=("prepared", "built", "host"), default="prepared", help="how a shard reaches its device"
    )
    ap.add_argument("--warm-up", action="store_true", help="run every shard for 1 µs first (a warm worker)")
    ap.add_argument("--top", type=int_at_least(1), default=25, help="functions listed per shard (default 25)")
    ap.add_argument("--json", help="write the results here")
    args = ap.parse_args()

    import warp as wp

    from aca_warp.common.devices import init_warp
    from aca_warp.common.files import host_cpu

    init_warp()
    from aca_warp.hf.engine import EngineTuning
    from aca_warp.hf.loop import _Run
    from aca_warp.hf.model import build_model, upload
    from aca_warp.hf.state import initial_state, state_from_host
    from aca_warp.sweep import hf1_product_doc, load_spec
    from aca_warp.sweep.prepare import prepare_batch, prepare_shard, run_options

    dev = wp.get_device(args.device)
    if args.release_threshold is not None:
        wp.set_mempool_release_threshold(dev, args.release_threshold)
    pads = args.shard_size * args.shards
    seeds = min(8, pads)
    n_m = 2 if pads >= 2 * seeds else 1  # friction.M values; n_f normal forces
    n_f = pads // (seeds * n_m)
    if n_m * n_f * seeds != pads:
        raise SystemExit(f"--shard-size × --shards = {pads} pads: choose a multiple of 16, or fewer than 9")
    doc = hf1_product_doc("turn", n_m, n_f, seeds, shard_size=args.shard_size, duration=args.duration, precision="fp32")
    if args.dt is None:
        doc["run"].pop("dt")
    else:
        doc["run"]["dt"] = args.dt
    spec = load_spec(doc)
    t = time.perf_counter()
    pool_device = str(dev) if args.path == "prepared" or args.warm_up else None  # None: scenes only
    prepared = [prepare_shard(spec.doc, str(spec.base_dir), i, device=pool_device) for i in range(args.shards)]
    prepare_s = time.perf_counter() - t
    if args.warm_up:
        for sh in prepared:
            (batch,) = sh.batches
            model = upload(batch.model, dev)
            state = state_from_host(model, batch.u, batch.v)
            options = dataclasses.replace(run_options(sh.spec), duration=1e-6)
            _Run(model, state, options, sh.spec.base.record, EngineTuning(), None, None).loop(None, False, None, 0.0)
            del model, state
        wp.synchronize_device(dev)
    shards = []
    for sh in prepared:
        clock = _Clock(dev)
        batch, checked = (sh.batches or [None])[0], None
        if args.path == "built":
            model = clock("build", build_model, sh.scenes, device=dev, precision="fp32")
            state = clock("build", initial_state, model)
        else:
            if args.path == "host":
                batch = clock("build", prepare_batch, sh.spec, sh.scenes, 0, len(sh.scenes), str(dev))
            model = clock("upload", upload, batch.model, dev, profiled=False)
            state = clock("upload", state_from_host, model, batch.u, batch.v, profiled=False)
            checked = batch.checked
        options, record = run_options(sh.spec), sh.spec.base.record
        run = clock("setup", _Run, model, state, options, record, EngineTuning(), None, checked)
        res = clock("run", run.loop, None, False, None, 0.0, profiled=False)
        del run, model, state
        phases = clock.phases
        profile = clock.profile
        shards.append(
            {
                "index": sh.index,
                "pads": len(sh.pads),
                "engine": res.engine,
                "steps": res.steps,
                "dt_s": res.dt,
                "phases_s": phases,
                "profile_top": _top(profile, args.top),
            }
        )
        print(f"shard {sh.index}: " + ", ".join(f"{k} {v:.3f} s" for k, v in phases.items()), flush=True)
        for r in shards[-1]["profile_top"][:12]:
            print(f"    {r['cumulative_s']:.4f} s  {r['calls']:6d}  {r['function']}")
    out = {
        "date": time.strftime("%Y-%m-%d"),
        "device": dev.name,
        "host": host_cpu(),
        "warp_version": wp.__version__,
        "release_threshold": args.release_threshold,
        "warm_up": args.warm_up,
        "path": args.path,
        "prepare_s": prepare_s,
        "shards": shards,
    }
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
