"""Per-patch terms of the HF model as Warp functions, the one home of each (every HF engine calls them).

Equation of motion of patch i (paper §2.1.2, docs/model.md §2.2), u along the local disc direction:

    m_i ü_i + c_i u̇_i + k_T,i u_i + Σ_j k_ij (u_i − u_j) = F_N,i f(ω r_i − u̇_i),   k_ij = K_C √A_i √A_j / D0_ij.

* the coupling gather F_s,i = Σ_j k_ij u_j − k_diag,i u_i (:func:`spring_force` over the CSR; the on-chip kernels'
  shared-memory gathers sum the links in the same order, :mod:`aca_warp.kernels.onchip_gather`);
* the explicit right-hand side :func:`patch_force` (symplectic Euler and the adaptive DP5 stages);
* the Strang velocity updates (:func:`strang_velocity`, :func:`strang_close_velocity`), kicks around the
  friction/damping sub-step :func:`~aca_warp.kernels.friction.friction_substep`;
* growth (paper Eq. 10, :func:`grow_patch`) and the coupling stiffnesses it changes (Eq. 3, :func:`patch_coupling`).

Functions are generic in the state precision T (float32 or float64); SI units.
"""

from __future__ import annotations

from typing import Any

import warp as wp
from aca_warp.kernels.friction import friction_coefficient, friction_substep

wp.set_module_options({"enable_backward": False})


@wp.func
def spring_force(
    i: int,
    u: wp.array[Any],
    k_diag: wp.array[Any],
    nbr_start: wp.array[wp.int32],
    nbr_index: wp.array[wp.int32],
    nbr_stiffness: wp.array[Any],
):
    """Elastic force on patch i: Σ_j k_ij u_j − (k_T,i + Σ_j k_ij) u_i [N].

    Two partial sums break the dependency chain of the gather (about 30 % faster on the CPU): the even links of the
    row into the first, the odd ones into the second; the order of summation is fixed, so results stay
    bit-reproducible, and every gather of the engines sums in this order.
    """
    a0 = u[i] - u[i]
    a1 = a0
    e = nbr_start[i]
    end = nbr_start[i + 1]
    while e + 1 < end:
        a0 += nbr_stiffness[e] * u[nbr_index[e]]
        a1 += nbr_stiffness[e + 1] * u[nbr_index[e + 1]]
        e += 2
    if e < end:
        a0 += nbr_stiffness[e] * u[nbr_index[e]]
    return (a0 + a1) - k_diag[i] * u[i]


@wp.func
def patch_force(fs: Any, v: Any, c: Any, fn: Any, vd: Any, mu_scale: Any, slope: Any, decay: Any):
    """Net force on a patch [N]: elastic force ``fs`` + friction F_N f(vd − v) − damping c v, at velocity ``v``
    [m/s], disc speed ``vd`` = ω r [m/s], normal force ``fn`` [N] and damping ``c`` [N s/m]."""
    return fs + fn * friction_coefficient(vd - v, mu_scale, slope, decay) - c * v


@wp.func
def strang_velocity(
    first: int,
    w: Any,
    fs: Any,
    dt: Any,
    im: Any,
    c: Any,
    fn: Any,
    vd: Any,
    mu_scale: Any,
    slope: Any,
    decay: Any,
    tol: Any,
):
    """Strang's velocity update of one step of a patch, before its drift u ← u + dt v; ``fs`` the cached F_s(uₙ)
    [N], ``im`` = 1/m [1/kg]. ``first`` ≠ 0, the opening half step from the synchronous velocity ``w``: the
    friction/damping sub-step over dt/2, then the half kick dt/2 · F_s/m. Otherwise a merged step on the staggered
    velocity ``w``: kick dt/2, friction/damping sub-step over dt, kick dt/2 (the closing friction half of step n and
    the opening half of step n+1 are one sub-step). Returns the staggered velocity (the one just before the next
    half kick)."""
    half = dt * type(dt)(0.5)
    if first != 0:
        return friction_substep(w, half, type(dt)(1.0) / im, c, fn, vd, mu_scale, slope, decay, tol) + half * im * fs
    kick = half * im * fs
    return friction_substep(w + kick, dt, type(dt)(1.0) / im, c, fn, vd, mu_scale, slope, decay, tol) + kick


@wp.func
def strang_close_velocity(
    w: Any, fs: Any, dt: Any, im: Any, c: Any, fn: Any, vd: Any, mu_scale: Any, slope: Any, decay: Any, tol: Any
):
    """The synchronous velocity of a patch from its staggered ``w`` and F_s(uₙ) ``fs``: half kick, then the
    friction/damping sub-step over dt/2."""
    half = dt * type(dt)(0.5)
    return friction_substep(w + half * im * fs, half, type(dt)(1.0) / im, c, fn, vd, mu_scale, slope, decay, tol)


@wp.func
def grow_patch(
    i: int,
    p: int,
    pad_growth: wp.array[Any],
    pad_k_t: wp.array[Any],
    pad_k_n: wp.array[Any],
    pad_mass_per_area: wp.array[Any],
    pad_zeta: wp.array[Any],
    area_io: wp.array[Any],
    sqrt_area_out: wp.array[Any],
    inv_mass_out: wp.array[Any],
    k_t_out: wp.array[Any],
    k_n_out: wp.array[Any],
    damping_out: wp.array[Any],
):
    """One growth event of patch i of pad p (paper Eq. 10): A ← A + g √A, then m, k_T, k_N, c follow the area."""
    a = area_io[i]
    a = a + pad_growth[p] * wp.sqrt(a)
    s = wp.sqrt(a)
    m = pad_mass_per_area[p] * a
    kt = pad_k_t[p] * s
    area_io[i] = a
    sqrt_area_out[i] = s
    inv_mass_out[i] = type(a)(1.0) / m
    k_t_out[i] = kt
    k_n_out[i] = pad_k_n[p] * s
    damping_out[i] = type(a)(2.0) * pad_zeta[p] * wp.sqrt(kt * m)


@wp.func
def link_stiffness(ki: Any, sqrt_area_j: Any, inv_dist: Any):
    """k_ij = K_C √A_i √A_j / D0_ij [N/m] (paper Eq. 3) from ``ki`` = K_C √A_i, √A_j and 1/D0_ij."""
    return ki * sqrt_area_j * inv_dist


@wp.func
def patch_coupling(
    i: int,
    p: int,
    sqrt_area: wp.array[Any],
    nbr_start: wp.array[wp.int32],
    nbr_index: wp.array[wp.int32],
    nbr_inv_dist: wp.array[Any],
    pad_kc: wp.array[Any],
    k_t: wp.array[Any],
    nbr_stiffness_out: wp.array[Any],
    k_diag_out: wp.array[Any],
):
    """k_ij (:func:`link_stiffness`) for every link of patch i of pad p [N/m] and k_T,i + Σ_j k_ij."""
    ki = pad_kc[p] * sqrt_area[i]
    d = k_t[i]
    for e in range(nbr_start[i], nbr_start[i + 1]):
        k = link_stiffness(ki, sqrt_area[nbr_index[e]], nbr_inv_dist[e])
        nbr_stiffness_out[e] = k
        d += k
    k_diag_out[i] = d
