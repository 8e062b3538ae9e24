"""The general HF engine: every integrator as per-step kernel launches, replayed from captured graphs.

Fixed-step schemes take ``options.dt`` shortened so that a whole number of steps fits a sample interval and
record one sample per interval; a chunk is a graph of up to ``max_graph_steps`` steps. ``adaptive`` steps every pad
with its own step and mode, decided on the device (:mod:`aca_warp.hf.adaptive`); a chunk is a graph of 128
iterations. Growing scenes run a growth event (areas, stiffnesses, the contact re-solve) every
``RunOptions.growth_dt`` (default the scene's ``growth.interval``) of simulated time: counted in steps on the
device (fixed step), or at the event times j·growth_dt, on which every pad lands (adaptive). Every stepping path is
captured in a Warp graph (CPU and CUDA); the host reads back only a few counters per replay.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import warp as wp

from aca_warp.common.devices import Kernels, block_threads, load_kernels
from aca_warp.common.launches import Launcher
from aca_warp.hf import adaptive
from aca_warp.hf.engine import EngineSetup, Progress, fault_cause, run_stages
from aca_warp.hf.model import PadModel
from aca_warp.hf.options import STEP_CONTROLLED
from aca_warp.hf.recorder import Recorder
from aca_warp.hf.solver import CONTACT_BLOCK, HFSolver, event_spacing, grown_arrays, growth_events
from aca_warp.kernels import hf as K


class Growth:
    """Growth events of a growing model on the general engine: the launches of one event, due every ``every``-th
    step of ``h`` [s] (fixed step; the device counts steps in ``step``) or, with ``h`` None (adaptive), wherever
    the adaptive landing sets ``step`` as the event flag: at the event times j·interval (``interval``: the spacing
    ``growth_dt`` [s], default the scene's growth interval), each event adding the scene's increment × the spacing
    over the scene's interval (``every`` = 1 of a step of one spacing)."""

    def __init__(self, model: PadModel, h: float | None, growth_dt: float | None = None) -> None:
        self.model = model
        self.interval = event_spacing(model, growth_dt)
        self.counted = h is not None
        self.every, self.per_event = growth_events(model, h if self.counted else self.interval, growth_dt)
        # int64 (1,): the completed steps (fixed step) or the event flag (adaptive)
        self.step = wp.zeros(1, dtype=wp.int64, device=model.device)
        self.due = (self.step, self.every if self.counted else 0)  # growth_due with every = 0 reads the flag
        self.kernel_model = model.struct(self.per_event)
        self.launcher = Launcher(model.device)  # its launches packed once, replayed (on the CPU)

    def saved(self) -> dict[str, wp.array]:
        """What a checkpoint holds: the step count (fixed step) or the event flag (adaptive)."""
        return {"growth/step" if self.counted else "growth/event": self.step}

    def launch(self) -> None:
        """Count one step (fixed step); when an event is due, grow the areas, update the stiffnesses and re-solve
        the contact."""
        m, km, launch = self.model, self.kernel_model, self.launcher
        for coupling in (0, 1):  # the areas, then the stiffnesses at the new areas
            launch(K.grow_patches, m.patch_count, [km, *self.due, coupling])
        threads = block_threads(m.device, CONTACT_BLOCK)
        launch(K.contact_flat, [m.pad_count], [km, *self.due, threads], block_dim=CONTACT_BLOCK)
        if self.counted:
            launch(K.tick, 1, [self.step])


CPU_CAPTURE_REPLAYS = 8
"""Replays of one captured graph from which capturing it pays on the CPU (:meth:`GeneralEngine._capture_pays`)."""


class GeneralEngine:
    """Per-step kernels for every integrator (:class:`~aca_warp.hf.loop.Engine`)."""

    blocks_per_pad = 1
    block_dim = None

    def __init__(self, setup: EngineSetup) -> None:
        model, state, options, record = setup.model, setup.state, setup.options, setup.record
        n_samples, tuning = setup.n_samples, setup.tuning
        self.model, self.state, self.record, self.n_samples = model, state, record, n_samples
        self.use_graph = tuning.use_graph
        integrator = options.integrator
        self.solver = HFSolver.for_run(model, options, setup.estimate)
        self.estimate = self.solver.estimate
        self.adaptive = integrator in STEP_CONTROLLED
        growing = "pad_growth" in model.arrays
        self.sps = max(1, math.ceil(record.sample_dt / self.solver.dt - 1e-9))
        self.h = record.sample_dt / self.sps
        self.block = max(1, min(n_samples, tuning.max_graph_steps // self.sps))
        self.recorder = Recorder(model, record, (adaptive.ROWS if self.adaptive else self.block) + 1, n_samples)
        self.stages = run_stages(model, self.recorder, integrator)
        self.cause = fault_cause(self.estimate, integrator, self.h)
        if integrator == "strang":
            self.solver.prepare(state)
        self.started = False
        self.growth = None
        if growing:
            self.growth = Growth(model, None if self.adaptive else self.h, self.solver.growth_dt)
        self.stepper = None
        if self.adaptive:
            t_end = n_samples * record.sample_dt
            self.stepper = adaptive.AdaptiveStepper(model, state, self.solver, self.recorder, t_end, self.growth)
        self.body: Callable[[], None] = self.stepper.body if self.stepper is not None else self._fixed_body
        self.graphs: dict[int, Any] = {}
        self._eager_uses: dict[int, int] = {}
        self.capture_time = 0.0

    # -- the Engine protocol

    def saved(self) -> dict[str, wp.array]:
        out: dict[str, wp.array] = {}
        if self.stepper is not None:
            out.update(self.stepper.saved())
        if self.growth is not None:
            out.update(self.growth.saved())
        return out | grown_arrays(self.model)

    def begin(self, resume: dict[str, int] | None) -> None:
        stepper = self.stepper.kernels() if self.stepper is not None else []
        growth: list[Kernels] = [(K, CONTACT_BLOCK)] if self.growth is not None else []  # the contact re-solve
        load_kernels([*self.solver.kernels(), *stepper, *growth], self.model.device)
        if resume is None:
            self.recorder.launch(self.state.u, self.state.v, conditional=False)  # sample 0: the initial state
        else:
            self.started = bool(resume.get("started", 0))

    def advance(self, p: Progress, most: int) -> Progress:
        if self.stepper is not None:
            self.stepper.stop_after(p.samples + most)
            self._replay(adaptive.ITERATIONS)
            return self.stepper.progress()
        reps = min(self.block, self.n_samples - p.samples, most)
        self._replay(reps, (self.n_samples - p.samples) // reps)
        samples = p.samples + reps
        return Progress(samples, samples * self.sps, 0, samples * self.record.sample_dt, samples >= self.n_samples)

    def counters(self) -> dict[str, int]:
        return {"started": int(self.started)}

    def step_used(self) -> float:
        return self.stepper.mean_step() if self.stepper is not None else self.h

    def finish(self) -> None:
        if self.stepper is not None:
            self.stepper.finish()
        elif self.started:
            self.solver.finish(self.state, self.h)

    # -- stepping

    def _fixed_body(self) -> None:
        """One sample interval: ``sps`` steps (growth events due among them) and one recorded sample."""
        s = self.state
        for _ in range(self.sps):
            self.solver.step(s, self.h, first=not self.started)
            self.started = True
            if self.growth is not None:
                self.growth.launch()
        v = self.solver.velocity(s, self.h)
        w1 = self.solver.next_drift  # None but for strang, whose sample comes from a solve
        staggered = None if w1 is None else (s.v, w1)
        self.recorder.launch(s.u, v, conditional=False, staggered=staggered, crossing=self.solver.crossing)

    def _capture_pays(self, reps: int, uses_left: int | None) -> bool:
        """Whether to capture the graph of ``reps`` bodies now: always on a GPU; on the CPU only once it will be
        replayed at least :data:`CPU_CAPTURE_REPLAYS` times (``uses_left``, the replays still to come with this one,
        when the run knows it; else from the count of eager uses so far). A CPU capture costs about as much as eight
        eager runs of the bodies it records (0.10–0.16 s for an hf1 pad), so a short run is faster launched eagerly;
        the kernels and their order are the same either way, and so are the results."""
        if not self.model.device.is_cpu or reps in self.graphs:
            return True
        if uses_left is not None:
            return uses_left >= CPU_CAPTURE_REPLAYS
        self._eager_uses[reps] = self._eager_uses.get(reps, 0) + 1
        return self._eager_uses[reps] > CPU_CAPTURE_REPLAYS

    def _replay(self, reps: int, uses_left: int | None = None) -> None:
        """Run ``reps`` bodies: from a captured graph (one per count) where graphs are used and capturing pays
        (:meth:`_capture_pays`), else eagerly; the first (opening) one eagerly, and the rest of its chunk counted as
        used once (a graph of one body fewer than the chunks after it: on the CPU launched eagerly)."""
        if not self.started and not self.adaptive:  # the opening step differs from the rest: run it eagerly
            self.body()
            reps, uses_left = reps - 1, 1
            if reps == 0:
                return
        if not (self.use_graph and self._capture_pays(reps, uses_left)):
            for _ in range(reps):
                self.body()
            return
        if reps not in self.graphs:
            tc = time.perf_counter()
            with wp.ScopedCapture(device=self.model.device) as cap:
                for _ in range(reps):
                    self.body()
            self.graphs[reps] = cap.graph
            self.capture_time += time.perf_counter() - tc
        wp.capture_launch(self.graphs[reps])
