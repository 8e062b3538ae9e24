"""HF integrators: stable-step estimate and the launch wrappers of one fixed step.

Integrators (:data:`~aca_warp.hf.options.INTEGRATORS`):

* ``symplectic-euler``: explicit; v ← v + dt/m (F_s(u) + F_N f(ωr − v) − c v), u ← u + dt v. Its step is
  bounded by the spring network *and* the friction slope at zero sliding speed (:func:`stable_step`).
* ``implicit-friction``: IMEX Euler; the friction and damping act on the new velocity, solved per patch by
  safeguarded Newton (no global solve); only the spring network bounds the step. Its velocity step is the
  θ-method with θ = 1 (backward Euler) of :mod:`aca_warp.kernels.physics`, the per-patch solve that ``strang``
  takes with its own θ.
* ``strang``: second order; a Strang splitting of "spring force + friction + damping at fixed u" (a damped
  implicit midpoint per patch with the spring force frozen inside its solve) against the drift u̇ = v.
  Consecutive half steps are merged, so a step costs one spring evaluation and one implicit solve; between steps
  the velocity is staggered and synchronised for output. Only the spring network bounds its step
  (docs/numerics.md).
* ``adaptive``: per pad, the explicit Dormand–Prince 5(4) pair with its embedded error estimate in a
  friction-weighted norm and a PI step controller on the device (:mod:`aca_warp.hf.adaptive`); ``dt`` is its first
  trial step.
* ``controlled``: ``strang``'s step with its own step per pad from an error estimate of the springs' and the
  friction sub-step's local errors (:mod:`aca_warp.kernels.hf_controlled`); ``dt`` is its first trial step.
* ``auto``: per pad, ``adaptive`` while every patch slides and ``controlled`` once a patch sticks
  (:mod:`aca_warp.hf.adaptive`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import warp as wp

from aca_warp.common.devices import Kernels, load_kernels
from aca_warp.common.errors import SceneError, StabilityError, option
from aca_warp.common.launches import Launcher
from aca_warp.hf.model import PadModel, coupling_matrix
from aca_warp.hf.options import (
    DEFAULT_SPLIT_TOLERANCE,
    DEFAULT_TOLERANCE,
    INTEGRATORS,
    NEWTON_TOL,
    STEP_CONTROLLED,
    RunOptions,
    check_crossing,
    check_solve_tol,
    default_crossing,
    default_step,
    steps_per_event,
)
from aca_warp.hf.recorder import RECORD_BLOCK
from aca_warp.hf.state import HFState
from aca_warp.kernels import hf as K
from aca_warp.kernels import step_bound

FP32_MIN_TOLERANCE = 1.0e-5  # relative; tighter asks fp32 for more digits than it has
ADAPTIVE_FIRST_STEP = 1.0e-9  # s; the adaptive controller grows it by up to 5× per accepted step
CONTACT_BLOCK = 256  # threads per pad of the growth events' contact re-solve (Warp's default block size)


def growth_interval(model: PadModel) -> float:
    """The growth interval [s] of a growing model (the scenes' ``growth.interval``, over which each event adds the
    scene's increment), which all its growing pads share."""
    intervals = {s.growth.interval for s in model.scenes if s.growth is not None}
    if len(intervals) > 1:
        raise SceneError("all growing pads of a batch need the same growth.interval")
    return intervals.pop()


def event_spacing(model: PadModel, growth_dt: float | None) -> float:
    """The simulated time between growth events [s]: ``growth_dt`` (``RunOptions.growth_dt``), or the model's
    :func:`growth_interval` when None."""
    return growth_interval(model) if growth_dt is None else growth_dt


def growth_events(model: PadModel, h: float, growth_dt: float | None = None) -> tuple[int, wp.array]:
    """(steps per growth event, growth increment per event per pad [m], shape (pads,)) for step ``h`` [s].

    An event every round(spacing / h) steps (spacing: :func:`event_spacing`); the increment is scaled by
    (steps × h) / interval, so that growth per simulated time is the scene's whatever the spacing and the step
    (h = spacing = interval, the adaptive integrator's events at the event times: every step, unscaled).
    """
    interval = growth_interval(model)
    every = steps_per_event(event_spacing(model, growth_dt), h)
    scale = every * h / interval
    return every, wp.array(model.host("pad_growth") * scale, dtype=model.dtype, device=model.device)


# model arrays that growth events rewrite on the device (saved in checkpoints of growing runs)
GROWTH_MUTABLE = (
    "area",
    "sqrt_area",
    "inv_mass",
    "k_t",
    "k_n",
    "damping",
    "nbr_stiffness",
    "k_diag",
    "normal_force",
    "pad_matrix_force",
    "pad_matrix_radius",
    "pad_gap",
)


def grown_arrays(model: PadModel) -> dict[str, wp.array]:
    """The model arrays a checkpoint of a growing run holds, as ``model/NAME`` (:data:`GROWTH_MUTABLE`); empty for
    a model that does not grow."""
    if "pad_growth" not in model.arrays:
        return {}
    return {f"model/{k}": model.arrays[k] for k in GROWTH_MUTABLE}


@dataclass(frozen=True)
class StepEstimate:
    """Stable-step estimate of the explicit parts of the schemes [s].

    Attributes:
        spring: 2/ω_max with ω_max² bounded by Gershgorin on M^-1/2 K M^-1/2 (springs alone).
        friction: min 2 m_i / (c_i + F_N,i max|f'|) (friction slope at zero sliding speed, explicit).
        explicit: Largest h with h²ω_i² < 4 − 2hγ_i for every patch (symplectic Euler with explicit friction).

    The implicit per-patch friction solves of ``implicit-friction`` and ``strang`` bound nothing: ``strang``'s
    damped midpoint keeps a held patch's chatter decaying at any h γ (docs/numerics.md), so only ``spring`` bounds
    their step.
    """

    spring: float
    friction: float
    explicit: float

    def limit(self, integrator: str) -> float:
        """The bound that applies to ``integrator`` [s]: ``explicit`` for symplectic Euler, ``spring`` for every
        other scheme (and adaptive's largest step)."""
        if integrator == "symplectic-euler":
            return self.explicit
        return self.spring

    def as_dict(self) -> dict[str, float]:
        """The estimate as stored in run files (``stable_step`` attribute) [s]."""
        return {"spring": self.spring, "friction": self.friction, "explicit": self.explicit}


def stable_step(model: PadModel) -> StepEstimate:
    """Stable-step estimate from the model's current areas and normal forces (all pads)."""
    start, index, kij = coupling_matrix(model)
    m = 1.0 / model.host("inv_mass").astype(np.float64)
    load_kernels([step_bound], "cpu")
    ksum, off = step_bound.spring_row_sums(start, index, kij, m)  # Σ_j k_ij, Σ_j k_ij / √(m_i m_j) per row
    w2 = (model.host("k_t").astype(np.float64) + ksum) / m + off
    slope = np.array([s.friction.max_slope() for s in model.scenes])[model.host("patch_pad")]
    gamma = (model.host("damping").astype(np.float64) + model.host("normal_force").astype(np.float64) * slope) / m
    # (-γ + √(γ² + 4ω²)) / ω², written without cancellation or overflow of γ²
    h_explicit = 4.0 / (gamma + np.hypot(gamma, 2.0 * np.sqrt(w2)))
    friction = 2.0 / gamma.max() if gamma.max() > 0 else math.inf
    return StepEstimate(
        spring=float(2.0 / np.sqrt(w2.max())),
        friction=float(friction),
        explicit=float(h_explicit.min()),
    )


FRICTION_H_GAMMA = 4.0  # h γ_max of the friction step (friction_step)


def friction_step(estimate: StepEstimate) -> float:
    """The step [s] at which h γ_max = :data:`FRICTION_H_GAMMA` for a model's stable-step estimate (whose
    ``friction`` is 2/γ_max): the resolution of the fastest friction relaxation of its patches. No stability bound
    of ``strang`` depends on it."""
    return 0.5 * FRICTION_H_GAMMA * estimate.friction


def fitted_step(dt: float, sample_dt: float) -> float:
    """The fixed step a run takes: ``dt`` shortened so that a whole number of steps fits a sample interval [s]
    (the engines compute it the same way)."""
    return sample_dt / max(1, math.ceil(sample_dt / dt - 1e-9))


def step_problem(estimate: StepEstimate, integrator: str, h: float) -> tuple[str, str, str] | None:
    """What is wrong with the fixed step ``h`` [s] for ``integrator``, or None: beyond the explicit bound (symplectic
    Euler) or the springs' (every other scheme). Returns (the problem, what to do instead, what a forced run then
    risks), each in words."""
    limit = estimate.explicit if integrator == "symplectic-euler" else estimate.spring
    if h > limit:
        dt = option("dt", "--dt", "run.dt")
        if h <= estimate.spring:
            ways = [f"a smaller {dt}", "an implicit-friction integrator (strang, implicit-friction)"]
        else:
            adaptive = option("integrator='adaptive'", "--integrator adaptive", "run.integrator = 'adaptive'")
            ways = [f"a smaller {dt} (the springs bound every fixed-step scheme)", adaptive]
        force = option("force=True", "--force", "")  # (a sweep has no forced step)
        ways += [force] if force else []
        hint = f"choose {', '.join(ways[:-1])}{',' if len(ways) > 2 else ''} or {ways[-1]}"
        return (
            f"dt = {h:.3g} s exceeds the stable-step estimate {limit:.3g} s of {integrator} "
            f"(springs {estimate.spring:.3g} s, friction slope {estimate.friction:.3g} s)",
            hint,
            "the run may diverge (the watchdog then stops it) and mu is not accurate",
        )
    return None


def step_refusal(estimate: StepEstimate, integrator: str, h: float) -> None:
    """Raise :class:`StabilityError` when the fixed step ``h`` [s] exceeds what ``integrator`` allows
    (:func:`step_problem`)."""
    problem = step_problem(estimate, integrator, h)
    if problem is not None:
        raise StabilityError(f"{problem[0]}; {problem[1]}")


def check_step(model: PadModel, options: Any, sample_dt: float) -> StepEstimate:
    """Check a run's step before anything is written; returns the stable-step estimate.

    The bound is checked for the step the run takes (:func:`fitted_step`), not the one asked for. Beyond it a
    :class:`StabilityError` (exit 2), or with ``options.force`` a warning that says what the forced step risks
    (:func:`step_problem`: the explicit and spring bounds). Steps per sample interval and
    per growth event (adaptive: growth events of the run) are checked against int32 (the kernels count them so);
    ``options.growth_dt`` is refused for a model that does not grow, and warned of when no event falls in the run.
    ``options``: :class:`~aca_warp.hf.options.RunOptions`.
    """
    from aca_warp.hf.limits import check_int32
    from aca_warp.hf.sanity import warn

    solver = HFSolver.for_run(model, options, force=True)
    est = solver.estimate
    grows = any(scene.growth is not None for scene in model.scenes)
    if options.growth_dt is not None and not grows:
        raise SceneError(
            f"{option('growth_dt', '--growth-dt')} sets the spacing of growth events; the scene does not grow "
            "(it has no [growth] table)"
        )
    spacing = event_spacing(model, options.growth_dt) if grows else None
    if spacing is not None and options.duration is not None and spacing > options.duration:
        warn(
            f"growth events every {spacing:.3g} s and a run of {options.duration:.3g} s: no growth event in the run "
            f"(choose a smaller {option('growth_dt', '--growth-dt')})"
        )
    if options.integrator in STEP_CONTROLLED:  # their steps are not counted; their growth events are (the index)
        if spacing is not None and options.duration is not None:
            events = options.duration / spacing
            hint = f"choose a larger {option('growth_dt', '--growth-dt')} or a shorter run"
            check_int32("growth events of the run", events, hint)
        return est
    h = fitted_step(solver.dt, sample_dt)
    check_int32(
        "steps per sample interval",
        round(sample_dt / h),
        f"choose a larger {option('dt', '--dt')} or a smaller sample interval",
    )
    if spacing is not None:
        check_int32("steps per growth event", steps_per_event(spacing, h), f"choose a larger {option('dt', '--dt')}")
        if spacing < 0.5 * h:
            warn(
                f"growth events asked every {spacing:.3g} s, less than half the step ({h:.3g} s): one event per step, "
                f"every {h:.3g} s, each with the growth of that time"
            )
    if not options.force:
        step_refusal(est, options.integrator, h)
    else:
        problem = step_problem(est, options.integrator, h)
        if problem is not None:
            warn(f"{problem[0]}; running as forced: {problem[2]}")
    return est


class HFSolver:
    """Launch wrappers of one integrator for a model; ``step`` advances all pads by one fixed step.

    ``estimate``: the model's :func:`stable_step`, when the caller has it already (it reads every link of the batch).
    ``tolerance``: the explicit pair's (``adaptive``, ``auto``), ``split_tolerance`` the split step's (``controlled``,
    ``auto``). ``growth_dt``: the spacing of a growing model's events [s] (:func:`event_spacing`), which the engines
    read. ``crossing``: ``strang``'s treatment of steps that cross zero slip (:data:`~aca_warp.hf.options.CROSSINGS`;
    None: :func:`~aca_warp.hf.options.default_crossing` for the model's scenes).
    ``solve_tol``: the implicit friction solve's tolerance (None: :data:`~aca_warp.hf.options.NEWTON_TOL` of the
    model's precision).
    """

    def __init__(
        self,
        model: PadModel,
        integrator: str,
        dt: float | None,
        *,
        force: bool = False,
        tolerance: float = DEFAULT_TOLERANCE,
        split_tolerance: float = DEFAULT_SPLIT_TOLERANCE,
        estimate: StepEstimate | None = None,
        growth_dt: float | None = None,
        crossing: str | None = None,
        solve_tol: float | None = None,
    ) -> None:
        if integrator not in INTEGRATORS:
            raise SceneError(f"unknown integrator {integrator!r}; choose from {', '.join(INTEGRATORS)}")
        check_crossing(crossing, integrator)
        if dt is None:  # before the crossing treatment: a batch that mixes regimes is asked for its step first
            dt = ADAPTIVE_FIRST_STEP if integrator in STEP_CONTROLLED else default_step(integrator, model.scenes)
        if crossing is None:
            crossing = default_crossing(integrator, model.scenes)
        check_solve_tol(solve_tol, crossing)  # before the stable-step estimate, which reads every link
        self.crossing = int(crossing == "mean")  # the kernels' flag
        self._advance, self._sample, _, self._close = K.STRANG_KERNELS[self.crossing]
        self.model = model
        self.integrator = integrator
        self.estimate = stable_step(model) if estimate is None else estimate
        self.T = model.dtype
        self.newton_tol = self.T(NEWTON_TOL[model.precision] if solve_tol is None else solve_tol)
        for name, value in (("tolerance", tolerance), ("split_tolerance", split_tolerance)):
            if not (value > 0 and math.isfinite(value)):
                raise SceneError(f"{name} must be a positive number, got {value}")
        self.tolerance, self.split_tolerance = tolerance, split_tolerance
        self.growth_dt = growth_dt  # spacing of growth events [s]; None: the scenes' growth.interval
        if integrator in ("adaptive", "auto"):
            if self.T == wp.float32 and tolerance < FP32_MIN_TOLERANCE:
                fp64 = option("precision='fp64'", "--precision fp64")
                raise SceneError(
                    f"tolerance {tolerance:g} is below what fp32 state can resolve (>= {FP32_MIN_TOLERANCE:g}); "
                    f"use {fp64} or a looser tolerance"
                )
        self.dt = dt
        if not (self.dt > 0 and math.isfinite(self.dt)):
            raise SceneError(f"dt must be a positive number of seconds, got {self.dt}")
        if integrator not in STEP_CONTROLLED and not force:  # there dt is only the first trial
            step_refusal(self.estimate, integrator, self.dt)
        self.kernel_model = model.struct()  # the model's arrays as one kernel argument
        self._v_sample: wp.array | None = None  # a sample's velocities V (strang; :meth:`velocity`)
        self._w_next: wp.array | None = None  # and the next step's drift velocities w⁺
        self.launcher = Launcher(model.device)  # its launches packed once, replayed (on the CPU)

    @classmethod
    def for_run(
        cls, model: PadModel, options: RunOptions, estimate: StepEstimate | None = None, *, force: bool | None = None
    ) -> HFSolver:
        """The solver of a run with ``options``: its integrator, dt, tolerances, growth spacing and force
        (``force``, when given, in place of ``options.force``)."""
        return cls(
            model,
            options.integrator,
            options.dt,
            force=options.force if force is None else force,
            tolerance=options.tolerance,
            split_tolerance=options.split_tolerance,
            estimate=estimate,
            growth_dt=options.growth_dt,
            crossing=options.crossing,
            solve_tol=options.solve_tol,
        )

    def kernels(self, *, stepping: bool = True) -> list[Kernels]:
        """The kernels this solver and a recorder of its samples launch, to load before a run's first step
        (:func:`~aca_warp.common.devices.load_kernels`; a module loaded at its first launch would put its compile into
        the run's stepping time): the HF kernels and, with strang's crossing treatment, its kernels (each in a module
        of its own). ``stepping`` False: for the on-chip engines, whose own kernel steps and samples; of the
        treatment's kernels they launch only the closing one (:meth:`finish`)."""
        hf = [K, (K, RECORD_BLOCK)]  # the recorder's sums run in blocks of RECORD_BLOCK
        if not self.crossing:
            return hf
        advance, sample, record, close = K.STRANG_KERNELS[self.crossing]
        return [*hf, advance, sample, (record, RECORD_BLOCK), close] if stepping else [*hf, close]

    def _launch(self, kernel: Any, inputs: list, dim: int | None = None) -> None:
        self.launcher(kernel, self.model.patch_count if dim is None else dim, inputs)

    def prepare(self, state: HFState) -> None:
        """Fill the spring-force cache F_s(u) of a state (Strang and adaptive schemes)."""
        self._launch(K.spring_forces, [self.kernel_model, state.u, state.force])

    def step(self, state: HFState, dt: float, *, first: bool = False) -> None:
        """One fixed step of every pad (graph-capturable: two launches, no host reads).

        ``strang`` keeps a staggered velocity between steps: ``first`` opens from the synchronous state
        (forced friction sub-step over dt/2, drift), later steps are merged (sub-step over dt, drift), and
        :meth:`finish` closes back to the synchronous velocity; :meth:`velocity` gives a sample's at any step.
        """
        h = self.T(dt)
        if self.integrator in ("symplectic-euler", "implicit-friction"):
            implicit = int(self.integrator == "implicit-friction")
            self._launch(K.euler_velocity, [self.kernel_model, h, self.newton_tol, implicit, state.u, state.v])
            self._launch(K.drift, [h, state.v, state.u])
        elif self.integrator == "strang":
            args = [self.kernel_model, h, self.newton_tol, int(first), state.force, state.u, state.v]
            self._launch(self._advance, args)
            self.prepare(state)
        else:
            raise SceneError(f"the {self.integrator} integrator steps each pad on its own; use run_hf")

    def velocity(self, state: HFState, dt: float) -> wp.array:
        """The patch velocities [m/s] of a sample: for strang from the staggered state, the velocity V of the merged
        friction sub-step that the next step of ``dt`` opens with
        (:func:`~aca_warp.kernels.physics.strang_sample_velocity`; that sub-step's w⁺ in :attr:`next_drift`), without
        changing the state."""
        if self.integrator != "strang":
            return state.v
        if self._v_sample is None:
            self._v_sample, self._w_next = wp.zeros_like(state.v), wp.zeros_like(state.v)
        args = [self.kernel_model, self.T(dt), self.newton_tol, state.force, state.v, self._v_sample, self._w_next]
        self._launch(self._sample, args)
        return self._v_sample

    @property
    def next_drift(self) -> wp.array | None:
        """The drift velocities w⁺ [m/s] of the merged sub-step of the last :meth:`velocity` (None before one)."""
        return self._w_next

    def finish(self, state: HFState, dt: float) -> None:
        """Bring a staggered strang state back to synchronous velocities by the closing half sub-step
        (:func:`~aca_warp.kernels.physics.strang_close_velocity`; no-op for other schemes): a later run that continues
        from it parts from one long run by O(dt³) per restart, where from a sample's velocity (:meth:`velocity`, a
        backward-Euler half step) it would by O(dt²)."""
        if self.integrator == "strang":
            args = [self.kernel_model, self.T(dt), self.newton_tol, state.force, state.v, state.v]
            self._launch(self._close, args)
