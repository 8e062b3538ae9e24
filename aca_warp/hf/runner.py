"""One HF run of one scene into one run file: the sequence behind ``aca-warp hf`` (and its Python twin).

:func:`run_scene` starts a run; :func:`resume_run` continues a killed or stopped one from the last checkpoint
in its run file (``aca-warp hf --resume``). Both stream samples into a :class:`~aca_warp.hf.runfile.RunWriter`
and close it complete or marked incomplete (docs/run_files.md, docs/faults.md).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from pathlib import Path

import warp as wp

from aca_warp.common.checkpoint import Checkpoint, has_checkpoint
from aca_warp.common.errors import SceneError
from aca_warp.common.files import OutputLock, check_output_path, open_h5, partial_path, reading
from aca_warp.hf.loop import RunResult, run_hf
from aca_warp.hf.model import PadModel, build_model
from aca_warp.hf.onchip_layout import choose_engine
from aca_warp.hf.options import RunOptions
from aca_warp.hf.recorder import check_run
from aca_warp.hf.runfile import BUSY, RunWriter
from aca_warp.hf.sanity import check_contact
from aca_warp.hf.solver import check_step
from aca_warp.hf.state import HFState, initial_state
from aca_warp.scene import Scene


def run_scene(
    scene: Scene,
    output: str | Path,
    options: RunOptions | None = None,
    *,
    device: str = "cpu",
    precision: str = "fp64",
    overwrite: bool = False,
    progress: bool = False,
) -> RunResult:
    """Simulate ``scene`` as ``options`` say (default :class:`RunOptions`: the scene's duration, ``strang`` at
    1e-8 s) on ``device`` in ``precision`` and write the run file ``output``.

    Everything is validated before the simulation starts. A fault or an interrupt (Ctrl-C) still leaves a
    readable file holding every sample up to that point, marked ``complete = False``. With
    ``options.checkpoint_interval`` the file also keeps the solver state of the last checkpoint, so that a killed
    run continues with :func:`resume_run`. The file stores the options with the duration and the engine resolved.
    """
    options = options or RunOptions()
    lock = OutputLock.acquire(output, what=BUSY)  # held from here until the file has its final name
    try:
        check_output_path(output, overwrite=overwrite)
        options = options.with_duration(scene.duration if options.duration is None else options.duration)
        # refuse bad step choices before a file is created
        check_run(options.duration, scene.record, options.checkpoint_interval)
        model = build_model([scene], device=device, precision=precision)
        state = initial_state(model)
        check_step(model, options, scene.record.sample_dt)  # the step the run takes, the sticking bound
        check_contact(model, accept=options.accept_unphysical)  # exit 3 before a file exists
        options = dataclasses.replace(options, engine=choose_engine(model, options.engine, options.integrator))
    except BaseException:
        lock.release()
        raise

    def open_writer() -> RunWriter:
        return RunWriter(
            output,
            model,
            overwrite=overwrite,
            lock=lock,
            attrs={
                "integrator": options.integrator,
                "precision": precision,
                "device": str(model.device),
                "device_name": model.device.name,
                "run_options": options.to_json(),
            },
        )

    return _execute(open_writer, model, state, options, progress=progress)


def _execute(
    open_writer: Callable[[], RunWriter],
    model: PadModel,
    state: HFState,
    options: RunOptions,
    *,
    progress: bool,
    resume: Checkpoint | None = None,
) -> RunResult:
    """Run into the writer ``open_writer()`` returns; close it complete, stopped, interrupted or failed (a storage
    failure leaves the ``.partial`` as it was at its last checkpoint and raises a one-line StorageError)."""
    writer = None
    try:
        writer = open_writer()
        result = run_hf(
            model,
            state,
            options,
            sink=writer.write,
            progress=progress,
            on_checkpoint=writer.checkpoint,
            resume=resume,
        )
        status = "complete" if result.complete else f"stopped: {result.fault}"
        writer.close(
            complete=result.complete,
            status=status,
            attrs={
                "stages": result.stages,
                "steps": result.steps,
                "rejected_steps": result.rejected,
                "sim_time": result.sim_time,
                "wall_time": result.wall_time,
                "compile_time": result.compile_time,
                "dt": result.dt,
                "stable_step": result.estimate.as_dict(),
                "fault": "" if result.fault is None else str(result.fault),
            },
        )
    except BaseException as e:
        if writer is None or not writer.lock.held:  # not opened, or closed (close raised its own error)
            raise
        status = "interrupted by the user" if isinstance(e, KeyboardInterrupt) else "failed"
        replacement = writer.finish(e, status)
        if replacement is not None:
            raise replacement from None
        raise
    wp.synchronize_device(model.device)
    return result


def find_resumable(path: str | Path) -> tuple[Path, Path]:
    """(run file, its ``.partial``) of the run ``path`` names: ``NAME``, ``NAME.partial`` or a stopped ``NAME``.

    A killed run left ``NAME.partial``; a run stopped by Ctrl-C or a fault was moved to ``NAME`` (incomplete)
    and keeps its checkpoint. Raises SceneError when there is nothing to resume.
    """
    p = Path(path)
    if p.name.endswith(".partial"):
        final, part = p.with_name(p.name.removesuffix(".partial")), p
    else:
        final, part = p, partial_path(p)
    if part.exists():
        if final.exists():
            raise SceneError(f"both {final} and {part} exist; move the one you do not want to resume away")
        return final, part
    if not final.exists():
        raise SceneError(f"nothing to resume: neither {final} nor {part} exists")
    try:
        with open_h5(final, "run file") as f:
            complete = bool(f.attrs.get("complete", False))
            resumable = has_checkpoint(f)
    except (OSError, RuntimeError, KeyError, ValueError) as e:
        raise SceneError(f"cannot read run file {final}: {e}") from None
    if complete:
        raise SceneError(f"{final} is a complete run; nothing to resume")
    if not resumable:
        raise SceneError(f"{final} holds no checkpoint (run without checkpoint_interval); use 'aca-warp rerun'")
    return final, part


def resume_run(
    path: str | Path,
    *,
    progress: bool = False,
    checkpoint_interval: float | None = None,
    device: str | None = None,
) -> tuple[RunResult, Path]:
    """Continue the run ``path`` (``NAME`` or ``NAME.partial``) from its last checkpoint; returns the result and
    the final file name. Same scene, options, precision and device as the run (``device`` overrides it: then the
    result is no longer bit-identical). The finished file equals an uninterrupted run's."""
    from aca_warp.hf.rerun import read_settings

    final, part = find_resumable(path)
    lock = OutputLock.acquire(final, what="it cannot be resumed while it runs")
    try:
        final, part = find_resumable(path)  # again, now that no other process can move it
        src = part if part.exists() else final
        s = read_settings(src)
        with reading(src, "run file"), open_h5(src, "run file") as f:
            if not has_checkpoint(f):
                raise SceneError(f"{src} holds no checkpoint (run without checkpoint_interval); use 'aca-warp rerun'")
        model = build_model([s.scene], device=device or s.device, precision=s.precision)
        state = initial_state(model)
        options = s.options
        if checkpoint_interval is not None:
            options = dataclasses.replace(options, checkpoint_interval=checkpoint_interval)
        if src == final:
            os.replace(final, part)  # a stopped run goes back to being written
    except BaseException:
        lock.release()
        raise
    try:
        writer, ckpt = RunWriter.reopen(part, model, lock=lock)
    except BaseException:
        if src == final and part.exists() and not final.exists():
            os.replace(part, final)  # not resumed: the stopped run keeps its name
        lock.release()
        raise
    if checkpoint_interval is not None:
        writer.f.attrs["run_options"] = options.to_json()
    return _execute(lambda: writer, model, state, options, progress=progress, resume=ckpt), final
