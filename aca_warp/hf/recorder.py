"""Recording of an HF run: the global outputs and per-patch histories on the device, flushed in chunks; the watchdog.

Every engine records through one :class:`Recorder`: device buffers of the global outputs (μ, torque, friction
radius, Σu̇, Σ|u̇|) per sample and pad, per-patch histories over the scene's window, a sample counter, and the
watchdog's fault table (the first non-finite or diverging patch per pad). The run loop flushes them to the host
at chunk ends (:mod:`aca_warp.hf.loop`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import warp as wp

from aca_warp.common.devices import block_threads
from aca_warp.common.errors import SceneError, SimulationFault, option
from aca_warp.common.launches import Launcher
from aca_warp.hf.limits import check_int32
from aca_warp.hf.model import PadModel
from aca_warp.hf.options import WATCHDOG_FACTOR, check_interval
from aca_warp.hf.state import HFState
from aca_warp.kernels import hf as K
from aca_warp.kernels.hf_types import HFRecorder
from aca_warp.kernels.physics import N_GLOBAL
from aca_warp.scene import Record

GLOBAL_NAMES = ("mu", "torque", "friction_radius", "sum_velocity", "sum_abs_velocity", "friction_centroid")
GLOBAL_UNITS = ("1", "N m", "m", "m s-1", "m s-1", "m")
RECORD_BLOCK = 256  # threads per pad of the global outputs' sums on CUDA (one on the CPU: sums in patch order)


def check_run(duration: float, record: Record, checkpoint_every: float | None = None) -> int:
    """Validate a run's duration [s], sample interval and checkpoint interval [s] (None: automatic, 0: none); returns
    the number of samples."""
    if not (duration > 0 and math.isfinite(duration)):
        raise SceneError(f"duration must be a positive number of seconds, got {duration}")
    sample_dt_name = option("record.sample_dt", "--sample-dt", "run.sample_dt")
    record.check_duration(duration, sample_dt_name, option("duration", "--duration", "run.duration"))
    check_interval(checkpoint_every)
    n_samples = max(1, round(duration / record.sample_dt))
    if n_samples > 2**31 - 2:  # the recorder counts samples in int32
        raise SceneError(
            f"{duration:g} s at a sample interval of {record.sample_dt:g} s is {n_samples:.3g} samples, more than "
            f"a run records (2^31 - 2); use a larger sample interval"
        )
    # the kernels take the decimation as an int32 (a wrapped value divides by zero: SIGFPE)
    check_int32("record.decimation", record.decimation, f"any value above {n_samples} records one row only")
    return n_samples


def check_sample_step(sample_dt: float, dt: float, anyway: str = "", follows: float | None = None) -> None:
    """Refuse a sample interval [s] shorter than the step ``dt`` [s] that was asked for (or the default): the run
    would shrink every step to the sample interval, silently multiplying the steps (``record.sample_dt = 1e-12``
    turned a 1e-8 s step into 1e-12 s and a run of hours). ``anyway`` names the override, if there is one;
    ``follows`` [s], where ``dt`` is a default step that becomes a shorter sample interval down to ``follows``
    (:func:`~aca_warp.hf.options.step_asked`): the message names that as the shortest interval."""
    if sample_dt < dt * (1 - 1e-9):
        least = dt if follows is None else follows
        which = f"the step {dt:g} s"
        if follows is not None:
            which = f"the default step {dt:.3g} s (which a sample interval down to {follows:g} s would shorten)"
        named = option(
            "record.sample_dt",
            "the sample interval (--sample-dt, or record.sample_dt in the scene)",
            "the sample interval (run.sample_dt, else the base's record.sample_dt)",
        )
        raise SceneError(
            f"{named} = {sample_dt:g} s is shorter than {which}: every step would shrink to the sample interval "
            f"({dt / sample_dt:.3g} times the steps); choose a sample interval of at least {least:g} s "
            f"({option('record.sample_dt', '--sample-dt', 'run.sample_dt')}, seconds) or a step of at most "
            f"{sample_dt:g} s ({option('dt', '--dt', 'run.dt')})" + (f"; {anyway}" if anyway else "")
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
        globals: Global outputs per sample and pad, shape (rows, pads, 6), order of ``GLOBAL_NAMES``.
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


class Recorder:
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
        self.globals = wp.zeros((rows, model.pad_count, N_GLOBAL), dtype=wp.float64, device=dev)
        # watchdog: [patch, sample, kind] of the first fault per pad (kind 0 non-finite, 1 beyond watch_bound)
        table = np.full((model.pad_count, 3), -1, np.int32)
        table[:, 2] = 0
        self.fault = wp.array(table, dtype=wp.int32, device=dev)
        self.fault_value = wp.zeros(model.pad_count, dtype=wp.float64, device=dev)
        self.watch_bound = wp.array(np.full(model.pad_count, np.inf), dtype=wp.float64, device=dev)
        self.velocity = wp.zeros((prow, n), dtype=T, device=dev)
        self.displacement = wp.zeros((prow if self.want_u else 0, n), dtype=T, device=dev)
        self.sample_index = 0
        names = ("counters", "globals", "watch_bound", "fault", "fault_value", "velocity", "displacement")
        names += ("first", "last", "every")
        # the kernels' parameter group (its arrays change in place only: graphs keep it)
        self.struct = HFRecorder.of(T, {k: getattr(self, k) for k in names})
        self.launcher = Launcher(dev)

    def due(self, k: int) -> bool:
        """Whether global sample k also records per-patch histories (``patch_sample_due`` of kernels.physics)."""
        return self.first <= k <= self.last and (k - self.first) % self.every == 0

    def kernel_rows(self) -> tuple[int, int, int]:
        """(next sample index, next globals row, next per-patch row) for a kernel that records in-kernel."""
        k_next, rows, prows = (int(x) for x in self.counters.numpy()[:3])
        return k_next, rows, prows

    def kernel_recorded(self, k_next: int, rows: int, prows: int, samples: int) -> None:
        """Count ``samples`` samples a kernel recorded from :meth:`kernel_rows` on (the per-patch rows of those
        due among them)."""
        due = sum(1 for k in range(k_next, k_next + samples) if self.due(k))
        self.counters.assign(np.array([k_next + samples, rows + samples, prows + due, 0], dtype=np.int32))

    @property
    def patch_stage(self) -> bool:
        """Whether per-patch histories are recorded at all."""
        return self.want_v or self.want_u

    def launch(
        self,
        u: wp.array,
        v: wp.array,
        conditional: bool,
        *,
        staggered: tuple[wp.array, wp.array] | None = None,
        crossing: int = 0,
    ) -> None:
        """Record one sample of (u, u̇) (conditional: only when the adaptive controller landed on a sample). With
        ``crossing`` ≠ 0, ``staggered`` holds the staggered velocities (w, w⁺) [m/s] before and after the merged
        sub-step whose solve gave v (``strang``'s samples), and a patch whose slip changes sign between them has its
        friction read at an instant of that sub-step (:func:`~aca_warp.kernels.physics.instant_velocity`)."""
        m, c, rec = self.model, int(conditional), self.struct
        threads = block_threads(m.device, RECORD_BLOCK)
        launch = self.launcher
        w, w1 = (v, v) if staggered is None else staggered
        record = K.STRANG_KERNELS[crossing][2]
        launch(record, [m.pad_count], [m.struct(), rec, c, threads, u, v, w, w1], block_dim=RECORD_BLOCK)
        if self.patch_stage:
            launch(K.record_patches, m.patch_count, [rec, c, u, v])
        launch(K.advance_counters, 1, [rec, c])

    def flush(self) -> tuple[Chunk, np.ndarray]:
        """Copy the recorded rows to the host and reset the buffers; returns the chunk and the fault table."""
        c = self.counters.numpy()
        rows, prows = int(c[1]), int(c[2])
        k = np.arange(self.sample_index, self.sample_index + rows)
        due = (k >= self.first) & (k <= self.last) & ((k - self.first) % self.every == 0)
        assert int(due.sum()) == prows, "per-patch rows out of step with the sample counter"
        chunk = Chunk(
            time=k * self.sample_dt,
            globals=rows_to_host(self.globals, rows),
            patch_time=k[due] * self.sample_dt,
            velocity=rows_to_host(self.velocity, prows) if self.want_v else None,
            displacement=rows_to_host(self.displacement, prows) if self.want_u else None,
        )
        self.sample_index += rows
        c[1] = c[2] = 0
        wp.copy(self.counters, wp.array(c, dtype=wp.int32, device=self.model.device))
        return chunk, self.fault.numpy()


def rows_to_host(buffer: wp.array, rows: int) -> np.ndarray:
    """The first ``rows`` rows of a recording buffer as a host array of their own. On a GPU only those rows are
    copied (``buffer.numpy()`` would copy the whole buffer: the per-patch history of a 32-pad hf1 batch holds up to
    262 MB, and every chunk of a run flushes it, also before the window when no row is filled); on the CPU the
    rows are copied out of the buffer, which the next chunk overwrites."""
    if buffer.device.is_cpu:
        return buffer.numpy()[:rows].copy()
    if rows == 0:
        return np.zeros((0, *buffer.shape[1:]), dtype=wp.dtype_to_numpy(buffer.dtype))
    return buffer[:rows].numpy()


def fault_from(
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
