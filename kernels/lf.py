"""Warp kernels of the LF automaton (docs/lf_model.md; thin wrappers in ``aca_warp.lf.solver``).

Three element sets, all float64 SoA arrays:

* matrix cells ``e`` of a polar grid over the pad (ring ``k`` = radial band, column ``j`` along the sliding
  direction, e = k·n_t + j), shape (C,);
* disc rings ``k`` (the same radial bands), shape (R,);
* patches ``i`` in a fixed-capacity slot array with ``alive`` flags, shape (P,).

Pad frame: pad centred on +y, φ = atan2(−x, y) ∈ [−half, +half]; the disc moves toward +φ, so column 0 is the
leading edge and column n_t − 1 the trailing edge. Global scalars live in ``glob`` (indices ``G_*`` below),
so that every kernel reads its inputs from the device and a step needs no host value but the topology flag.
Random numbers: a stateless counter hash keyed by (seed, step, element, stream), bit-identical on every device.
"""

from __future__ import annotations

from typing import Any

import warp as wp
from aca_warp.kernels.physics import friction_coefficient
from aca_warp.kernels.tiles import block_add, block_sync, tile_store_1d

wp.set_module_options({"enable_backward": False})

# threads of the block kernels (contact solve, debris sweep): Warp's default block size, so that no second
# module variant is compiled; also the debris sweep's chunk of cells per shared-memory load
LF_BLOCK = wp.constant(256)
_put = tile_store_1d(wp.float64, LF_BLOCK)

# indices into the global scalar array ``glob`` (float64)
G_LOAD = wp.constant(0)  # clamp force F_N this step [N]
G_OMEGA = wp.constant(1)  # disc angular velocity [rad/s]
G_GAP = wp.constant(2)  # contact gap g [m]
G_FN = wp.constant(3)  # Σ F_N [N]
G_FF = wp.constant(4)  # Σ friction force [N]
G_TORQUE = wp.constant(5)  # Σ r F_F [N m]
G_FN_PATCH = wp.constant(6)  # Σ F_N on patches [N]
G_MATRIX_IN = wp.constant(7)  # retained matrix debris entering the boundary layer this step [kg]
G_PATCH_LOST = wp.constant(8)  # patch wear debris lost (not retained) this step [kg]
G_EMITTED = wp.constant(9)  # debris leaving at the trailing edge this step [kg]
G_TOPOLOGY = wp.constant(10)  # 1 when patches were born or merged this step (candidate lists to rebuild)
G_COUNT = wp.constant(11)  # alive patches
G_AREA = wp.constant(12)  # Σ patch area [m²]
G_TPATCH = wp.constant(13)  # Σ A T over patches [m² K]
G_STEP = wp.constant(14)  # step counter (float64 integer value)
G_BIRTHS = wp.constant(15)  # births this step
G_DEATHS = wp.constant(16)  # deaths this step (not merges)
G_MERGES = wp.constant(17)  # merges this step (absorbed patches)
G_MATRIX_LOST = wp.constant(18)  # matrix wear debris lost (not retained) this step [kg]
G_PASSES = wp.constant(19)  # contact-solve passes over the elements this step
G_SIZE = wp.constant(20)

# columns of the per-step history
H_NAMES = (
    "mu",
    "torque",
    "friction_radius",
    "patch_count",
    "coverage",
    "disc_temperature_mean",
    "disc_temperature_max",
    "patch_temperature",
    "patch_share",
    "normal_force",
    "births",
    "deaths",
    "merges",
    "gap",
    "contact_passes",
)
H_UNITS = ("1", "N m", "m", "1", "1", "K", "K", "K", "1", "N", "1", "1", "1", "m", "1")
(
    H_MU,
    H_TORQUE,
    H_REFF,
    H_COUNT,
    H_COVER,
    H_TDISC_MEAN,
    H_TDISC_MAX,
    H_TPATCH,
    H_SHARE,
    H_LOAD,
    H_BIRTHS,
    H_DEATHS,
    H_MERGES,
    H_GAP,
    H_PASSES,
) = (wp.constant(k) for k in range(15))
H_SIZE = len(H_NAMES)


@wp.struct
class LFParams:
    """Constants of one LF model (SI; meanings in docs/lf_model.md and ``aca_warp.lf.scene.LFConstants``)."""

    r_in: wp.float64
    dr: wp.float64
    half: wp.float64
    dphi: wp.float64
    n_r: wp.int32
    n_t: wp.int32
    dt: wp.float64
    seed: wp.uint64
    K_N: wp.float64
    k_m: wp.float64
    mu_pad: wp.float64
    coulomb: wp.int32
    mu_coulomb: wp.float64
    M: wp.float64
    slope: wp.float64
    decay: wp.float64
    gamma_disc: wp.float64
    T_amb: wp.float64
    rho_d: wp.float64
    c_d: wp.float64
    k_d: wp.float64
    d_d: wp.float64
    h_conv: wp.float64
    rho_p: wp.float64
    c_p: wp.float64
    k_p: wp.float64
    t_eff: wp.float64
    L_b: wp.float64
    h_pd: wp.float64
    alpha_d: wp.float64
    kappa_d: wp.float64
    wear_m: wp.float64
    wear_p: wp.float64
    wear_T: wp.float64
    rho_m: wp.float64
    rho_patch: wp.float64
    f_ret: wp.float64
    p_cap: wp.float64
    p_store: wp.float64
    p_remob: wp.float64
    s_max_thick: wp.float64
    A0: wp.float64
    A_min: wp.float64
    A_max: wp.float64
    t0: wp.float64
    t_min: wp.float64
    k_shrink: wp.float64
    p_comp: wp.float64
    p_birth: wp.float64
    lam0: wp.float64
    T_c: wp.float64
    T_s: wp.float64
    T_kill: wp.float64
    cand_margin: wp.float64


# ----------------------------------------------------------------------------------------------- helpers


@wp.func
def splitmix64(x: wp.uint64) -> wp.uint64:
    z = x + wp.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> wp.uint64(30))) * wp.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> wp.uint64(27))) * wp.uint64(0x94D049BB133111EB)
    return z ^ (z >> wp.uint64(31))


@wp.func
def uniform64(seed: wp.uint64, step: wp.uint64, idx: wp.uint64, stream: wp.uint64) -> wp.float64:
    """Uniform [0, 1) with 53 bits from (seed, step, element, stream); identical on CPU and GPU."""
    h = splitmix64(seed ^ splitmix64(step ^ splitmix64(idx ^ splitmix64(stream))))
    return wp.float64(h >> wp.uint64(11)) * wp.float64(1.0 / 9007199254740992.0)


@wp.func
def polar(x: wp.float64, y: wp.float64) -> wp.vec2d:
    """(r [m], φ [rad]) of a point in the pad frame: r = √(x² + y²), φ = atan2(−x, y)."""
    return wp.vec2d(wp.sqrt(x * x + y * y), wp.atan2(-x, y))


@wp.func
def disc_radius(area: wp.float64) -> wp.float64:
    """Radius a = √(A/π) [m] of a round patch of area A [m²]."""
    return wp.sqrt(area / wp.float64(wp.pi))


@wp.func
def overlaps(x: wp.float64, y: wp.float64, a: wp.float64, xo: wp.float64, yo: wp.float64, ao: wp.float64) -> bool:
    """Whether the discs of radius a at (x, y) and ao at (xo, yo) overlap [m]."""
    dx = x - xo
    dy = y - yo
    return dx * dx + dy * dy < (a + ao) * (a + ao)


@wp.func
def cell_of(p: LFParams, x: wp.float64, y: wp.float64) -> wp.int32:
    rp = polar(x, y)
    r = rp[0]
    phi = rp[1]
    k = wp.clamp(wp.int32(wp.floor((r - p.r_in) / p.dr)), 0, p.n_r - 1)
    j = wp.clamp(wp.int32(wp.floor((phi + p.half) / p.dphi)), 0, p.n_t - 1)
    return k * p.n_t + j


@wp.func
def eq4(p: LFParams, v: wp.float64) -> wp.float64:
    """Patch friction coefficient: paper Eq. 4 at sliding speed v (the HF engines' law,
    :func:`~aca_warp.kernels.physics.friction_coefficient`), or the Coulomb value."""
    if p.coulomb != 0:
        return p.mu_coulomb
    return friction_coefficient(v, p.M / wp.float64(wp.pi), p.slope, p.decay)


@wp.func
def wear_factor(p: LFParams, T: wp.float64) -> wp.float64:
    if p.wear_T > wp.float64(0.0):
        return wp.exp(wp.min((T - p.T_amb) / p.wear_T, wp.float64(50.0)))
    return wp.float64(1.0)


# ----------------------------------------------------------------------------------------------- binning


@wp.kernel
def zero_step(
    # State out:
    cell_cover_out: wp.array[wp.float64],
    cell_chord_out: wp.array[wp.float64],
    cell_power_out: wp.array[wp.float64],
    ring_power_out: wp.array[wp.float64],
    glob_out: wp.array[wp.float64],
):
    """Reset per-step accumulators (dim = C)."""
    e = wp.tid()
    cell_cover_out[e] = wp.float64(0.0)
    cell_chord_out[e] = wp.float64(0.0)
    cell_power_out[e] = wp.float64(0.0)
    if e < ring_power_out.shape[0]:
        ring_power_out[e] = wp.float64(0.0)
    if e == 0:
        for g in range(G_FN, G_SIZE):
            if g != G_GAP and g != G_STEP:
                glob_out[g] = wp.float64(0.0)


@wp.kernel
def bin_patches(
    p: LFParams,
    # State in:
    alive: wp.array[wp.int32],
    x: wp.array[wp.float64],
    y: wp.array[wp.float64],
    area: wp.array[wp.float64],
    # State out:
    patch_cell_out: wp.array[wp.int32],
    cell_cover_out: wp.array[wp.float64],
    cell_chord_out: wp.array[wp.float64],
):
    """Cell of each alive patch (its centre) and per-cell covered area and summed chord 2a (dim = P)."""
    i = wp.tid()
    if alive[i] == 0:
        return
    e = cell_of(p, x[i], y[i])
    patch_cell_out[i] = e
    wp.atomic_add(cell_cover_out, e, area[i])
    wp.atomic_add(cell_chord_out, e, wp.float64(2.0) * disc_radius(area[i]))


@wp.func
def element(
    p: LFParams,
    t: wp.int32,
    n_cells: wp.int32,
    cell_area: wp.array[wp.float64],
    cell_z: wp.array[wp.float64],
    cell_cover: wp.array[wp.float64],
    ring_bulge: wp.array[wp.float64],
    alive: wp.array[wp.int32],
    area: wp.array[wp.float64],
    top: wp.array[wp.float64],
    patch_cell: wp.array[wp.int32],
) -> wp.vec2d:
    """(stiffness [N/m], free elevation [m]) of element t: cells first, then patch slots; k = 0 if inactive."""
    if t < n_cells:
        free = wp.max(cell_area[t] - cell_cover[t], wp.float64(0.0))
        return wp.vec2d(p.k_m * free, cell_z[t] + ring_bulge[t / p.n_t])
    i = t - n_cells
    if alive[i] == 0:
        return wp.vec2d(wp.float64(0.0), wp.float64(0.0))
    return wp.vec2d(p.K_N * wp.sqrt(area[i]), top[i] + ring_bulge[patch_cell[i] / p.n_t])


# ----------------------------------------------------------------------------------------------- contact


@wp.kernel
def contact_elements(
    p: LFParams,
    n_cells: wp.int32,
    # Model:
    cell_area: wp.array[wp.float64],
    # State in:
    cell_z: wp.array[wp.float64],
    cell_cover: wp.array[wp.float64],
    ring_bulge: wp.array[wp.float64],
    alive: wp.array[wp.int32],
    area: wp.array[wp.float64],
    top: wp.array[wp.float64],
    patch_cell: wp.array[wp.int32],
    # Scratch out:
    kh_out: wp.array[wp.vec2d],
):
    """(k, h) of every element for the contact solve (dim = C + P; see :func:`element`)."""
    t = wp.tid()
    kh_out[t] = element(p, t, n_cells, cell_area, cell_z, cell_cover, ring_bulge, alive, area, top, patch_cell)


@wp.kernel
def contact_solve(
    max_iter: wp.int32,
    tol: wp.float64,
    threads: wp.int32,
    # Scratch in:
    kh: wp.array[wp.vec2d],
    # State in/out:
    glob: wp.array[wp.float64],
):
    """Newton on Σ k max(h − g, 0) = F_N for the gap g, all iterations in one thread block (dim = [1]).

    Convex and piecewise linear, so after one step the iterate is at or left of the root and then converges
    monotonically, exactly once the active set is right (typically one step and one check per LF step). It stops
    when |Σ − F_N| ≤ tol · F_N or, from the second step on, when |Σ − F_N| no longer falls (the rounding floor of
    the sums, which for ~1e4 elements can lie above tol = 1e-13). The passes made are counted in ``G_PASSES``. Thread
    ``lane`` sums elements lane, lane + B, …; the block reduces the sums, so every thread takes the same branches.
    With no element in contact the next iterate is the all-active bound (Σkh − F_N)/Σk, at or left of the root.
    Launch with ``wp.launch_tiled(dim=[1], block_dim=LF_BLOCK)``; ``threads`` as in ``aca_warp.hf.block_threads``.
    """
    _blk, lane = wp.tid()
    n = kh.shape[0]
    zero = wp.float64(0.0)
    load = glob[G_LOAD]
    g = glob[G_GAP]
    sk = zero
    skh = zero
    r_prev = wp.float64(1.0e300)
    passes = int(0)
    for it in range(max_iter):
        passes += 1
        s0 = zero
        s1 = zero
        t = lane
        while t < n:
            e = kh[t]
            d = e[1] - g
            if e[0] != zero and d > zero:
                s0 += e[0] * d
                s1 += e[0]
            if it == 0:
                sk += e[0]
                skh += e[0] * e[1]
            t += threads
        s0 = wp.tile_sum(wp.tile(s0))[0]
        s1 = wp.tile_sum(wp.tile(s1))[0]
        if it == 0:  # the same for every thread: the block-wide sums stay outside per-thread branches
            sk = wp.tile_sum(wp.tile(sk))[0]
            skh = wp.tile_sum(wp.tile(skh))[0]
        if s1 > zero:
            r = s0 - load
            # converged: within tol, or (from the second Newton step on, where |r| must fall) at the rounding floor
            if wp.abs(r) <= tol * load or (it >= 2 and wp.abs(r) >= r_prev):
                break
            r_prev = wp.abs(r)
            g = g + r / s1
        else:
            g = (skh - load) / sk
    if lane == 0:
        glob[G_GAP] = g
        glob[G_PASSES] = wp.float64(passes)


# ----------------------------------------------------------------------------------------------- friction


@wp.kernel
def friction(
    p: LFParams,
    n_cells: wp.int32,
    threads: wp.int32,
    # Model:
    cell_r: wp.array[wp.float64],
    # State in:
    kh: wp.array[wp.vec2d],
    alive: wp.array[wp.int32],
    x: wp.array[wp.float64],
    y: wp.array[wp.float64],
    patch_cell: wp.array[wp.int32],
    # State out:
    cell_fn_out: wp.array[wp.float64],
    cell_power_out: wp.array[wp.float64],
    patch_fn_out: wp.array[wp.float64],
    patch_power_out: wp.array[wp.float64],
    ring_power_out: wp.array[wp.float64],
    glob: wp.array[wp.float64],
):
    """Normal forces at the solved gap (from the contact scratch ``kh``), friction forces and powers, global sums.

    Block b covers elements b·LF_BLOCK … (b+1)·LF_BLOCK − 1 of the C + P; the block reduces its global sums
    before one atomic add each. Launch with ``wp.launch_tiled(dim=[⌈(C+P)/LF_BLOCK⌉], block_dim=LF_BLOCK)``.
    """
    blk, lane = wp.tid()
    n = kh.shape[0]
    g = glob[G_GAP]
    omega = glob[G_OMEGA]
    zero = wp.float64(0.0)
    s_fn = zero  # Σ F_N, Σ F_F, Σ r F_F over loaded elements, Σ F_N over patches
    s_ff = zero
    s_tq = zero
    s_fp = zero
    j = lane
    while j < LF_BLOCK:
        t = blk * LF_BLOCK + j
        j += threads
        if t >= n:
            continue
        e = kh[t]
        fn = e[0] * wp.max(e[1] - g, zero)
        r = zero
        ff = zero
        ring = wp.int32(0)
        if t < n_cells:
            r = cell_r[t]
            ff = p.mu_pad * fn
            cell_fn_out[t] = fn
            wp.atomic_add(cell_power_out, t, ff * omega * r)
            ring = t / p.n_t
        else:
            i = t - n_cells
            if alive[i] == 0:
                patch_fn_out[i] = zero
                patch_power_out[i] = zero
                continue
            r = wp.sqrt(x[i] * x[i] + y[i] * y[i])
            ff = eq4(p, omega * r) * fn
            patch_fn_out[i] = fn
            patch_power_out[i] = ff * omega * r
            ring = patch_cell[i] / p.n_t
            s_fp += fn
        if fn > zero:
            wp.atomic_add(ring_power_out, ring, ff * omega * r)
            s_fn += fn
            s_ff += ff
            s_tq += ff * r
    block_add(glob, G_FN, s_fn, lane)
    block_add(glob, G_FF, s_ff, lane)
    block_add(glob, G_TORQUE, s_tq, lane)
    block_add(glob, G_FN_PATCH, s_fp, lane)


# ----------------------------------------------------------------------------------------------- temperatures


@wp.kernel
def disc_temperature(
    p: LFParams,
    # Model:
    ring_r: wp.array[wp.float64],
    # State in/out:
    ring_power: wp.array[wp.float64],
    ring_T: wp.array[wp.float64],
    ring_bulge_out: wp.array[wp.float64],
    work: wp.array[wp.float64],
):
    """Backward Euler of the ring temperatures with radial conduction (Thomas algorithm; dim = 1).

    C_k dT_k/dt = γ P_k − h A_k (T_k − T_amb) + G_k−½ (T_k−1 − T_k) + G_k+½ (T_k+1 − T_k);
    then the thermal bulge Δz_k = κ α d (T_k − T_amb) toward the pad.
    """
    n = p.n_r
    dt = p.dt
    two_pi = wp.float64(2.0 * wp.pi)
    # work: [0, n) c' (super-diagonal), [n, 2n) d'; the recurrences carry c'_k−1, d'_k−1 and T_k+1 in registers
    cp = wp.float64(0.0)
    dp = wp.float64(0.0)
    for k in range(n):
        r = ring_r[k]
        C = p.rho_d * p.c_d * two_pi * r * p.dr * p.d_d
        hA = p.h_conv * wp.float64(2.0) * two_pi * r * p.dr
        g_lo = wp.float64(0.0)
        g_hi = wp.float64(0.0)
        if k > 0:
            g_lo = p.k_d * two_pi * (r - wp.float64(0.5) * p.dr) * p.d_d / p.dr
        if k < n - 1:
            g_hi = p.k_d * two_pi * (r + wp.float64(0.5) * p.dr) * p.d_d / p.dr
        diag = C / dt + hA + g_lo + g_hi
        rhs = C / dt * ring_T[k] + p.gamma_disc * ring_power[k] + hA * p.T_amb
        a = -g_lo
        c = -g_hi
        if k > 0:
            m = diag - a * cp
            cp = c / m
            dp = (rhs - a * dp) / m
        else:
            cp = c / diag
            dp = rhs / diag
        work[k] = cp
        work[n + k] = dp
    T_next = dp
    ring_T[n - 1] = T_next
    for kk in range(n - 1):
        k = n - 2 - kk
        T_next = work[n + k] - work[k] * T_next
        ring_T[k] = T_next
    for k in range(n):
        ring_bulge_out[k] = p.kappa_d * p.alpha_d * p.d_d * (ring_T[k] - p.T_amb)


@wp.func
def implicit_temperature(
    c_dt: wp.float64, T: wp.float64, q: wp.float64, g_d: wp.float64, T_d: wp.float64, g_b: wp.float64, T_b: wp.float64
) -> wp.float64:
    """Backward Euler of C dT/dt = q + g_d (T_d − T) + g_b (T_b − T): the new temperature [K] from ``c_dt`` = C/Δt
    [W/K], the heat input q [W] and the conductances to the disc ring (g_d, at T_d) and the bulk (g_b, at T_b)."""
    return (c_dt * T + q + g_d * T_d + g_b * T_b) / (c_dt + g_d + g_b)


@wp.kernel
def pad_temperature(
    p: LFParams,
    n_cells: wp.int32,
    # Model:
    cell_area: wp.array[wp.float64],
    # State in:
    ring_T: wp.array[wp.float64],
    cell_fn: wp.array[wp.float64],
    cell_power: wp.array[wp.float64],
    alive: wp.array[wp.int32],
    area: wp.array[wp.float64],
    patch_fn: wp.array[wp.float64],
    patch_power: wp.array[wp.float64],
    patch_cell: wp.array[wp.int32],
    # State in/out:
    cell_T: wp.array[wp.float64],
    patch_T: wp.array[wp.float64],
):
    """Backward Euler of a pad cell (t < C) or patch (t ≥ C) temperature against its disc ring and the pad bulk.

    Cell: C_e = ρ_p c_p A_e t_eff, heated by (1 − γ) P_e, contact conductance h_pd a_e to the ring while in
    contact, k_p A_e / L_b to the bulk at T_amb. Patch: C_i = ρ_p c_p A_i t_eff, (1 − γ) P_i, flash
    (constriction) conductance 4 k_d a_i to the ring while loaded, k_p A_i / L_b to its cell. Cells are
    updated in the same launch, so a patch couples to its cell's previous temperature (operator split).
    """
    t = wp.tid()
    dt = p.dt
    if t < n_cells:
        A = cell_area[t]
        C = p.rho_p * p.c_p * A * p.t_eff
        g_d = wp.float64(0.0)
        if cell_fn[t] > wp.float64(0.0):
            g_d = p.h_pd * A
        g_b = p.k_p * A / p.L_b
        Td = ring_T[t / p.n_t]
        q = (wp.float64(1.0) - p.gamma_disc) * cell_power[t]
        cell_T[t] = implicit_temperature(C / dt, cell_T[t], q, g_d, Td, g_b, p.T_amb)
        return
    i = t - n_cells
    if alive[i] == 0:
        return
    A = area[i]
    e = patch_cell[i]
    C = p.rho_p * p.c_p * A * p.t_eff
    g_d = wp.float64(0.0)
    if patch_fn[i] > wp.float64(0.0):
        g_d = wp.float64(4.0) * p.k_d * disc_radius(A)
    g_b = p.k_p * A / p.L_b
    Td = ring_T[e / p.n_t]
    q = (wp.float64(1.0) - p.gamma_disc) * patch_power[i]
    patch_T[i] = implicit_temperature(C / dt, patch_T[i], q, g_d, Td, g_b, cell_T[e])


# ----------------------------------------------------------------------------------------------- wear


@wp.func
def wear_depth(p: LFParams, k_e: wp.float64, T: wp.float64, power: wp.float64, a: wp.float64) -> wp.float64:
    """Energy wear depth of one step, Δz = k_E f(T) P Δt / a [m] (wear constant k_E [m³/J], friction power P [W] on
    the area a [m²])."""
    return k_e * wear_factor(p, T) * power * p.dt / a


@wp.kernel
def wear(
    p: LFParams,
    n_cells: wp.int32,
    threads: wp.int32,
    # Model:
    cell_area: wp.array[wp.float64],
    # State in:
    cell_cover: wp.array[wp.float64],
    cell_power: wp.array[wp.float64],
    cell_T: wp.array[wp.float64],
    alive: wp.array[wp.int32],
    area: wp.array[wp.float64],
    patch_power: wp.array[wp.float64],
    patch_T: wp.array[wp.float64],
    patch_cell: wp.array[wp.int32],
    # State in/out:
    cell_z: wp.array[wp.float64],
    thick: wp.array[wp.float64],
    top: wp.array[wp.float64],
    cell_src: wp.array[wp.float64],
    glob: wp.array[wp.float64],
):
    """Energy wear: Δz = k_E f(T) P Δt / a. A fraction f_ret of the debris mass enters the cell's debris source,
    the rest is lost (counted in ``glob``). Blocks and launch as in :func:`friction`."""
    blk, lane = wp.tid()
    n = n_cells + alive.shape[0]
    zero = wp.float64(0.0)
    one = wp.float64(1.0)
    s_in = zero  # debris mass: retained matrix, lost matrix, lost patch [kg]
    s_ml = zero
    s_pl = zero
    j = lane
    while j < LF_BLOCK:
        t = blk * LF_BLOCK + j
        j += threads
        if t >= n:
            continue
        if t < n_cells:
            pw = cell_power[t]
            free = wp.max(cell_area[t] - cell_cover[t], zero)
            if pw <= zero or free <= zero:
                continue
            dz = wear_depth(p, p.wear_m, cell_T[t], pw, free)
            cell_z[t] = cell_z[t] - dz
            m = p.rho_m * dz * free
            wp.atomic_add(cell_src, t, p.f_ret * m)
            s_in += p.f_ret * m
            s_ml += (one - p.f_ret) * m
            continue
        i = t - n_cells
        if alive[i] == 0:
            continue
        pw = patch_power[i]
        if pw <= zero:
            continue
        A = area[i]
        dz = wp.min(wear_depth(p, p.wear_p, patch_T[i], pw, A), thick[i])
        thick[i] = thick[i] - dz
        top[i] = top[i] - dz
        m = p.rho_patch * dz * A
        wp.atomic_add(cell_src, patch_cell[i], p.f_ret * m)
        s_pl += (one - p.f_ret) * m
    block_add(glob, G_MATRIX_IN, s_in, lane)
    block_add(glob, G_MATRIX_LOST, s_ml, lane)
    block_add(glob, G_PATCH_LOST, s_pl, lane)


# ----------------------------------------------------------------------------------------------- debris


@wp.kernel
def debris_sweep(
    p: LFParams,
    threads: wp.int32,
    # Model:
    cell_area: wp.array[wp.float64],
    # State in:
    cell_cover: wp.array[wp.float64],
    cell_chord: wp.array[wp.float64],
    cell_fn: wp.array[wp.float64],
    # State in/out:
    cell_src: wp.array[wp.float64],
    cell_store: wp.array[wp.float64],
    # State out:
    cell_capture_out: wp.array[wp.float64],
    ring_emit_out: wp.array[wp.float64],
):
    """Streamline sweep of the mobile debris along one radial band, leading → trailing edge (one block per ring).

    Per cell: take the source; capture p_cap · min(1, Σ2a/Δr) of the stream by the cell's patches;
    re-mobilise p_remob of the store of a loaded cell; store p_store (1 − coverage) of the stream in the cell's
    gaps up to s_max. What is left at the trailing edge is emitted. Every transfer is a subtraction from one term and
    the same addition to another, so the sweep conserves mass to rounding.

    Only the stream M is sequential: the block computes each chunk of LF_BLOCK cells' terms that do not depend
    on M in parallel into shared memory, then thread 0 walks the chunk. Launch with
    ``wp.launch_tiled(dim=[R], block_dim=LF_BLOCK)``; ``threads`` as in ``aca_warp.hf.block_threads``.
    """
    k, lane = wp.tid()
    src_t = wp.tile_zeros(shape=LF_BLOCK, dtype=wp.float64, storage="shared")
    frac_t = wp.tile_zeros(shape=LF_BLOCK, dtype=wp.float64, storage="shared")
    remob_t = wp.tile_zeros(shape=LF_BLOCK, dtype=wp.float64, storage="shared")
    store_t = wp.tile_zeros(shape=LF_BLOCK, dtype=wp.float64, storage="shared")
    room_t = wp.tile_zeros(shape=LF_BLOCK, dtype=wp.float64, storage="shared")
    open_t = wp.tile_zeros(shape=LF_BLOCK, dtype=wp.float64, storage="shared")
    zero = wp.float64(0.0)
    one = wp.float64(1.0)
    M = zero
    c0 = wp.int32(0)
    while c0 < p.n_t:
        m = wp.min(LF_BLOCK, p.n_t - c0)
        j = lane
        while j < m:
            e = k * p.n_t + c0 + j
            _put(src_t, j, cell_src[e])
            cell_src[e] = zero
            _put(frac_t, j, p.p_cap * wp.min(cell_chord[e] / p.dr, one))
            A = cell_area[e]
            s = cell_store[e]
            dr = zero
            if cell_fn[e] > zero:
                dr = p.p_remob * s
                s = s - dr
            _put(remob_t, j, dr)
            _put(store_t, j, s)
            _put(room_t, j, wp.max(p.rho_patch * p.s_max_thick * A - s, zero))
            _put(open_t, j, p.p_store * (one - wp.min(cell_cover[e] / A, one)))
            j += threads
        block_sync()
        if lane == 0:
            for jj in range(m):
                e = k * p.n_t + c0 + jj
                M = M + src_t[jj]
                cap = frac_t[jj] * M
                cell_capture_out[e] = cap
                M = M - cap
                M = M + remob_t[jj]
                ds = wp.min(open_t[jj] * M, room_t[jj])
                cell_store[e] = store_t[jj] + ds
                M = M - ds
        block_sync()
        c0 += LF_BLOCK
    if lane == 0:
        ring_emit_out[k] = M


@wp.kernel
def capture_gather(
    # State in:
    alive: wp.array[wp.int32],
    area: wp.array[wp.float64],
    patch_cell: wp.array[wp.int32],
    cell_chord: wp.array[wp.float64],
    cell_capture: wp.array[wp.float64],
    # State in/out:
    mcap: wp.array[wp.float64],
):
    """Each patch takes its chord share 2a_i / Σ2a of its cell's captured mass (dim = P)."""
    i = wp.tid()
    if alive[i] == 0:
        return
    e = patch_cell[i]
    c = cell_chord[e]
    if c > wp.float64(0.0):
        mcap[i] = mcap[i] + cell_capture[e] * (wp.float64(2.0) * disc_radius(area[i])) / c


# ----------------------------------------------------------------------------------------------- life cycle


@wp.func
def clamp_inside(p: LFParams, x: wp.float64, y: wp.float64, a: wp.float64) -> wp.vec2d:
    """Move a disc of radius a centred at (x, y) the least amount radially/angularly to lie inside the pad."""
    rp = polar(x, y)
    r = rp[0]
    phi = rp[1]
    r_out = p.r_in + p.dr * wp.float64(p.n_r)
    r = wp.clamp(r, p.r_in + a, r_out - a)
    lim = p.half - wp.asin(wp.min(a / r, wp.float64(1.0)))
    phi = wp.clamp(phi, -lim, lim)
    return wp.vec2d(-r * wp.sin(phi), r * wp.cos(phi))


@wp.kernel
def life_cycle(
    p: LFParams,
    # State in:
    patch_power: wp.array[wp.float64],
    patch_T: wp.array[wp.float64],
    patch_cell: wp.array[wp.int32],
    # State in/out:
    alive: wp.array[wp.int32],
    x: wp.array[wp.float64],
    y: wp.array[wp.float64],
    area: wp.array[wp.float64],
    thick: wp.array[wp.float64],
    top: wp.array[wp.float64],
    mcap: wp.array[wp.float64],
    age: wp.array[wp.float64],
    cell_src: wp.array[wp.float64],
    glob: wp.array[wp.float64],
    # Out:
    death_count: wp.array[wp.int32],
    death_age: wp.array[wp.float64],
    death_area: wp.array[wp.float64],
):
    """Growth from captured debris, shrinking by friction power, death (dim = P); released mass → cell source.

    Growth ΔA = m_cap / (ρ_p t), capped at A_max (excess released). Shrink ΔA = k_shrink P Δt / t. Death when
    A < A_min, t < t_min, T ≥ T_kill, or with probability 1 − exp(−λ0 exp((T − T_c)/T_s) Δt).
    """
    i = wp.tid()
    if alive[i] == 0:
        return
    e = patch_cell[i]
    rho = p.rho_patch
    t = thick[i]
    A = area[i]
    released = wp.float64(0.0)
    if t > wp.float64(0.0):
        A_grow = A + mcap[i] / (rho * t)
        A_new = wp.min(A_grow, wp.max(p.A_max, A))
        released = released + (A_grow - A_new) * rho * t
        ds = wp.min(p.k_shrink * patch_power[i] * p.dt / t, A_new)
        A = A_new - ds
        released = released + ds * rho * t
    else:
        released = released + mcap[i]
    mcap[i] = wp.float64(0.0)
    age[i] = age[i] + p.dt
    T = patch_T[i]
    lam = p.lam0 * wp.exp(wp.min((T - p.T_c) / p.T_s, wp.float64(50.0)))
    u = uniform64(p.seed, wp.uint64(glob[G_STEP]), wp.uint64(i), wp.uint64(1))
    if A < p.A_min or t < p.t_min or T >= p.T_kill or u < wp.float64(1.0) - wp.exp(-lam * p.dt):
        released = released + rho * A * t
        alive[i] = 0  # no G_TOPOLOGY: the grid and candidate lists may keep a dead slot (every query checks alive)
        wp.atomic_add(glob, G_DEATHS, wp.float64(1.0))
        slot = wp.atomic_add(death_count, 0, 1)
        if slot < death_age.shape[0]:
            death_age[slot] = age[i]
            death_area[slot] = A
        A = wp.float64(0.0)
    else:
        xy = clamp_inside(p, x[i], y[i], disc_radius(A))
        x[i] = xy[0]
        y[i] = xy[1]
    area[i] = A
    if released != wp.float64(0.0):
        wp.atomic_add(cell_src, e, released)


@wp.kernel
def merge_target(
    # Model (candidate CSR, rebuilt when the patch set changes):
    nbr_start: wp.array[wp.int32],
    nbr_index: wp.array[wp.int32],
    # State in:
    alive: wp.array[wp.int32],
    x: wp.array[wp.float64],
    y: wp.array[wp.float64],
    area: wp.array[wp.float64],
    # State out:
    target_out: wp.array[wp.int32],
):
    """target[i] = the lowest-index alive patch j < i that overlaps i, else −1 (dim = P)."""
    i = wp.tid()
    target_out[i] = -1
    if alive[i] == 0:
        return
    ai = disc_radius(area[i])
    best = wp.int32(-1)
    for q in range(nbr_start[i], nbr_start[i + 1]):
        j = nbr_index[q]
        if j < i and alive[j] != 0 and (best < 0 or j < best):
            if overlaps(x[i], y[i], ai, x[j], y[j], disc_radius(area[j])):
                best = j
    target_out[i] = best


@wp.kernel
def merge_apply(
    p: LFParams,
    nbr_start: wp.array[wp.int32],
    nbr_index: wp.array[wp.int32],
    target: wp.array[wp.int32],
    patch_cell: wp.array[wp.int32],
    # State in/out (roots write only their own entries, read only absorbed ones):
    alive: wp.array[wp.int32],
    x: wp.array[wp.float64],
    y: wp.array[wp.float64],
    area: wp.array[wp.float64],
    thick: wp.array[wp.float64],
    top: wp.array[wp.float64],
    temp: wp.array[wp.float64],
    age: wp.array[wp.float64],
    cell_src: wp.array[wp.float64],
    glob: wp.array[wp.float64],
):
    """A root (target −1) absorbs every neighbour whose target it is: area sum, area-weighted centroid, top,
    temperature; volume-weighted thickness (mass conserved); oldest age (dim = P). A merged area above
    max(A_max, the root's area) is cut back to it and the cut mass goes to the cell's debris source."""
    i = wp.tid()
    if alive[i] == 0 or target[i] != -1:
        return
    A = area[i]
    sx = A * x[i]
    sy = A * y[i]
    sv = A * thick[i]
    stop = A * top[i]
    sT = A * temp[i]
    ag = age[i]
    n = int(0)
    for q in range(nbr_start[i], nbr_start[i + 1]):
        j = nbr_index[q]
        if target[j] == i:
            Aj = area[j]
            A = A + Aj
            sx = sx + Aj * x[j]
            sy = sy + Aj * y[j]
            sv = sv + Aj * thick[j]
            stop = stop + Aj * top[j]
            sT = sT + Aj * temp[j]
            ag = wp.max(ag, age[j])
            n += 1
    if n == 0:
        return
    t_new = sv / A
    cap = wp.max(p.A_max, area[i])
    if A > cap:
        wp.atomic_add(cell_src, patch_cell[i], (A - cap) * t_new * p.rho_patch)
        sx = sx * (cap / A)
        sy = sy * (cap / A)
        stop = stop * (cap / A)
        sT = sT * (cap / A)
        A = cap
    xy = clamp_inside(p, sx / A, sy / A, disc_radius(A))
    x[i] = xy[0]
    y[i] = xy[1]
    area[i] = A
    thick[i] = t_new
    top[i] = stop / A
    temp[i] = sT / A
    age[i] = ag
    glob[G_TOPOLOGY] = wp.float64(1.0)
    wp.atomic_add(glob, G_MERGES, wp.float64(n))


@wp.kernel
def merge_kill(
    target: wp.array[wp.int32],
    alive: wp.array[wp.int32],
    area: wp.array[wp.float64],
    mcap: wp.array[wp.float64],
):
    """Free the slots of absorbed patches (those whose target is a root) (dim = P)."""
    i = wp.tid()
    t = target[i]
    if t >= 0 and target[t] == -1:
        alive[i] = 0
        area[i] = wp.float64(0.0)
        mcap[i] = wp.float64(0.0)


@wp.kernel
def birth_want(
    p: LFParams,
    grid: wp.uint64,
    query_radius: wp.float64,
    # Model:
    cell_area: wp.array[wp.float64],
    cell_r: wp.array[wp.float64],
    # State in:
    cell_store: wp.array[wp.float64],
    cell_fn: wp.array[wp.float64],
    cell_cover: wp.array[wp.float64],
    alive: wp.array[wp.int32],
    x: wp.array[wp.float64],
    y: wp.array[wp.float64],
    area: wp.array[wp.float64],
    glob: wp.array[wp.float64],
    # State out:
    want_out: wp.array[wp.int32],
    birth_xy_out: wp.array[wp.vec2d],
):
    """Flag a birth in cell e (dim = C): stored debris ≥ ρ_p t0 A0, matrix pressure ≥ p_comp, a draw < p_birth,
    and a free spot for a disc of A0 at a random point of the cell (at least a0 from its edges)."""
    e = wp.tid()
    want_out[e] = 0
    s_crit = p.rho_patch * p.t0 * p.A0
    free = wp.max(cell_area[e] - cell_cover[e], wp.float64(0.0))
    if cell_store[e] < s_crit or free <= wp.float64(0.0) or cell_fn[e] < p.p_comp * free:
        return
    step = wp.uint64(glob[G_STEP])
    if uniform64(p.seed, step, wp.uint64(e), wp.uint64(2)) >= p.p_birth:
        return
    a0 = disc_radius(p.A0)
    k = e / p.n_t
    j = e - k * p.n_t
    r = cell_r[e]
    u1 = uniform64(p.seed, step, wp.uint64(e), wp.uint64(3))
    u2 = uniform64(p.seed, step, wp.uint64(e), wp.uint64(4))
    rr = p.r_in + (wp.float64(k) * p.dr + a0) + u1 * wp.max(p.dr - wp.float64(2.0) * a0, wp.float64(0.0))
    arc = r * p.dphi
    s = wp.float64(j) * arc + a0 + u2 * wp.max(arc - wp.float64(2.0) * a0, wp.float64(0.0))
    phi = -p.half + s / r
    bx = -rr * wp.sin(phi)
    by = rr * wp.cos(phi)
    xy = clamp_inside(p, bx, by, a0)
    q = wp.vec3d(xy[0], xy[1], wp.float64(0.0))
    for i in wp.hash_grid_query(grid, q, query_radius):
        if alive[i] != 0 and overlaps(x[i], y[i], disc_radius(area[i]), xy[0], xy[1], a0):
            return
    want_out[e] = 1
    birth_xy_out[e] = xy


@wp.kernel
def free_slots(alive: wp.array[wp.int32], free_out: wp.array[wp.int32]):
    """free[i] = 1 for an empty slot (dim = P)."""
    i = wp.tid()
    free_out[i] = 1 - wp.min(alive[i], 1)


@wp.kernel
def free_list(free: wp.array[wp.int32], free_rank: wp.array[wp.int32], list_out: wp.array[wp.int32]):
    """list[rank] = slot for every empty slot (dim = P)."""
    i = wp.tid()
    if free[i] != 0:
        list_out[free_rank[i]] = i


@wp.kernel
def birth_apply(
    p: LFParams,
    want: wp.array[wp.int32],
    want_rank: wp.array[wp.int32],
    free: wp.array[wp.int32],
    free_rank: wp.array[wp.int32],
    slot_list: wp.array[wp.int32],
    birth_xy: wp.array[wp.vec2d],
    cell_z: wp.array[wp.float64],
    cell_T: wp.array[wp.float64],
    # State in/out:
    cell_store: wp.array[wp.float64],
    alive: wp.array[wp.int32],
    x: wp.array[wp.float64],
    y: wp.array[wp.float64],
    area: wp.array[wp.float64],
    thick: wp.array[wp.float64],
    top: wp.array[wp.float64],
    temp: wp.array[wp.float64],
    mcap: wp.array[wp.float64],
    age: wp.array[wp.float64],
    glob: wp.array[wp.float64],
):
    """Create the flagged patches in the lowest free slots, in cell order (dim = C); the cell's store pays
    ρ_p t0 A0. Births beyond the capacity are dropped (and pay nothing)."""
    e = wp.tid()
    if want[e] == 0:
        return
    n = free.shape[0]
    n_free = free_rank[n - 1] + free[n - 1]
    r = want_rank[e]
    if r >= n_free:
        return
    i = slot_list[r]
    xy = birth_xy[e]
    alive[i] = 1
    x[i] = xy[0]
    y[i] = xy[1]
    area[i] = p.A0
    thick[i] = p.t0
    top[i] = cell_z[e] + p.t0
    temp[i] = cell_T[e]
    mcap[i] = wp.float64(0.0)
    age[i] = wp.float64(0.0)
    cell_store[e] = cell_store[e] - p.rho_patch * p.t0 * p.A0
    glob[G_TOPOLOGY] = wp.float64(1.0)
    wp.atomic_add(glob, G_BIRTHS, wp.float64(1.0))


# ----------------------------------------------------------------------------------------------- outputs


@wp.kernel
def patch_stats(
    alive: wp.array[wp.int32],
    area: wp.array[wp.float64],
    temp: wp.array[wp.float64],
    glob: wp.array[wp.float64],
):
    """Count, Σ area and Σ A T of the alive patches (dim = P)."""
    i = wp.tid()
    if alive[i] == 0:
        return
    wp.atomic_add(glob, G_COUNT, wp.float64(1.0))
    wp.atomic_add(glob, G_AREA, area[i])
    wp.atomic_add(glob, G_TPATCH, area[i] * temp[i])


@wp.kernel
def record_step(
    pad_area: wp.float64,
    ring_r: wp.array[wp.float64],
    ring_T: wp.array[wp.float64],
    ring_emit: wp.array[wp.float64],
    glob: wp.array[wp.float64],
    hist_out: wp.array2d[wp.float64],
):
    """Write this step's global outputs into the history row of the step counter, then advance it (dim = 1).

    μ = ΣF_F / F_N and r_eff = T / ΣF_F, both 0 without contact (pauses); the emitted debris is summed here.
    """
    row = wp.min(wp.int32(glob[G_STEP]), hist_out.shape[0] - 1)
    fn = glob[G_FN]
    ff = glob[G_FF]
    mu = wp.float64(0.0)
    reff = wp.float64(0.0)
    share = wp.float64(0.0)
    if fn > wp.float64(0.0) and glob[G_LOAD] > wp.float64(0.0):
        mu = ff / fn
        share = glob[G_FN_PATCH] / fn
    if ff > wp.float64(0.0) and glob[G_LOAD] > wp.float64(0.0):
        reff = glob[G_TORQUE] / ff
    tsum = wp.float64(0.0)
    wsum = wp.float64(0.0)
    tmax = ring_T[0]
    em = wp.float64(0.0)
    for k in range(ring_T.shape[0]):
        tsum = tsum + ring_T[k] * ring_r[k]
        wsum = wsum + ring_r[k]
        tmax = wp.max(tmax, ring_T[k])
        em = em + ring_emit[k]
        ring_emit[k] = wp.float64(0.0)
    glob[G_EMITTED] = em
    tp = wp.float64(0.0)
    if glob[G_AREA] > wp.float64(0.0):
        tp = glob[G_TPATCH] / glob[G_AREA]
    if glob[G_LOAD] <= wp.float64(0.0):
        glob[G_GAP] = wp.float64(1.0)  # no contact: restart the next contact solve from the all-active bound
    hist_out[row, H_MU] = mu
    hist_out[row, H_TORQUE] = glob[G_TORQUE]
    hist_out[row, H_REFF] = reff
    hist_out[row, H_COUNT] = glob[G_COUNT]
    hist_out[row, H_COVER] = glob[G_AREA] / pad_area
    hist_out[row, H_TDISC_MEAN] = tsum / wsum
    hist_out[row, H_TDISC_MAX] = tmax
    hist_out[row, H_TPATCH] = tp
    hist_out[row, H_SHARE] = share
    hist_out[row, H_LOAD] = glob[G_LOAD]
    hist_out[row, H_BIRTHS] = glob[G_BIRTHS]
    hist_out[row, H_DEATHS] = glob[G_DEATHS]
    hist_out[row, H_MERGES] = glob[G_MERGES]
    hist_out[row, H_GAP] = glob[G_GAP]
    hist_out[row, H_PASSES] = glob[G_PASSES]
    glob[G_STEP] = glob[G_STEP] + wp.float64(1.0)


@wp.kernel
def set_load(
    schedule: wp.array2d[wp.float64],
    glob: wp.array[wp.float64],
):
    """Copy this step's (F_N, ω) from the schedule table (row = step counter) into ``glob`` (dim = 1)."""
    s = wp.int32(glob[G_STEP])
    s = wp.min(s, schedule.shape[0] - 1)
    glob[G_LOAD] = schedule[s, 0]
    glob[G_OMEGA] = schedule[s, 1]


# ----------------------------------------------------------------------------------------------- neighbours


@wp.kernel
def positions3(
    alive: wp.array[wp.int32],
    x: wp.array[wp.float64],
    y: wp.array[wp.float64],
    park: wp.vec3d,
    pos_out: wp.array[wp.vec3d],
):
    """Points for the hash grid; empty slots all at ``park``, in a cell no query visits (dim = P)."""
    i = wp.tid()
    if alive[i] != 0:
        pos_out[i] = wp.vec3d(x[i], y[i], wp.float64(0.0))
    else:
        pos_out[i] = park


@wp.func
def candidate(i: int, j: int, alive: wp.array[wp.int32], pos: wp.array[wp.vec3d], radius: wp.float64) -> bool:
    """Whether patch j (a hash-grid hit) is a merge candidate of patch i: another alive patch within ``radius``."""
    return j != i and alive[j] != 0 and wp.length_sq(pos[j] - pos[i]) <= radius * radius


@wp.kernel
def count_candidates(
    grid: wp.uint64,
    radius: wp.float64,
    alive: wp.array[wp.int32],
    pos: wp.array[wp.vec3d],
    count_out: wp.array[wp.int32],
):
    """Number of alive patches within ``radius`` of each alive patch (dim = P)."""
    i = wp.tid()
    count_out[i] = 0
    if alive[i] == 0:
        return
    n = int(0)
    for j in wp.hash_grid_query(grid, pos[i], radius):
        if candidate(i, j, alive, pos, radius):
            n += 1
    count_out[i] = n


@wp.kernel
def fill_candidates(
    grid: wp.uint64,
    radius: wp.float64,
    alive: wp.array[wp.int32],
    pos: wp.array[wp.vec3d],
    start: wp.array[wp.int32],
    index_out: wp.array[wp.int32],
):
    """CSR rows of merge candidates, sorted by index within each row (deterministic on every device)."""
    i = wp.tid()
    if alive[i] == 0:
        return
    a = start[i]
    k = a
    for j in wp.hash_grid_query(grid, pos[i], radius):
        if candidate(i, j, alive, pos, radius):
            # insertion sort keeps the row ordered whatever order the grid returns
            q = k
            while q > a and index_out[q - 1] > j:
                index_out[q] = index_out[q - 1]
                q -= 1
            index_out[q] = j
            k += 1


@wp.kernel
def set_row_end(count: wp.array[wp.int32], start: wp.array[wp.int32], n: wp.int32):
    """start[n] = total number of entries (dim = 1)."""
    start[n] = start[n - 1] + count[n - 1]


@wp.kernel
def compact_map(alive: wp.array[wp.int32], rank: wp.array[wp.int32], dst_out: wp.array[wp.int32]):
    """Destination slot of each patch for compaction: alive patches keep their order at the front (dim = P)."""
    i = wp.tid()
    if alive[i] != 0:
        dst_out[i] = rank[i]
    else:
        dst_out[i] = -1


@wp.kernel
def scatter(dst: wp.array[wp.int32], src: wp.array[Any], out: wp.array[Any]):
    """out[dst[i]] = src[i] where dst[i] ≥ 0 (compaction; dim = P)."""
    i = wp.tid()
    if dst[i] >= 0:
        out[dst[i]] = src[i]


for _t in (wp.float64, wp.int32):
    wp.overload(scatter, {"dst": wp.array[wp.int32], "src": wp.array[_t], "out": wp.array[_t]})
