"""The ``adaptive`` integrator on the general engine: the Dormand–Prince 5(4) pair with its own step per pad.

Every pad has its own clock and step on the device (:mod:`aca_warp.kernels.hf_adaptive`): the explicit 5th-order
pair, its embedded 4th-order error estimate in a friction-weighted maximum norm relative to ``tolerance`` and a PI
controller. In sliding it takes steps of tenths of a microsecond; near sticking, where the steep friction law has
nanosecond transients, the friction weight shrinks its steps as far as the forces need. All pads land on every
sample time (samples are exact states, no interpolation); one replay of the captured graph runs a fixed number of
iterations, each one trial per pad. In a growing model they land on every growth event time j·interval as well,
where the growth launches run for all pads inside the graph. Choice and measurements: docs/numerics.md and
docs/work_precision.md.

The same stepper runs ``controlled``, the error-controlled split step (strang's forced damped midpoint with its own
step per pad, :mod:`aca_warp.kernels.hf_controlled`), and ``auto``, where every pad takes the pair while all its
patches slide and the split step once one sticks (docs/friction_step.md §5–6): both share the per-pad clocks,
accept/reject, landing, growth events and checkpointed control; a per-pad flag says which trial a pad takes.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
import warp as wp

from aca_warp.common.devices import Kernels, block_threads
from aca_warp.common.errors import SimulationFault
from aca_warp.common.launches import Launcher
from aca_warp.hf.engine import Progress
from aca_warp.hf.model import PadModel
from aca_warp.hf.recorder import Recorder
from aca_warp.hf.solver import HFSolver
from aca_warp.hf.state import HFState
from aca_warp.kernels import hf_adaptive as KA
from aca_warp.kernels import hf_controlled as KC
from aca_warp.kernels.hf_types import HFAdaptive

MIN_STEP = 1.0e-15  # s; a pad whose error needs a smaller step stops the run (a fault)
CONTROL_BLOCK = 256  # threads per pad of the error reduction and step control
EVAL_LANES = 32  # threads per patch of a stage evaluation on CUDA, for small batches (links read in parallel)
LANE_THREADS_PER_SM = 1024  # lanes only while patches × EVAL_LANES ≤ this × the device's SMs (else one per patch)
ITERATIONS = 128  # trials (or strang steps) per pad per graph replay
ROWS = 256  # sample rows the recorder holds between flushes (more than one replay can land)
SPRING_SAFETY = 0.9  # the split step stays below this share of the spring bound (StepEstimate.spring)


class GrowthEvents(Protocol):
    """The growth events of a growing model (:class:`aca_warp.hf.general.Growth` with ``h`` None)."""

    interval: float  # s, between events
    step: wp.array  # int64 (1,): the event flag, set by the landing

    def launch(self) -> None:
        """The launches of one event, which run only while the flag is set."""


def first_target(sample_dt: float, interval: float) -> float:
    """The first target [s]: the first sample time, or the first growth event when it comes earlier by more than
    the merge width (as :func:`~aca_warp.kernels.hf_adaptive.target_after` chooses; ``interval`` 0: no growth)."""
    if interval > 0.0 and interval < sample_dt - KA.EVENT_MERGE * min(sample_dt, interval):
        return interval
    return sample_dt


def eval_lanes(device: wp.Device, patches: int) -> int:
    """Threads per patch of a stage evaluation: EVAL_LANES for a batch of up to LANE_THREADS_PER_SM × SMs /
    EVAL_LANES patches on CUDA (on an H200, 4224 patches: one hf1 pad took 0.23 s for 1 ms at tol 1e-5 with
    lanes, 0.29 s without), one above that (64 hf1 pads: 2.6 s with lanes, 0.43 s without) and on the CPU (where
    a block is one lane, unless Warp's CPU fibers are on)."""
    if block_threads(device, EVAL_LANES) == 1:
        return 1
    if device.is_cuda and patches * EVAL_LANES > LANE_THREADS_PER_SM * device.sm_count:
        return 1
    return EVAL_LANES


def stability_function(z: complex) -> complex:
    """R(z) of the Dormand–Prince 5(4) pair's 5th-order solution: y_{n+1} = R(hλ) y_n on y′ = λy."""
    a = np.array(KA.DP5_A)
    return complex(1.0 + z * a[-1] @ np.linalg.solve(np.eye(len(a)) - z * a, np.ones(len(a))))


def stability_bounds(step: float = 1e-4) -> tuple[float, float]:
    """(x, y): |R| ≤ 1 on the real interval [−x, 0] and on the imaginary segment [0, iy] (scanned outward from 0 in
    steps of ``step``; |R| within 1e-9 of 1 counts as 1). The time step that keeps a real decay rate γ [1/s] stable
    is x/γ, an undamped oscillation of ω [rad/s] y/ω."""
    bounds = []
    for unit in (-1.0, 1.0j):
        k = 1
        while abs(stability_function(unit * k * step)) <= 1.0 + 1e-9:
            k += 1
        bounds.append((k - 1) * step)
    return bounds[0], bounds[1]


def underflow_fault(t: float) -> SimulationFault:
    """The fault of a pad whose error needs a step below MIN_STEP, at simulated time t [s]."""
    return SimulationFault(
        f"adaptive step fell below {MIN_STEP:g} s at t = {t:.6g} s: the tolerance cannot be met there",
        time=t,
        pad=-1,
        patch=-1,
        cause="step-size underflow",
    )


class AdaptiveStepper:
    """Device state and launches of the per-pad step-controlled integrators for one model (general engine): the
    solver's ``adaptive`` (DP5 on every pad), ``controlled`` (the split step on every pad) or ``auto`` (DP5 until a
    patch sticks, then the split step); ``growth``: the growth events of a growing model (their flag set by the
    landing, their launches between it and the recorder)."""

    def __init__(
        self,
        model: PadModel,
        state: HFState,
        solver: HFSolver,
        recorder: Recorder,
        t_end: float,
        growth: GrowthEvents | None = None,
    ) -> None:
        self.model, self.state, self.solver, self.rec, self.growth = model, state, solver, recorder, growth
        dev, T, n, P = model.device, model.dtype, model.patch_count, model.pad_count
        self.sample_dt = recorder.sample_dt
        self.interval = 0.0 if growth is None else growth.interval
        self.t_end = t_end
        integrator = solver.integrator
        self.pair = integrator in ("adaptive", "auto")  # pads may take DP5 trials
        self.split = integrator in ("controlled", "auto")  # pads may take split-step trials
        self.tol = wp.float64(solver.tolerance)
        self.tol_i = wp.float64(solver.split_tolerance)
        self.h_max = self.sample_dt  # steps land on every sample: none is longer
        self.h_max_i = wp.float64(min(self.sample_dt, SPRING_SAFETY * solver.estimate.spring))
        target = first_target(self.sample_dt, self.interval)
        self.h_start = min(solver.dt, target)  # the PI controller grows it up to 5× per accepted step
        ctl = np.zeros((P, KA.CTL))
        ctl[:, KA.C_TARGET] = target
        ctl[:, KA.C_H] = self.h_start
        ctl[:, KA.C_TRIAL] = self.h_start
        ctl[:, KA.C_ERR] = 1.0e-4
        mode = np.zeros((P, KA.MODE), dtype=np.int32)
        mode[:, KA.M_NEEDK1] = 1
        mode[:, KA.M_SAMPLE] = 1
        mode[:, KA.M_EVENT] = 1
        if not self.pair:  # every pad on the split step from the start: equal steps to the first target
            mode[:, KA.M_SPLIT] = 1
            ctl[:, KA.C_TRIAL] = target / max(1, math.ceil(target / self.h_start - 1e-9))
        self.ctl = wp.array(ctl, dtype=wp.float64, device=dev)
        self.mode = wp.array(mode, dtype=wp.int32, device=dev)
        self.stats = wp.zeros((P, 2), dtype=wp.int64, device=dev)
        self.done = wp.zeros(3, dtype=wp.int32, device=dev)  # [run over, waiting at t_stop, step underflow]
        # the growth event flag (set by the landing, read by the growth kernels); a placeholder without growth
        self.event = wp.zeros(1, dtype=wp.int64, device=dev) if growth is None else growth.step
        self.t_stop = wp.array([t_end], dtype=wp.float64, device=dev)
        self.accepted = wp.zeros(P, dtype=wp.int32, device=dev)
        self.ku = wp.zeros((KA.STAGES, n), dtype=T, device=dev)
        self.kv = wp.zeros((KA.STAGES, n), dtype=T, device=dev)
        # stage states, odd stages in the first pair, even ones in the second (y_6, the 5th-order solution, there)
        self.stage_u = (wp.zeros(n, dtype=T, device=dev), wp.zeros(n, dtype=T, device=dev))
        self.stage_v = (wp.zeros(n, dtype=T, device=dev), wp.zeros(n, dtype=T, device=dev))
        self.coeff = wp.array(np.array(KA.DP5_A), dtype=wp.float64, device=dev)
        self.err_coeff = wp.array(np.array(KA.DP5_E), dtype=wp.float64, device=dev)
        self.u_scale, self.v_scale = self._scales()
        self.lanes = eval_lanes(dev, n)
        # the kernels' parameter group (its arrays change in place only: graphs and checkpoints keep it)
        names = ("coeff", "err_coeff", "u_scale", "v_scale", "tol", "h_max", "sample_dt", "interval", "t_end")
        names += ("t_stop", "ctl", "mode", "stats", "accepted", "done", "ku", "kv", "tol_i", "h_max_i")
        stages = {"u_a": self.stage_u[0], "v_a": self.stage_v[0], "u_b": self.stage_u[1], "v_b": self.stage_v[1]}
        split = {}
        if self.split:
            # per patch: F_{n-1}, the trial's F⁺ and sub-step error, the recorded synchronous velocity
            split = {k: wp.zeros(n, dtype=T, device=dev) for k in ("force_prev", "force_new", "err_f", "v_rec")}
            solver.prepare(state)  # F_n at the start state (a resumed run restores it)
        self.split_arrays = split
        fields = {k: getattr(self, k) for k in names} | stages | split
        fields |= {"h_min": MIN_STEP, "switching": int(self.pair and self.split)}
        self.struct = HFAdaptive.of(T, fields)
        self.launcher = Launcher(dev)  # its launches packed once, replayed (on the CPU)

    def _scales(self) -> tuple[wp.array, wp.array]:
        """Per-patch scales of the error norm: U_i = F_N,i M / k_T,i [m], the static deflection under the largest
        friction force, and V_i = max(|ω r_i|, F_N,i M / √(k_T,i m_i)) [m/s], the disc speed or the speed of a patch
        released from that deflection; each at least a 1e-6 share of its pad's largest (an unloaded patch is not
        judged against 0)."""
        m = self.model
        pad = m.host("patch_pad")
        M = np.array([s.friction.M for s in m.scenes])[pad]
        omega = np.abs(np.array([s.angular_velocity for s in m.scenes]))[pad]
        k_t = m.host("k_t").astype(np.float64)
        mass = 1.0 / m.host("inv_mass").astype(np.float64)
        force = m.host("normal_force").astype(np.float64) * M
        u = force / k_t
        v = np.maximum(omega * m.host("radius").astype(np.float64), force / np.sqrt(k_t * mass))
        for x in (u, v):
            floor = np.zeros(m.pad_count)
            np.maximum.at(floor, pad, x)
            np.maximum(x, 1.0e-6 * floor[pad] + 1.0e-30, out=x)
        return (wp.array(a, dtype=m.dtype, device=m.device) for a in (u, v))

    def kernels(self) -> list[Kernels]:
        """The kernel modules its launches use, each at the block sizes it is launched with, to load before the run's
        first step (:func:`~aca_warp.common.devices.load_kernels`): the landing's; the explicit pair's where pads may
        take it (its control in blocks of ``CONTROL_BLOCK``, its evaluations in blocks of ``lanes`` threads where a
        patch takes more than one); the split step's where pads may take it (its control likewise)."""
        out: list[Kernels] = [KA]
        if self.pair:
            out += [(KA, CONTROL_BLOCK), *([(KA, self.lanes)] if self.lanes > 1 else [])]
        if self.split:
            out += [KC, (KC, CONTROL_BLOCK)]
        return out

    def saved(self) -> dict[str, wp.array]:
        """Arrays a checkpoint holds: the clocks, modes, counters, the first stage (FSAL) and, with the split step, the
        spring force of the step before (F_n is the state's)."""
        out = {
            "adaptive/ctl": self.ctl,
            "adaptive/mode": self.mode,
            "adaptive/stats": self.stats,
            "adaptive/done": self.done,
            "adaptive/ku": self.ku,
            "adaptive/kv": self.kv,
        }
        if self.split:
            out["adaptive/force_prev"] = self.split_arrays["force_prev"]
        return out

    def stop_after(self, samples: int) -> None:
        """Let the next replays run at most to sample ``samples`` (the run loop's chunk end)."""
        self.t_stop.assign(np.array([samples * self.sample_dt]))

    def progress(self) -> Progress:
        """Samples done, accepted steps (the busiest pad's), rejected trials (all pads), time of the last sample,
        done; a step underflow as a fault."""
        st = self.stats.numpy()
        done = self.done.numpy()
        # the last recorded sample: the pads' next sample while they wait there, else the one before it
        k = int(self.mode.numpy()[:, KA.M_SAMPLE].min())
        t = (k if done[1] else k - 1) * self.sample_dt
        fault = underflow_fault(t) if done[2] else None
        if done[0]:
            t = self.t_end
        return Progress(round(t / self.sample_dt), int(st[:, 0].max()), int(st[:, 1].sum()), t, bool(done[0]), fault)

    def mean_step(self) -> float:
        """Simulated time per accepted step of the busiest pad [s] (the step the run reports)."""
        n = int(self.stats.numpy()[:, 0].max())
        return float(self.ctl.numpy()[:, KA.C_START].min()) / n if n else self.h_start

    def finish(self) -> None:
        """Leave the state synchronous: the split pads' staggered velocity closed."""
        if self.split:
            m, s = self.model, self.state
            args = [m.struct(), self.struct, self.solver.newton_tol, s.force, s.v]
            self.launcher(KC.split_finish, m.patch_count, args)

    def body(self) -> None:
        """One iteration: a trial of every pad that has not landed, the landing check and (when every pad has
        landed) a growth event and a sample, as the targets fall."""
        m, s = self.model, self.state
        if self.pair:
            self._pair_trial()
        if self.split:
            self._split_trial()
        self.launcher(KA.landing, 1, [m.pad_count, self.struct, self.rec.struct, self.event])
        if self.growth is not None:
            self.growth.launch()
        if not self.split:
            self.rec.launch(s.u, s.v, conditional=True)
            return
        args = [m.struct(), self.struct, self.solver.newton_tol, self.rec.struct, self.event, s.u, s.force, s.v]
        self.launcher(KC.split_sample, m.patch_count, args)
        if self.pair:
            self.launcher(KC.switch_done, m.pad_count, [self.struct])
        self.rec.launch(s.u, self.split_arrays["v_rec"], conditional=True)

    def _split_trial(self) -> None:
        """A split-step trial of every pad on it that has not landed: sub-step and drift, gather, control, commit."""
        m, s, dev, n = self.model, self.state, self.model.device, self.model.patch_count
        km, ctl = m.struct(), self.struct
        self.launcher(KC.split_trial, n, [km, ctl, self.solver.newton_tol, s.u, s.v, s.force])
        self.launcher(KC.split_gather, n, [km, ctl])
        threads = block_threads(dev, CONTROL_BLOCK)
        self.launcher(KC.split_control, [m.pad_count], [km, ctl, threads, s.force], block_dim=CONTROL_BLOCK)
        self.launcher(KC.split_commit, n, [km, ctl, s.force, s.u, s.v])

    def _pair_trial(self) -> None:
        """A DP5 trial of every pad on the pair that has not landed: seven stages, control, commit."""
        m, s, dev, n = self.model, self.state, self.model.device, self.model.patch_count
        km, dp5, lanes = m.struct(), self.struct, self.lanes
        su, sv = self.stage_u, self.stage_v

        def evaluate(stage: int, first: int, u: wp.array, v: wp.array, u_next: wp.array, v_next: wp.array) -> None:
            inputs = [km, dp5, stage, first, lanes, u, v, s.u, s.v, u_next, v_next]
            if lanes > 1:
                self.launcher(KA.dp5_eval, [n], inputs, block_dim=lanes)
            else:
                self.launcher(KA.dp5_eval, (n, 1), inputs)

        evaluate(0, 1, s.u, s.v, su[1], sv[1])
        self.launcher(KA.k1_done, m.pad_count, [dp5])
        self.launcher(KA.dp5_stage, n, [km, dp5, 1, s.u, s.v, su[1], sv[1]])
        for stage in range(1, KA.STAGES):  # each evaluation also forms its patch's next stage state
            a, b = stage % 2, (stage + 1) % 2
            evaluate(stage, 0, su[a], sv[a], su[b], sv[b])
        u_new, v_new = su[(KA.STAGES - 1) % 2], sv[(KA.STAGES - 1) % 2]
        threads = block_threads(dev, CONTROL_BLOCK)
        self.launcher(
            KA.dp5_control, [m.pad_count], [km, dp5, threads, s.u, s.v, u_new, v_new], block_dim=CONTROL_BLOCK
        )
        self.launcher(KA.dp5_commit, n, [km, dp5, u_new, v_new, s.u, s.v])
