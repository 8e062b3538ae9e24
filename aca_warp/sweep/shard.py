"""One shard task: its scenes, batched HF run(s) and HDF5 file (the function a Dask worker runs).

:func:`run_shard` builds the shard's pads as one batch (several when the memory estimate, :func:`batch_capacity`,
says they do not fit), runs them, streams the samples into ``shard-NNNNN.h5.partial`` (inline, or behind the run
through a :class:`~aca_warp.sweep.overlap.ChunkWriter`) and renames the file when done. :func:`shard_finished` tells
a finished shard file from one to run again.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import time
import traceback
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.scene import Scene
from aca_warp.sweep.overlap import ChunkWriter, KernelTurn, ShardCancelled, ShardContext
from aca_warp.sweep.prepare import PreparedShard, prepare_shard
from aca_warp.sweep.spec import FORMAT, PARAMETERS, SweepSpec

# -------------------------------------------------------------------------------------------- memory


def pad_bytes(scene: Scene, precision: str) -> int:
    """Estimated device bytes of one pad in a batch (model, state, solver scratch, CSR, recorder) [B].

    Per patch: 10 model arrays and ``patch_pad`` (10 T + 4), state u, u̇, force and the synchronous velocity
    (4 T), adaptive trial buffers (5 T); per directed link: index, inverse distance, stiffness (4 + 2 T); per
    pad: 257 recorded rows × 5 float64. Doubled for the neighbour build's temporaries and allocator slack.
    """
    from scipy.spatial import cKDTree

    t = 4 if precision == "fp32" else 8
    p = scene.patches
    links = 2 * len(cKDTree(np.column_stack([p.x, p.y])).query_pairs(scene.material.coupling_radius))
    per_patch = 10 * t + 4 + 4 * t + 5 * t + 4
    return int(2 * (p.count * per_patch + links * (4 + 2 * t) + 257 * 5 * 8))


def device_memory(device: str) -> int:
    """Free memory of a Warp device (CUDA: free device memory; CPU: available host memory) [B]."""
    import warp as wp

    dev = wp.get_device(device)
    if dev.is_cuda:
        return int(dev.free_memory)
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover
        return int(dev.total_memory or 8 * 2**30)


def batch_capacity(scene: Scene, precision: str, device: str, *, fraction: float = 0.5, sharing: int = 1) -> int:
    """How many pads like ``scene`` fit in ``fraction`` of the device's free memory, split ``sharing`` ways."""
    return max(1, int(fraction * device_memory(device) / max(1, sharing) / pad_bytes(scene, precision)))


# ---------------------------------------------------------------------------------------------- shard


def shard_name(index: int) -> str:
    """File name of shard ``index``."""
    return f"shard-{index:05d}.h5"


class _Clock:
    """Seconds per phase of a shard task, summed; ``with clock("build"): ...``."""

    def __init__(self) -> None:
        self.s: dict[str, float] = {}

    def add(self, phase: str, seconds: float) -> None:
        self.s[phase] = self.s.get(phase, 0.0) + seconds

    @contextlib.contextmanager
    def __call__(self, phase: str) -> Iterator[None]:
        t = time.perf_counter()
        try:
            yield
        finally:
            self.add(phase, time.perf_counter() - t)


TIMING_PHASES = (
    "prepare",
    "prepare_ahead",
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
prepare_ahead: present when a preparation pool made the spec and scenes before the task began, the time it took
there (not part of the task); build: build_model and initial_state (contact solve, neighbour lists,
device arrays); setup: run_hf before its first step (checks, engine, launch layout; RunResult.compile_time);
kernel: the run loop less the time in the sink (steps, recording, flushing to the host); sink: time inside the
sink (serial: the HDF5 writes; overlapped: handing chunks to the writer, and the wait for the GPU's turn);
write: header and chunk writes (overlapped: in the writer thread, beside the run); turn_wait: waiting for the
device's turn; write_wait: waiting after the run for the writer to finish; close: final attributes, close and
rename (not in the file's own copy); task: the whole task. run_start, run_end: wall-clock time (time.time()) when
the run began and ended [s]."""


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
        group.create_dataset("index", data=pads)
        group.create_dataset("patch_count", data=np.array([s.patches.count for s in scenes], dtype=np.int64))
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
    prepared: PreparedShard | None = None,
) -> dict:
    """Run shard ``index`` of the spec ``doc`` (already resolved, overrides applied) and write its file.

    This is the task a Dask worker runs; it rebuilds the spec from ``doc`` and makes the shard's scenes
    (:func:`~aca_warp.sweep.prepare.prepare_shard`; cheap, deterministic), or takes them ``prepared`` ahead by a
    :class:`~aca_warp.sweep.prepare.Preparer`; runs the shard's pads as one batch (several when the memory estimate
    says they do not fit), streams the samples into ``shard-NNNNN.h5.partial`` and renames it when done.
    ``overlap``: write the samples behind the run (a :class:`ChunkWriter` thread) and take the device in turns
    (:class:`KernelTurn`), so that several tasks of one process overlap their scenes and writes, and several
    processes on one GPU also their model builds, with each other's kernels (``ctx`` overrides it, with a cancel
    event). Same results either way. Returns a summary for the manifest, with the time per phase (``timings``,
    :data:`TIMING_DOC`).
    """
    import warp as wp

    from aca_warp.common.files import OutputLock, new_path
    from aca_warp.common.storage import storage_errno, storage_error

    ctx = ctx or ShardContext(overlap=overlap)
    wp.config.log_level = wp.LOG_WARNING
    clock = _Clock()
    t_start = time.perf_counter()
    ctx.check()
    with clock("prepare"):
        if prepared is None:
            prepared = prepare_shard(doc, base_dir, index)
        else:
            clock.add("prepare_ahead", prepared.seconds)
        if prepared.index != index:
            raise ValueError(f"shard {index} was handed the scenes of shard {prepared.index}")
        spec, pads, scenes = prepared.spec, prepared.pads, prepared.scenes
        dev = wp.get_device(device)
        largest = max(scenes, key=lambda s: s.patches.count)
        cap = batch_capacity(largest, spec.precision, device, fraction=memory_fraction, sharing=sharing)
    final = Path(out_dir) / shard_name(index)
    partial = final.with_name(final.name + ".partial")
    n_samples = max(1, round(spec.duration / spec.base.record.sample_dt)) + 1
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
        run = _run_batches(spec, scenes, dev, cap, ctx, clock, turn, writer.put if writer else write, pads)
        _end_run(turn, writer, clock)
        clock.add("task", time.perf_counter() - t_start)
        timings = {**clock.s, "run_start": run["run_start"], "run_end": run["run_end"]}
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
    timings["task"] = time.perf_counter() - t_start
    return _summary(index, dev, final.name, scenes, run, timings)


def _end_run(turn: KernelTurn | None, writer: ChunkWriter | None, clock: _Clock) -> None:
    """After the shard's last batch: give the device's turn back and wait for the writer (its time is ``write``)."""
    if turn is not None:
        turn.exit()
        clock.add("turn_wait", turn.waited)
    if writer is not None:
        with clock("write_wait"):
            writer.close()
        clock.add("write", writer.seconds)
    else:
        clock.add("write", clock.s.get("sink", 0.0))


def _summary(index: int, dev: Any, file: str, scenes: list[Scene], run: dict, timings: dict) -> dict:
    """The manifest entry of a finished shard (:func:`run_shard`)."""
    return {
        "index": index,
        "device": str(dev),
        "device_name": dev.name,
        "batches": run["batches"],
        "state": "done" if run["fault"] is None else "fault",
        "file": file,
        "pads": len(scenes),
        "steps": run["steps"],
        "wall_time": run["wall"],
        "compile_time": run["compile"],
        "task_time": timings["task"],
        "patch_steps": int(sum(s.patches.count for s in scenes)) * run["steps"],
        "fault": run["fault"],
        "timings": timings,
    }


def _run_batches(
    spec: SweepSpec,
    scenes: list[Scene],
    dev: Any,
    cap: int,
    ctx: ShardContext,
    clock: _Clock,
    turn: KernelTurn | None,
    emit: Callable[[tuple[int, int, Any]], None],
    pads: np.ndarray,
) -> dict:
    """Build and run the shard's pads (global indices ``pads``) in batches of at most ``cap``; every recorded chunk
    goes to ``emit`` as ``(b0, b1, chunk)``. Returns the run's attributes for the file and its figures for the
    summary."""
    steps, wall, compile_time, batches = 0, 0.0, 0.0, 0
    engines: set[str] = set()
    fault = None
    dt_used = math.nan
    run_start = run_end = math.nan
    for b0 in range(0, len(scenes), cap):
        b1 = min(b0 + cap, len(scenes))
        res, began = _run_batch(spec, scenes[b0:b1], b0, dev, ctx, clock, turn, emit)
        run_start = began if math.isnan(run_start) else run_start
        run_end = time.time()
        batches += 1
        steps = max(steps, res.steps)
        wall += res.wall_time
        engines.add(res.engine)
        compile_time += res.compile_time
        dt_used = res.dt
        if res.fault is not None:
            fault = f"pads {_pad_list(pads[b0:b1])}: {res.fault}"
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


def _pad_list(pads: np.ndarray) -> str:
    """Global pad indices in words: ``a..b`` for a run of consecutive ones, else a list (the first 8)."""
    if np.all(np.diff(pads) == 1):
        return f"{pads[0]}..{pads[-1]}"
    shown = ", ".join(str(p) for p in pads[:8])
    return shown + (f", ... ({len(pads)} pads)" if len(pads) > 8 else "")


def _run_batch(
    spec: SweepSpec,
    scenes: list[Scene],
    b0: int,
    dev: Any,
    ctx: ShardContext,
    clock: _Clock,
    turn: KernelTurn | None,
    emit: Callable[[tuple[int, int, Any]], None],
) -> tuple[Any, float]:
    """Build and run one batch (the shard's pads [b0, b0 + len(scenes))) in its turn on the device; returns the
    :class:`~aca_warp.hf.loop.RunResult` and the wall-clock time its run began (``time.time()``) [s]. Clock:
    ``build``, ``setup``, ``kernel`` (the run less its sink), ``sink``."""
    from aca_warp.hf.loop import run_hf
    from aca_warp.hf.model import build_model
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.state import initial_state

    b1 = b0 + len(scenes)
    ctx.check()
    if turn is not None:
        turn.enter()  # the build is Warp work too: see KernelTurn
    with clock("build"):
        model = build_model(scenes, device=dev, precision=spec.precision)
        state = initial_state(model)

    def sink(chunk: Any) -> None:
        t = time.perf_counter()
        ctx.check()
        if turn is not None:
            turn.first_chunk()
        emit((b0, b1, chunk))
        clock.add("sink", time.perf_counter() - t)

    options = RunOptions(
        duration=spec.duration, integrator=spec.integrator, dt=spec.dt, tolerance=spec.tolerance
    )  # engine auto: the on-chip kernel on CUDA where the model allows it, else the general one
    sink_before = clock.s.get("sink", 0.0)
    began = time.time()
    res = run_hf(model, state, options, record=spec.base.record, sink=sink)
    del model, state  # freed within the turn
    clock.add("setup", res.compile_time)
    clock.add("kernel", max(0.0, res.wall_time - (clock.s.get("sink", 0.0) - sink_before)))
    return res, began


def shard_finished(path: Path, spec_hash: str, start: int, stop: int) -> str | None:
    """``"done"``/``"fault"`` when ``path`` holds a finished, readable shard of this spec and pad range, else None
    (then it runs again). Readable: every object opens and the last sample of every output reads (a damaged group
    or chunk index shows up here)."""
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
            ):
                return None
            f.visititems(lambda name, obj: None)
            f["global/time"][-1:]
            for k in GLOBAL_NAMES:
                f["global"][k][:, -1:]
            return "done" if bool(a.get("complete", False)) else "fault"
    except (OSError, KeyError, ValueError, RuntimeError, TypeError):  # missing, truncated or damaged: run it again
        return None
