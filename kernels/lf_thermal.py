"""LF kernels of the temperatures: the disc rings (radial conduction, backward Euler by the Thomas algorithm) and
their thermal bulge, the pad cells and the patches against their ring and the pad bulk (docs/lf_model.md).
"""

from __future__ import annotations

import warp as wp
from aca_warp.kernels.lf_types import (
    LF_BLOCK,
    LFCells,
    LFParams,
    LFPatches,
    LFRings,
    disc_radius,
    get_chunk,
    put_chunk,
)
from aca_warp.kernels.tiles import block_sync

wp.set_module_options({"enable_backward": False})


@wp.kernel
def disc_temperature(
    p: LFParams,
    threads: wp.int32,
    # State in/out (the rings' temperatures and bulge):
    rings: LFRings,
    work: wp.array[wp.float64],
):
    """Backward Euler of the ring temperatures with radial conduction (Thomas algorithm; one block, dim = [1]).

    C_k dT_k/dt = γ P_k − h A_k (T_k − T_amb) + G_k−½ (T_k−1 − T_k) + G_k+½ (T_k+1 − T_k);
    then the thermal bulge Δz_k = κ α d (T_k − T_amb) toward the pad.

    A chunk of LF_BLOCK rings at a time: the block's threads form the rings' coefficients in shared memory, thread 0
    runs the forward recurrence over them (c'_k, d'_k, carried in registers from chunk to chunk), and the threads
    copy c', d' to ``work`` ([0, n) c', [n, 2n) d'); then, from the last chunk back, the threads load c', d', thread
    0 runs the back substitution and the threads store T_k and the bulge. Thread 0 reads only shared memory, so that
    its serial recurrences do not wait on global loads. Launch with ``wp.launch_tiled(dim=[1],
    block_dim=LF_BLOCK)``; ``threads`` as in ``aca_warp.common.devices.block_threads``.
    """
    _blk, lane = wp.tid()
    x0 = wp.tile_zeros(shape=LF_BLOCK, dtype=wp.float64, storage="shared")  # diagonal, then c'
    x1 = wp.tile_zeros(shape=LF_BLOCK, dtype=wp.float64, storage="shared")  # right-hand side, then d'
    x2 = wp.tile_zeros(shape=LF_BLOCK, dtype=wp.float64, storage="shared")  # sub-diagonal a, then T
    x3 = wp.tile_zeros(shape=LF_BLOCK, dtype=wp.float64, storage="shared")  # super-diagonal c
    n = p.n_r
    dt = p.dt
    two_pi = wp.float64(2.0 * wp.pi)
    cp = wp.float64(0.0)
    dp = wp.float64(0.0)
    c0 = wp.int32(0)
    while c0 < n:
        m = wp.min(LF_BLOCK, n - c0)
        j = lane
        while j < m:
            k = c0 + j
            r = rings.r[k]
            C = p.rho_d * p.c_d * two_pi * r * p.dr * p.d_d
            hA = p.h_conv * wp.float64(2.0) * two_pi * r * p.dr
            g_lo = wp.float64(0.0)
            g_hi = wp.float64(0.0)
            if k > 0:
                g_lo = p.k_d * two_pi * (r - wp.float64(0.5) * p.dr) * p.d_d / p.dr
            if k < n - 1:
                g_hi = p.k_d * two_pi * (r + wp.float64(0.5) * p.dr) * p.d_d / p.dr
            put_chunk(x0, j, C / dt + hA + g_lo + g_hi)
            put_chunk(x1, j, C / dt * rings.T[k] + p.gamma_disc * rings.power[k] + hA * p.T_amb)
            put_chunk(x2, j, -g_lo)
            put_chunk(x3, j, -g_hi)
            j += threads
        block_sync()
        if lane == 0:
            for jj in range(m):
                diag = get_chunk(x0, jj)
                rhs = get_chunk(x1, jj)
                a = get_chunk(x2, jj)
                c = get_chunk(x3, jj)
                if c0 + jj > 0:
                    mk = diag - a * cp
                    cp = c / mk
                    dp = (rhs - a * dp) / mk
                else:
                    cp = c / diag
                    dp = rhs / diag
                put_chunk(x0, jj, cp)
                put_chunk(x1, jj, dp)
        block_sync()
        j = lane
        while j < m:
            work[c0 + j] = get_chunk(x0, j)
            work[n + c0 + j] = get_chunk(x1, j)
            j += threads
        block_sync()
        c0 += LF_BLOCK
    bulge = p.kappa_d * p.alpha_d * p.d_d  # Δz per kelvin above ambient [m/K]
    T_next = dp
    c0 = (n - 1) // LF_BLOCK * LF_BLOCK
    while c0 >= 0:
        m = wp.min(LF_BLOCK, n - c0)
        j = lane
        while j < m:
            put_chunk(x0, j, work[c0 + j])
            put_chunk(x1, j, work[n + c0 + j])
            j += threads
        block_sync()
        if lane == 0:
            for jj in range(m):
                q = m - 1 - jj
                if c0 + q < n - 1:
                    T_next = get_chunk(x1, q) - get_chunk(x0, q) * T_next
                put_chunk(x2, q, T_next)
        block_sync()
        j = lane
        while j < m:
            T = get_chunk(x2, j)
            rings.T[c0 + j] = T
            rings.bulge[c0 + j] = bulge * (T - p.T_amb)
            j += threads
        block_sync()
        c0 -= LF_BLOCK


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
    first: wp.int32,
    # State in/out (the cells' and patches' temperatures):
    cells: LFCells,
    rings: LFRings,
    patches: LFPatches,
):
    """Backward Euler of a pad cell (t < C) or patch (t ≥ C) temperature against its disc ring and the pad bulk.

    Cell: C_e = ρ_p c_p A_e t_eff, heated by (1 − γ) P_e, contact conductance h_pd a_e to the ring while in
    contact, k_p A_e / L_b to the bulk at T_amb. Patch: C_i = ρ_p c_p A_i t_eff, (1 − γ) P_i, flash
    (constriction) conductance 4 k_d a_i to the ring while loaded, k_p A_i / L_b to its cell. Element t =
    ``first`` + thread: launched for the cells (first 0, dim C), then for the patches (first C, dim P), so a patch
    couples to its cell's new temperature (operator split), whatever order the threads run in.
    """
    t = wp.tid() + first
    dt = p.dt
    if t < n_cells:
        A = cells.area[t]
        C = p.rho_p * p.c_p * A * p.t_eff
        g_d = wp.float64(0.0)
        if cells.fn[t] > wp.float64(0.0):
            g_d = p.h_pd * A
        g_b = p.k_p * A / p.L_b
        Td = rings.T[t / p.n_t]
        q = (wp.float64(1.0) - p.gamma_disc) * cells.power[t]
        cells.T[t] = implicit_temperature(C / dt, cells.T[t], q, g_d, Td, g_b, p.T_amb)
        return
    i = t - n_cells
    if patches.alive[i] == 0:
        return
    A = patches.area[i]
    e = patches.cell[i]
    C = p.rho_p * p.c_p * A * p.t_eff
    g_d = wp.float64(0.0)
    if patches.fn[i] > wp.float64(0.0):
        g_d = wp.float64(4.0) * p.k_d * disc_radius(A)
    g_b = p.k_p * A / p.L_b
    Td = rings.T[e / p.n_t]
    q = (wp.float64(1.0) - p.gamma_disc) * patches.power[i]
    patches.temp[i] = implicit_temperature(C / dt, patches.temp[i], q, g_d, Td, g_b, cells.T[e])
