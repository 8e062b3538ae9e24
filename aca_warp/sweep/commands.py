"""Parameter sweeps: a TOML spec expanded into many pads, run in shards (serially, overlapped, or through Dask),
resumable; the ``aca-warp sweep`` command.

A sweep spec (``docs/sweeps.md``) names a base scene (a preset, a TOML scene file, or inline tables) and grids
or lists of scene parameters (``friction.M``, ``load.normal_force``, ``disc.sliding_speed``, ``patches.seed``,
``patches.area_min``, ``material.K_C``, ...), combined as a Cartesian product or zipped. Every combination is
one pad. Pads are cut into shards of a fixed size; each shard is one batched HF run (one :func:`build_model`,
one :func:`aca_warp.hf.loop.run_hf` with the engine ``auto``: the on-chip kernel on CUDA, else the general one;
split only when the estimated device memory says the batch does not fit) and one HDF5 file::

    DIR/manifest.json            spec, spec hash, shards and their state (written only by the client)
    DIR/shard-00000.h5           /global/time (samples,) [s]
                                 /global/mu, torque, friction_radius, sum_velocity, sum_abs_velocity, friction_centroid
                                     (pads, samples), unit attributes as in run files
                                 /parameters/<key> (pads,) one dataset per swept parameter, unit attribute
                                 /pads/index (pads,) global pad index, /pads/patch_count (pads,)
                                 attrs: spec (JSON), spec_hash, shard, pad_start, pad_stop, complete,
                                     finished, status, device, integrator, precision, dt, steps, timings, ...

A shard file is written as ``NAME.partial`` and renamed when its run ends: a final name always holds a whole
shard. A rerun skips a shard only when the manifest *and* the file agree that it finished under the same spec
hash; everything else (a ``.partial`` left by a killed worker, a missing or foreign file, a shard marked
``interrupted``) is run again.

The code lives in modules of one concern each, re-exported here (``from aca_warp.sweep import run_sweep`` etc.):

* :mod:`aca_warp.sweep_spec`: the spec, its pads and hash (:func:`load_spec`, :class:`SweepSpec`);
* :mod:`aca_warp.sweep_shard`: one shard task and its file (:func:`run_shard`, :func:`shard_finished`);
* :mod:`aca_warp.sweep_overlap`: the writer thread, the device's turns and the cancel event of a shard task;
* :mod:`aca_warp.sweep_manifest`: the sweep directory, its manifest and :func:`load_sweep`;
* :mod:`aca_warp.sweep_cluster`: Dask (a loopback-only local cluster, a scheduler or a client);
* :mod:`aca_warp.sweep_run`: :func:`run_sweep` and the in-process paths;
* this module: the command line (signals: one line, exit 130 / 143, shards marked ``interrupted``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from aca_warp.common import interrupts
from aca_warp.sweep_cluster import LOOPBACK, WORKERS_PER_GPU, cuda_ordinals, local_cluster, warm_workers
from aca_warp.sweep_manifest import MANIFEST, SHARD_STATES, SweepResult, load_sweep, prepare_dir, read_manifest
from aca_warp.sweep_overlap import ChunkWriter, KernelTurn, ShardCancelled, ShardContext
from aca_warp.sweep_run import PIPELINE_DEPTH, run_sweep
from aca_warp.sweep_shard import (
    TIMING_DOC,
    TIMING_PHASES,
    batch_capacity,
    device_memory,
    pad_bytes,
    run_shard,
    shard_finished,
    shard_name,
)
from aca_warp.sweep_spec import (
    DEFAULT_SHARD_SIZE,
    FORMAT,
    MAX_PADS,
    MAX_STEPS,
    MODES,
    PARAMETERS,
    SweepError,
    SweepSpec,
    apply_parameters,
    hf1_product_doc,
    load_spec,
)

__all__ = [
    "DEFAULT_SHARD_SIZE",
    "FORMAT",
    "LOOPBACK",
    "MANIFEST",
    "MAX_PADS",
    "MAX_STEPS",
    "MODES",
    "PARAMETERS",
    "PIPELINE_DEPTH",
    "SHARD_STATES",
    "TIMING_DOC",
    "TIMING_PHASES",
    "WORKERS_PER_GPU",
    "ChunkWriter",
    "KernelTurn",
    "ShardCancelled",
    "ShardContext",
    "SweepError",
    "SweepResult",
    "SweepSpec",
    "add_parsers",
    "apply_parameters",
    "hf1_product_doc",
    "batch_capacity",
    "cuda_ordinals",
    "device_memory",
    "load_spec",
    "load_sweep",
    "local_cluster",
    "pad_bytes",
    "prepare_dir",
    "read_manifest",
    "run_shard",
    "run_sweep",
    "shard_finished",
    "shard_name",
    "warm_workers",
]


# ------------------------------------------------------------------------------------------------- CLI

EPILOG = """\
SPEC is a TOML sweep spec (docs/sweeps.md; example: aca_warp/data/sweep_hf1.toml). DIR receives manifest.json and
one HDF5 file per shard. A rerun in the same DIR skips finished shards and redoes unfinished ones.
Examples:
  aca-warp sweep aca_warp/data/sweep_hf1.toml -o sweep_out --workers 2            # two CPU worker processes
  aca-warp sweep aca_warp/data/sweep_hf1.toml -o sweep_out --device cuda          # two workers per GPU
  aca-warp sweep aca_warp/data/sweep_hf1.toml -o sweep_out --device cuda --scheduler tcp://host:8786
Exit codes: 0 every shard finished, 2 bad input, 3 some shard stopped on a fault or failed (rerun to retry),
4 a shard file could not be written (disk full), 130 interrupted (Ctrl-C), 143 terminated (SIGTERM); after an
interrupt the manifest marks the shards that were running "interrupted" and a rerun finishes them.
"""


def add_parsers(sub: Any) -> None:
    """Register ``aca-warp sweep``."""
    from aca_warp.common.argtypes import fraction, int_at_least, positive
    from aca_warp.hf.options import INTEGRATORS

    p = sub.add_parser(
        "sweep",
        help="run a parameter sweep (many pads, batched, sharded, resumable; Dask for several workers)",
        description="Expand a TOML sweep spec into pads, run them in shards of batched pads and write one HDF5 "
        "file per shard plus a manifest. Several GPUs, CPU cores or hosts through Dask distributed.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=EPILOG,
    )
    p.add_argument("spec", metavar="SPEC", help="TOML sweep spec")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="sweep directory (created if missing)")
    p.add_argument(
        "--device", default="cpu", help="cpu (default), cuda (every GPU), cuda:N, or a list such as cuda:0,cuda:1"
    )
    p.add_argument(
        "--shard-size", type=int_at_least(1), metavar="N", help="pads per shard (default: the spec's, else 64)"
    )
    g = p.add_mutually_exclusive_group()
    g.add_argument(
        "--workers",
        type=int_at_least(0),
        metavar="N",
        help="local Dask workers (default: one per GPU, or one per CPU core for cpu); 0 runs in this process",
    )
    g.add_argument("--scheduler", metavar="ADDRESS", help="use the Dask cluster at this scheduler address")
    p.add_argument("--overwrite", action="store_true", help="replace a different sweep in DIR")
    p.add_argument("--duration", type=positive, metavar="S", help="simulated time per pad [s] (default: the spec's)")
    p.add_argument("--integrator", choices=INTEGRATORS, help="time integrator (default: the spec's, else strang)")
    p.add_argument("--precision", choices=("fp32", "fp64"), help="state precision (default: the spec's, else fp64)")
    p.add_argument("--dt", type=positive, metavar="S", help="fixed step [s] (default: the spec's, else 1e-8)")
    p.add_argument(
        "--memory-fraction",
        type=fraction,
        default=0.5,
        metavar="F",
        help="share of free device memory one batch may use (default 0.5); larger shards are split",
    )
    p.add_argument(
        "--no-overlap",
        dest="overlap",
        action="store_false",
        help="the serial path: one worker per GPU, one shard at a time per worker, writes inline (same results); "
        "default: model builds and writes overlap the kernels (docs/sweeps.md)",
    )
    p.add_argument("--quiet", action="store_true", help="print only the summary")
    p.set_defaults(handler=_cmd_sweep)


def _interrupted_line(out: str, e: KeyboardInterrupt) -> str:
    """The one line printed when a sweep is stopped by a signal."""
    what = "terminated (SIGTERM)" if isinstance(e, interrupts.Terminated) else "interrupted"
    try:
        m = read_manifest(out)
    except SweepError:
        m = None
    if m is None:
        return f"aca-warp: {what}; nothing was run"
    hit = [str(s["index"]) for s in m.get("shards", []) if s.get("state") == "interrupted"]
    done = sum(s.get("state") in ("done", "fault") for s in m.get("shards", []))
    shards = f"shard(s) {', '.join(hit)} marked interrupted" if hit else "no shard was running"
    return (
        f"aca-warp: {what}; {done} of {len(m.get('shards', []))} shard(s) finished, {shards} in "
        f"{Path(out) / MANIFEST}; run the same command again to finish the sweep"
    )


def _cmd_sweep(args: argparse.Namespace) -> int:
    spec = load_spec(
        args.spec,
        shard_size=args.shard_size,
        duration=args.duration,
        integrator=args.integrator,
        precision=args.precision,
        dt=args.dt,
    )
    log = None if args.quiet else (lambda s: print(s, flush=True))
    if log:
        log(
            f"sweep {spec.name!r}: {spec.pad_count} pads ({', '.join(spec.parameters) or 'base only'}), "
            f"{spec.shard_count} shard(s) of {spec.shard_size}, {spec.duration:g} s each, "
            f"{spec.integrator} {spec.precision}, spec hash {spec.hash[:12]}"
        )
    try:
        with interrupts.second_signal_exits():  # the signals are the command line's (aca_warp.cli.main)
            res = run_sweep(
                spec,
                args.output,
                device=args.device,
                workers=args.workers,
                scheduler=args.scheduler,
                overwrite=args.overwrite,
                memory_fraction=args.memory_fraction,
                log=log,
                overlap=args.overlap,
            )
    except KeyboardInterrupt as e:
        print(_interrupted_line(args.output, e), file=sys.stderr, flush=True)
        return interrupts.exit_code(e)
    rate = res.patch_steps / max(res.wall_time, 1e-12)
    print(
        f"{args.output}: {len(res.ran)} shard(s) run, {len(res.skipped)} skipped, {len(res.faults)} stopped on a "
        f"fault, {len(res.failed)} failed; {res.wall_time:.3g} s wall, {rate:.3g} patch-steps/s overall"
    )
    return 3 if res.failed or res.faults else 0
