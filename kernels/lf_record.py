"""LF kernels of a step's load and outputs: this step's clamp force and disc speed from the schedule, the patch
statistics and the deaths' calibration lists, and the history row (docs/lf_model.md).
"""

from __future__ import annotations

import warp as wp
from aca_warp.kernels.lf_types import (
    G_AREA,
    G_BIRTHS,
    G_COUNT,
    G_DEATHS,
    G_EMITTED,
    G_FF,
    G_FN,
    G_FN_PATCH,
    G_GAP,
    G_LOAD,
    G_MERGES,
    G_OMEGA,
    G_PASSES,
    G_STEP,
    G_TORQUE,
    G_TPATCH,
    LF_BLOCK,
    LFPatches,
    LFRings,
    get_chunk,
    put_chunk,
)
from aca_warp.kernels.tiles import block_sync

wp.set_module_options({"enable_backward": False})

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


@wp.kernel
def patch_stats(
    threads: wp.int32,
    patches: LFPatches,
    # In/out (this step's deaths, from ``life_cycle``; the flags are cleared):
    died: wp.array[wp.int32],
    died_at: wp.array[wp.vec2d],
    # Out:
    glob: wp.array[wp.float64],
    death_count: wp.array[wp.int32],
    death_age: wp.array[wp.float64],
    death_area: wp.array[wp.float64],
):
    """Count, Σ area and Σ A T of the alive patches onto ``glob``, and this step's deaths appended to the
    calibration lists ``death_age``/``death_area`` (as far as they reach; ``death_count`` counts them all), both
    in slot order (one block, dim = [1]).

    The block finds the last slot that is alive or died this step, the alive count (a whole number: its sum is
    exact in any order) and whether any died (block-wide reductions). Then, up to the last slot, it loads a chunk of
    LF_BLOCK slots' areas, A T and death flags into shared memory in parallel (an empty slot's terms as +0, which
    changes no sum that starts at +0; the flags cleared), and thread 0 adds the terms in slot order and, on a step
    with deaths, appends the chunk's deaths.
    Launch with ``wp.launch_tiled(dim=[1], block_dim=LF_BLOCK)``; ``threads`` as in
    ``aca_warp.common.devices.block_threads``.
    """
    _blk, lane = wp.tid()
    a_t = wp.tile_zeros(shape=LF_BLOCK, dtype=wp.float64, storage="shared")
    at_t = wp.tile_zeros(shape=LF_BLOCK, dtype=wp.float64, storage="shared")
    d_t = wp.tile_zeros(shape=LF_BLOCK, dtype=wp.float64, storage="shared")
    zero = wp.float64(0.0)
    n = patches.alive.shape[0]
    s_a = glob[G_AREA]
    s_at = glob[G_TPATCH]
    last = int(-1)
    alive = int(0)
    deaths = int(0)
    for i in range(lane, n, threads):
        if patches.alive[i] != 0:
            alive += 1
            last = i
        if died[i] != 0:
            deaths += 1
            last = i
    end = wp.tile_max(wp.tile(last))[0] + 1
    alive = wp.tile_sum(wp.tile(alive))[0]
    deaths = wp.tile_sum(wp.tile(deaths))[0]
    c0 = wp.int32(0)
    while c0 < end:
        m = wp.min(LF_BLOCK, end - c0)
        j = lane
        while j < m:
            i = c0 + j
            if patches.alive[i] != 0:
                put_chunk(a_t, j, patches.area[i])
                put_chunk(at_t, j, patches.area[i] * patches.temp[i])
            else:
                put_chunk(a_t, j, zero)
                put_chunk(at_t, j, zero)
            put_chunk(d_t, j, wp.float64(died[i]))
            died[i] = 0
            j += threads
        block_sync()
        if lane == 0:
            jj = wp.int32(0)
            while jj + 4 <= m:  # four slots' loads at once, then their adds in slot order
                a0 = get_chunk(a_t, jj)
                a1 = get_chunk(a_t, jj + 1)
                a2 = get_chunk(a_t, jj + 2)
                a3 = get_chunk(a_t, jj + 3)
                b0 = get_chunk(at_t, jj)
                b1 = get_chunk(at_t, jj + 1)
                b2 = get_chunk(at_t, jj + 2)
                b3 = get_chunk(at_t, jj + 3)
                s_a = s_a + a0
                s_at = s_at + b0
                s_a = s_a + a1
                s_at = s_at + b1
                s_a = s_a + a2
                s_at = s_at + b2
                s_a = s_a + a3
                s_at = s_at + b3
                jj += 4
            while jj < m:
                s_a = s_a + get_chunk(a_t, jj)
                s_at = s_at + get_chunk(at_t, jj)
                jj += 1
            if deaths > 0:
                for jj in range(m):
                    if get_chunk(d_t, jj) != zero:
                        slot = death_count[0]
                        if slot < death_age.shape[0]:
                            rec = died_at[c0 + jj]
                            death_age[slot] = rec[0]
                            death_area[slot] = rec[1]
                        death_count[0] = slot + 1
        block_sync()
        c0 += LF_BLOCK
    if lane == 0:
        glob[G_COUNT] = glob[G_COUNT] + wp.float64(alive)  # the sum of alive × 1.0 in any order
        glob[G_AREA] = s_a
        glob[G_TPATCH] = s_at


@wp.kernel
def record_step(
    pad_area: wp.float64,
    rings: LFRings,
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
    tmax = rings.T[0]
    em = wp.float64(0.0)
    for k in range(rings.T.shape[0]):
        tsum = tsum + rings.T[k] * rings.r[k]
        wsum = wsum + rings.r[k]
        tmax = wp.max(tmax, rings.T[k])
        em = em + rings.emit[k]
        rings.emit[k] = wp.float64(0.0)
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
