"""The one HF run loop: chunks, recording, faults, progress, checkpoints and sinks, over an engine.

An engine advances the pads and records samples into its :class:`~aca_warp.hf.recorder.Recorder`; everything
around that — flushing chunks to a sink, the watchdog's faults, the progress bar, checkpoints and resume — is
written once, here, for every engine:

* :class:`~aca_warp.hf.general.GeneralEngine`: per-step kernels replayed from captured graphs, every integrator;
* :class:`~aca_warp.hf.onchip.OnchipEngine`: one thread block (or cluster) per pad for many ``strang`` steps;
* :class:`~aca_warp.hf.onchip_adaptive.OnchipAdaptiveEngine`: one thread block per pad for many ``adaptive`` trials.

A new integrator or engine implements :class:`Engine` (docs/architecture.md).
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from aca_warp.common.checkpoint import Checkpoint, CheckpointClock
from aca_warp.common.errors import SceneError, SimulationFault, option
from aca_warp.common.progress import LogProgress
from aca_warp.hf.engine import Engine, EngineSetup, EngineTuning, Progress
from aca_warp.hf.model import PadModel
from aca_warp.hf.options import RunOptions
from aca_warp.hf.recorder import Chunk, check_run, fault_from, watchdog_bound
from aca_warp.hf.sanity import check_contact, mu_bounds, mu_fault, warn
from aca_warp.hf.solver import StepEstimate, check_step
from aca_warp.hf.state import HFState
from aca_warp.scene import Record


@dataclass
class RunResult:
    """What a run did.

    Attributes:
        complete: True when the whole duration was simulated.
        fault: The fault that stopped the run, or None.
        steps: Accepted steps (all pads advance together).
        rejected: Rejected steps (adaptive only).
        sim_time: Simulated time reached [s].
        wall_time: Wall time of the stepping loop, graph captures excluded [s].
        compile_time: Wall time to load/compile the kernels and to capture the graphs [s].
        dt: Step used (fixed-step) or the last desired step (adaptive) [s].
        estimate: Stable-step estimate.
        stages: Names of the stages that ran.
        chunks: Recorded chunks when no sink was given (see :meth:`collect`).
        blocks_per_pad: Thread blocks that advanced each pad (the on-chip engine's cluster size; 1 otherwise).
        block_dim: Threads per block of the on-chip engine's launches (None for the general engine).
        checkpoints: Checkpoints written.
        checkpoint_time: Wall time spent writing them [s] (part of ``wall_time``).
    """

    complete: bool
    fault: SimulationFault | None
    steps: int
    rejected: int
    sim_time: float
    wall_time: float
    compile_time: float
    dt: float
    estimate: StepEstimate
    stages: list[str]
    chunks: list[Chunk] = field(default_factory=list)
    blocks_per_pad: int = 1
    block_dim: int | None = None
    checkpoints: int = 0
    checkpoint_time: float = 0.0

    def collect(self) -> Chunk:
        """All recorded chunks joined into one."""
        c = self.chunks

        def cat(name: str) -> np.ndarray | None:
            parts = [getattr(x, name) for x in c if getattr(x, name) is not None]
            return np.concatenate(parts) if parts else None

        return Chunk(cat("time"), cat("globals"), cat("patch_time"), cat("velocity"), cat("displacement"))

    @property
    def engine(self) -> str:
        """The engine that stepped the run: ``onchip`` (a ``step:…:onchip`` stage) or ``general``."""
        return "onchip" if any(s.startswith("step:") and s.endswith(":onchip") for s in self.stages) else "general"


def make_engine(
    model: PadModel,
    state: HFState,
    options: RunOptions,
    record: Record,
    n_samples: int,
    tuning: EngineTuning,
    estimate: StepEstimate | None = None,
) -> Engine:
    """The engine ``options.engine`` resolves to (:func:`~aca_warp.hf.onchip.choose_engine`); ``estimate``: the model's
    stable-step estimate, if known (else the engine computes it)."""
    from aca_warp.hf.onchip_layout import choose_engine

    setup = EngineSetup(model, state, options, record, n_samples, tuning, estimate)
    if choose_engine(model, options.engine, options.integrator, options.fast_math) == "onchip":
        if options.integrator == "adaptive":
            from aca_warp.hf.onchip_adaptive import OnchipAdaptiveEngine

            return OnchipAdaptiveEngine(setup)
        from aca_warp.hf.onchip import OnchipEngine

        return OnchipEngine(setup)
    from aca_warp.hf.general import GeneralEngine

    return GeneralEngine(setup)


def restore(saved: dict[str, wp.array], ckpt: Checkpoint) -> None:
    """Copy a checkpoint's arrays into the run's device arrays (names, shapes and dtypes must match)."""
    missing = sorted(set(saved) - set(ckpt.arrays))
    extra = sorted(set(ckpt.arrays) - set(saved))
    if missing or extra:
        raise SceneError(
            f"the checkpoint does not fit this run (missing {', '.join(missing) or 'nothing'}, "
            f"unexpected {', '.join(extra) or 'nothing'}): another integrator, engine or scene?"
        )
    for name, arr in saved.items():
        data = ckpt.arrays[name]
        want = np.dtype(wp.dtype_to_numpy(arr.dtype))
        if data.shape != arr.shape or data.dtype != want:
            raise SceneError(
                f"checkpoint array {name} has shape {data.shape} and dtype {data.dtype}, the run needs {arr.shape} "
                f"{want}: another scene or precision, or a checkpoint of an older aca_warp?"
            )
        arr.assign(data)


def _progress_bar(total: float):  # noqa: ANN202 (tqdm)
    from tqdm import tqdm

    return tqdm(
        total=total,
        unit="s",
        unit_scale=True,
        dynamic_ncols=True,
        bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} s simulated [{elapsed}<{remaining}{postfix}]",
    )


def run_hf(
    model: PadModel,
    state: HFState,
    options: RunOptions,
    *,
    record: Record | None = None,
    sink: Callable[[Chunk], None] | None = None,
    progress: bool = False,
    on_checkpoint: Callable[[Checkpoint], None] | None = None,
    resume: Checkpoint | None = None,
    tuning: EngineTuning | None = None,
    checked: Preflight | None = None,
) -> RunResult:
    """Advance all pads of ``model`` from ``state`` as ``options`` say, recording as ``record`` says.

    ``options.duration`` None means the first scene's duration. Samples go to ``sink`` (or into the result's
    ``chunks``) at every chunk end. ``progress``: a progress bar on stderr when it is a terminal (none in a log).
    A non-finite value, or a patch beyond the watchdog bound (:func:`~aca_warp.hf.recorder.watchdog_bound`), stops
    the run: the result carries the fault and every sample before it. With ``on_checkpoint``, the chunk ends that
    ``options.checkpoint_interval`` names (:class:`~aca_warp.common.checkpoint.CheckpointClock`: automatic, every
    interval of simulated time, or none) hand a :class:`~aca_warp.common.checkpoint.Checkpoint` to
    ``on_checkpoint``; ``resume`` (a checkpoint of the same scene,
    options, device and precision) continues from it with the same arithmetic in the same order, so the samples
    equal an uninterrupted run's bit for bit. ``checked``: :func:`preflight` of this model, state, options and
    record, made beforehand (e.g. in another process, on the model's host arrays); None: made here.
    """
    t_compile = time.perf_counter()
    record = record or model.scenes[0].record
    run = _Run(model, state, options, record, tuning or EngineTuning(), resume, checked)
    compile_time = time.perf_counter() - t_compile
    return run.loop(sink, progress, on_checkpoint, compile_time)


@dataclass(frozen=True)
class Preflight:
    """What a run checks and derives before its first step from its model, initial state and options
    (:func:`preflight`): host work that reads every patch and link of the batch.

    Attributes:
        estimate: The model's stable-step estimate.
        mu_bound: Largest |μ| each pad can reach (:func:`~aca_warp.hf.sanity.mu_bounds`), shape (pads,).
        watch_bound: The watchdog's bound per pad (:func:`~aca_warp.hf.recorder.watchdog_bound`; +inf when off)
            [m/s], shape (pads,).
    """

    estimate: StepEstimate
    mu_bound: np.ndarray
    watch_bound: np.ndarray


def preflight(model: PadModel, state: HFState, options: RunOptions, record: Record) -> Preflight:
    """The checks of a run before anything is written, and their results: the step (as the run takes it) and the
    int32 step counts (:func:`~aca_warp.hf.solver.check_step`), the contact solution
    (:func:`~aca_warp.hf.sanity.check_contact`), the μ bound and the watchdog's bound. Reads only the model's and
    state's values, so a model on the host (:func:`~aca_warp.hf.model.upload` with ``copy=False``) gives what its
    copy on a device gives."""
    duration = model.scenes[0].duration if options.duration is None else options.duration
    options = options.with_duration(duration)
    estimate = check_step(model, options, record.sample_dt)
    check_contact(model, accept=options.accept_unphysical)
    factor = options.watchdog_factor
    bounds = np.full(model.pad_count, np.inf) if factor is None else watchdog_bound(model, state, factor)
    return Preflight(estimate, mu_bounds(model), bounds)


class _Run:
    """One run's engine, recorder, watchdog bounds, checkpointed arrays and progress (:func:`run_hf`)."""

    def __init__(
        self,
        model: PadModel,
        state: HFState,
        options: RunOptions,
        record: Record,
        tuning: EngineTuning,
        resume: Checkpoint | None,
        checked: Preflight | None = None,
    ) -> None:
        self.model, self.record = model, record
        duration = model.scenes[0].duration if options.duration is None else options.duration
        self.n_samples = check_run(duration, record, options.checkpoint_interval)
        self.options = options = options.with_duration(duration)
        checked = preflight(model, state, options, record) if checked is None else checked
        # the engines skip their own check of the step asked for (it is not the step they take); a checkpoint
        # continues on the engine that wrote it when the run leaves the choice to ``auto`` (their checkpointed arrays
        # differ for growing pads, and the choice of ``auto`` may have changed since)
        from aca_warp.hf.onchip_layout import choose_engine

        engine = options.engine
        if resume is not None and engine == "auto" and "onchip" in resume.counters:
            engine = "onchip" if resume.counters["onchip"] else "general"
        engine = choose_engine(model, engine, options.integrator, options.fast_math)  # resolved once: onchip or general
        self.onchip = engine == "onchip"
        engine_options = dataclasses.replace(options, force=True, engine=engine)
        self.engine = make_engine(model, state, engine_options, record, self.n_samples, tuning, checked.estimate)
        self.rec = rec = self.engine.recorder
        self.mu_bound = checked.mu_bound
        self.bounds = checked.watch_bound
        rec.watch_bound.assign(self.bounds)
        self.saved = {
            "state/u": state.u,
            "state/v": state.v,
            "state/force": state.force,
            "recorder/counters": rec.counters,
            "watchdog/bound": rec.watch_bound,
            **self.engine.saved(),
        }
        self.p = Progress()
        if resume is not None:
            restore(self.saved, resume)
            c = resume.counters
            self.p = Progress(int(c["samples"]), int(c["steps"]), int(c["rejected"]), resume.sim_time)
            rec.sample_index = int(c["sample_index"])
            self.bounds = rec.watch_bound.numpy()
        self.engine.begin(None if resume is None else resume.counters)
        self.last_sample = self.p.sim_time  # time of the last sample handed to the sink [s]
        self.unphysical_seen = False

    def loop(
        self,
        sink: Callable[[Chunk], None] | None,
        progress: bool,
        on_checkpoint: Callable[[Checkpoint], None] | None,
        compile_time: float,
    ) -> RunResult:
        """Advance chunk by chunk to the end or a fault: emit samples, show progress, write checkpoints."""
        engine, record, p = self.engine, self.record, self.p
        total, tty = self.n_samples * record.sample_dt, sys.stderr.isatty()
        bar = _progress_bar(total) if progress and tty else None  # a terminal: a bar; a log: a line every 30 s
        log = LogProgress("hf:", total) if progress and not tty else None
        if bar is not None and p.sim_time > 0:
            bar.update(p.sim_time)
        clock = self.clock = CheckpointClock(
            self.options.checkpoint_interval if on_checkpoint is not None else 0.0, p.sim_time
        )
        out: list[Chunk] = []
        emit = sink or out.append
        t0, steps0 = time.perf_counter(), p.steps  # a resumed run's rate counts this loop's steps only

        def rate() -> str:
            return f"{(self.p.steps - steps0) / max(time.perf_counter() - t0, 1e-9):.3g} steps/s"

        fault: SimulationFault | None = None
        try:
            while fault is None and not p.done:
                most = self.n_samples
                if not math.isinf(clock.bound):
                    most = math.ceil(clock.bound / record.sample_dt - 1e-9)
                p = self.p = engine.advance(p, max(1, most - p.samples))
                fault = self._chunk(emit)
                if bar is not None:
                    bar.update(p.sim_time - bar.n)
                    bar.set_postfix_str(rate())
                elif log is not None:
                    log.update(p.sim_time, rate)
                if fault is None and not p.done and clock.due(p.sim_time):
                    clock.write(lambda: on_checkpoint(self._checkpoint()), p.sim_time)  # type: ignore[misc]
        finally:
            if bar is not None:
                bar.close()
            engine.finish()
        wp.synchronize_device(self.model.device)
        return self._result(fault, out, t0, compile_time)

    def _chunk(self, emit: Callable[[Chunk], None]) -> SimulationFault | None:
        """Flush the recorder, find the first fault (the watchdog's, the engine's, μ beyond its bound) and emit the
        samples before it; returns the fault or None."""
        rec, record = self.rec, self.record
        chunk, table = rec.flush()
        fault = fault_from(table, self.model, record.sample_dt, self.engine.cause, rec.fault_value.numpy(), self.bounds)
        fault = fault or self.p.fault
        if fault is None and not self.unphysical_seen:
            fault = mu_fault(chunk.time, chunk.globals[:, :, 0], self.mu_bound)
            if fault is not None and self.options.accept_unphysical:
                accepted = option("accept_unphysical=True", "--accept-unphysical")
                warn(f"{fault} (accepted: {accepted}; not checked again)")
                fault, self.unphysical_seen = None, True
        if fault is not None:
            chunk = chunk.before(fault.time - 0.5 * record.sample_dt)
        emit(chunk)
        if len(chunk.time):
            self.last_sample = float(chunk.time[-1])
        return fault

    def _checkpoint(self) -> Checkpoint:
        """The run's state now: every checkpointed array and the counters to continue from."""
        p = self.p
        counters = {"samples": p.samples, "steps": p.steps, "rejected": p.rejected, "onchip": int(self.onchip)}
        counters.update(self.engine.counters())
        counters["sample_index"] = self.rec.sample_index
        arrays = {k: a.numpy().copy() for k, a in self.saved.items()}
        return Checkpoint(sim_time=p.sim_time, arrays=arrays, counters=counters)

    def _result(self, fault: SimulationFault | None, out: list[Chunk], t0: float, compile_time: float) -> RunResult:
        """The :class:`RunResult`; after a fault, time and steps describe the samples kept, not the chunk the fault
        was found in."""
        p, engine = self.p, self.engine
        steps, sim_time = p.steps, p.sim_time
        if fault is not None:
            sim_time = self.last_sample
            if p.samples > 0:  # whole steps per sample interval (fixed-step engines; the adaptive mean)
                steps = round(self.last_sample / self.record.sample_dt) * (p.steps // p.samples)
        return RunResult(
            complete=fault is None,
            fault=fault,
            steps=steps,
            rejected=p.rejected,
            sim_time=sim_time,
            wall_time=time.perf_counter() - t0 - engine.capture_time,
            compile_time=compile_time + engine.capture_time,
            dt=engine.step_used(),
            estimate=engine.estimate,
            stages=engine.stages,
            chunks=out,
            blocks_per_pad=engine.blocks_per_pad,
            block_dim=engine.block_dim,
            checkpoints=self.clock.count,
            checkpoint_time=self.clock.seconds,
        )
