"""HF solver: integrators, stable-step estimate, step control, recording and the run loop.

Integrators (``--integrator``):

* ``symplectic-euler``: explicit; v ← v + dt/m (F_s(u) + F_N f(ωr − v) − c v), u ← u + dt v. Its step is
  bounded by the spring network *and* the friction slope at zero sliding speed (:func:`stable_step`).
* ``implicit-friction``: IMEX Euler; the friction and damping act on the new velocity, solved per patch by
  safeguarded Newton (no global solve); only the spring network bounds the step.
* ``strang``: second order; Strang splitting of friction/damping (implicit midpoint, per patch) and the
  springs (velocity Verlet). Consecutive friction half steps are merged, so a step costs one spring
  evaluation and one implicit solve; between steps the velocity is staggered and synchronised for output.
* ``adaptive``: ``strang`` with the embedded IMEX-Euler step as error estimate; the controller (accept,
  reject, next step, landing on sample times) runs on the device, in the captured graph.

Every stepping path is captured in a Warp graph (CPU and CUDA) and replayed; the host reads back only a
few counters per replay to flush recorded samples and watch for faults.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import warp as wp

from aca_warp.common.checkpoint import Checkpoint
from aca_warp.common.errors import SceneError, SimulationFault, StabilityError
from aca_warp.hf.model import PadModel, coupling_matrix
from aca_warp.hf.state import HFState
from aca_warp.kernels import hf as K
from aca_warp.scene import Record

INTEGRATORS = ("symplectic-euler", "implicit-friction", "strang", "adaptive")
DEFAULT_INTEGRATOR = "strang"
DEFAULT_DT = 1.0e-8  # s
DEFAULT_TOLERANCE = 1.0e-4
FP32_MIN_TOLERANCE = 1.0e-5  # relative; tighter asks fp32 for more digits than it has
GLOBAL_NAMES = ("mu", "torque", "friction_radius", "sum_velocity", "sum_abs_velocity")
GLOBAL_UNITS = ("1", "N m", "m", "m s-1", "m s-1")
WATCHDOG_FACTOR = 100.0  # watchdog bound = this × the scene's velocity scale (:func:`watchdog_bound`)
CONTACT_BLOCK = 256  # threads per pad of the growth events' contact re-solve (Warp's default block size)


def growth_events(model: PadModel, h: float) -> tuple[int, wp.array]:
    """(steps per growth event, growth increment per event per pad [m], shape (pads,)) for step ``h`` [s].

    An event every round(interval / h) steps; the increment is scaled so that growth per simulated time is exact.
    """
    intervals = {s.growth.interval for s in model.scenes if s.growth is not None}
    if len(intervals) > 1:
        raise SceneError("all growing pads of a batch need the same growth.interval")
    interval = intervals.pop()
    every = max(1, round(interval / h))
    scale = every * h / interval
    return every, wp.array(model.host("pad_growth") * scale, dtype=model.dtype, device=model.device)


def block_threads(device: wp.Device, block_dim: int) -> int:
    """Threads a ``launch_tiled`` block of ``block_dim`` really runs: all on CUDA and with Warp's CPU fibers
    (``wp.config.enable_cpu_blocks``), else one (a CPU block is one thread)."""
    return block_dim if device.is_cuda or wp.config.enable_cpu_blocks else 1


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


@dataclass(frozen=True)
class StepEstimate:
    """Stable-step estimate of the explicit parts of the schemes [s].

    Attributes:
        spring: 2/ω_max with ω_max² bounded by Gershgorin on M^-1/2 K M^-1/2 (springs alone).
        friction: min 2 m_i / (c_i + F_N,i max|f'|) (friction slope at zero sliding speed, explicit).
        explicit: Largest h with h²ω_i² < 4 − 2hγ_i for every patch (symplectic Euler with explicit friction).
    """

    spring: float
    friction: float
    explicit: float

    def limit(self, integrator: str) -> float:
        """The bound that applies to ``integrator`` [s]."""
        return self.explicit if integrator == "symplectic-euler" else self.spring


def stable_step(model: PadModel) -> StepEstimate:
    """Stable-step estimate from the model's current areas and normal forces (all pads)."""
    start, index, kij = coupling_matrix(model)
    n = model.patch_count
    m = 1.0 / model.host("inv_mass").astype(np.float64)
    rows = np.repeat(np.arange(n), np.diff(start))
    ksum = np.bincount(rows, kij, minlength=n)
    off = np.bincount(rows, kij / np.sqrt(m[rows] * m[index]), minlength=n) if len(kij) else np.zeros(n)
    w2 = (model.host("k_t").astype(np.float64) + ksum) / m + off
    slope = np.array([s.friction.max_slope() for s in model.scenes])[model.host("patch_pad")]
    gamma = (model.host("damping").astype(np.float64) + model.host("normal_force").astype(np.float64) * slope) / m
    # (-γ + √(γ² + 4ω²)) / ω², written without cancellation or overflow of γ²
    h_explicit = 4.0 / (gamma + np.hypot(gamma, 2.0 * np.sqrt(w2)))
    friction = 2.0 / gamma.max() if gamma.max() > 0 else math.inf
    return StepEstimate(
        spring=float(2.0 / np.sqrt(w2.max())), friction=float(friction), explicit=float(h_explicit.min())
    )


def watchdog_bound(model: PadModel, state: HFState, factor: float = WATCHDOG_FACTOR) -> np.ndarray:
    """Per-pad bound on the patch energy speed s_i = √(u̇_i² + (k_T,i/m_i) u_i²) [m/s], shape (pads,).

    B = max_i ω r_i + 3 max_i F_N,i M / √(k_T,i m_i) + 3 √(2 E₀ / m_min), bound = ``factor`` × B. The first
    term is the disc speed (friction feeds energy only while 0 < u̇ < ω r); the second the speed of a patch
    released from its largest static deflection F_N M / k_T under the largest friction force (|f| ≤ M); the
    third the initial energy E₀ = Σ ½ m u̇₀² + ½ k_T u₀² concentrated in the lightest patch. Bounded runs stay
    within about B (tests/test_extreme.py asserts |u̇| < B over its whole table); an unstable step grows
    exponentially and crosses ``factor`` × B within a few dozen e-foldings, before it turns non-finite. A pad
    with no load, no disc speed and no initial energy cannot move: its bound is +inf (only the non-finite check).
    """
    m = 1.0 / model.host("inv_mass").astype(np.float64)
    k = model.host("k_t").astype(np.float64)
    fn = model.host("normal_force").astype(np.float64)
    r = model.host("radius").astype(np.float64)
    u0, v0 = (a.astype(np.float64) for a in state.numpy())
    out = np.empty(model.pad_count)
    for p, s in enumerate(model.scenes):
        a, b = (int(x) for x in model.pad_patch_start_host[p : p + 2])
        e0 = 0.5 * float(np.sum(m[a:b] * v0[a:b] ** 2 + k[a:b] * u0[a:b] ** 2))
        scale = (
            float(np.max(np.abs(s.angular_velocity * r[a:b])))
            + 3.0 * float(np.max(fn[a:b] * s.friction.M / np.sqrt(k[a:b] * m[a:b])))
            + 3.0 * math.sqrt(2.0 * e0 / float(m[a:b].min()))
        )
        out[p] = factor * scale if scale > 0 and math.isfinite(scale) else math.inf
    return out


@dataclass
class Chunk:
    """Samples recorded since the previous flush.

    Attributes:
        time: Sample times [s], shape (rows,).
        globals: Global outputs per sample and pad, shape (rows, pads, 5), order of ``GLOBAL_NAMES``.
        patch_time: Times of the per-patch samples [s], shape (prows,).
        velocity: Patch velocities [m/s], shape (prows, patch_count), or None.
        displacement: Patch displacements [m], shape (prows, patch_count), or None.
    """

    time: np.ndarray
    globals: np.ndarray
    patch_time: np.ndarray
    velocity: np.ndarray | None
    displacement: np.ndarray | None

    def before(self, t: float) -> Chunk:
        """The samples taken before time ``t`` [s] (a fault's samples and those after it dropped)."""
        keep, pkeep = self.time < t, self.patch_time < t
        return Chunk(
            self.time[keep],
            self.globals[keep],
            self.patch_time[pkeep],
            None if self.velocity is None else self.velocity[pkeep],
            None if self.displacement is None else self.displacement[pkeep],
        )


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

    def collect(self) -> Chunk:
        """All recorded chunks joined into one."""
        c = self.chunks

        def cat(name: str) -> np.ndarray | None:
            parts = [getattr(x, name) for x in c if getattr(x, name) is not None]
            return np.concatenate(parts) if parts else None

        return Chunk(cat("time"), cat("globals"), cat("patch_time"), cat("velocity"), cat("displacement"))


class HFSolver:
    """Launch wrappers of one integrator for a model; ``step`` advances all pads by one fixed step."""

    def __init__(
        self,
        model: PadModel,
        integrator: str,
        dt: float | None,
        *,
        force: bool = False,
        tolerance: float = DEFAULT_TOLERANCE,
    ) -> None:
        if integrator not in INTEGRATORS:
            raise SceneError(f"unknown integrator {integrator!r}; choose from {', '.join(INTEGRATORS)}")
        self.model = model
        self.integrator = integrator
        self.estimate = stable_step(model)
        self.T = model.dtype
        self.newton_tol = self.T(1.0e-6 if self.T == wp.float32 else 1.0e-9)  # of the velocity increment
        if integrator == "adaptive":
            if not (tolerance > 0 and math.isfinite(tolerance)):
                raise SceneError(f"tolerance must be a positive number, got {tolerance}")
            if self.T == wp.float32 and tolerance < FP32_MIN_TOLERANCE:
                raise SceneError(
                    f"tolerance {tolerance:g} is below what fp32 state can resolve (>= {FP32_MIN_TOLERANCE:g}); "
                    "use --precision fp64 or a looser tolerance"
                )
            self.tolerance = tolerance
            self.dt = min(dt or 1.0e-9, 0.9 * self.estimate.spring)
        else:
            self.dt = DEFAULT_DT if dt is None else dt
            if not (self.dt > 0 and math.isfinite(self.dt)):
                raise SceneError(f"dt must be a positive number of seconds, got {self.dt}")
            limit = self.estimate.limit(integrator)
            if self.dt > limit and not force:
                hint = (
                    "choose a smaller --dt, an implicit-friction integrator (strang, implicit-friction), or --force"
                    if self.dt <= self.estimate.spring
                    else "choose a smaller --dt (the springs bound every fixed-step scheme), --integrator adaptive, "
                    "or --force"
                )
                raise StabilityError(
                    f"dt = {self.dt:.3g} s exceeds the stable-step estimate {limit:.3g} s of {integrator} "
                    f"(springs {self.estimate.spring:.3g} s, friction slope {self.estimate.friction:.3g} s); {hint}"
                )
        m = model
        self._model_args = [
            m.patch_pad,
            m.inv_mass,
            m.k_diag,
            m.damping,
            m.normal_force,
            m.radius,
            m.nbr_start,
            m.nbr_index,
            m.nbr_stiffness,
            m.pad_omega,
            m.pad_mu_scale,
            m.pad_slope,
            m.pad_decay,
        ]
        self._local_args = [
            m.patch_pad,
            m.inv_mass,
            m.damping,
            m.normal_force,
            m.radius,
            m.pad_omega,
            m.pad_mu_scale,
            m.pad_slope,
            m.pad_decay,
        ]
        self._v_sync: wp.array | None = None

    def _launch(self, kernel: Any, inputs: list, dim: int | None = None) -> None:
        wp.launch(kernel, dim=self.model.patch_count if dim is None else dim, inputs=inputs, device=self.model.device)

    def prepare(self, state: HFState) -> None:
        """Fill the spring-force cache F_s(u) of a state (Strang and adaptive schemes)."""
        m = self.model
        self._launch(K.spring_forces, [m.k_diag, m.nbr_start, m.nbr_index, m.nbr_stiffness, state.u, state.force])

    def step(self, state: HFState, dt: float, *, first: bool = False) -> None:
        """One fixed step of every pad (graph-capturable: two launches, no host reads).

        ``strang`` keeps a staggered velocity between steps: ``first`` opens from the synchronous state
        (friction dt/2, kick, drift), later steps are merged (kick, friction dt, kick, drift), and
        :meth:`finish` closes back to the synchronous velocity; :meth:`velocity` gives it at any step.
        """
        h = self.T(dt)
        if self.integrator == "symplectic-euler":
            self._launch(K.euler_velocity, [*self._model_args, h, state.u, state.v])
            self._launch(K.drift, [h, state.v, state.u])
        elif self.integrator == "implicit-friction":
            self._launch(K.implicit_velocity, [*self._model_args, h, self.newton_tol, state.u, state.v])
            self._launch(K.drift, [h, state.v, state.u])
        elif self.integrator == "strang":
            kernel = K.strang_open if first else K.strang_step
            self._launch(kernel, [*self._local_args, h, self.newton_tol, state.force, state.u, state.v])
            self.prepare(state)
        else:
            raise SceneError("the adaptive integrator has no fixed step; use run_hf")

    def velocity(self, state: HFState, dt: float) -> wp.array:
        """The synchronous patch velocities [m/s] (for strang computed from the staggered state)."""
        if self.integrator != "strang":
            return state.v
        if self._v_sync is None:
            self._v_sync = wp.zeros_like(state.v)
        self._launch(
            K.strang_close, [*self._local_args, self.T(dt), self.newton_tol, state.force, state.v, self._v_sync]
        )
        return self._v_sync

    def finish(self, state: HFState, dt: float) -> None:
        """Bring a staggered strang state back to synchronous velocities (no-op for other schemes)."""
        if self.integrator == "strang":
            self._launch(
                K.strang_close, [*self._local_args, self.T(dt), self.newton_tol, state.force, state.v, state.v]
            )


class _Recorder:
    """Device buffers and launches for the global outputs and per-patch histories."""

    def __init__(self, model: PadModel, record: Record, rows: int, n_samples: int) -> None:
        self.model = model
        self.record = record
        dev, T = model.device, model.dtype
        self.sample_dt = record.sample_dt
        k0 = math.ceil(record.window[0] / record.sample_dt - 1e-9)
        k1 = record.window[1] / record.sample_dt + 1e-9
        self.first = int(k0)
        self.last = int(min(k1, n_samples, 2**31 - 2))
        self.every = record.decimation
        self.want_v = "velocity" in record.patches and self.first <= self.last
        self.want_u = "displacement" in record.patches and self.first <= self.last
        if not (self.want_v or self.want_u):
            self.first, self.last = 0, -1  # no sample is due
        prow = rows if (self.want_v or self.want_u) else 0
        n = model.patch_count if prow else 0
        self.counters = wp.zeros(4, dtype=wp.int32, device=dev)
        self.globals = wp.zeros((rows, model.pad_count, K.N_GLOBAL), dtype=wp.float64, device=dev)
        # watchdog: [patch, sample, kind] of the first fault per pad (kind 0 non-finite, 1 beyond watch_bound)
        table = np.full((model.pad_count, 3), -1, np.int32)
        table[:, 2] = 0
        self.fault = wp.array(table, dtype=wp.int32, device=dev)
        self.fault_value = wp.zeros(model.pad_count, dtype=wp.float64, device=dev)
        self.watch_bound = wp.array(np.full(model.pad_count, np.inf), dtype=wp.float64, device=dev)
        self.velocity = wp.zeros((prow, n), dtype=T, device=dev)
        self.displacement = wp.zeros((prow if self.want_u else 0, n), dtype=T, device=dev)
        self.sample_index = 0

    @property
    def patch_stage(self) -> bool:
        """Whether per-patch histories are recorded at all."""
        return self.want_v or self.want_u

    def launch(self, u: wp.array, v: wp.array, conditional: bool) -> None:
        """Record one sample of (u, u̇) (conditional: only when the adaptive controller landed on a sample)."""
        m, c = self.model, int(conditional)
        wp.launch(
            K.record_globals,
            dim=m.pad_count,
            device=m.device,
            inputs=[
                m.pad_patch_start,
                m.normal_force,
                m.radius,
                m.pad_omega,
                m.pad_mu_scale,
                m.pad_slope,
                m.pad_decay,
                m.pad_mu_pad,
                m.pad_load,
                m.pad_matrix_force,
                m.pad_matrix_radius,
                m.inv_mass,
                m.k_t,
                c,
                u,
                v,
                self.counters,
                self.globals,
                self.watch_bound,
                self.fault,
                self.fault_value,
            ],
        )
        if self.patch_stage:
            wp.launch(
                K.record_patches,
                dim=m.patch_count,
                device=m.device,
                inputs=[self.first, self.last, self.every, c, u, v, self.counters, self.velocity, self.displacement],
            )
        wp.launch(
            K.advance_counters, dim=1, device=m.device, inputs=[self.first, self.last, self.every, c, self.counters]
        )

    def flush(self) -> tuple[Chunk, np.ndarray]:
        """Copy the recorded rows to the host and reset the buffers; returns the chunk and the fault table."""
        c = self.counters.numpy()
        rows, prows = int(c[1]), int(c[2])
        k = np.arange(self.sample_index, self.sample_index + rows)
        due = (k >= self.first) & (k <= self.last) & ((k - self.first) % self.every == 0)
        assert int(due.sum()) == prows, "per-patch rows out of step with the sample counter"
        chunk = Chunk(
            time=k * self.sample_dt,
            globals=self.globals.numpy()[:rows].copy(),
            patch_time=k[due] * self.sample_dt,
            velocity=self.velocity.numpy()[:prows].copy() if self.want_v else None,
            displacement=self.displacement.numpy()[:prows].copy() if self.want_u else None,
        )
        self.sample_index += rows
        c[1] = c[2] = 0
        wp.copy(self.counters, wp.array(c, dtype=wp.int32, device=self.model.device))
        return chunk, self.fault.numpy()


def _fault_from(
    table: np.ndarray,
    model: PadModel,
    sample_dt: float,
    cause: str,
    values: np.ndarray | None = None,
    bounds: np.ndarray | None = None,
) -> SimulationFault | None:
    """The earliest fault of the watchdog table (pads, 2 or 3): [patch, sample, kind]; None when there is none."""
    bad = np.flatnonzero(table[:, 0] >= 0)
    if len(bad) == 0:
        return None
    pad = int(bad[np.argmin(table[bad, 1])])
    patch, k = int(table[pad, 0]), int(table[pad, 1])
    kind = int(table[pad, 2]) if table.shape[1] > 2 else 0
    t = k * sample_dt
    if kind == 1:
        what = (
            f"diverging state (patch energy speed {values[pad]:.3g} m/s beyond the watchdog bound "
            f"{bounds[pad]:.3g} m/s; stopped before it turns non-finite)"
            if values is not None and bounds is not None
            else "diverging state (beyond the watchdog bound)"
        )
    else:
        what = "non-finite state"
    return SimulationFault(
        f"{what} at t <= {t:.6g} s (sample {k}, between {max(t - sample_dt, 0):.6g} and {t:.6g} s), "
        f"pad {pad}, patch {patch}; likely cause: {cause}",
        time=t,
        pad=pad,
        patch=patch,
        cause=cause,
    )


def _restore(saved: dict[str, wp.array], ckpt: Checkpoint) -> None:
    """Copy a checkpoint's arrays into the run's device arrays (names, shapes and dtypes must match)."""
    missing = sorted(set(saved) - set(ckpt.arrays))
    extra = sorted(set(ckpt.arrays) - set(saved))
    if missing or extra:
        raise SceneError(
            f"the checkpoint does not fit this run (missing {', '.join(missing) or 'nothing'}, "
            f"unexpected {', '.join(extra) or 'nothing'}): another integrator or scene?"
        )
    for name, arr in saved.items():
        data = ckpt.arrays[name]
        want = np.dtype(wp.dtype_to_numpy(arr.dtype))
        if data.shape != arr.shape or data.dtype != want:
            raise SceneError(
                f"checkpoint array {name} has shape {data.shape} and dtype {data.dtype}, the run needs {arr.shape} "
                f"{want}: another scene or precision?"
            )
        arr.assign(data)


def check_run(duration: float, record: Record, checkpoint_every: float | None = None) -> int:
    """Validate a run's duration [s], sample interval and checkpoint interval [s]; returns the number of samples."""
    if not (duration > 0 and math.isfinite(duration)):
        raise SceneError(f"duration must be a positive number of seconds, got {duration}")
    if record.sample_dt > duration * (1 + 1e-12):
        raise SceneError(f"sample interval {record.sample_dt:g} s exceeds the duration {duration:g} s")
    if checkpoint_every is not None and not (checkpoint_every > 0 and math.isfinite(checkpoint_every)):
        raise SceneError(f"checkpoint interval must be a positive number of seconds, got {checkpoint_every}")
    n_samples = max(1, round(duration / record.sample_dt))
    if n_samples > 2**31 - 2:  # the recorder counts samples in int32
        raise SceneError(
            f"{duration:g} s at a sample interval of {record.sample_dt:g} s is {n_samples:.3g} samples, more than "
            f"a run records (2^31 - 2); use a larger sample interval"
        )
    return n_samples


def run_hf(
    model: PadModel,
    state: HFState,
    *,
    duration: float,
    integrator: str = DEFAULT_INTEGRATOR,
    dt: float | None = None,
    tolerance: float = DEFAULT_TOLERANCE,
    force: bool = False,
    record: Record | None = None,
    sink: Callable[[Chunk], None] | None = None,
    progress: bool = False,
    use_graph: bool = True,
    max_graph_steps: int = 256,
    checkpoint_every: float | None = None,
    on_checkpoint: Callable[[Checkpoint], None] | None = None,
    resume: Checkpoint | None = None,
    watchdog_factor: float | None = WATCHDOG_FACTOR,
) -> RunResult:
    """Advance all pads of ``model`` from ``state`` for ``duration`` [s], recording as ``record`` says.

    Fixed-step schemes take ``dt`` (shortened so that a whole number of steps fits a sample interval);
    ``adaptive`` takes ``tolerance`` (relative, per patch, against the displacement and velocity scales).
    Samples go to ``sink`` (or into the result's ``chunks``) after every graph replay. A non-finite value
    stops the run: the result carries the fault and everything recorded before it.

    Watchdog: at every sample the recording kernel also flags a patch whose energy speed exceeds
    :func:`watchdog_bound` (``watchdog_factor`` × the scene's velocity scale; None: non-finite check only);
    the host reads the flags with the samples, at chunk ends. Checkpoints: with ``checkpoint_every`` [s of
    simulated time] and ``on_checkpoint``, the first chunk end at or past each multiple of it hands a
    :class:`~aca_warp.common.checkpoint.Checkpoint` to ``on_checkpoint`` (device reads only then). ``resume`` (a
    checkpoint of the same scene, integrator, step policy, device and precision) continues from it: the rest
    of the run is the same arithmetic in the same order, so the samples equal an uninterrupted run's bit for bit.
    """
    t_compile = time.perf_counter()
    record = record or model.scenes[0].record
    n_samples = check_run(duration, record, checkpoint_every)
    solver = HFSolver(model, integrator, dt, force=force, tolerance=tolerance)
    growth = "pad_growth" in model.arrays
    if growth and integrator == "adaptive":
        raise SceneError("patch growth needs a fixed-step integrator (growth events are counted in steps)")
    adaptive = integrator == "adaptive"
    sps = 1 if adaptive else max(1, math.ceil(record.sample_dt / solver.dt - 1e-9))
    h = record.sample_dt / sps
    block = 1 if adaptive else max(1, min(n_samples, max_graph_steps // sps))
    rows = 256 if adaptive else block
    rec = _Recorder(model, record, rows + 1, n_samples)
    off = watchdog_factor is None
    bounds = np.full(model.pad_count, np.inf) if off else watchdog_bound(model, state, watchdog_factor)
    rec.watch_bound.assign(bounds)
    dev = model.device
    stages = [
        "contact",
        "neighbours" if model.has_coupling else "no-coupling",
        f"step:{integrator}",
        "record:globals",
    ] + (["record:patches"] if rec.patch_stage else [])
    out: list[Chunk] = []
    emit = sink or out.append
    cause = (
        f"step {h:.3g} s beyond the stable estimate {solver.estimate.limit(integrator):.3g} s"
        if h > solver.estimate.limit(integrator)
        else "extreme scene parameters (check loads, areas, speeds)"
    )

    if integrator in ("strang", "adaptive"):
        solver.prepare(state)
    started = False
    growth_every, step_counter = 0, None
    if growth:
        stages.append("growth")
        growth_every, growth_per_event = growth_events(model, h)
        step_counter = wp.zeros(1, dtype=wp.int64, device=dev)

    def grow() -> None:
        m = model
        wp.launch(
            K.grow_patches,
            dim=m.patch_count,
            device=dev,
            inputs=[
                step_counter,
                growth_every,
                m.patch_pad,
                growth_per_event,
                m.pad_k_t,
                m.pad_k_n,
                m.pad_mass_per_area,
                m.pad_zeta,
                m.area,
                m.sqrt_area,
                m.inv_mass,
                m.k_t,
                m.k_n,
                m.damping,
            ],
        )
        wp.launch(
            K.coupling_stiffness,
            dim=m.patch_count,
            device=dev,
            inputs=[
                step_counter,
                growth_every,
                m.patch_pad,
                m.sqrt_area,
                m.nbr_start,
                m.nbr_index,
                m.nbr_inv_dist,
                m.pad_kc,
                m.k_t,
                m.nbr_stiffness,
                m.k_diag,
            ],
        )
        wp.launch_tiled(
            K.contact_flat,
            dim=[m.pad_count],
            block_dim=CONTACT_BLOCK,
            device=dev,
            inputs=[
                step_counter,
                growth_every,
                block_threads(dev, CONTACT_BLOCK),
                m.pad_patch_start,
                m.k_n,
                m.height,
                m.area,
                m.radius,
                m.pad_area,
                m.pad_moment,
                m.pad_k_m,
                m.pad_load,
                m.pad_gap,
                m.normal_force,
                m.pad_matrix_force,
                m.pad_matrix_radius,
            ],
        )
        wp.launch(K.tick, dim=1, device=dev, inputs=[step_counter])

    if adaptive:
        T = model.dtype
        n = model.patch_count
        trial = {k: wp.zeros(n, dtype=T, device=dev) for k in ("u", "v", "ue", "ve", "f")}
        clock = wp.array([0.0, solver.dt, solver.dt, record.sample_dt], dtype=wp.float64, device=dev)
        flags = wp.zeros(3, dtype=wp.int32, device=dev)
        steps_arr = wp.zeros(2, dtype=wp.int64, device=dev)
        err = wp.zeros(1, dtype=wp.float64, device=dev)
        t_end = n_samples * record.sample_dt
        dt_max = 0.9 * solver.estimate.spring

        def body() -> None:
            m = model
            rt = T(solver.tolerance)
            wp.launch(
                K.adaptive_trial_open,
                dim=n,
                device=dev,
                inputs=[
                    *solver._local_args,
                    solver.newton_tol,
                    clock,
                    flags,
                    state.u,
                    state.v,
                    state.force,
                    trial["u"],
                    trial["v"],
                    trial["ue"],
                    trial["ve"],
                ],
            )
            wp.launch(
                K.adaptive_trial_close,
                dim=n,
                device=dev,
                inputs=[
                    *solver._model_args,
                    solver.newton_tol,
                    rt,
                    clock,
                    flags,
                    trial["u"],
                    trial["v"],
                    trial["ue"],
                    trial["ve"],
                    trial["f"],
                    err,
                ],
            )
            wp.launch(
                K.adaptive_control,
                dim=1,
                device=dev,
                inputs=[
                    wp.float64(record.sample_dt),
                    wp.float64(t_end),
                    wp.float64(1.0e-15),
                    wp.float64(dt_max),
                    clock,
                    flags,
                    steps_arr,
                    err,
                    rec.counters,
                ],
            )
            wp.launch(
                K.adaptive_commit,
                dim=n,
                device=dev,
                inputs=[flags, trial["u"], trial["v"], trial["f"], state.u, state.v, state.force],
            )
            rec.launch(state.u, state.v, conditional=True)
            del m
    else:

        def body() -> None:
            nonlocal started
            for _ in range(sps):
                solver.step(state, h, first=not started)
                started = True
                if growth:
                    grow()
            rec.launch(state.u, solver.velocity(state, h), conditional=False)

    graphs: dict[int, Any] = {}
    capture_time = 0.0

    def replay(reps: int) -> None:
        if not use_graph:
            for _ in range(reps):
                body()
            return
        if not started:  # the opening step differs from the rest: run the first block eagerly
            body()
            reps -= 1
            if reps == 0:
                return
        if reps not in graphs:
            nonlocal capture_time
            tc = time.perf_counter()
            with wp.ScopedCapture(device=dev, force_module_load=True) as cap:
                for _ in range(reps):
                    body()
            graphs[reps] = cap.graph
            capture_time += time.perf_counter() - tc
        wp.capture_launch(graphs[reps])

    saved: dict[str, wp.array] = {
        "state/u": state.u,
        "state/v": state.v,
        "state/force": state.force,
        "recorder/counters": rec.counters,
        "watchdog/bound": rec.watch_bound,
    }
    if adaptive:
        saved.update({"adaptive/clock": clock, "adaptive/flags": flags, "adaptive/steps": steps_arr})
    if growth:
        saved["growth/step"] = step_counter
        saved.update({f"model/{k}": model.arrays[k] for k in GROWTH_MUTABLE})
    if resume is not None:
        _restore(saved, resume)
        started = bool(resume.counters.get("started", 0))
        rec.sample_index = int(resume.counters["sample_index"])
        bounds = rec.watch_bound.numpy()
    else:
        rec.launch(state.u, state.v, conditional=False)  # sample 0: the initial state
    wp.load_module(K, device=dev)
    compile_time = time.perf_counter() - t_compile
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(
            total=n_samples * record.sample_dt,
            unit="s",
            unit_scale=True,
            dynamic_ncols=True,
            bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} s simulated [{elapsed}<{remaining}{postfix}]",
        )
    t0 = time.perf_counter()
    fault: SimulationFault | None = None
    done_samples, steps, rejected, sim_t = 0, 0, 0, 0.0
    if resume is not None:
        c = resume.counters
        done_samples, steps, rejected, sim_t = int(c["samples"]), int(c["steps"]), int(c["rejected"]), resume.sim_time
        if bar is not None:
            bar.update(sim_t)
    next_checkpoint = math.inf
    if checkpoint_every is not None and on_checkpoint is not None:
        next_checkpoint = (math.floor(sim_t / checkpoint_every) + 1) * checkpoint_every
    iters = 128
    try:
        while True:
            if adaptive:
                replay(iters)
                fl = flags.numpy()
                done = bool(fl[1])
                st = steps_arr.numpy()
                steps, rejected = int(st[0]), int(st[1])
                sim_t = float(clock.numpy()[0])
            else:
                reps = min(block, n_samples - done_samples)
                replay(reps)
                done_samples += reps
                steps = done_samples * sps
                sim_t = done_samples * record.sample_dt
                done = done_samples >= n_samples
            chunk, table = rec.flush()
            fault = _fault_from(table, model, record.sample_dt, cause, rec.fault_value.numpy(), bounds)
            if adaptive and fault is None and fl[2]:
                fault = SimulationFault(
                    f"adaptive step fell below 1e-15 s at t = {sim_t:.6g} s; likely cause: {cause}",
                    time=sim_t,
                    pad=-1,
                    patch=-1,
                    cause="step-size underflow",
                )
            if fault is not None:
                chunk = chunk.before(fault.time - 0.5 * record.sample_dt)
            emit(chunk)
            if bar is not None:
                bar.update(sim_t - bar.n)
                el = time.perf_counter() - t0
                bar.set_postfix_str(f"{steps / max(el, 1e-9):.3g} steps/s")
            if fault is None and not done and sim_t >= next_checkpoint * (1 - 1e-12):
                on_checkpoint(  # type: ignore[misc]
                    Checkpoint(
                        sim_time=sim_t,
                        arrays={k: a.numpy().copy() for k, a in saved.items()},
                        counters={
                            "samples": done_samples,
                            "steps": steps,
                            "rejected": rejected,
                            "started": int(started),
                            "sample_index": rec.sample_index,
                        },
                    )
                )
                next_checkpoint = (math.floor(sim_t / checkpoint_every) + 1) * checkpoint_every  # type: ignore[operator]
            if fault is not None or done:
                break
    finally:
        if bar is not None:
            bar.close()
        if not adaptive and started:
            solver.finish(state, h)
    wp.synchronize_device(dev)
    wall = time.perf_counter() - t0 - capture_time
    return RunResult(
        complete=fault is None,
        fault=fault,
        steps=steps,
        rejected=rejected,
        sim_time=sim_t,
        wall_time=wall,
        compile_time=compile_time + capture_time,
        dt=float(clock.numpy()[2]) if adaptive else h,
        estimate=solver.estimate,
        stages=stages,
        chunks=out,
    )
