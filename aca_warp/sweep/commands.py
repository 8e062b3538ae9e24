"""The ``aca-warp sweep`` command: its parser and handler (signals: one line, exit 130 / 143, shards marked
``interrupted``; the sweep itself is :func:`aca_warp.sweep.run.run_sweep`)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from aca_warp.common import interrupts

EPILOG = """\
SPEC is a TOML sweep spec (docs/sweeps.md; example: aca_warp/data/sweep_hf1.toml). DIR receives manifest.json and
one HDF5 file per shard. A rerun in the same DIR skips finished shards and redoes unfinished ones.
Examples:
  aca-warp sweep aca_warp/data/sweep_hf1.toml -o sweep_out --workers 2            # two CPU worker processes
  aca-warp sweep aca_warp/data/sweep_hf1.toml -o sweep_out --device cuda          # one worker per GPU
  aca-warp sweep aca_warp/data/sweep_hf1.toml -o sweep_out --device cuda --scheduler tls://host:8786
Exit codes: 0 every shard finished, 2 bad input, 3 some shard stopped on a fault or failed (rerun to retry),
4 a shard file could not be written (disk full), 130 interrupted (Ctrl-C), 143 terminated (SIGTERM); after an
interrupt the manifest marks the shards that were running "interrupted" and a rerun finishes them.
"""


def add_parsers(sub: Any) -> None:
    """Register ``aca-warp sweep``."""
    from aca_warp.common.argtypes import fraction, int_at_least, positive, spacing
    from aca_warp.hf.options import CROSSINGS, INTEGRATORS

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
    g.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="use the Dask cluster at this scheduler address: tls://HOST:PORT with your own TLS certificates in "
        "Dask's configuration (distributed.comm.tls.*); a plain tcp:// address is accepted but is NOT "
        "authenticated: anyone who can reach that scheduler runs code on its workers (docs/sweeps.md, Security). "
        "Without it the local cluster listens on 127.0.0.1 only, behind TLS with credentials of its own",
    )
    p.add_argument("--overwrite", action="store_true", help="replace a different sweep in DIR")
    p.add_argument("--duration", type=positive, metavar="S", help="simulated time per pad [s] (default: the spec's)")
    p.add_argument("--integrator", choices=INTEGRATORS, help="time integrator (default: the spec's, else strang)")
    p.add_argument(
        "--precision",
        choices=("fp32", "fp64"),
        help="state precision (default: the spec's, else fp32 for strang and fp64 for the other integrators)",
    )
    p.add_argument(
        "--dt",
        type=positive,
        metavar="S",
        help="fixed step [s] (default: the spec's, else strang 3.33e-7 or 2.5e-7 by preset (aca-warp hf --help) for a "
        "sweep of a shipped preset whose pads all "
        "keep its physics (seeds and initial states varied, other parameters at the preset's values only), 5e-8 for "
        "any other; the other fixed-step integrators 1e-8)",
    )
    p.add_argument(
        "--fast-math",
        action="store_true",
        default=None,
        help="the on-chip strang kernel compiled with CUDA fast math (the spec's run.fast_math; fp32 strang on CUDA "
        "only; aca-warp hf --fast-math, docs/onchip.md 'Fast math')",
    )
    p.add_argument(
        "--crossing",
        choices=CROSSINGS,
        help="strang's treatment of steps that cross zero slip (the spec's run.crossing; default mean for a sweep "
        "of a shipped preset whose pads all share its physics, else point; aca-warp hf --crossing, "
        "docs/friction_step.md section 8.1)",
    )
    p.add_argument(
        "--growth-dt",
        type=spacing,
        metavar="S",
        help="simulated time between growth events of growing pads [s] (the spec's run.growth_dt; default with "
        "strang 5e-6, or the base scene's growth interval if longer or the run shorter; with the other "
        "integrators, or 'scene', the scenes' interval; aca-warp hf --growth-dt, docs/model.md 2.10)",
    )
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
        help="the serial path: one shard at a time per worker, writes inline (same results); default: two shard "
        "tasks per worker take the device in turns, the next one waiting ready, writes behind the runs "
        "(docs/sweeps.md)",
    )
    p.add_argument(
        "--prepare",
        type=int_at_least(0),
        metavar="N",
        help="processes that make the shards ahead of their runs: scenes, models on the host, initial states and "
        "checks (default: 2 per GPU of a local CUDA sweep, 4 per GPU where the sweep makes at least one patch "
        "layout per two pads, at least 4, at most the cores the workers leave; else 0: each shard task makes its "
        "own)",
    )
    p.add_argument("--quiet", action="store_true", help="print only the summary")
    p.set_defaults(handler=_cmd_sweep)


def _interrupted_line(out: str, e: KeyboardInterrupt) -> str:
    """The one line printed when a sweep is stopped by a signal."""
    from aca_warp.sweep.manifest import MANIFEST, read_manifest
    from aca_warp.sweep.spec import SweepError

    what = "terminated (SIGTERM)" if isinstance(e, interrupts.Terminated) else "interrupted"
    try:
        m = read_manifest(out)
    except SweepError:
        m = None
    if m is None:
        return f"aca-warp: {what}; nothing was run"
    hit = [str(s["index"]) for s in m.get("shards", []) if s.get("state") == "interrupted"]
    done = sum(s.get("state") in ("done", "fault") for s in m.get("shards", []))
    total = len(m.get("shards", []))
    if total and done == total:
        faults = sum(s.get("state") == "fault" for s in m.get("shards", []))
        stopped = f", {faults} stopped on a fault" if faults else ""
        return (
            f"aca-warp: {what} after every shard had finished ({done} of {total}{stopped}; {Path(out) / MANIFEST}): "
            "the sweep is complete; running the same command again skips every shard"
        )
    shards = f"shard(s) {', '.join(hit)} marked interrupted" if hit else "none was running"
    return (
        f"aca-warp: {what}; {done} of {total} shard(s) finished, {shards} ({Path(out) / MANIFEST}); run the same "
        "command again to finish the sweep"
    )


def _run_words(spec: Any) -> str:
    """A pad's run as the shards take it, in words: the time it covers (whole sample intervals: a duration that is
    not one is said with it), integrator, precision and fixed step (fitted to the sample interval: a step that is
    shortened is said with it)."""
    from aca_warp.hf.options import STEP_CONTROLLED
    from aca_warp.hf.solver import fitted_step
    from aca_warp.sweep.shard import shard_samples

    sample = spec.base.record.sample_dt
    covered = (shard_samples(spec) - 1) * sample  # the samples after t = 0
    words = f"{covered:g} s each"
    if not math.isclose(covered, spec.duration, rel_tol=1e-9):
        words += f" ({spec.duration:g} s asked: whole sample intervals of {sample:g} s)"
    words += f", {spec.integrator} {spec.precision}"
    if spec.dt is not None and spec.integrator not in STEP_CONTROLLED:
        step = fitted_step(spec.dt, sample)
        words += f" at {step:.3g} s"
        if not math.isclose(step, spec.dt, rel_tol=1e-9):
            words += f" ({spec.dt:g} s asked, fitted to the {sample:g} s samples)"
    elif spec.dt is not None:
        words += f" from {spec.dt:g} s"
    return words


def _cmd_sweep(args: argparse.Namespace) -> int:
    from aca_warp.hf.options import crossing_words, growth_words
    from aca_warp.sweep.run import check_local_gpus, run_sweep
    from aca_warp.sweep.spec import SweepError, load_spec

    spec = load_spec(
        args.spec,
        shard_size=args.shard_size,
        duration=args.duration,
        integrator=args.integrator,
        precision=args.precision,
        dt=args.dt,
        fast_math=args.fast_math,
        growth_dt=args.growth_dt,
        crossing=args.crossing,
    )
    if spec.fast_math and args.scheduler is None and "cpu" in args.device.split(","):
        raise SweepError("fast math applies to CUDA devices only: run the sweep with --device cuda")
    if args.scheduler is None:
        check_local_gpus(args.device)  # before the header: a missing GPU is one line on stderr
    log = None if args.quiet else (lambda s: print(s, flush=True))
    if log:
        pads = lambda n: f"{n} pad{'' if n == 1 else 's'}"  # noqa: E731
        log(
            f"sweep {spec.name!r}: {pads(spec.pad_count)} ({', '.join(spec.parameters) or 'base only'}), "
            f"{spec.shard_count} shard(s) of up to {pads(min(spec.shard_size, spec.pad_count))}, "
            f"{_run_words(spec)}{', fast math' if spec.fast_math else ''}"
            f"{crossing_words(spec.crossing)}"
            f"{growth_words(spec.growth_dt)}"
            f", spec hash {spec.hash[:12]}"
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
                prepare=args.prepare,
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
