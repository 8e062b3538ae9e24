#!/usr/bin/env python3
"""Sweep throughput on one and on two GPUs, the new path against a baseline in the same run: wall rate, in-shard rate,
their ratio, the speedup of two GPUs over one, every shard's phase times and the devices' time lines.

The sweep: ``--pads`` hf1 pads, ``strang``, fp32, 1 µs samples, 1 ms simulated, shards of 256 (``aca-warp sweep
--device cuda`` but the shard size and, by default, the step). ``--sweep product`` (default): friction.M ×
load.normal_force × patches.seed, 8 layouts; ``--sweep seeds``: patch seeds 1…pads, every pad a layout of its own
(the ensembles of the statistics), whose layouts the preparation makes. ``--dt``: 1e-8 s by default, the step of
the earlier runs, so that they compare; ``--dt default`` runs the sweep's own default step, as a user's sweep does
(5e-8 s for the product sweep, whose M and load vary; 1e-6/3 s for the seeds sweep, hf1's physics, whose default
crossing treatment, ``mean``, it takes at any step; 1e-7 s with the point treatment before).
Each configuration runs in a child process that imports the code under test (its Dask workers and preparation
processes inherit it), starts a local Dask cluster as that code's ``aca-warp sweep --device cuda:0[,cuda:1]`` does
(loopback only; this code: one worker process per GPU with two shard tasks in its threads, overlapped, or one,
``sequential``, as ``--no-overlap``; a code from before it: two single-threaded workers per GPU overlapped, one
sequential), runs a warm-up sweep of the same pads (of the seeds sweep, two shards per unit) for 1 µs (kernels
compiled or loaded in every worker; the pool's fork server started), then the timed sweep into a fresh directory.
Configurations:

* ``new``: the checkout this script belongs to, with its preparation pool (``--prepare``, default as ``aca-warp
  sweep``: two processes per GPU and at least four, none on the CPU), overlapped, on each of ``--units`` GPUs (CPU
  worker processes with ``--device cpu``); and once ``sequential`` on the first of ``--units``: the in-shard rate of
  kernels that do not share their GPU, the reference of the targets; with ``--kept-pool`` also ``kept`` on each of
  ``--units``: overlapped, its warm-up and timed sweeps inside ``keep_preparation_pool()``, so that the timed sweep
  prepares its shards in the processes the warm-up started (a script that runs sweeps one after another);
* ``baseline`` (with ``--baseline DIR``): the checkout at DIR (e.g. ``git archive <commit> aca_warp kernels | tar -x
  -C DIR``), overlapped, on each of ``--units``.

Reported per configuration (JSON, and one Markdown line; with ``--repeat N`` every configuration runs N times, in turn,
and its run of the shortest wall time is reported, all runs kept in the JSON's ``runs``): the sweep call's wall time
(cluster start and warm-up not counted), wall rate = patch-steps / wall time, in-shard rate = patch-steps / Σ over
shards of ``timings.kernel`` (per GPU: each shard runs on one), wall rate / (units × in-shard rate), the same against
the sequential reference's in-shard rate (target: ≥ 0.9 on one GPU), the speedup over the same code on the first of
``--units`` (target: ≥ 1.9 for two GPUs over one), and per phase of a shard task (prepare, prepare_ahead, upload, build,
setup, kernel, write, task) the median and the total over the shards (and, over repeated runs, the least of the medians:
``phase_least_s``). ``timeline``: every shard's phases on the sweep call's clock (seconds from its start;
``timings.spans``, or for a code without them its run's start and end) and, per worker process (one per GPU in this
code), its device time: ``start`` (the call's start to its first shard's turn: upload or build), ``busy`` (the turns, to
each run's end), ``idle`` (between one run's end and the next turn), ``tail`` (the last run's end to the call's end: the
last file and the manifest); ``preparations``: who made the shards and in what time (:func:`preparations`: the pool's
first wave, begun before its first preparation had finished, its later ones, what their hand-over cost the tasks, and
the shards the tasks made themselves). Before the sweeps, per code, the host phases of one shard measured alone in one
process (``--host-repeat`` times; :func:`host_phases`): the least wall time and the least CPU time of prepare, build and
setup, and for a code with a preparation of models on the host, the pool's work per shard (``pool``: scenes, host model,
initial state, checks) and what is left to the device's turn (``upload``, and ``setup_checked``: the run's set-up with
the checks given), which on a machine shared with other work say more than the sweeps' wall times. Every overlapped
configuration also runs once as ``aca-warp sweep`` runs it, in a process of its own (:func:`command_sweep`):
``command_wall_s`` from the call's start to its return (pool, cluster start, shards), ``command_exit_s`` from the call's
start to its process's end (what a user of the command waits for: the interpreter's exit waits for processes the call
left, such as a preparation pool's), and ``command_shards_s`` from the first device turn to the call's return (the
cluster's start left out, which does not grow with the sweep; the pool's head start, which prepares every worker's first
shard during that start, kept in), each with its speedup over the fewest units. The JSON and the Markdown line are
written after every run (the JSON's ``partial`` true until the last), so that a command stopped by a time limit leaves
what it measured.

Two H200s (one GPU and two, the code before as baseline; a few minutes)::

    mkdir -p build/baseline && git archive <commit> aca_warp kernels | tar -x -C build/baseline
    NCCL_NVLS_ENABLE=0 python scripts/bench_sweep.py --device cuda --units 1 2 --baseline build/baseline

The host phases alone (no sweep), this code against a baseline: a shard of 256 pads of the seeds sweep, each its
own layout, 3 times per code::

    python scripts/bench_sweep.py --device cpu --host-only --sweep seeds --pads 512 --dt default --baseline build/base

CPU (the host time per shard before and after: 2 shards of 256 hf1 pads, 1 µs simulated, 3 times in turn)::

    python scripts/bench_sweep.py --device cpu --units 1 --pads 512 --duration 1e-6 --repeat 3 --baseline build/baseline
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import functools
import inspect
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("NCCL_NVLS_ENABLE", "0")  # never use NVLink multicast (shared machines)

WARM_UP_S = 1e-6  # simulated time of the warm-up sweep [s]: one sample, enough to load every kernel in every worker
PHASES = ("prepare", "prepare_ahead", "upload", "build", "setup", "kernel", "write", "task")
TURN = ("upload", "build", "setup", "kernel")  # the phases of a shard's turn on its device
HERE = Path(__file__).resolve().parent


def sweep_doc(hf1_product_doc: Any, cfg: dict, duration: float, pads: int | None = None) -> dict:
    """The spec of the bench's sweep of ``pads`` (default ``cfg["pads"]``) hf1 pads for ``duration`` [s]:
    ``cfg["sweep"]`` ``product``, M × F_N × seed with 8 seeds (fewer for tiny sweeps), pads a power of two
    (``hf1_product_doc`` of the code under test), or ``seeds``, patch seeds 1…pads, each pad its own layout;
    ``strang`` at ``cfg["dt"]`` [s], or at the sweep's default step where it is None."""
    pads = cfg["pads"] if pads is None else pads
    if pads < 1 or pads & (pads - 1):
        raise SystemExit(f"--pads {pads}: choose a power of two (the bench's sweeps have 2^k pads)")
    shard, patches, precision = cfg["shard_size"], cfg["patches"], cfg["precision"]
    if cfg["sweep"] == "seeds":
        doc: dict = {
            "sweep": {"name": f"bench-seeds-{pads}", "base": "hf1", "shard_size": shard},
            "run": {"duration": duration, "precision": precision, "integrator": "strang"},
            "parameters": {"patches.seed": {"range": [1, pads + 1]}},
        }
        if patches is not None:
            doc["base"] = {"patches": {"count": patches}}
    else:
        seeds = min(8, pads)
        rest = pads // seeds
        n_m = 2 ** (rest.bit_length() // 2)
        n_f = rest // n_m
        doc = hf1_product_doc(
            f"bench-{pads}", n_m, n_f, seeds, shard_size=shard, duration=duration, precision=precision, patches=patches
        )
    if cfg["dt"] is None:
        doc["run"].pop("dt", None)
    else:
        doc["run"]["dt"] = cfg["dt"]
    return doc


def warm_up_pads(cfg: dict) -> int:
    """Pads of the warm-up sweep: all of them for the product sweep (8 layouts); for the seeds sweep, whose every pad
    is a layout of its own, two shards per unit (every worker's threads load their kernels, the pool starts)."""
    if cfg["sweep"] != "seeds":
        return cfg["pads"]
    return min(cfg["pads"], 1 << (2 * cfg["shard_size"] * cfg["units"] - 1).bit_length())


# ----------------------------------------------------------------------------------------------------- child


def host_phases(cfg: dict) -> dict:
    """The host phases of one shard (shard 1 of the sweep) as a shard task has them, in this process, ``cfg["repeat"]``
    times: the spec and scenes (``prepare``), ``build_model`` and ``initial_state`` (``build``), the run's set-up
    before its first step (``setup``: checks, stable-step estimate, engine, launch layout); per phase the least wall
    time and the least CPU time of this process over the repeats [s] (CPU time: the work itself, whatever else the
    machine runs). The first repeat loads the kernels; the least is the steady state of a warm worker."""
    import copy
    import importlib
    import inspect

    import warp as wp

    import aca_warp
    from aca_warp.common.devices import init_warp

    init_warp()
    from aca_warp.hf.engine import EngineTuning
    from aca_warp.hf.loop import _Run
    from aca_warp.hf.model import build_model
    from aca_warp.hf.state import initial_state
    from aca_warp.sweep import hf1_product_doc, load_spec
    from aca_warp.sweep import spec as spec_module

    spec = load_spec(sweep_doc(hf1_product_doc, cfg, cfg["duration"]))
    device = "cpu" if cfg["device"] == "cpu" else "cuda:0"
    index = min(1, spec.shard_count - 1)
    resolve = spec_module._resolve
    unchecked = {"check": False} if "check" in inspect.signature(resolve).parameters else {}  # a task's resolve

    def prepare() -> list:
        s = resolve(copy.deepcopy(spec.doc), spec.base_dir, **unchecked)
        a, b = s.shard_range(index)
        return s.scenes(s.shard_pads(index)) if hasattr(s, "shard_pads") else s.scenes(a, b)

    least: dict[str, list[float]] = {}

    def build(scenes: list) -> tuple:
        model = build_model(scenes, device=device, precision=spec.precision)
        return model, initial_state(model)

    def uploaded(batch: Any) -> tuple:
        from aca_warp.hf.model import upload
        from aca_warp.hf.state import state_from_host

        model = upload(batch.model, device)
        return model, state_from_host(model, batch.u, batch.v)

    def clock(phase: str, fn: Any) -> Any:
        w, c = time.perf_counter(), time.process_time()
        out = fn()
        wp.synchronize_device(device)
        w, c = time.perf_counter() - w, time.process_time() - c
        got = least.setdefault(phase, [w, c])
        got[:] = [min(got[0], w), min(got[1], c)]
        return out

    pool = importlib.import_module("aca_warp.sweep.prepare")
    options = pool.run_options(spec)  # the sweep's own run options
    record, tuning = spec.base.record, EngineTuning()
    for _ in range(cfg["repeat"]):
        scenes = clock("prepare", prepare)
        model, state = clock("build", functools.partial(build, scenes))
        run = clock("setup", functools.partial(_Run, model, state, options, record, tuning, None))
        engine = type(run.engine).__name__
        del run, model, state
        if hasattr(pool, "prepare_batch"):  # models made on the host by the pool: its work, and the turn's
            made = clock("pool", lambda: pool.prepare_shard(spec.doc, str(spec.base_dir), index, device=device))
            batch = made.batches[0]
            model, state = clock("upload", functools.partial(uploaded, batch))
            run = clock("setup_checked", lambda: _Run(model, state, options, record, tuning, None, batch.checked))  # noqa: B023
            del run, model, state, made, batch
    return {
        "code": cfg["code"],
        "mode": "host",
        "package": str(Path(aca_warp.__file__).parent),
        "pads": len(scenes),
        "engine": engine,
        "repeats": cfg["repeat"],
        "wall_s": {p: v[0] for p, v in least.items()},
        "cpu_s": {p: v[1] for p, v in least.items()},
    }


def child(cfg: dict) -> dict:
    """One configuration, in a process whose ``aca_warp`` is the code under test: cluster, warm-up, timed sweep (or,
    for mode ``host``, :func:`host_phases`)."""
    if cfg["mode"] == "host":
        return host_phases(cfg)
    if cfg.get("command"):
        return command_sweep(cfg)
    import warp as wp

    import aca_warp

    wp.config.log_level = wp.LOG_WARNING
    from distributed import Client

    from aca_warp.sweep import hf1_product_doc, load_spec, local_cluster, run_sweep

    spec = load_spec(sweep_doc(hf1_product_doc, cfg, cfg["duration"]))
    warm = load_spec(sweep_doc(hf1_product_doc, cfg, WARM_UP_S, warm_up_pads(cfg)))
    units, cpu = cfg["units"], cfg["device"] == "cpu"
    device = "cpu" if cpu else ",".join(f"cuda:{i}" for i in range(units))
    overlap = cfg["mode"] in ("overlapped", "kept")
    t0 = time.perf_counter()
    workers = units if cpu else None
    if "threads" in inspect.signature(local_cluster).parameters:  # one worker per GPU, shard tasks in its threads
        from aca_warp.sweep import PIPELINE_DEPTH

        cluster, worker_device = local_cluster(device, workers, threads=PIPELINE_DEPTH if overlap else 1)
    else:  # a code from before: two single-threaded workers per GPU overlapped
        cluster, worker_device = local_cluster(device, workers, per_gpu=2 if overlap else 1)
    client = Client(cluster)
    client.wait_for_workers(len(cluster.worker_spec))
    start_s = time.perf_counter() - t0
    kwargs: dict[str, Any] = {"device": worker_device, "client": client, "overlap": overlap}
    prepare = None
    if "prepare" in inspect.signature(run_sweep).parameters:  # a code with a preparation pool
        from aca_warp.sweep.run import prepare_processes

        by_spec = "spec" in inspect.signature(prepare_processes).parameters  # a code whose default reads the sweep
        default = prepare_processes(device, None, True, *([spec] if by_spec else []))
        prepare = cfg["prepare"] if cfg["prepare"] is not None else default
        kwargs["prepare"] = prepare
    scratch = Path(cfg["dir"])
    kept = contextlib.nullcontext()
    if cfg["mode"] == "kept":  # the warm-up's preparation pool kept for the timed sweep
        from aca_warp.sweep import keep_preparation_pool

        kept = keep_preparation_pool()
    try:
        with kept:
            t0 = time.perf_counter()
            run_sweep(warm, scratch / "warm", **kwargs)
            warm_s = time.perf_counter() - t0
            called = time.time()
            res = run_sweep(spec, scratch / "timed", **kwargs)
    finally:
        client.close()
        cluster.close()
    if res.failed or res.faults:
        raise SystemExit(f"{cfg['code']}: failed shards {res.failed}, faults {res.faults}")
    timings = [s["timings"] for s in sorted(res.summaries, key=lambda s: s["index"])]
    kernel = sum(t["kernel"] for t in timings)
    in_shard = res.patch_steps / kernel
    return {
        **{k: cfg[k] for k in ("code", "units", "mode")},
        "package": str(Path(aca_warp.__file__).parent),
        "workers": res.workers,
        "prepare": prepare,
        "device_names": sorted({s["device_name"] for s in res.summaries}),
        "cluster_start_s": start_s,
        "warm_up_s": warm_s,
        "wall_s": res.wall_time,
        "patch_steps": res.patch_steps,
        "kernel_s": kernel,
        "wall_rate": res.patch_steps / res.wall_time,
        "in_shard_rate": in_shard,
        "wall_over_in_shard": res.patch_steps / res.wall_time / (units * in_shard),
        "phase_median_s": {p: statistics.median(t.get(p, 0.0) for t in timings) for p in PHASES},
        "phase_total_s": {p: sum(t.get(p, 0.0) for t in timings) for p in PHASES},
        "shards": [{"index": s["index"], **s["timings"]} for s in sorted(res.summaries, key=lambda s: s["index"])],
        "timeline": timeline(res.summaries, called, res.wall_time),
    }


def command_sweep(cfg: dict) -> dict:
    """The sweep as ``aca-warp sweep`` runs it: one ``run_sweep`` call that starts its own local cluster (its default
    workers) and its preparation pool, then hands out the shards; timed from the call's start (both starts, side by
    side in this code, one after the other in older ones, are inside it). Run in a process of its own after the
    configuration's warm-up (the kernels are in the disk cache then: loaded, not compiled; the pool's fork server
    starts in the call)."""
    import inspect

    import aca_warp
    from aca_warp.sweep import hf1_product_doc, load_spec, run_sweep

    spec = load_spec(sweep_doc(hf1_product_doc, cfg, cfg["duration"]))
    units, cpu = cfg["units"], cfg["device"] == "cpu"
    device = "cpu" if cpu else ",".join(f"cuda:{i}" for i in range(units))
    kwargs: dict[str, Any] = {"device": device, "workers": units if cpu else None, "overlap": True}
    if "prepare" in inspect.signature(run_sweep).parameters:
        kwargs["prepare"] = cfg["prepare"]
    called = time.time()
    res = run_sweep(spec, Path(cfg["dir"]) / "command", **kwargs)
    if res.failed or res.faults:
        raise SystemExit(f"{cfg['code']} command: failed shards {res.failed}, faults {res.faults}")
    line = timeline(res.summaries, called, res.wall_time)
    first: dict[str, dict] = {}
    for s in sorted(res.summaries, key=lambda s: s["timings"]["run_start"]):
        first.setdefault(str(s.get("process", "?")), s["timings"])
    return {
        "package": str(Path(aca_warp.__file__).parent),
        "command_wall_s": res.wall_time,
        "command_called": called,  # when the call began (time.time()): run_child adds command_exit_s from it
        "command_shards_s": res.wall_time - min(d["start"] for d in line["devices"].values()),
        "command_rate": res.patch_steps / res.wall_time,
        "command_first_prepared": sum("upload" in t for t in first.values()),
        "command_timeline": line,
    }


def timeline(summaries: list[dict], called: float, wall: float) -> dict:
    """Every shard's phases on the sweep call's clock ([start, end] in seconds from ``called``, the wall-clock time
    the call began) and per worker process its device's time: start, busy, idle, tail [s] (module docstring)."""
    shards, turns = [], {}
    for s in sorted(summaries, key=lambda s: s["index"]):
        t = s["timings"]
        spans = t.get("spans") or {"kernel": [t["run_start"], t["run_end"]]}  # a code without spans: its runs
        phases = {k: [a - called, b - called] for k, (a, b) in spans.items()}
        turn = [min(phases[k][0] for k in TURN if k in phases), phases["kernel"][1]]
        where = str(s.get("process", "?"))
        shards.append({"index": s["index"], "process": where, "turn": turn, "phases": phases})
        turns.setdefault(where, []).append(turn)
    devices = {}
    for where, spans in turns.items():
        spans.sort()
        idle = sum(max(0.0, b[0] - a[1]) for a, b in zip(spans, spans[1:], strict=False))
        devices[where] = {
            "shards": len(spans),
            "start": spans[0][0],
            "busy": sum(b - a for a, b in spans),
            "idle": idle,
            "tail": wall - max(b for _, b in spans),
        }
    return {"shards": shards, "devices": devices, "preparations": preparations(shards)}


def preparations(shards: list[dict]) -> dict:
    """Who made the shards of one call, and in what time [s] (lists in shard order; empty where none):
    ``first``, the pool's preparations begun before its first one had finished (``prepare_ahead``), and ``later``,
    the rest; ``handover_first`` and ``handover_later``, what each of those cost its task before the kernel (reading
    it, ``prepare``; ``upload``; ``setup``); ``own``, a shard its task made itself (``prepare``, ``build``,
    ``setup``); ``pool_begun`` and ``pool_ready``, when each pool process whose first shard the call used started
    and was ready (its kernels loaded) on the call's clock, ``pool_warp`` its start's time to Warp started (the
    phases ``pool_start`` and ``pool_warp`` of that shard; a process whose first shard went unused, its task having
    made the shard, and a pool kept from an earlier call have none)."""

    def took(ph: dict, *names: str) -> float:
        return sum(ph[k][1] - ph[k][0] for k in names if k in ph)

    pooled = [s["phases"] for s in shards if "prepare_ahead" in s["phases"]]
    done = min((ph["prepare_ahead"][1] for ph in pooled), default=0.0)
    out: dict[str, list[float]] = {k: [] for k in ("first", "later", "handover_first", "handover_later", "own")}
    for ph in pooled:
        wave = "first" if ph["prepare_ahead"][0] < done else "later"
        out[wave].append(took(ph, "prepare_ahead"))
        out[f"handover_{wave}"].append(took(ph, "prepare", "upload", "setup"))
    out["own"] = [took(s["phases"], "prepare", "build", "setup") for s in shards if "build" in s["phases"]]
    started = [s["phases"] for s in shards if "pool_start" in s["phases"]]
    out["pool_begun"] = [ph["pool_start"][0] for ph in started]
    out["pool_ready"] = [ph["pool_start"][1] for ph in started]
    out["pool_warp"] = [took(ph, "pool_warp") for ph in started]
    return out


# ---------------------------------------------------------------------------------------------------- parent


def run_child(code_dir: Path, cfg: dict, scratch: Path) -> dict:
    """Run :func:`child` for ``cfg`` in a fresh process that imports the ``aca_warp`` of ``code_dir`` (its Dask
    workers and preparation processes inherit that path); returns its row."""
    sys.path.insert(0, str(HERE))
    from compare_checkouts import package_view

    view = scratch / f"view-{cfg['code']}"
    if not view.exists():
        package_view(code_dir, view)
    out = scratch / f"sweep-{cfg['code']}-{cfg['mode']}-{cfg['units']}"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(view), os.environ.get("PYTHONPATH", "")]).rstrip(":")}
    if "WARP_CACHE_PATH" not in env:
        env["WARP_CACHE_PATH"] = str(scratch / f"warp-cache-{cfg['code']}")
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", json.dumps({**cfg, "dir": str(out)})]
    # the output to files, not pipes: the processes the child leaves (a pool's fork server) would hold pipes open
    # past the child's end, and its end is what command_exit_s times
    with tempfile.TemporaryFile("w+") as stdout, tempfile.TemporaryFile("w+") as stderr:
        code = subprocess.Popen(cmd, env=env, stdout=stdout, stderr=stderr, text=True, cwd=scratch).wait()
        exited = time.time()
        stdout.seek(0)
        stderr.seek(0)
        text, errors = stdout.read(), stderr.read()
    shutil.rmtree(out, ignore_errors=True)
    if code != 0:
        raise SystemExit(f"{cfg['code']} {cfg['mode']} x{cfg['units']} failed:\n{errors[-3000:]}")
    row = json.loads(text.strip().splitlines()[-1])
    if "command_called" in row:
        row["command_exit_s"] = exited - row["command_called"]
    if not row["package"].startswith(str(view)):
        raise SystemExit(f"the child imported {row['package']}, not the code under test at {code_dir}")
    return row


def configurations(args: argparse.Namespace) -> list[dict]:
    """The runs: new overlapped on every unit count, new sequential on the first, with ``--kept-pool`` new kept on every
    unit count, the baseline overlapped on every."""
    keys = ("device", "pads", "patches", "shard_size", "duration", "precision", "sweep", "dt")
    base = {k: getattr(args, k) for k in keys}
    runs = [{**base, "code": "new", "mode": "overlapped", "units": u, "prepare": args.prepare} for u in args.units]
    runs.append({**base, "code": "new", "mode": "sequential", "units": args.units[0], "prepare": args.prepare})
    if args.kept_pool:
        runs += [{**base, "code": "new", "mode": "kept", "units": u, "prepare": args.prepare} for u in args.units]
    if args.baseline:
        runs += [{**base, "code": "baseline", "mode": "overlapped", "units": u, "prepare": None} for u in args.units]
    return runs


def best_runs(runs: list[dict]) -> list[dict]:
    """Per configuration (code, mode, units) its run of the shortest wall time, in the order of the first runs, with
    ``runs`` (how many) and ``phase_least_s``: per phase the least of the runs' medians (on a shared machine, the host
    time per shard least disturbed by other work)."""
    best: dict[tuple, dict] = {}
    least: dict[tuple, dict[str, float]] = {}
    count: dict[tuple, int] = {}
    for r in runs:
        key = (r["code"], r["mode"], r["units"])
        if key not in best or r["wall_s"] < best[key]["wall_s"]:
            best[key] = r
        seen = least.setdefault(key, dict(r["phase_median_s"]))
        for p, v in r["phase_median_s"].items():
            seen[p] = min(seen[p], v)
        count[key] = count.get(key, 0) + 1
    return [{**r, "phase_least_s": least[k], "runs": count[k]} for k, r in best.items()]


def summarise(rows: list[dict]) -> None:
    """Add to each row its speedup over the same code and mode on the fewest units, and its wall rate against the
    sequential reference's in-shard rate (kernels alone on their GPU)."""
    ref = next((r for r in rows if r["code"] == "new" and r["mode"] == "sequential"), None)
    for r in rows:
        same = [q for q in rows if q["code"] == r["code"] and q["mode"] == r["mode"]]
        first = min(same, key=lambda q: q["units"])
        r["speedup_vs_fewest_units"] = r["wall_rate"] / first["wall_rate"]
        if "command_rate" in r and "command_rate" in first:
            r["command_speedup_vs_fewest_units"] = r["command_rate"] / first["command_rate"]
            if "command_shards_s" in r and "command_shards_s" in first:
                r["command_shards_speedup_vs_fewest_units"] = first["command_shards_s"] / r["command_shards_s"]
        if ref is not None:
            r["wall_over_reference_in_shard"] = r["wall_rate"] / (r["units"] * ref["in_shard_rate"])


def markdown_line(doc: dict) -> str:
    """One line: machine, sweep, and per configuration wall time, rates, ratios and median host phases."""
    unit = "CPU worker" if doc["device"] == "cpu" else "GPU"
    parts = []
    for r in doc["results"]:
        ph = r["phase_least_s"]
        ahead = f" (+{ph['prepare_ahead']:.2f} ahead)" if ph.get("prepare_ahead") else ""
        parts.append(
            f"{r['code']} {r['mode']} on {r['units']} {unit}(s): {r['wall_s']:.1f} s wall, {r['wall_rate']:.3g} "
            f"patch-steps/s against {r['in_shard_rate']:.3g} in-shard per {unit} "
            f"({100 * r['wall_over_in_shard']:.0f} %"
            + (
                f"; {100 * r['wall_over_reference_in_shard']:.0f} % of the reference"
                if "wall_over_reference_in_shard" in r
                else ""
            )
            + f"), {r['speedup_vs_fewest_units']:.2f}× its {min(q['units'] for q in doc['results'])}-{unit} rate; "
            f"per shard (median; least of {r['runs']} run(s)) prepare {ph['prepare']:.2f}{ahead}, "
            + (f"upload {ph['upload']:.2f}, " if ph.get("upload") else "")
            + f"build {ph['build']:.2f}, setup {ph['setup']:.2f}, kernel {ph['kernel']:.2f} s"
            + device_time(r["timeline"]["devices"])
            + made_by(r["timeline"].get("preparations", {}))
            + (
                f"; the whole call as the command runs it (pool, cluster start, shards): {r['command_wall_s']:.1f} s "
                f"({r['command_exit_s']:.1f} s to its process's end), "
                f"{r['command_speedup_vs_fewest_units']:.2f}× its fewest-{unit} rate, first shard prepared ahead "
                f"on {r['command_first_prepared']} of {len(r['command_timeline']['devices'])} worker(s)"
                if "command_speedup_vs_fewest_units" in r
                else ""
            )
            + (
                f"; its shards, from the first device turn to the end: {r['command_shards_s']:.1f} s, "
                f"{r['command_shards_speedup_vs_fewest_units']:.2f}× its fewest-{unit} time"
                if "command_shards_speedup_vs_fewest_units" in r
                else ""
            )
        )
    for h in doc.get("host", []):
        w, c = h["wall_s"], h["cpu_s"]
        phases = [p for p in ("prepare", "build", "setup", "pool", "upload", "setup_checked") if p in w]
        parts.append(
            f"{h['code']}: host time per shard (least of {h['repeats']}, wall / CPU) "
            + ", ".join(f"{p} {w[p]:.2f} / {c[p]:.2f}" for p in phases)
            + " s"
        )
    s = doc["sweep"]
    m = doc["machine"]
    where = m["device_name"] if doc["device"] == "cpu" else f"{m['device_name']} ({m['host']})"
    return (
        f"{doc['date']}, {where}, Warp {doc['warp_version']}: {s['pads']} hf1 pads × {s['patches_per_pad']} "
        f"patches, shards of {s['shard_size']}, {s['duration_s']:g} s, strang {s['precision']}; "
        + "; ".join(parts)
        + "."
    )


def write_outputs(doc: dict, args: argparse.Namespace) -> None:
    """``doc`` into ``--json``, its Markdown line into ``--md``; the line and the two names printed, unless ``doc``
    is ``partial`` (written after every run, so that a run stopped by a time limit leaves what it measured)."""
    line = markdown_line(doc)
    Path(args.json).write_text(json.dumps(doc, indent=1))
    Path(args.md).write_text(line + "\n")
    if not doc.get("partial"):
        print(line)
        print(f"wrote {args.json} and {args.md}")


def made_by(prep: dict) -> str:
    """Who made the shards (:func:`preparations`) in words: per kind, how many and their range of times."""

    def span(xs: list[float]) -> str:
        return f"{len(xs)}, {min(xs):.2f}–{max(xs):.2f} s" if xs else "none"

    if not prep:
        return ""
    starts = ""
    if prep.get("pool_ready"):
        starts = (
            f"; pool processes begun {span(prep['pool_begun'])} into the call, ready {span(prep['pool_ready'])} "
            f"(Warp started after {span(prep['pool_warp'])})"
        )
    return (
        f"; shards made by the pool before its first was done {span(prep['first'])} (their hand-over "
        f"{span(prep['handover_first'])}), later {span(prep['later'])} (hand-over {span(prep['handover_later'])}), "
        f"by their tasks {span(prep['own'])}{starts}"
    )


def device_time(devices: dict) -> str:
    """The devices' time of a configuration in words: per worker process (one per GPU), summed over them."""
    n = len(devices)
    total = {k: sum(d[k] for d in devices.values()) for k in ("start", "idle", "tail")}
    return (
        f"; {n} worker process(es): before the first turn {total['start'] / n:.2f} s, idle between turns "
        f"{total['idle'] / n:.2f} s, after the last run {total['tail'] / n:.2f} s (mean per process)"
    )


def power_of_two(text: str) -> int:
    """A pad count of the bench's sweeps (argparse type): a power of two (the product's M x F_N x seed; the seeds
    sweep's warm-up of two shards per unit)."""
    from aca_warp.common.argtypes import int_at_least

    v = int_at_least(1)(text)
    if v & (v - 1):
        raise argparse.ArgumentTypeError(f"choose a power of two (the bench's sweeps have 2^k pads), got {text!r}")
    return v


def step_or_default(text: str) -> float | None:
    """A step [s] (argparse type): a positive number, or ``default`` (None: the sweep's own default step)."""
    from aca_warp.common.argtypes import positive

    return None if text == "default" else positive(text)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The options, checked: a bad number, --pads not a power of two, --baseline not a checkout, an output in a missing
    folder are refused here (exit 2), before the first run. (Imports the package's checks; a child, which may run an
    older package, never parses.)"""
    from aca_warp.common.argtypes import int_at_least, positive
    from aca_warp.common.errors import AcaError
    from aca_warp.common.files import check_output_folder, check_output_path

    sys.path.insert(0, str(HERE))
    from compare_checkouts import checkout_problem

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cuda", choices=("cuda", "cpu"), help="cuda (GPUs 0..N-1) or cpu")
    ap.add_argument(
        "--units", nargs="+", type=int_at_least(1), default=[1, 2], help="GPUs (CPU worker processes) per run"
    )
    ap.add_argument("--pads", type=power_of_two, default=2048, help="pads in the sweep (a power of two; default 2048)")
    ap.add_argument("--patches", type=int_at_least(1), help="patches per pad (default: hf1's 1758)")
    ap.add_argument("--shard-size", type=int_at_least(1), default=256, help="pads per shard (default 256)")
    ap.add_argument("--duration", type=positive, default=1e-3, help="simulated time per pad [s] (default 1e-3)")
    ap.add_argument("--precision", default="fp32", choices=("fp32", "fp64"))
    ap.add_argument(
        "--sweep",
        default="product",
        choices=("product", "seeds"),
        help="product: M x F_N x 8 patch seeds (8 layouts); seeds: patch seeds 1..pads, a layout per pad "
        "(default product)",
    )
    ap.add_argument(
        "--dt",
        type=step_or_default,
        default=1e-8,
        help="strang's step [s], or 'default': the sweep's default step (5e-8 s for the product sweep, whose M and "
        "load vary; 1e-6/3 s for the seeds sweep, hf1's physics) (default 1e-8, the step of the earlier runs)",
    )
    ap.add_argument(
        "--prepare", type=int_at_least(0), help="preparation processes of the new code (default: as aca-warp sweep)"
    )
    ap.add_argument(
        "--kept-pool",
        action="store_true",
        help="also run the new code's overlapped sweeps with the warm-up's preparation pool kept for the timed sweep "
        "(keep_preparation_pool: sweeps one after another in one script)",
    )
    ap.add_argument("--baseline", type=Path, help="a checkout of the code to compare against (e.g. the previous main)")
    ap.add_argument(
        "--repeat", type=int_at_least(1), default=1, help="runs of every configuration, in turn (default 1)"
    )
    ap.add_argument(
        "--host-repeat",
        type=int_at_least(0),
        default=3,
        help="repeats of the host phases of one shard per code, in one process (default 3; 0: none)",
    )
    ap.add_argument(
        "--host-only",
        action="store_true",
        help="only the host phases of one shard per code (--host-repeat times): no sweep, no Dask needed",
    )
    ap.add_argument("--dir", type=Path, help="scratch folder (default: a temporary one, removed)")
    ap.add_argument("--json", default="bench_sweep.json", help="output JSON file")
    ap.add_argument("--md", default="bench_sweep.md", help="output Markdown file (one line)")
    args = ap.parse_args(argv)
    if args.baseline is not None and (problem := checkout_problem(args.baseline)):
        ap.error(f"--baseline {problem}")
    if args.host_only and not args.host_repeat:
        ap.error("--host-only measures the host phases: give --host-repeat 1 or more")
    try:  # every refusal before the first run: nothing run, nothing written
        for out in (args.json, args.md):
            check_output_path(out, overwrite=True)
        if args.dir is not None:
            check_output_folder(args.dir)
    except AcaError as e:
        ap.error(str(e))
    return args


def main(argv: list[str] | None = None) -> int:
    given = sys.argv[1:] if argv is None else argv
    if given[:1] == ["--child"]:  # one run, started by run_child with the code under test
        print(json.dumps(child(json.loads(given[1]))), flush=True)
        return 0
    args = parse_args(argv)
    if not args.host_only:
        from distributed import Client  # noqa: F401  (fails here, before any work, where Dask is missing)

    from aca_warp.common.devices import init_warp

    init_warp()
    scratch = Path(args.dir or tempfile.mkdtemp(prefix="aca_bench_sweep_"))
    scratch.mkdir(parents=True, exist_ok=True)
    codes = {"new": HERE.parent, "baseline": args.baseline}
    runs, hosts = [], []
    try:
        for code in ("new", "baseline") if args.host_repeat else ():  # first: on an idle device
            if codes[code] is not None:
                cfg = {**configurations(args)[0], "code": code, "mode": "host", "repeat": args.host_repeat}
                h = run_child(codes[code].resolve(), cfg, scratch)
                hosts.append(h)
                print(
                    f"{code} host phases of a shard ({h['engine']}): wall {h['wall_s']}, CPU {h['cpu_s']}", flush=True
                )
        # in turn: a slow spell of a shared machine spreads over every configuration
        for rep in range(0 if args.host_only else args.repeat):
            for cfg in configurations(args):
                r = {**run_child(codes[cfg["code"]].resolve(), cfg, scratch), "run": rep + 1}
                if cfg["mode"] == "overlapped":  # the whole call, as the command runs it (its own cluster and pool)
                    r.update(run_child(codes[cfg["code"]].resolve(), {**cfg, "command": True}, scratch))
                runs.append(r)
                ph = r["phase_median_s"]
                print(
                    f"{r['code']} {r['mode']} x{r['units']} (run {rep + 1}): {r['wall_s']:.2f} s wall, wall rate "
                    f"{r['wall_rate']:.3g}, in-shard {r['in_shard_rate']:.3g} per unit "
                    f"({100 * r['wall_over_in_shard']:.0f} %); median per shard: "
                    + ", ".join(f"{p} {ph[p]:.3f}" for p in PHASES)
                    + " s"
                    + device_time(r["timeline"]["devices"]),
                    flush=True,
                )
                write_outputs(document(args, runs, hosts, argv, done=False), args)
    finally:
        if not args.dir:
            shutil.rmtree(scratch, ignore_errors=True)
    write_outputs(document(args, runs, hosts, argv, done=True), args)
    return 0


def document(args: argparse.Namespace, runs: list[dict], hosts: list[dict], argv: list[str] | None, done: bool) -> dict:
    """The JSON document of the runs so far (``done``: all of them; else ``partial`` is true)."""
    import warp as wp

    from aca_warp.common.files import machine

    rows = best_runs(runs)
    summarise(rows)
    dev = wp.get_device("cpu" if args.device == "cpu" else "cuda:0")
    return {
        "date": datetime.date.today().isoformat(),
        "machine": machine(dev),
        "warp_version": wp.__version__,
        "device": args.device,
        "command": " ".join(["scripts/bench_sweep.py", *(sys.argv[1:] if argv is None else argv)]),
        **({} if done else {"partial": True}),
        "sweep": {
            "pads": args.pads,
            "patches_per_pad": args.patches or 1758,
            "shard_size": args.shard_size,
            "duration_s": args.duration,
            "precision": args.precision,
            "kind": args.sweep,
            "dt_s": args.dt,
            "step": "named" if args.dt is not None else "the sweep's default",
        },
        "results": rows,
        "runs": runs,
        "host": hosts,
    }


if __name__ == "__main__":
    sys.exit(main())
