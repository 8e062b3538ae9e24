"""LF kernels of a step's load and outputs: this step's clamp force and disc speed from the schedule, the patch
statistics, and the history row (docs/lf_model.md).
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
    LFPatches,
    LFRings,
)

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
    patches: LFPatches,
    glob: wp.array[wp.float64],
):
    """Count, Σ area and Σ A T of the alive patches (dim = P)."""
    i = wp.tid()
    if patches.alive[i] == 0:
        return
    wp.atomic_add(glob, G_COUNT, wp.float64(1.0))
    wp.atomic_add(glob, G_AREA, patches.area[i])
    wp.atomic_add(glob, G_TPATCH, patches.area[i] * patches.temp[i])


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
