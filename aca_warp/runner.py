"""One HF run of one scene into one run file: the sequence behind ``aca-warp hf`` (and its Python twin)."""

from __future__ import annotations

from pathlib import Path

import warp as wp

from aca_warp.errors import SceneError
from aca_warp.hf import DEFAULT_INTEGRATOR, DEFAULT_TOLERANCE, RunResult, run_hf
from aca_warp.io import RunWriter, check_output_path
from aca_warp.model import build_model
from aca_warp.scene import Scene
from aca_warp.state import initial_state


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
) -> RunResult:
    """Simulate ``scene`` for ``duration`` [s] (default: the scene's) and write the run file ``output``.

    Everything is validated before the simulation starts. A fault or an interrupt (Ctrl-C) still leaves a
    readable file holding every sample up to that point, marked ``complete = False``.
    """
    check_output_path(output, overwrite=overwrite)
    duration = scene.duration if duration is None else duration
    if not duration > 0:
        raise SceneError(f"duration must be > 0 s, got {duration}")
    model = build_model([scene], device=device, precision=precision)
    state = initial_state(model)
    policy = {
        "integrator": integrator,
        "dt": dt,
        "tolerance": tolerance,
        "sample_dt": scene.record.sample_dt,
        "force": force,
        "duration": duration,
    }
    writer = None
    try:
        # refuse bad step choices before a file is created
        from aca_warp.hf import HFSolver

        HFSolver(model, integrator, dt, force=force, tolerance=tolerance)
        writer = RunWriter(
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
        result = run_hf(
            model,
            state,
            duration=duration,
            integrator=integrator,
            dt=dt,
            tolerance=tolerance,
            force=force,
            sink=writer.write,
            progress=progress,
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
