"""HF kernels of the general engine: one launch per stage (stepping, recording, growth) over flat batched arrays.

The physics they launch lives in Warp functions with one home each, shared by every engine
(:mod:`aca_warp.kernels.physics`: friction law and sub-step, coupling gather, net force, Strang velocity updates,
growth, coupling stiffness, contact, sample sums).

All kernels are generic in the state precision T (float32 or float64; overloads generated at the bottom). Batched
pads are flat arrays: ``patch_pad`` gives each patch's pad, ``pad_patch_start`` (pads+1) the offsets, and
``pad_*`` arrays hold per-pad parameters. Recorded sums are accumulated in float64 whatever T is.
"""

from __future__ import annotations

from typing import Any

import warp as wp
from aca_warp.kernels import precision_overloads
from aca_warp.kernels.physics import (
    contact_block,
    grow_patch,
    patch_coupling,
    patch_force,
    patch_sample_due,
    record_pad,
    solve_velocity,
    spring_force,
    store_patch_sample,
    strang_close_velocity,
    strang_velocity,
)

wp.set_module_options({"enable_backward": False})

# counters[] slots shared by the recording kernels (int32 array of length 4)
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
    # Model:
    patch_pad: wp.array[wp.int32],
    inv_mass: wp.array[Any],
    k_diag: wp.array[Any],
    damping: wp.array[Any],
    normal_force: wp.array[Any],
    radius: wp.array[Any],
    nbr_start: wp.array[wp.int32],
    nbr_index: wp.array[wp.int32],
    nbr_stiffness: wp.array[Any],
    pad_omega: wp.array[Any],
    pad_mu_scale: wp.array[Any],
    pad_slope: wp.array[Any],
    pad_decay: wp.array[Any],
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
    Newton per patch (:func:`~aca_warp.kernels.physics.solve_velocity`, relative tolerance ``tol``)."""
    i = wp.tid()
    p = patch_pad[i]
    v = v_io[i]
    fs = spring_force(i, u_in, k_diag, nbr_start, nbr_index, nbr_stiffness)
    vd = pad_omega[p] * radius[i]
    if implicit != 0:
        m = type(v)(1.0) / inv_mass[i]
        a = m + dt * damping[i]
        b = m * v + dt * fs
        v_io[i] = solve_velocity(a, b, dt * normal_force[i], vd, v, pad_mu_scale[p], pad_slope[p], pad_decay[p], tol)
    else:
        f = patch_force(fs, v, damping[i], normal_force[i], vd, pad_mu_scale[p], pad_slope[p], pad_decay[p])
        v_io[i] = v + dt * inv_mass[i] * f


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
    # Model:
    k_diag: wp.array[Any],
    nbr_start: wp.array[wp.int32],
    nbr_index: wp.array[wp.int32],
    nbr_stiffness: wp.array[Any],
    # State in:
    u_in: wp.array[Any],
    # State out:
    force_out: wp.array[Any],
):
    """Elastic force F_s(u) on every patch [N] (first-same-as-last cache of the Strang scheme)."""
    i = wp.tid()
    force_out[i] = spring_force(i, u_in, k_diag, nbr_start, nbr_index, nbr_stiffness)


@wp.kernel
def strang_advance(
    # Model:
    patch_pad: wp.array[wp.int32],
    inv_mass: wp.array[Any],
    damping: wp.array[Any],
    normal_force: wp.array[Any],
    radius: wp.array[Any],
    pad_omega: wp.array[Any],
    pad_mu_scale: wp.array[Any],
    pad_slope: wp.array[Any],
    pad_decay: wp.array[Any],
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
    opening half step from a synchronous state when ``first`` ≠ 0, else a merged step), then the drift u ← u + dt v.

    Afterwards ``v_io`` holds the staggered velocity w; follow with :func:`spring_forces` at the new u.
    """
    i = wp.tid()
    p = patch_pad[i]
    v = strang_velocity(
        first, v_io[i], force_in[i], dt, inv_mass[i], damping[i], normal_force[i], pad_omega[p] * radius[i],
        pad_mu_scale[p], pad_slope[p], pad_decay[p], tol,
    )  # fmt: skip
    v_io[i] = v
    u_io[i] = u_io[i] + dt * v


@wp.kernel
def strang_close(
    # Model:
    patch_pad: wp.array[wp.int32],
    inv_mass: wp.array[Any],
    damping: wp.array[Any],
    normal_force: wp.array[Any],
    radius: wp.array[Any],
    pad_omega: wp.array[Any],
    pad_mu_scale: wp.array[Any],
    pad_slope: wp.array[Any],
    pad_decay: wp.array[Any],
    dt: Any,
    tol: Any,
    # State in:
    force_in: wp.array[Any],
    v_in: wp.array[Any],
    # Out:
    v_out: wp.array[Any],
):
    """Synchronous velocity from the staggered w and F_s(uₙ) (:func:`~aca_warp.kernels.physics.strang_close_velocity`;
    may be in place)."""
    i = wp.tid()
    p = patch_pad[i]
    v_out[i] = strang_close_velocity(
        v_in[i], force_in[i], dt, inv_mass[i], damping[i], normal_force[i], pad_omega[p] * radius[i],
        pad_mu_scale[p], pad_slope[p], pad_decay[p], tol,
    )  # fmt: skip


# ---------------------------------------------------------------------------------------------- recording


@wp.kernel
def record_globals(
    # Model:
    pad_patch_start: wp.array[wp.int32],
    normal_force: wp.array[Any],
    radius: wp.array[Any],
    pad_omega: wp.array[Any],
    pad_mu_scale: wp.array[Any],
    pad_slope: wp.array[Any],
    pad_decay: wp.array[Any],
    pad_mu_pad: wp.array[Any],
    pad_load: wp.array[Any],
    pad_matrix_force: wp.array[Any],
    pad_matrix_radius: wp.array[Any],
    inv_mass: wp.array[Any],
    k_t: wp.array[Any],
    x: wp.array[Any],
    y: wp.array[Any],
    conditional: int,
    threads: int,
    # State in:
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    # Recorder:
    counters: wp.array[wp.int32],
    globals_out: wp.array3d[wp.float64],
    watch_bound: wp.array[wp.float64],
    fault_out: wp.array2d[wp.int32],
    fault_value_out: wp.array[wp.float64],
):
    """Per pad (one block, ``launch_tiled``): the sample ``counters[0]`` into globals row ``counters[1]``
    (:func:`record_pad`); with ``conditional``, only when ``counters[3]`` flags a sample."""
    pad, lane = wp.tid()
    if conditional != 0 and counters[3] == 0:
        return
    record_pad(
        pad, lane, threads, counters[1], counters[0], pad_patch_start, normal_force, radius, pad_omega, pad_mu_scale,
        pad_slope, pad_decay, pad_mu_pad, pad_load, pad_matrix_force, pad_matrix_radius, inv_mass, k_t, x, y, u_in,
        v_in, globals_out, watch_bound, fault_out, fault_value_out,
    )  # fmt: skip


@wp.kernel
def record_patches(
    first: int,
    last: int,
    every: int,
    conditional: int,
    # State in:
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    # Recorder:
    counters: wp.array[wp.int32],
    velocity_out: wp.array2d[Any],
    displacement_out: wp.array2d[Any],
):
    """Copy u̇ (and u, when its buffer has rows) of every patch into the per-patch buffers when due."""
    i = wp.tid()
    if conditional != 0 and counters[3] == 0:
        return
    if not patch_sample_due(counters[0], first, last, every):
        return
    store_patch_sample(velocity_out, displacement_out, counters[2], i, v_in[i], u_in[i])


@wp.kernel
def advance_counters(first: int, last: int, every: int, conditional: int, counters: wp.array[wp.int32]):
    """After a sample: next sample index and buffer rows (one thread)."""
    if conditional != 0 and counters[3] == 0:
        return
    k = counters[0]
    if patch_sample_due(k, first, last, every):
        counters[2] = counters[2] + 1
    counters[0] = k + 1
    counters[1] = counters[1] + 1


# ---------------------------------------------------------------------------------------------- growth


@wp.kernel
def tick(step: wp.array[wp.int64]):
    """Count a completed step (one thread); growth kernels read the count to fire every n-th step."""
    step[0] = step[0] + wp.int64(1)


@wp.kernel
def grow_patches(
    # Model:
    patch_pad: wp.array[wp.int32],
    pad_growth: wp.array[Any],
    pad_k_t: wp.array[Any],
    pad_k_n: wp.array[Any],
    pad_mass_per_area: wp.array[Any],
    pad_zeta: wp.array[Any],
    # Control:
    step: wp.array[wp.int64],
    every: int,
    # Model in/out:
    area_io: wp.array[Any],
    sqrt_area_out: wp.array[Any],
    inv_mass_out: wp.array[Any],
    k_t_out: wp.array[Any],
    k_n_out: wp.array[Any],
    damping_out: wp.array[Any],
):
    """One growth event for every patch (:func:`grow_patch`) when an event is due (:func:`growth_due`)."""
    i = wp.tid()
    if not growth_due(step, every):
        return
    grow_patch(
        i, patch_pad[i], pad_growth, pad_k_t, pad_k_n, pad_mass_per_area, pad_zeta, area_io, sqrt_area_out,
        inv_mass_out, k_t_out, k_n_out, damping_out,
    )  # fmt: skip


@wp.kernel
def coupling_stiffness(
    # Model:
    patch_pad: wp.array[wp.int32],
    sqrt_area: wp.array[Any],
    nbr_start: wp.array[wp.int32],
    nbr_index: wp.array[wp.int32],
    nbr_inv_dist: wp.array[Any],
    pad_kc: wp.array[Any],
    k_t: wp.array[Any],
    # Control:
    step: wp.array[wp.int64],
    every: int,
    # Model out:
    nbr_stiffness_out: wp.array[Any],
    k_diag_out: wp.array[Any],
):
    """Coupling stiffnesses of every patch (:func:`patch_coupling`) when an event is due (:func:`growth_due`)."""
    i = wp.tid()
    if not growth_due(step, every):
        return
    patch_coupling(
        i, patch_pad[i], sqrt_area, nbr_start, nbr_index, nbr_inv_dist, pad_kc, k_t, nbr_stiffness_out, k_diag_out
    )


@wp.kernel
def contact_flat(
    # Model:
    pad_patch_start: wp.array[wp.int32],
    k_n: wp.array[Any],
    height: wp.array[Any],
    area: wp.array[Any],
    radius: wp.array[Any],
    pad_area: wp.array[wp.float64],
    pad_moment: wp.array[wp.float64],
    pad_k_m: wp.array[wp.float64],
    pad_load: wp.array[Any],
    # Control:
    step: wp.array[wp.int64],
    every: int,
    threads: int,
    # Contact in/out:
    pad_gap: wp.array[wp.float64],
    normal_force_out: wp.array[Any],
    pad_matrix_force_out: wp.array[Any],
    pad_matrix_radius_out: wp.array[Any],
):
    """:func:`contact_block` for every pad (one thread block each) when an event is due (:func:`growth_due`)."""
    pad, lane = wp.tid()
    if not growth_due(step, every):
        return
    g = contact_block(
        pad, lane, threads, pad_patch_start, k_n, height, area, radius, pad_area, pad_moment, pad_k_m, pad_load,
        pad_gap[pad], pad_patch_start[pad], pad_patch_start[pad + 1], True, normal_force_out, pad_matrix_force_out,
        pad_matrix_radius_out,
    )  # fmt: skip
    if lane == 0:
        pad_gap[pad] = g  # every thread read the old gap: the reductions in contact_block are block barriers


# ---------------------------------------------------------------------------------------------- overloads

precision_overloads(
    euler_velocity, drift, spring_forces, strang_advance, strang_close,
    record_globals, record_patches, grow_patches, coupling_stiffness, contact_flat,
)  # fmt: skip
