"""One HF run of one scene into one run file: the sequence behind ``aca-warp hf`` (and its Python twin).

:func:`run_scene` starts a run; :func:`resume_run` continues a killed or stopped one from the last checkpoint
in its run file (``aca-warp hf --resume``). Both stream samples into a :class:`~aca_warp.hf.runfile.RunWriter` and
close it complete or marked incomplete (docs/run_files.md, docs/faults.md).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import h5py
import warp as wp

from aca_warp.common.checkpoint import Checkpoint, has_checkpoint
from aca_warp.common.errors import SceneError
from aca_warp.common.files import check_output_path, partial_path
from aca_warp.hf.model import PadModel, build_model
from aca_warp.hf.runfile import RunWriter
from aca_warp.hf.solver import DEFAULT_INTEGRATOR, DEFAULT_TOLERANCE, RunResult, run_hf
from aca_warp.hf.state import HFState, initial_state
from aca_warp.scene import Scene


def run_scene(
    scene: Scene,
    output: str | Path,
    *,
    duration: float | None = None,
    device: str = "cpu",
    integrator: str = DEFAULT_INTEGRATOR,
    dt: float | None = None,
    tolerance: float = DEFAULT_TOLERANCE,
    precision: str = "fp64",
    force: bool = False,
    overwrite: bool = False,
    progress: bool = False,
    checkpoint_interval: float | None = None,
    engine: str = "auto",
) -> RunResult:
    """Simulate ``scene`` for ``duration`` [s] (default: the scene's) and write the run file ``output``.

    Everything is validated before the simulation starts. A fault or an interrupt (Ctrl-C) still leaves a
    readable file holding every sample up to that point, marked ``complete = False``. With
    ``checkpoint_interval`` [s of simulated time] the file also keeps the solver state of the last checkpoint,
    so that a killed run continues with :func:`resume_run`. ``engine``: ``auto``, ``onchip`` or ``general``
    (:func:`aca_warp.hf.onchip.choose_engine`); checkpointed runs take the general engine.
    """
    check_output_path(output, overwrite=overwrite)
    duration = scene.duration if duration is None else duration
    if not duration > 0:
        raise SceneError(f"duration must be > 0 s, got {duration}")
    if checkpoint_interval is not None and not checkpoint_interval > 0:
        raise SceneError(f"checkpoint interval must be > 0 s, got {checkpoint_interval}")
    model = build_model([scene], device=device, precision=precision)
    state = initial_state(model)
    policy = {
        "integrator": integrator,
        "dt": dt,
        "tolerance": tolerance,
        "sample_dt": scene.record.sample_dt,
        "force": force,
        "duration": duration,
        "checkpoint_interval": checkpoint_interval,
    }
    # refuse bad step choices before a file is created
    from aca_warp.hf.solver import HFSolver, check_run

    check_run(duration, scene.record, checkpoint_interval)
    HFSolver(model, integrator, dt, force=force, tolerance=tolerance)
    from aca_warp.hf.onchip import choose_engine

    if checkpoint_interval is not None:
        if engine == "onchip":
            raise SceneError("--engine onchip: checkpoints and resume need the general engine")
        engine = "general"
    engine = choose_engine(model, engine, integrator)
    policy["engine"] = engine

    def open_writer() -> RunWriter:
        return RunWriter(
            output,
            model,
            overwrite=overwrite,
            attrs={
                "integrator": integrator,
                "precision": precision,
                "device": str(model.device),
                "device_name": model.device.name,
                "step_policy": policy,
            },
        )

    return _execute(open_writer, model, state, policy, progress=progress, engine=engine)


def _execute(
    open_writer: Any,
    model: PadModel,
    state: HFState,
    policy: dict[str, Any],
    *,
    progress: bool,
    resume: Checkpoint | None = None,
    engine: str = "general",
) -> RunResult:
    """Run into the writer ``open_writer()`` returns; close it complete, stopped, interrupted or failed.

    ``engine`` is resolved already: ``onchip`` or ``general`` (:func:`run_hf`)."""
    writer = None
    interval = policy.get("checkpoint_interval")
    try:
        writer = open_writer()
        if engine == "onchip":
            from aca_warp.hf.onchip import run_onchip

            result = run_onchip(
                model,
                state,
                duration=policy["duration"],
                dt=policy["dt"],
                force=policy["force"],
                sink=writer.write,
                progress=progress,
            )
        else:
            result = run_hf(
                model,
                state,
                duration=policy["duration"],
                integrator=policy["integrator"],
                dt=policy["dt"],
                tolerance=policy["tolerance"],
                force=policy["force"],
                sink=writer.write,
                progress=progress,
                **(
                    {}
                    if interval is None and resume is None
                    else {"checkpoint_every": interval, "on_checkpoint": writer.checkpoint, "resume": resume}
                ),
            )
    except KeyboardInterrupt:
        if writer is not None:
            writer.close(complete=False, status="interrupted by the user")
        raise
    except BaseException:
        if writer is not None:
            writer.close(complete=False, status="failed")
        raise
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
            "stable_step": {
                "spring": result.estimate.spring,
                "friction": result.estimate.friction,
                "explicit": result.estimate.explicit,
            },
            "fault": "" if result.fault is None else str(result.fault),
        },
    )
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
        with h5py.File(final, "r") as f:
            complete = bool(f.attrs.get("complete", False))
            resumable = has_checkpoint(f)
    except OSError as e:
        raise SceneError(f"cannot open run file {final}: {e}") from None
    if complete:
        raise SceneError(f"{final} is a complete run; nothing to resume")
    if not resumable:
        raise SceneError(f"{final} holds no checkpoint (run without --checkpoint-interval); use 'aca-warp rerun'")
    return final, part


def resume_run(
    path: str | Path,
    *,
    progress: bool = False,
    checkpoint_interval: float | None = None,
    device: str | None = None,
) -> tuple[RunResult, Path]:
    """Continue the run ``path`` (``NAME`` or ``NAME.partial``) from its last checkpoint; returns the result and
    the final file name. Same scene, step policy, precision and device as the run (``device`` overrides it: then
    the result is no longer bit-identical). The finished file equals an uninterrupted run's."""
    from aca_warp.hf.rerun import read_settings

    final, part = find_resumable(path)
    src = part if part.exists() else final
    s = read_settings(src)
    with h5py.File(src, "r") as f:
        if not has_checkpoint(f):
            raise SceneError(f"{src} holds no checkpoint (run without --checkpoint-interval); use 'aca-warp rerun'")
    model = build_model([s.scene], device=device or s.device, precision=s.precision)
    state = initial_state(model)
    policy = {
        "integrator": s.integrator,
        "dt": s.dt,
        "tolerance": s.tolerance,
        "sample_dt": s.scene.record.sample_dt,
        "force": s.force,
        "duration": s.duration,
        "checkpoint_interval": checkpoint_interval or s.checkpoint_interval,
        "engine": "general",
    }
    if src == final:
        os.replace(final, part)  # a stopped run goes back to being written
    writer, ckpt = RunWriter.reopen(part, model)
    if checkpoint_interval is not None:
        import json

        writer.f.attrs["step_policy"] = json.dumps(policy)
    return _execute(lambda: writer, model, state, policy, progress=progress, resume=ckpt), final
