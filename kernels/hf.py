"""HF kernels of the general engine: one launch per stage (stepping, recording, growth) over flat batched arrays.

The physics they launch lives in Warp functions with one home each, shared by every engine
(:mod:`aca_warp.kernels.physics`: friction law and sub-step, coupling gather, net force, Strang velocity updates,
growth, coupling stiffness, contact, sample sums).

All kernels are generic in the state precision T (float32 or float64; overloads generated at the bottom) and take the
model's arrays as one struct, ``model`` (:data:`~aca_warp.kernels.hf_types.HFModel`). Batched pads are flat arrays:
``model.patch_pad`` gives each patch's pad, ``model.pad_patch_start`` (pads+1) the offsets, and the ``pad_*`` fields
hold per-pad parameters. Recorded sums are accumulated in float64 whatever T is.
"""

from __future__ import annotations

from typing import Any

import warp as wp
from aca_warp.kernels import precision_overloads
from aca_warp.kernels.hf_types import HFModel, HFRecorder
from aca_warp.kernels.physics import (
    contact_block,
    grow_patch,
    patch_coupling,
    patch_force,
    patch_sample_due,
    record_pad,
    spring_force,
    store_patch_sample,
    strang_close_velocity,
    strang_sample_velocity,
    strang_velocity,
    theta_substep,
)

wp.set_module_options({"enable_backward": False})

# slots of the recorder's counters (HFRecorder.counters, int32 (4,)) shared by the recording kernels
SAMPLE_INDEX = 0  # absolute index of the next global sample
GLOBAL_ROWS = 1  # rows written to the global buffer since the last flush
PATCH_ROWS = 2  # rows written to the per-patch buffer since the last flush
RECORD_FLAG = 3  # adaptive stepping: 1 when every pad has landed on the sample time (kernels.hf_adaptive.landing)


# ---------------------------------------------------------------------------------------------- control


@wp.func
def growth_due(step: wp.array[wp.int64], every: int) -> bool:
    """Whether a growth event is due. ``every`` > 0 (fixed step): whether the step just taken (``step[0]`` counts
    completed steps before it) ends a growth interval; ``every`` = 0 (adaptive): whether ``step[0]``, the event
    flag that the adaptive landing sets when every pad stands on an event time, is set."""
    if every == 0:
        return step[0] != wp.int64(0)
    return (step[0] + wp.int64(1)) % wp.int64(every) == wp.int64(0)


# ---------------------------------------------------------------------------------------------- stepping


@wp.kernel
def euler_velocity(
    model: Any,
    # Control:
    dt: Any,
    tol: Any,
    implicit: int,
    # State in:
    u_in: wp.array[Any],
    # State in/out:
    v_io: wp.array[Any],
):
    """The velocity half of both Euler schemes. ``implicit`` = 0, symplectic Euler (explicit friction):
    v ← v + dt/m (F_s(u) + F_N f(ωr − v) − c v). Otherwise IMEX Euler: m(v⁺ − v) = dt (F_s(u) + F_N f(ωr − v⁺) − c v⁺),
    the θ-method step with θ = 1 (backward Euler, :func:`~aca_warp.kernels.physics.theta_substep`, relative
    tolerance ``tol``)."""
    i = wp.tid()
    p = model.patch_pad[i]
    v = v_io[i]
    fs = spring_force(i, u_in, model)
    vd = model.pad_omega[p] * model.radius[i]
    if implicit != 0:
        v_io[i] = theta_substep(
            v, dt, type(v)(1.0), type(v)(1.0) / model.inv_mass[i], model.damping[i], model.normal_force[i], fs, vd,
            model.pad_mu_scale[p], model.pad_slope[p], model.pad_decay[p], tol,
        )  # fmt: skip
    else:
        f = patch_force(
            fs, v, model.damping[i], model.normal_force[i], vd, model.pad_mu_scale[p], model.pad_slope[p],
            model.pad_decay[p],
        )  # fmt: skip
        v_io[i] = v + dt * model.inv_mass[i] * f


@wp.kernel
def drift(
    dt: Any,
    # State in:
    v_in: wp.array[Any],
    # State in/out:
    u_io: wp.array[Any],
):
    """Position update u ← u + dt v (second half of both Euler schemes)."""
    i = wp.tid()
    u_io[i] = u_io[i] + dt * v_in[i]


@wp.kernel
def spring_forces(
    model: Any,
    # State in:
    u_in: wp.array[Any],
    # State out:
    force_out: wp.array[Any],
):
    """Elastic force F_s(u) on every patch [N] (first-same-as-last cache of the Strang scheme)."""
    i = wp.tid()
    force_out[i] = spring_force(i, u_in, model)


@wp.func
def patch_close_velocity(i: int, p: int, w: Any, force: Any, dt: Any, model: Any, tol: Any, crossing: int):
    """Patch i's (pad p) synchronous velocity [m/s] from its staggered w and F_s(uₙ) ``force`` [N] after a step
    ``dt`` [s]: :func:`~aca_warp.kernels.physics.strang_close_velocity` with the patch's parameters from ``model``
    (a run's end, and the error-controlled split step's samples)."""
    return strang_close_velocity(
        w, force, dt, model.inv_mass[i], model.damping[i], model.normal_force[i],
        model.pad_omega[p] * model.radius[i], model.pad_mu_scale[p], model.pad_slope[p], model.pad_decay[p], tol,
        crossing,
    )  # fmt: skip


@wp.func
def patch_sample_velocity(i: int, p: int, w: Any, force: Any, dt: Any, model: Any, tol: Any, crossing: int):
    """Patch i's (pad p) sample velocity V and the next step's drift velocity w⁺ [m/s] from its staggered w and
    F_s(uₙ) ``force`` [N] after a step ``dt`` [s]: :func:`~aca_warp.kernels.physics.strang_sample_velocity` with the
    patch's parameters from ``model``."""
    return strang_sample_velocity(
        w, force, dt, model.inv_mass[i], model.damping[i], model.normal_force[i],
        model.pad_omega[p] * model.radius[i], model.pad_mu_scale[p], model.pad_slope[p], model.pad_decay[p], tol,
        crossing,
    )  # fmt: skip


# ---------------------------------------------------------------------------------------------- recording


@wp.func
def sample_flagged(rec: Any, conditional: int) -> bool:
    """Whether a sample is taken now: always, or with ``conditional`` only when ``rec``'s counters flag one."""
    return conditional == 0 or rec.counters[RECORD_FLAG] != 0


# ------------------------------------------------------------------------- strang's steps and the sample they close


def _strang_kernels(crossing: int, module: str | None) -> tuple[wp.Kernel, wp.Kernel, wp.Kernel, wp.Kernel]:
    """``strang_advance``, ``strang_sample``, ``record_globals`` and ``strang_close`` with strang's treatment of
    steps that cross zero slip compiled in (``crossing`` 1: ``RunOptions.crossing`` "mean",
    :func:`~aca_warp.kernels.physics.friction_substep` and :func:`~aca_warp.kernels.physics.instant_velocity`;
    0: "point"), so that the default kernels carry none of the other treatment's code; ``module``: the Warp module
    (None: this one; "unique": a module of their own, compiled only when a run asks for it)."""
    CROSSING = wp.constant(crossing)

    @wp.kernel(module=module, enable_backward=False)
    def strang_advance(
        model: Any,
        # Control:
        dt: Any,
        tol: Any,
        first: int,
        # State in:
        force_in: wp.array[Any],
        # State in/out:
        u_io: wp.array[Any],
        v_io: wp.array[Any],
    ):
        """One Strang step of every patch: the velocity update (:func:`~aca_warp.kernels.physics.strang_velocity`; the
        opening half step from a synchronous state when ``first`` ≠ 0, else a merged step), then the drift
        u ← u + dt v.

        Afterwards ``v_io`` holds the staggered velocity w; follow with :func:`spring_forces` at the new u.
        """
        i = wp.tid()
        p = model.patch_pad[i]
        v = strang_velocity(
            first, v_io[i], force_in[i], dt, model.inv_mass[i], model.damping[i], model.normal_force[i],
            model.pad_omega[p] * model.radius[i], model.pad_mu_scale[p], model.pad_slope[p], model.pad_decay[p], tol,
            CROSSING,
        )  # fmt: skip
        v_io[i] = v
        u_io[i] = u_io[i] + dt * v

    @wp.kernel(module=module, enable_backward=False)
    def strang_sample(
        model: Any,
        # Control:
        dt: Any,
        tol: Any,
        # State in:
        force_in: wp.array[Any],
        v_in: wp.array[Any],
        # Out:
        v_out: wp.array[Any],
        w1_out: wp.array[Any],
    ):
        """A sample's velocity V and the next step's drift velocity w⁺ [m/s] from the staggered w and F_s(uₙ) after
        a step ``dt`` [s] (:func:`~aca_warp.kernels.physics.strang_sample_velocity`; ``v_out`` may be ``v_in``)."""
        i = wp.tid()
        v, w1 = patch_sample_velocity(i, model.patch_pad[i], v_in[i], force_in[i], dt, model, tol, CROSSING)
        v_out[i] = v
        w1_out[i] = w1

    @wp.kernel(module=module, enable_backward=False)
    def strang_close(
        model: Any,
        # Control:
        dt: Any,
        tol: Any,
        # State in:
        force_in: wp.array[Any],
        v_in: wp.array[Any],
        # Out:
        v_out: wp.array[Any],
    ):
        """Synchronous velocity from the staggered w and F_s(uₙ): the closing half sub-step, which ends a run
        (:func:`~aca_warp.kernels.physics.strang_close_velocity`; may be in place)."""
        i = wp.tid()
        v_out[i] = patch_close_velocity(i, model.patch_pad[i], v_in[i], force_in[i], dt, model, tol, CROSSING)

    @wp.kernel(module=module, enable_backward=False)
    def record_globals(
        model: Any,
        rec: Any,
        # Control:
        conditional: int,
        threads: int,
        # State in:
        u_in: wp.array[Any],
        v_in: wp.array[Any],
        w_in: wp.array[Any],
        w1_in: wp.array[Any],
    ):
        """Per pad (one block, ``launch_tiled``): the sample of the recorder's sample index into its next globals row
        (:func:`record_pad`; ``w_in``, ``w1_in`` the staggered velocities before and after the sub-step whose solve
        gave ``v_in``, read by the crossing treatment), when one is taken (:func:`sample_flagged`)."""
        pad, lane = wp.tid()
        if not sample_flagged(rec, conditional):
            return
        k = rec.counters[SAMPLE_INDEX]
        record_pad(pad, lane, threads, rec.counters[GLOBAL_ROWS], k, model, u_in, v_in, w_in, w1_in, CROSSING, rec)

    return strang_advance, strang_sample, record_globals, strang_close


@wp.kernel
def record_patches(
    rec: Any,
    conditional: int,
    # State in:
    u_in: wp.array[Any],
    v_in: wp.array[Any],
):
    """Copy u̇ (and u, when its buffer has rows) of every patch into the per-patch buffers when due."""
    i = wp.tid()
    if not sample_flagged(rec, conditional):
        return
    if not patch_sample_due(rec, rec.counters[SAMPLE_INDEX]):
        return
    store_patch_sample(rec, rec.counters[PATCH_ROWS], i, v_in[i], u_in[i])


@wp.kernel
def advance_counters(rec: Any, conditional: int):
    """After a sample: next sample index and buffer rows (one thread)."""
    if not sample_flagged(rec, conditional):
        return
    k = rec.counters[SAMPLE_INDEX]
    if patch_sample_due(rec, k):
        rec.counters[PATCH_ROWS] = rec.counters[PATCH_ROWS] + 1
    rec.counters[SAMPLE_INDEX] = k + 1
    rec.counters[GLOBAL_ROWS] = rec.counters[GLOBAL_ROWS] + 1


# ---------------------------------------------------------------------------------------------- growth


@wp.kernel
def tick(step: wp.array[wp.int64]):
    """Count a completed step (one thread); growth kernels read the count to fire every n-th step."""
    step[0] = step[0] + wp.int64(1)


@wp.kernel
def grow_patches(
    model: Any,
    # Control:
    step: wp.array[wp.int64],
    every: int,
    coupling: int,
):
    """The per-patch part of a growth event, when one is due (:func:`growth_due`): ``coupling`` = 0, every patch
    grows (:func:`grow_patch`; the model's areas, masses, stiffnesses and dampings); ``coupling`` = 1, the coupling
    stiffnesses at the new areas (:func:`patch_coupling`; k_ij and k_diag), a launch of their own because they read
    the neighbours' new √A."""
    i = wp.tid()
    if not growth_due(step, every):
        return
    if coupling == 0:
        grow_patch(i, model.patch_pad[i], model)
    else:
        patch_coupling(i, model.patch_pad[i], model)


@wp.kernel
def contact_flat(
    model: Any,
    # Control:
    step: wp.array[wp.int64],
    every: int,
    threads: int,
):
    """:func:`contact_block` for every pad (one thread block each) when an event is due (:func:`growth_due`): writes
    the model's normal forces, matrix forces and radii and gaps."""
    pad, lane = wp.tid()
    if not growth_due(step, every):
        return
    g = contact_block(
        pad, lane, threads, model, model.pad_gap[pad], model.pad_patch_start[pad], model.pad_patch_start[pad + 1], True
    )
    if lane == 0:
        model.pad_gap[pad] = g  # every thread read the old gap: the reductions in contact_block are block barriers


# ---------------------------------------------------------------------------------------------- overloads

strang_advance, strang_sample, record_globals, strang_close = _strang_kernels(0, None)
# per crossing treatment (RunOptions.crossing: 0 point, 1 mean): strang_advance, strang_sample, record_globals,
# strang_close
STRANG_KERNELS = {0: (strang_advance, strang_sample, record_globals, strang_close), 1: _strang_kernels(1, "unique")}

precision_overloads(
    euler_velocity, drift, spring_forces, *STRANG_KERNELS[0], *STRANG_KERNELS[1], record_patches, advance_counters,
    grow_patches, contact_flat, model=HFModel, rec=HFRecorder,
)  # fmt: skip
