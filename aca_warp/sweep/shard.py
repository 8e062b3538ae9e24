"""One shard task: its batched HF run(s) and HDF5 file (the function a Dask worker runs).

:func:`run_shard` takes the shard's batches prepared on the host (:mod:`aca_warp.sweep.prepare`) and puts them on the
device, or builds them itself (the shard's pads as one batch, several when the memory estimate,
:func:`~aca_warp.sweep.prepare.batch_capacity`, says they do not fit), runs them, streams the samples into
``shard-NNNNN.h5.partial`` (inline, or behind the run through a :class:`~aca_warp.sweep.overlap.ChunkWriter`) and
renames the file when done. :func:`shard_finished` tells a finished shard file from one to run again.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import time
import traceback
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.common.errors import sweep_spec
from aca_warp.scene import Scene
from aca_warp.sweep.overlap import ChunkWriter, KernelTurn, ShardCancelled, ShardContext
from aca_warp.sweep.prepare import (
    PreparedBatch,
    PreparedShard,
    SpooledShard,
    prepare_shard,
    run_options,
    shard_capacity,
)
from aca_warp.sweep.spec import FORMAT, PARAMETERS, SweepSpec, pad_list

# ---------------------------------------------------------------------------------------------- shard


def shard_name(index: int) -> str:
    """File name of shard ``index``."""
    return f"shard-{index:05d}.h5"


class _Clock:
    """Seconds per phase of a shard task, summed, and the wall-clock time (``time.time()``) each phase first began
    and last ended (:attr:`spans`); ``with clock("build"): ...``."""

    def __init__(self) -> None:
        self.s: dict[str, float] = {}
        self.spans: dict[str, list[float]] = {}

    def add(self, phase: str, seconds: float) -> None:
        self.s[phase] = self.s.get(phase, 0.0) + seconds

    def span(self, phase: str, began: float, ended: float) -> None:
        got = self.spans.get(phase)
        self.spans[phase] = [began, ended] if got is None else [min(got[0], began), max(got[1], ended)]

    @contextlib.contextmanager
    def __call__(self, phase: str) -> Iterator[None]:
        t, began = time.perf_counter(), time.time()
        try:
            yield
        finally:
            self.add(phase, time.perf_counter() - t)
            self.span(phase, began, time.time())

    def timings(self, **extra: float) -> dict:
        """The seconds per phase, ``extra`` and the spans (:data:`TIMING_DOC`)."""
        return {**self.s, **extra, "spans": {k: list(v) for k, v in self.spans.items()}}


TIMING_PHASES = (
    "prepare",
    "prepare_ahead",
    "upload",
    "build",
    "setup",
    "kernel",
    "sink",
    "write",
    "turn_wait",
    "write_wait",
    "close",
    "task",
)
TIMING_DOC = """Seconds per phase of a shard task:
prepare: the spec and the shard's scenes (taken as prepared ahead: almost nothing) and the memory estimate;
prepare_ahead: present when a preparation pool made the shard before the task began, the time it took there (not
part of the task); upload: putting prepared batches (models and initial states) on the device; build: build_model
and initial_state in the task (contact solve, neighbour lists, device arrays), when the shard was not prepared;
setup: run_hf before its first step (checks unless prepared, engine, launch layout; RunResult.compile_time);
kernel: the run loop less the time in the sink (steps, recording, flushing to the host); sink: time inside the sink
(serial: the HDF5 writes; overlapped: handing chunks to the writer); write: header and chunk writes (overlapped: in
the writer thread, beside the run); turn_wait: waiting for the device's turn; write_wait: waiting after the run for
the writer to finish; close: final attributes, close and rename (not in the file's own copy); task: the whole task.
run_start, run_end: wall-clock time (time.time()) when the run began and ended [s]. spans: per phase the wall-clock
times it first began and last ended, [start, end] [s] (prepare_ahead: in the pool; write: the first and last write;
setup and kernel: of the run calls), so that shards' phases on one device can be laid on one time line; with the
first shard a pool process prepared, also that process's start: pool_warp, from its start to Warp started, and
pool_start, to its kernels loaded."""


def _create_shard_file(
    tmp: Path, partial: Path, lock: Any, spec: SweepSpec, index: int, scenes: list[Scene], dev: Any, n_samples: int
) -> tuple[Any, Any]:
    """Create the shard file at ``tmp`` (for the holder of ``lock``, :func:`~aca_warp.common.files.create_h5`) with
    its header, datasets and parameters, flush it and rename it to ``partial``; returns (h5py file,
    :class:`~aca_warp.common.storage.GuardedFile`)."""
    import h5py

    from aca_warp.common.files import create_h5, versions
    from aca_warp.common.storage import GuardedFile
    from aca_warp.hf.recorder import GLOBAL_NAMES, GLOBAL_UNITS

    start, stop = spec.shard_range(index)
    pads = spec.shard_pads(index)
    n = stop - start
    f = create_h5(tmp, lock)
    out = GuardedFile(f, partial)
    try:
        attrs = {
            "format": FORMAT,
            "spec": json.dumps(spec.doc, default=str),
            "spec_hash": spec.hash,
            "shard": index,
            "pad_start": start,
            "pad_stop": stop,
            "complete": False,
            "finished": False,
            "status": "running",
            "device": str(dev),
            "device_name": dev.name,
            "integrator": spec.integrator,
            "precision": spec.precision,
            "run": json.dumps(spec.run_settings()),
            "versions": json.dumps(versions()),
            **({"patch_data": spec.patch_data} if spec.patch_data is not None else {}),
        }
        for k, v in attrs.items():
            f.attrs[k] = v
        g = f.create_group("global")
        g.create_dataset("time", shape=(0,), maxshape=(None,), dtype="f8", chunks=(4096,)).attrs["unit"] = "s"
        for nm, unit in zip(GLOBAL_NAMES, GLOBAL_UNITS, strict=True):
            d = g.create_dataset(
                nm, shape=(n, 0), maxshape=(n, None), dtype="f8", chunks=(1, min(n_samples, 4096)), fillvalue=np.nan
            )
            d.attrs["unit"] = unit
        pg = f.create_group("parameters")
        for key, vals in spec.parameters.items():
            v = [vals[p] for p in pads]
            data = np.array(v, dtype=h5py.string_dtype()) if key == "initial.state" else np.asarray(v)
            out.reserve(data.nbytes)
            pg.create_dataset(key, data=data).attrs["unit"] = PARAMETERS[key][0]
        group = f.create_group("pads")
        group.create_dataset("index", data=pads).attrs["unit"] = "1"
        counts = np.array([s.patches.count for s in scenes], dtype=np.int64)
        group.create_dataset("patch_count", data=counts).attrs["unit"] = "1"
        out.flush()
        os.replace(tmp, partial)  # readable from the moment it has this name
    except BaseException:
        out.abandon()
        raise
    return f, out


def _chunk_writer(f: Any, out: Any, n: int) -> Callable[[tuple[int, int, Any]], None]:
    """The function that appends one recorded chunk ``(b0, b1, chunk)`` of the batch of pads [b0, b1) of the shard
    to its file (rows counted per batch; the time axis written by the first batch)."""
    from aca_warp.hf.recorder import GLOBAL_NAMES

    g = f["global"]
    rows: dict[int, int] = {}

    def write(item: tuple[int, int, Any]) -> None:
        b0, b1, chunk = item
        k = len(chunk.time)
        if k == 0:
            return
        r0 = rows.get(b0, 0)
        out.touch(g["time"], r0, r0 + k)
        for nm in GLOBAL_NAMES:
            out.touch(g[nm], r0, r0 + k, axis=1)
        out.reserve()
        if b0 == 0:
            t = g["time"]
            t.resize((r0 + k,))
            t[r0:] = chunk.time
        for j, nm in enumerate(GLOBAL_NAMES):
            d = g[nm]
            if d.shape[1] < r0 + k:
                d.resize((n, r0 + k))
            d[b0:b1, r0 : r0 + k] = chunk.globals[:, :, j].T
        rows[b0] = r0 + k

    return write


@sweep_spec()  # its refusals name the spec's keys (run.dt), not options a sweep does not have
def run_shard(
    doc: dict,
    base_dir: str,
    out_dir: str,
    index: int,
    device: str = "cpu",
    *,
    memory_fraction: float = 0.5,
    sharing: int = 1,
    overlap: bool = False,
    ctx: ShardContext | None = None,
    prepared: PreparedShard | SpooledShard | None = None,
) -> dict:
    """Run shard ``index`` of the spec ``doc`` (already resolved, overrides applied) and write its file.

    This is the task a Dask worker runs. ``prepared`` (by a :class:`~aca_warp.sweep.prepare.Preparer`, or its file:
    a :class:`~aca_warp.sweep.prepare.SpooledShard`): the shard's spec and scenes, and its batches made on the host,
    which the task puts on the device as they are (when they are no larger than the device holds now:
    :func:`~aca_warp.sweep.prepare.shard_capacity`); otherwise the task
    resolves the spec and makes the scenes (:func:`~aca_warp.sweep.prepare.prepare_shard`; cheap, deterministic)
    and builds its batches itself. The shard's pads run as one batch (several when the memory estimate says they
    do not fit); the samples stream into ``shard-NNNNN.h5.partial``, renamed when done. ``overlap``: write the
    samples behind the run (a :class:`ChunkWriter` thread) and take the device in turns (:class:`KernelTurn`,
    from the first upload or build to the end of the run), so that the tasks of a process overlap their waiting and
    writing with each other's runs (``ctx`` overrides it, with a cancel event). Same results either way. Returns a
    summary for the manifest, with the time per phase (``timings``, :data:`TIMING_DOC`). Its refusals name the spec's
    keys (``run.dt``), not options a sweep does not have (:func:`~aca_warp.common.errors.sweep_spec`).
    """
    import warp as wp

    from aca_warp.common.devices import init_warp
    from aca_warp.common.files import OutputLock, new_path
    from aca_warp.common.storage import storage_errno, storage_error

    ctx = ctx or ShardContext(overlap=overlap)
    init_warp()
    clock = _Clock()
    t_start = time.perf_counter()
    ctx.check()
    with clock("prepare"):
        if isinstance(prepared, SpooledShard):
            prepared = prepared.load()  # left in its file by the pool (a local cluster's worker); None: gone
        if prepared is None:
            prepared = prepare_shard(doc, base_dir, index)
        else:
            clock.add("prepare_ahead", prepared.seconds)
            clock.span("prepare_ahead", *prepared.span)
            if prepared.process_start:  # the first shard its pool process made: that process's start
                begun, warp, ready = prepared.process_start
                clock.span("pool_warp", begun, warp)
                clock.span("pool_start", begun, ready)
        if prepared.index != index:
            raise ValueError(f"shard {index} was handed the scenes of shard {prepared.index}")
        spec, pads, scenes = prepared.spec, prepared.pads, prepared.scenes
        dev = wp.get_device(device)
        cap = shard_capacity(scenes, spec.precision, device, memory_fraction, sharing)
        fits = prepared.batches and max(b.stop - b.start for b in prepared.batches) <= cap
        batches = prepared.batches if fits else []
        cap = prepared.capacity if batches else cap
    final = Path(out_dir) / shard_name(index)
    partial = final.with_name(final.name + ".partial")
    n_samples = shard_samples(spec)
    lock = OutputLock.acquire(final, what="a worker of another sweep still writes this shard")
    tmp = new_path(partial)
    out = writer = None
    turn = KernelTurn(dev, ctx.cancel, processes=ctx.processes) if ctx.overlap else None
    try:
        ctx.check()
        with clock("write"):
            f, out = _create_shard_file(tmp, partial, lock, spec, index, scenes, dev, n_samples)
        write = _chunk_writer(f, out, len(pads))
        writer = ChunkWriter(write) if ctx.overlap else None
        work = _Work(spec, dev, ctx, clock, turn, writer.put if writer else write)
        run = _run_batches(work, scenes, batches, cap, pads)
        _end_run(turn, writer, clock)
        clock.add("task", time.perf_counter() - t_start)
        timings = clock.timings(run_start=run["run_start"], run_end=run["run_end"])
        with clock("close"):
            for k, v in run["attrs"].items():
                f.attrs[k] = v
            f.attrs["batch_capacity"] = cap
            f.attrs["timings"] = json.dumps(timings)
            out.close()
            os.replace(partial, final)
    except BaseException as e:
        traceback.clear_frames(e.__traceback__)  # the failed run's device arrays are freed now, within the turn
        if writer is not None:
            writer.abort()
        if out is not None:
            out.abandon()
        tmp.unlink(missing_ok=True)
        if isinstance(e, (ShardCancelled, KeyboardInterrupt)):
            partial.unlink(missing_ok=True)  # a stopped shard runs again from its start
        code = storage_errno(e)
        if code is not None:
            raise storage_error(code, partial, "the shard runs again when the sweep is rerun") from None
        raise
    finally:
        if turn is not None:
            turn.exit()
        lock.release()
    timings["close"] = clock.s["close"]
    timings["spans"]["close"] = clock.spans["close"]
    timings["task"] = time.perf_counter() - t_start
    return _summary(index, dev, final.name, spec, scenes, run, timings)


def _end_run(turn: KernelTurn | None, writer: ChunkWriter | None, clock: _Clock) -> None:
    """After the shard's last batch: give the device's turn back and wait for the writer (its time is ``write``)."""
    if turn is not None:
        turn.exit()
        clock.add("turn_wait", turn.waited)
    if writer is not None:
        with clock("write_wait"):
            writer.close()
        clock.add("write", writer.seconds)
        if writer.span:
            clock.span("write", *writer.span)
    else:
        clock.add("write", clock.s.get("sink", 0.0))


def _summary(index: int, dev: Any, file: str, spec: SweepSpec, scenes: list[Scene], run: dict, timings: dict) -> dict:
    """The manifest entry of a finished shard (:func:`run_shard`); ``process``: the id of the process that ran it;
    ``patch_data``: the digest of the patch file's patches it ran over (None for generated patches)."""
    return {
        "index": index,
        "device": str(dev),
        "device_name": dev.name,
        "process": os.getpid(),
        "batches": run["batches"],
        "state": "done" if run["fault"] is None else "fault",
        "file": file,
        "pads": len(scenes),
        "steps": run["steps"],
        "wall_time": run["wall"],
        "compile_time": run["compile"],
        "task_time": timings["task"],
        "patch_steps": int(sum(s.patches.count for s in scenes)) * run["steps"],
        "patch_data": spec.patch_data,
        "fault": run["fault"],
        "timings": timings,
    }


@dataclass
class _Work:
    """What every batch of a shard task runs with: the sweep, the device, the task's context, clock and turn, and
    where recorded chunks go (``emit((b0, b1, chunk))``)."""

    spec: SweepSpec
    dev: Any
    ctx: ShardContext
    clock: _Clock
    turn: KernelTurn | None
    emit: Callable[[tuple[int, int, Any]], None]


def _run_batches(work: _Work, scenes: list[Scene], prepared: list[PreparedBatch], cap: int, pads: np.ndarray) -> dict:
    """Run the shard's pads (global indices ``pads``): the ``prepared`` batches, or batches of at most ``cap`` pads
    built here; every recorded chunk goes to ``work.emit`` as ``(b0, b1, chunk)``. Returns the run's attributes for
    the file and its figures for the summary."""
    steps, wall, compile_time, batches = 0, 0.0, 0.0, 0
    engines: set[str] = set()
    fault = None
    dt_used = math.nan
    run_start = run_end = math.nan
    ranges = [(b.start, b.stop) for b in prepared] or [
        (b0, min(b0 + cap, len(scenes))) for b0 in range(0, len(scenes), cap)
    ]
    for k, (b0, b1) in enumerate(ranges):
        res, began = _run_batch(work, scenes[b0:b1], b0, prepared[k] if prepared else None)
        run_start = began if math.isnan(run_start) else run_start
        run_end = time.time()
        batches += 1
        steps = max(steps, res.steps)
        wall += res.wall_time
        engines.add(res.engine)
        compile_time += res.compile_time
        dt_used = res.dt
        if res.fault is not None:
            fault = f"pads {pad_list(pads[b0:b1])}: {res.fault}"
            break
    attrs = {
        "complete": fault is None,
        "finished": True,
        "status": "complete" if fault is None else f"stopped: {fault}",
        "steps": steps,
        "dt": dt_used,
        "wall_time": wall,
        "compile_time": compile_time,
        "engine": ",".join(sorted(engines)),
    }
    return {
        "attrs": attrs,
        "steps": steps,
        "wall": wall,
        "compile": compile_time,
        "batches": batches,
        "fault": fault,
        "run_start": run_start,
        "run_end": run_end,
    }


def _run_batch(work: _Work, scenes: list[Scene], b0: int, prepared: PreparedBatch | None) -> tuple[Any, float]:
    """Put one batch (the shard's pads [b0, b0 + len(scenes))) on the device in its turn, as ``prepared`` or built
    here, and run it; returns the :class:`~aca_warp.hf.loop.RunResult` and the wall-clock time its run began
    (``time.time()``) [s]. Clock: ``turn_wait`` (its span), ``upload`` or ``build``, ``setup``, ``kernel`` (the run
    less its sink), ``sink``."""
    from aca_warp.hf.loop import run_hf
    from aca_warp.hf.model import build_model, upload
    from aca_warp.hf.state import initial_state, state_from_host

    spec, dev, ctx, clock, turn = work.spec, work.dev, work.ctx, work.clock, work.turn
    b1 = b0 + len(scenes)
    ctx.check()
    if turn is not None:
        waiting = time.time()
        turn.enter()
        clock.span("turn_wait", waiting, time.time())
    if prepared is None:
        with clock("build"):
            model = build_model(scenes, device=dev, precision=spec.precision)
            state = initial_state(model)
    else:
        with clock("upload"):
            model = upload(prepared.model, dev)
            state = state_from_host(model, prepared.u, prepared.v)

    def sink(chunk: Any) -> None:
        t = time.perf_counter()
        ctx.check()
        work.emit((b0, b1, chunk))
        clock.add("sink", time.perf_counter() - t)

    sink_before = clock.s.get("sink", 0.0)
    began = time.time()
    checked = None if prepared is None else prepared.checked
    res = run_hf(model, state, run_options(spec), record=spec.base.record, sink=sink, checked=checked)
    ended = time.time()
    del model, state  # freed within the turn
    clock.add("setup", res.compile_time)
    clock.add("kernel", max(0.0, res.wall_time - (clock.s.get("sink", 0.0) - sink_before)))
    clock.span("setup", began, began + res.compile_time)
    clock.span("kernel", began + res.compile_time, ended)
    return res, began


def shard_samples(spec: SweepSpec) -> int:
    """The samples of a shard's run, t = 0 included."""
    return max(1, round(spec.duration / spec.base.record.sample_dt)) + 1


def shard_bytes(spec: SweepSpec, indices: list[int]) -> int:
    """About how many bytes the files of shards ``indices`` take once written [bytes]: every global output of every
    pad in whole HDF5 chunks (float64, a pad's row cut in chunks of up to 4096 samples), the time, the parameters, the
    spec each file stores, and 128 KiB a file for its other attributes and headers (most of a small shard's file)."""
    from aca_warp.hf.recorder import GLOBAL_NAMES

    samples = shard_samples(spec)
    chunk = min(samples, 4096)
    stored = -(-samples // chunk) * chunk
    per_file = 8 * stored + len(json.dumps(spec.doc, default=str)) + 2**17
    pads = sum(b - a for a, b in map(spec.shard_range, indices))
    return 8 * pads * (len(GLOBAL_NAMES) * stored + len(spec.parameters) + 2) + len(indices) * per_file


def shard_finished(path: Path, spec_hash: str, start: int, stop: int, patch_data: str | None = None) -> str | None:
    """``"done"``/``"fault"`` when ``path`` holds a finished, readable shard of this spec and pad range (with
    ``patch_data``, made over the patches of that digest: :attr:`~aca_warp.sweep.spec.SweepSpec.patch_data`), else
    None (then it runs again). Readable: every object opens and the last sample of every output reads (a damaged
    group or chunk index shows up here)."""
    import h5py

    from aca_warp.hf.recorder import GLOBAL_NAMES

    if not path.is_file():
        return None
    try:
        with h5py.File(path, "r") as f:
            a = f.attrs
            if not (
                bool(a.get("finished", False))
                and a.get("spec_hash") == spec_hash
                and int(a.get("pad_start", -1)) == start
                and int(a.get("pad_stop", -1)) == stop
                and (patch_data is None or a.get("patch_data") == patch_data)
            ):
                return None
            f.visititems(lambda name, obj: None)
            f["global/time"][-1:]
            for k in GLOBAL_NAMES:
                f["global"][k][:, -1:]
            return "done" if bool(a.get("complete", False)) else "fault"
    except (OSError, KeyError, ValueError, RuntimeError, TypeError):  # missing, truncated or damaged: run it again
        return None
