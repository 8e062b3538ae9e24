"""LF kernels of the contact stage: binning the patches into cells, the elements' stiffnesses and heights, the
gap's Newton solve, then the normal forces, friction forces and powers (docs/lf_model.md). Sums over several
elements go through :mod:`~aca_warp.kernels.lf_sums` in a fixed order.
"""

from __future__ import annotations

import warp as wp
from aca_warp.kernels.lf_sums import LFGroups
from aca_warp.kernels.lf_types import (
    G_FF,
    G_FN,
    G_FN_PATCH,
    G_GAP,
    G_LOAD,
    G_OMEGA,
    G_PASSES,
    G_SIZE,
    G_STEP,
    G_TORQUE,
    LF_BLOCK,
    LFCells,
    LFParams,
    LFPatches,
    LFRings,
    block_end,
    disc_radius,
    get_chunk,
    polar,
    put_chunk,
)
from aca_warp.kernels.physics import friction_coefficient
from aca_warp.kernels.tiles import block_put, block_sync

wp.set_module_options({"enable_backward": False})


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


# ----------------------------------------------------------------------------------------------- binning


@wp.kernel
def zero_step(
    # State out:
    cells: LFCells,
    rings: LFRings,
    glob_out: wp.array[wp.float64],
):
    """Reset per-step accumulators (dim = C)."""
    e = wp.tid()
    cells.cover[e] = wp.float64(0.0)
    cells.chord[e] = wp.float64(0.0)
    cells.power[e] = wp.float64(0.0)
    if e < rings.power.shape[0]:
        rings.power[e] = wp.float64(0.0)
    if e == 0:
        for g in range(G_FN, G_SIZE):
            if g != G_GAP and g != G_STEP:
                glob_out[g] = wp.float64(0.0)


@wp.kernel
def bin_patches(
    p: LFParams,
    # State in/out (the patches' cells):
    patches: LFPatches,
):
    """Cell of each alive patch (its centre) (dim = P)."""
    i = wp.tid()
    if patches.alive[i] != 0:
        patches.cell[i] = cell_of(p, patches.x[i], patches.y[i])


@wp.kernel
def cover_chord(
    groups: LFGroups,
    patches: LFPatches,
    # State out (the cells' cover and chord):
    cells: LFCells,
):
    """Per-cell covered area and summed chord 2a of the cell's patches, in slot order (dim = C; a cell without
    patches keeps the zeros of :func:`zero_step`)."""
    e = wp.tid()
    lo = groups.start[e]
    hi = groups.start[e + 1]
    if lo == hi:
        return
    cover = wp.float64(0.0)
    chord = wp.float64(0.0)
    for q in range(lo, hi):
        i = groups.cell[q]
        cover = cover + patches.area[i]
        chord = chord + wp.float64(2.0) * disc_radius(patches.area[i])
    cells.cover[e] = cover
    cells.chord[e] = chord


@wp.func
def element(
    p: LFParams,
    t: wp.int32,
    n_cells: wp.int32,
    cells: LFCells,
    rings: LFRings,
    patches: LFPatches,
) -> wp.vec2d:
    """(stiffness [N/m], free elevation [m]) of element t: cells first, then patch slots; k = 0 if inactive."""
    if t < n_cells:
        free = wp.max(cells.area[t] - cells.cover[t], wp.float64(0.0))
        return wp.vec2d(p.k_m * free, cells.z[t] + rings.bulge[t / p.n_t])
    i = t - n_cells
    if patches.alive[i] == 0:
        return wp.vec2d(wp.float64(0.0), wp.float64(0.0))
    return wp.vec2d(p.K_N * wp.sqrt(patches.area[i]), patches.top[i] + rings.bulge[patches.cell[i] / p.n_t])


# ----------------------------------------------------------------------------------------------- contact


@wp.kernel
def contact_elements(
    p: LFParams,
    n_cells: wp.int32,
    # State in:
    cells: LFCells,
    rings: LFRings,
    patches: LFPatches,
    # Scratch out:
    kh_out: wp.array[wp.vec2d],
):
    """(k, h) of every element for the contact solve (dim = C + P; see :func:`element`)."""
    t = wp.tid()
    kh_out[t] = element(p, t, n_cells, cells, rings, patches)


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
    Launch with ``wp.launch_tiled(dim=[1], block_dim=LF_BLOCK)``; ``threads`` as in
    ``aca_warp.common.devices.block_threads``.
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
    # Scratch in:
    kh: wp.array[wp.vec2d],
    # State in/out (writes the normal forces and powers):
    cells: LFCells,
    patches: LFPatches,
    glob: wp.array[wp.float64],
    # Scratch out (the block's Σ F_N, Σ F_F, Σ r F_F, Σ F_N on patches):
    partial_out: wp.array2d[wp.float64],
):
    """Normal forces at the solved gap (from the contact scratch ``kh``), friction forces and powers, and each
    block's global sums (then :func:`~aca_warp.kernels.lf_sums.add_block_sums`; the rings' powers then
    :func:`ring_power`).

    Block b covers elements b·LF_BLOCK … (b+1)·LF_BLOCK − 1 of the C + P; the block reduces its global sums into
    row b of ``partial_out``. Launch with ``wp.launch_tiled(dim=[⌈(C+P)/LF_BLOCK⌉], block_dim=LF_BLOCK)``.
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
    for t in range(blk * LF_BLOCK + lane, block_end(blk, n), threads):
        e = kh[t]
        fn = e[0] * wp.max(e[1] - g, zero)
        r = zero
        ff = zero
        if t < n_cells:
            r = cells.r[t]
            ff = p.mu_pad * fn
            cells.fn[t] = fn
            cells.power[t] = ff * omega * r
        else:
            i = t - n_cells
            if patches.alive[i] == 0:
                patches.fn[i] = zero
                patches.power[i] = zero
                continue
            r = wp.sqrt(patches.x[i] * patches.x[i] + patches.y[i] * patches.y[i])
            ff = eq4(p, omega * r) * fn
            patches.fn[i] = fn
            patches.power[i] = ff * omega * r
            s_fp += fn
        if fn > zero:
            s_fn += fn
            s_ff += ff
            s_tq += ff * r
    block_put(partial_out, blk, 0, s_fn, lane)
    block_put(partial_out, blk, 1, s_ff, lane)
    block_put(partial_out, blk, 2, s_tq, lane)
    block_put(partial_out, blk, 3, s_fp, lane)


# the glob entries of the columns of ``friction``'s block sums
FRICTION_SUMS = wp.vec4i(G_FN, G_FF, G_TORQUE, G_FN_PATCH)


@wp.kernel
def ring_power(
    p: LFParams,
    threads: wp.int32,
    groups: LFGroups,
    cells: LFCells,
    patches: LFPatches,
    # State out (the rings' powers):
    rings: LFRings,
):
    """Friction power into each disc ring: Σ over its loaded cells, then its loaded patches, in element order (one
    block per ring: the block stages a chunk of LF_BLOCK terms in shared memory, an unloaded element's as +0, and
    thread 0 adds them in order). Launch with ``wp.launch_tiled(dim=[R],
    block_dim=LF_BLOCK)``; ``threads`` as in ``aca_warp.common.devices.block_threads``."""
    k, lane = wp.tid()
    buf = wp.tile_zeros(shape=LF_BLOCK, dtype=wp.float64, storage="shared")
    zero = wp.float64(0.0)
    lo = groups.start[k * p.n_t]
    n = p.n_t + groups.start[(k + 1) * p.n_t] - lo  # the ring's cells, then its patches
    s = zero
    c0 = wp.int32(0)
    while c0 < n:
        m = wp.min(LF_BLOCK, n - c0)
        j = lane
        while j < m:
            t = c0 + j
            v = zero
            if t < p.n_t:
                if cells.fn[k * p.n_t + t] > zero:
                    v = cells.power[k * p.n_t + t]
            else:
                i = groups.ring[lo + t - p.n_t]
                if patches.fn[i] > zero:
                    v = patches.power[i]
            put_chunk(buf, j, v)
            j += threads
        block_sync()
        if lane == 0:
            for jj in range(m):
                s = s + get_chunk(buf, jj)  # an unloaded element's +0 changes no sum that starts at +0
        block_sync()
        c0 += LF_BLOCK
    if lane == 0:
        rings.power[k] = s
