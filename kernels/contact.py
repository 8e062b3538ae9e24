"""The contact of an HF pad on the flat matrix: the normal forces from the clamp load (one home for every engine).

:func:`contact_block` re-solves one pad's normal forces in one thread block; the general engine's growth events
(``contact_flat`` in :mod:`aca_warp.kernels.hf`) and both on-chip kernels call it.
"""

from __future__ import annotations

from typing import Any

import warp as wp

wp.set_module_options({"enable_backward": False})


@wp.func
def contact_block(
    pad: int,
    lane: int,
    threads: int,
    pad_patch_start: wp.array[wp.int32],
    k_n: wp.array[Any],
    height: wp.array[Any],
    area: wp.array[Any],
    radius: wp.array[Any],
    pad_area: wp.array[wp.float64],
    pad_moment: wp.array[wp.float64],
    pad_k_m: wp.array[wp.float64],
    pad_load: wp.array[Any],
    gap: wp.float64,
    out_start: int,
    out_end: int,
    writer: bool,
    normal_force_out: wp.array[Any],
    pad_matrix_force_out: wp.array[Any],
    pad_matrix_radius_out: wp.array[Any],
) -> wp.float64:
    """Re-solve the normal forces of one pad on a flat matrix at elevation 0 (one thread block per pad).

    Σ_i k_N,i max(h_i − g, 0) + k_m a_free max(−g, 0) = F_N by Newton from the left of the root (monotone
    and exact on a piecewise-linear convex function), warm-started from the previous gap; it stops when the step
    falls below 1e-15 of the gap or stops being positive (the rounding floor of the block sums; with the first
    test alone, the re-solve late in the varying-area study cost 7.3 µs per step on the H100 against 1.0 µs after
    this stop, docs/onchip.md). Launch with
    ``wp.launch_tiled(dim=[pads], block_dim=B)``; ``threads`` is the block size the device runs (B on CUDA, 1 on
    the CPU): thread ``lane`` sums patches lane, lane + B, … and the block reduces the sums, so every thread
    sees the same values and takes the same branches (the block-wide reductions stay outside per-thread code).
    Every thread of the block must call it (block-wide reductions inside).

    ``gap``: the previous gap g [m] (the warm start); returns the new one (unchanged when the load is 0), which the
    caller stores. Writes the normal forces of the patches ``out_start`` … ``out_end − 1`` only (global indices;
    the pad's whole range on the general path, a block's own part in a cluster, where every block of the cluster
    solves the same contact redundantly) and, when ``writer``, the pad's matrix force and radius.
    """
    s = pad_patch_start[pad]
    e = pad_patch_start[pad + 1]
    zero = wp.float64(0.0)
    load = wp.float64(pad_load[pad])
    covered = zero
    moment = zero
    hmin = zero
    ktot = zero
    i = s + lane
    while i < e:
        covered += wp.float64(area[i])
        moment += wp.float64(area[i] * radius[i])
        hmin = wp.min(hmin, wp.float64(height[i]))
        ktot += wp.float64(k_n[i])
        i += threads
    covered = wp.tile_sum(wp.tile(covered))[0]
    moment = wp.tile_sum(wp.tile(moment))[0]
    hmin = wp.tile_min(wp.tile(hmin))[0]
    ktot = wp.tile_sum(wp.tile(ktot))[0]
    free = wp.max(pad_area[pad] - covered, zero)
    km = pad_k_m[pad] * free
    ktot += km
    if free > zero and lane == 0 and writer:
        pad_matrix_radius_out[pad] = type(pad_load[pad])((pad_moment[pad] - moment) / free)
    g = gap
    if load > zero:
        for it in range(200):
            fp = zero
            kp = zero
            i = s + lane
            while i < e:
                d = wp.float64(height[i]) - g
                if d > zero:
                    fp += wp.float64(k_n[i]) * d
                    kp += wp.float64(k_n[i])
                i += threads
            f = km * wp.max(-g, zero) + wp.tile_sum(wp.tile(fp))[0]
            kact = wp.tile_sum(wp.tile(kp))[0]
            if g < zero:
                kact += km
            if it == 0 and f < load:
                g = hmin - load / ktot  # restart left of the root, where every element is compressed
                continue
            if kact <= zero:
                break
            dg = (f - load) / kact
            if dg <= zero:  # from the left of the root Newton only moves right: here f = F_N to rounding
                break
            g = g + dg
            if dg <= wp.float64(1.0e-15) * (wp.abs(g) + wp.float64(1.0e-9)):
                break
    i = out_start + lane
    while i < out_end:
        f_i = zero
        if load > zero:
            f_i = wp.float64(k_n[i]) * wp.max(wp.float64(height[i]) - g, zero)
        normal_force_out[i] = type(pad_load[pad])(f_i)
        i += threads
    if lane == 0 and writer:
        if load > zero:
            pad_matrix_force_out[pad] = type(pad_load[pad])(km * wp.max(-g, zero))
        else:
            pad_matrix_force_out[pad] = type(pad_load[pad])(0.0)
    return g
