"""One HF run of one scene into one run file: the sequence behind ``aca-warp hf`` (and its Python twin).

:func:`run_scene` starts a run; :func:`resume_run` continues a killed or stopped one from the last checkpoint
in its run file (``aca-warp hf --resume``). Both stream samples into a :class:`~aca_warp.hf.runfile.RunWriter`
and close it complete or marked incomplete (docs/run_files.md, docs/faults.md).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import warp as wp

from aca_warp.common import interrupts, plausible
from aca_warp.common.checkpoint import Checkpoint
from aca_warp.common.errors import SceneError, option
from aca_warp.common.files import OutputLock, check_output_path, check_room, machine
from aca_warp.common.runfile import busy, reopen_resumable
from aca_warp.hf.loop import RunResult, run_hf
from aca_warp.hf.model import PadModel, build_model
from aca_warp.hf.onchip_layout import choose_engine
from aca_warp.hf.options import (
    STEP_CONTROLLED,
    RunOptions,
    crossing_asked,
    default_follows,
    default_precision,
    default_step,
    growth_asked,
    step_asked,
)
from aca_warp.hf.recorder import check_run, check_sample_step
from aca_warp.hf.runfile import RunWriter, file_bytes
from aca_warp.hf.sanity import check_contact
from aca_warp.hf.solver import check_step
from aca_warp.hf.state import HFState, initial_state
from aca_warp.scene import Scene

MAX_STEPS = 1.0e10  # steps of one run without force=True (≈ 5 h of the fastest on-chip pad, months on a CPU)
MAX_OUTPUT_BYTES = 50.0e9  # bytes of recorded samples of one run without force=True


@dataclass(frozen=True)
class RunPlan:
    """What a run will do, known before it starts.

    Attributes:
        steps: Fixed steps (None for the adaptive integrator, whose count is not known ahead).
        step: The step those are [s] (the requested one, or :func:`~aca_warp.hf.options.default_step`, shortened
            to fit the sample interval), or None.
        samples: Global samples to record (the initial one included).
        patch_rows: Per-patch history rows to record.
        output_bytes: Bytes the recorded samples take in the run file (uncompressed).
        file_bytes: Bytes the run file takes on disk (chunks allocated whole, headers, checkpoint slots;
            :func:`~aca_warp.hf.runfile.file_bytes`): what the free-space check asks for.
    """

    steps: int | None
    step: float | None
    samples: int
    patch_rows: int
    output_bytes: int
    file_bytes: int

    def describe(self) -> str:
        """One line for the user."""
        steps = "adaptive steps" if self.steps is None else f"{self.steps:.4g} steps of {self.step:.3g} s"
        return f"{steps}, {self.samples:.4g} samples, about {_size(self.output_bytes)} to record"


def _size(b: float) -> str:
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if b >= scale:
            return f"{b / scale:.3g} {unit}"
    return f"{b:.0f} B"


def plan_run(
    scene: Scene, options: RunOptions, precision: str | None = None, *, force_limits: bool | None = None
) -> RunPlan:
    """The :class:`RunPlan` of ``scene`` under ``options`` in ``precision`` (None: the integrator's default,
    :func:`~aca_warp.hf.options.default_precision`; ``options.duration`` None: the scene's); raises
    :class:`SceneError` for one beyond :data:`MAX_STEPS` or :data:`MAX_OUTPUT_BYTES`, or whose sample interval is
    shorter than its step, unless ``force_limits`` (None: ``options.force``; ``rerun`` passes its own ``--force``,
    so that a run file's stored ``force`` does not lift these limits)."""
    forced = options.force if force_limits is None else force_limits
    duration = scene.duration if options.duration is None else options.duration
    rec = scene.record
    n = check_run(duration, rec, options.checkpoint_interval)
    plausible.check("duration", duration, "hf_duration", allow=scene.allow_implausible)
    if options.dt is not None:
        plausible.check("dt", options.dt, "hf_step", allow=scene.allow_implausible)
    steps = step = None
    asked = step_asked(options.integrator, options.dt, [scene], rec.sample_dt)
    dt = default_step(options.integrator) if asked is None else asked  # step-controlled: the first trial's bound
    if not forced:
        anyway = f"{option('force=True', '--force')} runs it anyway"
        check_sample_step(rec.sample_dt, dt, anyway, follows=default_follows(options.integrator, options.dt, dt))
    if options.integrator not in STEP_CONTROLLED:
        sps = max(1, math.ceil(rec.sample_dt / dt - 1e-9))
        steps, step = n * sps, rec.sample_dt / sps
    rows = rec.patch_rows(duration)
    if rec.patches and rows == 0:
        raise SceneError(
            f"the per-patch window [{rec.window[0]:g}, {rec.window[1]:g}] s holds no sample of the run (0 to "
            f"{duration:g} s, every {rec.sample_dt:g} s): nothing would be recorded; choose a window inside the run"
        )
    item = 4 if (precision or default_precision(options.integrator)) == "fp32" else 8
    out = (n + 1) * 8 * 7 + rows * (8 + len(rec.patches) * scene.patches.count * item)
    cells = 0 if scene.matrix is None else len(scene.matrix.area)
    ckpt = options.checkpoint_interval is not None
    disk = file_bytes(n + 1, rows, scene.patches.count, len(rec.patches), item, cells=cells, checkpoints=ckpt)
    plan = RunPlan(steps, step, n + 1, rows, out, disk)
    if forced:
        return plan
    if steps is not None and steps > MAX_STEPS:
        raise SceneError(
            f"{duration:g} s at a step of {step:.3g} s is {steps:.3g} steps, more than {MAX_STEPS:.0e} (check the "
            f"duration and {option('dt', '--dt')} units: seconds); {option('force=True', '--force')} runs it anyway"
        )
    if out > MAX_OUTPUT_BYTES:
        raise SceneError(
            f"the run would record about {_size(out)} ({n + 1:.3g} samples, {rows:.3g} per-patch rows), more than "
            f"{_size(MAX_OUTPUT_BYTES)}; use a larger sample interval, a shorter patch window or decimation, or "
            f"{option('force=True', '--force')}"
        )
    return plan


def run_scene(
    scene: Scene,
    output: str | Path,
    options: RunOptions | None = None,
    *,
    device: str = "cpu",
    precision: str | None = None,
    overwrite: bool = False,
    progress: bool = False,
    announce: Callable[[RunPlan], None] | None = None,
    force_limits: bool | None = None,
) -> RunResult:
    """Simulate ``scene`` as ``options`` say (default :class:`RunOptions`: the scene's duration, ``strang`` at its
    default step, :func:`~aca_warp.hf.options.default_step`) on ``device`` in ``precision`` (None: the integrator's
    default, fp32 for ``strang`` and fp64 for the others, :func:`~aca_warp.hf.options.default_precision`) and write
    the run file ``output``.

    Everything is validated before the simulation starts. A fault or an interrupt (Ctrl-C) still leaves a
    readable file holding every sample up to that point, marked ``complete = False``. The file also keeps the
    solver state of the last checkpoint (``options.checkpoint_interval``: automatic by default, 0 for none), so that
    a stopped or killed run continues with :func:`resume_run`. The file stores the options with the duration, the
    step (a fixed-step integrator's default written out), the spacing of a growing scene's growth events (``strang``'s
    default written out, :func:`~aca_warp.hf.options.growth_asked`), the crossing treatment (its default written out,
    :func:`~aca_warp.hf.options.crossing_asked`) and the engine resolved. ``announce`` receives the
    :class:`RunPlan` once everything is validated, just before the run starts. ``force_limits`` lifts the size
    limits and the free-space check (:func:`plan_run`; None: ``options.force``).
    """
    options = options or RunOptions()
    precision = precision or default_precision(options.integrator)
    lock = OutputLock.acquire(output, what=busy())  # held from here until the file has its final name
    try:
        check_output_path(output, overwrite=overwrite)
        options = options.with_duration(scene.duration if options.duration is None else options.duration)
        # planned before the step is written out: plan_run resolves the same step, and knows whether one was asked
        plan = plan_run(scene, options, precision, force_limits=force_limits)  # absurd counts or sizes: refused early
        interval = scene.growth.interval if scene.growth is not None else None
        options = dataclasses.replace(  # the file keeps both
            options,
            dt=step_asked(options.integrator, options.dt, [scene], scene.record.sample_dt),
            growth_dt=growth_asked(options.integrator, options.growth_dt, interval, options.duration),
            crossing=crossing_asked(options.integrator, options.crossing, [scene]),
        )
        if not (options.force if force_limits is None else force_limits):
            hint = "a larger sample interval, a shorter patch window or decimation; "
            check_room(Path(output).parent, plan.file_bytes, hint + f"{option('force=True', '--force')} tries anyway")
        model = build_model([scene], device=device, precision=precision)
        state = initial_state(model)
        check_step(model, options, scene.record.sample_dt)  # the step the run takes
        check_contact(model, accept=options.accept_unphysical)  # exit 3 before a file exists
        engine = choose_engine(model, options.engine, options.integrator, options.fast_math)
        options = dataclasses.replace(options, engine=engine)
    except BaseException:
        lock.release()
        raise
    if announce is not None:
        announce(plan)

    writer = RunWriter(
        output,
        model,
        overwrite=overwrite,
        lock=lock,
        planned=(plan.samples, plan.patch_rows),
        attrs={
            "integrator": options.integrator,
            "precision": precision,
            **machine(model.device),  # device, device_name, host, platform: as an LF file names them
            "run_options": options.to_json(),
        },
    )
    return _execute(writer, model, state, options, progress=progress)


def _execute(
    writer: RunWriter,
    model: PadModel,
    state: HFState,
    options: RunOptions,
    *,
    progress: bool,
    resume: Checkpoint | None = None,
) -> RunResult:
    """Run into ``writer``; close it complete, stopped, interrupted or failed (a storage
    failure leaves the ``.partial`` as it was at its last checkpoint and raises a one-line StorageError). Appends,
    checkpoints and the closing are not interrupted half-way (:func:`aca_warp.common.interrupts.deferred`)."""
    with writer.closed_when_stopped():
        result = run_hf(
            model,
            state,
            options,
            sink=interrupts.undivided(writer.write),
            progress=progress,
            on_checkpoint=interrupts.undivided(writer.checkpoint),
            resume=resume,
        )
        status = "complete" if result.complete else f"stopped: {result.fault}"
        with interrupts.deferred():
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
    wp.synchronize_device(model.device)
    return result


def resume_run(
    path: str | Path,
    *,
    progress: bool = False,
    checkpoint_interval: float | None = None,
    device: str | None = None,
) -> tuple[RunResult, Path]:
    """Continue the run ``path`` (``NAME`` or ``NAME.partial``) from its last checkpoint, or from its start when it
    has none (stopped before its first checkpoint, or run with ``checkpoint_interval=0``); returns the result and
    the final file name. Same scene, options, precision and device as the run (``device`` overrides it: then the
    result is no longer bit-identical; ``checkpoint_interval`` replaces the run's). The finished file equals an
    uninterrupted run's."""
    from aca_warp.hf.rerun import read_settings

    Prepared = tuple[PadModel, HFState, RunOptions, RunPlan]

    def prepare(src: Path) -> Prepared:
        s = read_settings(src)
        model = build_model([s.scene], device=s.device_for(device, src), precision=s.precision)
        options = s.options
        if checkpoint_interval is not None:
            options = dataclasses.replace(options, checkpoint_interval=checkpoint_interval)
        plan = plan_run(s.scene, options, s.precision, force_limits=True)  # the rows, as the run planned them
        return model, initial_state(model), options, plan

    def reopen(prepared: Prepared, part: Path, lock: OutputLock) -> tuple[RunWriter, Checkpoint | None]:
        planned = (prepared[3].samples, prepared[3].patch_rows)
        return RunWriter.reopen(part, prepared[0], lock=lock, planned=planned)

    (model, state, options, _), (writer, ckpt), final = reopen_resumable(path, prepare, reopen)
    if checkpoint_interval is not None:
        writer.f.attrs["run_options"] = options.to_json()
    return _execute(writer, model, state, options, progress=progress, resume=ckpt), final
