"""LF kernels of wear and the debris it releases: energy wear of cells and patches, the streamline sweep of the
mobile debris along each ring, and its capture by the patches (docs/lf_model.md).
"""

from __future__ import annotations

import warp as wp
from aca_warp.kernels.lf_types import (
    G_MATRIX_IN,
    G_MATRIX_LOST,
    G_PATCH_LOST,
    LF_BLOCK,
    LFCells,
    LFParams,
    LFPatches,
    LFRings,
    block_end,
    disc_radius,
    put_chunk,
)
from aca_warp.kernels.tiles import block_put, block_sync

wp.set_module_options({"enable_backward": False})


@wp.func
def wear_factor(p: LFParams, T: wp.float64) -> wp.float64:
    if p.wear_T > wp.float64(0.0):
        return wp.exp(wp.min((T - p.T_amb) / p.wear_T, wp.float64(50.0)))
    return wp.float64(1.0)


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
    # State in/out (the cells' elevations and debris sources, the patches' thicknesses and tops):
    cells: LFCells,
    patches: LFPatches,
    # Scratch out (per slot: the retained debris of the patch's wear [kg]; per block: Σ retained matrix debris,
    # Σ lost matrix debris, Σ lost patch debris [kg]):
    src_out: wp.array[wp.float64],
    partial_out: wp.array2d[wp.float64],
):
    """Energy wear: Δz = k_E f(T) P Δt / a. A fraction f_ret of the debris mass enters the cell's debris source
    (a cell's own at once; a patch's into ``src_out``, then added to its cell's by
    :func:`~aca_warp.kernels.lf_sums.add_by_cell`), the rest is lost (the blocks' sums into ``partial_out``, then
    :func:`~aca_warp.kernels.lf_sums.add_block_sums`). Blocks and launch as in
    :func:`~aca_warp.kernels.lf_contact.friction`."""
    blk, lane = wp.tid()
    n = n_cells + patches.alive.shape[0]
    zero = wp.float64(0.0)
    one = wp.float64(1.0)
    s_in = zero  # debris mass: retained matrix, lost matrix, lost patch [kg]
    s_ml = zero
    s_pl = zero
    for t in range(blk * LF_BLOCK + lane, block_end(blk, n), threads):
        if t < n_cells:
            pw = cells.power[t]
            free = wp.max(cells.area[t] - cells.cover[t], zero)
            if pw <= zero or free <= zero:
                continue
            dz = wear_depth(p, p.wear_m, cells.T[t], pw, free)
            cells.z[t] = cells.z[t] - dz
            m = p.rho_m * dz * free
            cells.src[t] = cells.src[t] + p.f_ret * m
            s_in += p.f_ret * m
            s_ml += (one - p.f_ret) * m
            continue
        i = t - n_cells
        src_out[i] = zero
        if patches.alive[i] == 0:
            continue
        pw = patches.power[i]
        if pw <= zero:
            continue
        A = patches.area[i]
        dz = wp.min(wear_depth(p, p.wear_p, patches.temp[i], pw, A), patches.thick[i])
        patches.thick[i] = patches.thick[i] - dz
        patches.top[i] = patches.top[i] - dz
        m = p.rho_patch * dz * A
        src_out[i] = p.f_ret * m
        s_pl += (one - p.f_ret) * m
    block_put(partial_out, blk, 0, s_in, lane)
    block_put(partial_out, blk, 1, s_ml, lane)
    block_put(partial_out, blk, 2, s_pl, lane)


# the glob entries of the columns of ``wear``'s block sums (the fourth unused)
WEAR_SUMS = wp.vec4i(G_MATRIX_IN, G_MATRIX_LOST, G_PATCH_LOST, -1)


# ----------------------------------------------------------------------------------------------- debris


@wp.kernel
def debris_sweep(
    p: LFParams,
    threads: wp.int32,
    # State in/out (the cells' sources, stores and captures, the rings' emitted debris):
    cells: LFCells,
    rings: LFRings,
):
    """Streamline sweep of the mobile debris along one radial band, leading → trailing edge (one block per ring).

    Per cell: take the source; capture p_cap · min(1, Σ2a/Δr) of the stream by the cell's patches;
    re-mobilise p_remob of the store of a loaded cell; store p_store (1 − coverage) of the stream in the cell's
    gaps up to s_max. What is left at the trailing edge is emitted. Every transfer is a subtraction from one term and
    the same addition to another, so the sweep conserves mass to rounding.

    Only the stream M is sequential: the block computes each chunk of LF_BLOCK cells' terms that do not depend
    on M in parallel into shared memory, then thread 0 walks the chunk. Launch with
    ``wp.launch_tiled(dim=[R], block_dim=LF_BLOCK)``; ``threads`` as in ``aca_warp.common.devices.block_threads``.
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
            put_chunk(src_t, j, cells.src[e])
            cells.src[e] = zero
            put_chunk(frac_t, j, p.p_cap * wp.min(cells.chord[e] / p.dr, one))
            A = cells.area[e]
            s = cells.store[e]
            dr = zero
            if cells.fn[e] > zero:
                dr = p.p_remob * s
                s = s - dr
            put_chunk(remob_t, j, dr)
            put_chunk(store_t, j, s)
            put_chunk(room_t, j, wp.max(p.rho_patch * p.s_max_thick * A - s, zero))
            put_chunk(open_t, j, p.p_store * (one - wp.min(cells.cover[e] / A, one)))
            j += threads
        block_sync()
        if lane == 0:
            for jj in range(m):
                e = k * p.n_t + c0 + jj
                M = M + src_t[jj]
                cap = frac_t[jj] * M
                cells.capture[e] = cap
                M = M - cap
                M = M + remob_t[jj]
                ds = wp.min(open_t[jj] * M, room_t[jj])
                cells.store[e] = store_t[jj] + ds
                M = M - ds
        block_sync()
        c0 += LF_BLOCK
    if lane == 0:
        rings.emit[k] = M


@wp.kernel
def capture_gather(
    # State in/out (the patches' captured debris):
    cells: LFCells,
    patches: LFPatches,
):
    """Each patch takes its chord share 2a_i / Σ2a of its cell's captured mass (dim = P)."""
    i = wp.tid()
    if patches.alive[i] == 0:
        return
    e = patches.cell[i]
    c = cells.chord[e]
    if c > wp.float64(0.0):
        patches.mcap[i] = patches.mcap[i] + cells.capture[e] * (wp.float64(2.0) * disc_radius(patches.area[i])) / c
