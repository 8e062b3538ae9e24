"""On-chip kernel of the ``adaptive`` integrator: one thread block, or a thread-block cluster, per pad runs its
Dormand–Prince 5(4) trials, step control and samples for many sample intervals per launch.

Block ``rank`` of a K-block cluster owns patches n·rank // K … n·(rank + 1) // K − 1 of the pad; its threads own
every B-th of them (B threads; one on the CPU, where Warp runs a block as one thread). A trial is six stage
evaluations separated by barriers of the pad (a stage reads its neighbours' stage displacements, written by other
threads and blocks), the pad's error as a maximum over its blocks (each block's maximum into block 0's shared
table), the step decision by thread 0 of block 0 (:func:`~aca_warp.kernels.hf_adaptive.pi_control`, broadcast into
every block's shared memory), the commit and the next trial's first stage state. On landing, block 0 records the
sample (:func:`~aca_warp.kernels.hf.record_pad`, the per-patch histories) and opens the next interval. The state,
the stages and the control live in the general engine's arrays in global memory (a cluster barrier releases and
acquires them across its blocks), so a pad's step is its own and no launch waits for another pad.

Same per-patch arithmetic as the general engine's kernels (:mod:`aca_warp.kernels.hf_adaptive`: the same
``wp.func`` s in the same order), so on the CPU the runs are bit-identical to it; on CUDA the general engine may
read a patch's links with 32 lanes and both reduce a sample's sums over threads, which reorders float sums.
Barrier rule: :mod:`aca_warp.kernels.tiles` (every barrier and block reduction sits in block-uniform loops).
"""

# Annotations stay eager (no ``from __future__ import annotations``): the kernel made in the factory is typed by the
# factory's precision T, which string annotations could not see.
from functools import cache
from typing import Any

import warp as wp
from aca_warp.kernels.hf import patch_sample_due, record_pad, spring_force
from aca_warp.kernels.hf_adaptive import (
    C_TARGET,
    C_TRIAL,
    M_LANDED,
    M_NEEDK1,
    STAGES,
    acceleration,
    open_interval,
    patch_error,
    pi_control,
    stage_state,
)
from aca_warp.kernels.tiles import (
    block_sync,
    cluster_sync,
    lane_sum,
    tile_load_rows,
    tile_store_rows,
    tile_store_rows_remote,
)

wp.set_module_options({"enable_backward": False})


@wp.func
def stage_rest(
    i: int,
    p: int,
    stage: int,
    fs: Any,
    inv_mass: wp.array[Any],
    damping: wp.array[Any],
    normal_force: wp.array[Any],
    radius: wp.array[Any],
    pad_omega: wp.array[Any],
    pad_mu_scale: wp.array[Any],
    pad_slope: wp.array[Any],
    pad_decay: wp.array[Any],
    coeff: wp.array2d[wp.float64],
    ctl: wp.array2d[wp.float64],
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    v_stage: wp.array[Any],
    ku: wp.array2d[Any],
    kv: wp.array2d[Any],
    u_next: wp.array[Any],
    v_next: wp.array[Any],
):
    """Patch i's k_s from its elastic force ``fs`` [N] at the stage state and, for 0 < s < 6, its next stage state
    (the rest of ``dp5_eval``)."""
    v = v_stage[i]
    ku[stage, i] = v
    kv[stage, i] = acceleration(
        i, p, fs, v, inv_mass, damping, normal_force, radius, pad_omega, pad_mu_scale, pad_slope, pad_decay
    )
    if stage > 0 and stage + 1 < STAGES:
        stage_state(i, p, stage + 1, coeff, ctl, u_in, v_in, ku, kv, u_next, v_next)


@wp.func
def stage_eval(
    i: int,
    p: int,
    stage: int,
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
    coeff: wp.array2d[wp.float64],
    ctl: wp.array2d[wp.float64],
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    u_stage: wp.array[Any],
    v_stage: wp.array[Any],
    ku: wp.array2d[Any],
    kv: wp.array2d[Any],
    u_next: wp.array[Any],
    v_next: wp.array[Any],
):
    """Patch i's k_s and next stage state by one thread (``dp5_eval`` with one lane: the same sums)."""
    fs = spring_force(i, u_stage, k_diag, nbr_start, nbr_index, nbr_stiffness)
    stage_rest(
        i, p, stage, fs, inv_mass, damping, normal_force, radius, pad_omega, pad_mu_scale, pad_slope, pad_decay, coeff,
        ctl, u_in, v_in, v_stage, ku, kv, u_next, v_next,
    )  # fmt: skip


ABLATIONS = frozenset({"gather", "record", "sync"})


@cache
def onchip_dp5_kernel(
    dtype: Any, cluster: int = 1, block_dim: int = 256, lanes: int = 1, ablate: frozenset[str] = frozenset()
) -> wp.Kernel:
    """The on-chip DP5 kernel in precision ``dtype`` on ``cluster`` blocks per pad (CUDA sm_90+ for more than one)
    of ``block_dim`` threads. Launch with ``wp.launch_tiled(kernel, dim=[pads · cluster], block_dim=block_dim)``;
    ``threads`` must be the block size the device really runs (``block_dim`` on CUDA or with CPU fibers, else 1).

    ``lanes`` (CUDA only, a power of two ≤ 32 dividing ``block_dim``): threads per patch of a stage evaluation;
    lane l of a patch sums its links l, l + lanes, … and the lanes add their sums by warp shuffles
    (:func:`~aca_warp.kernels.tiles.lane_sum`), so the links of a row are read side by side (coalesced) instead of
    in one dependent chain. 1: one thread per patch, the general engine's sums (bit-identical on the CPU).

    ``ablate`` (profiling only, ``scripts/profile_onchip_adaptive.py``; the results are then wrong) leaves out
    ``gather`` (the neighbour sums of the stage evaluations with lanes), ``record`` (the samples' global outputs)
    or ``sync`` (the barriers between stages)."""
    if not ablate <= ABLATIONS:
        raise ValueError(f"unknown ablations {sorted(ablate - ABLATIONS)}")
    T = dtype
    GATHER = wp.constant(0 if "gather" in ablate else 1)
    RECORD = wp.constant(0 if "record" in ablate else 1)
    SYNC = wp.constant(0 if "sync" in ablate else 1)
    CLUSTER = wp.constant(cluster)
    LANES = wp.constant(lanes)
    total = lane_sum(dtype, lanes)
    SLOTS = wp.constant(max(cluster, 2))
    put_red = tile_store_rows(wp.float64, 2, max(cluster, 2))  # row 0: the blocks' errors; row 1: [accepted, stop]
    put_red_at = tile_store_rows_remote(wp.float64, 2, max(cluster, 2))
    get_red = tile_load_rows(wp.float64, 2, max(cluster, 2))
    pad_sync = block_sync if cluster == 1 else cluster_sync  # (a one-block "cluster" barrier would be dearer)

    @wp.func
    def stage_one(
        lo: int,
        hi: int,
        lane: int,
        threads: int,
        pad: int,
        coeff: wp.array2d[wp.float64],
        ctl: wp.array2d[wp.float64],
        u_io: wp.array[T],
        v_io: wp.array[T],
        ku: wp.array2d[T],
        kv: wp.array2d[T],
        u_b: wp.array[T],
        v_b: wp.array[T],
    ):
        """The first stage state y_1 of the block's patches lo … hi − 1 (global indices) at the pad's trial step."""
        g = lo + lane
        while g < hi:
            stage_state(g, pad, 1, coeff, ctl, u_io, v_io, ku, kv, u_b, v_b)
            g += threads

    @wp.kernel(enable_backward=False, module="unique", launch_bounds=(block_dim, 1), cluster_dim=cluster)
    def onchip_dp5(
        # Model:
        pad_patch_start: wp.array[wp.int32],
        inv_mass: wp.array[T],
        k_diag: wp.array[T],
        damping: wp.array[T],
        normal_force: wp.array[T],
        radius: wp.array[T],
        nbr_start: wp.array[wp.int32],
        nbr_index: wp.array[wp.int32],
        nbr_stiffness: wp.array[T],
        pad_omega: wp.array[T],
        pad_mu_scale: wp.array[T],
        pad_slope: wp.array[T],
        pad_decay: wp.array[T],
        pad_mu_pad: wp.array[T],
        pad_load: wp.array[T],
        pad_matrix_force: wp.array[T],
        pad_matrix_radius: wp.array[T],
        k_t: wp.array[T],
        x: wp.array[T],
        y: wp.array[T],
        # Integrator:
        coeff: wp.array2d[wp.float64],
        err_coeff: wp.array[wp.float64],
        u_scale: wp.array[T],
        v_scale: wp.array[T],
        tol: wp.float64,
        h_max: wp.float64,
        h_min: wp.float64,
        sample_dt: wp.float64,
        t_end: wp.float64,
        # Control:
        threads: int,
        samples: int,
        k0: int,
        row0: int,
        prow0: int,
        first: int,
        last: int,
        every: int,
        # State in/out:
        u_io: wp.array[T],
        v_io: wp.array[T],
        # Integrator state in/out (stages, two stage-state buffers, per-pad control):
        ku: wp.array2d[T],
        kv: wp.array2d[T],
        u_a: wp.array[T],
        v_a: wp.array[T],
        u_b: wp.array[T],
        v_b: wp.array[T],
        ctl: wp.array2d[wp.float64],
        mode: wp.array2d[wp.int32],
        stats: wp.array2d[wp.int64],
        done: wp.array[wp.int32],
        # Recorder out:
        globals_out: wp.array3d[wp.float64],
        watch_bound: wp.array[wp.float64],
        fault_out: wp.array2d[wp.int32],
        fault_value_out: wp.array[wp.float64],
        velocity_out: wp.array2d[T],
        displacement_out: wp.array2d[T],
    ):
        """Advance pad ``pad`` through ``samples`` sample intervals (its interval is open unless the run is over),
        recording sample ``k0 + s`` into globals row ``row0 + s`` and, when due, per-patch rows from ``prow0``.

        Stage states alternate between buffer b (odd stages) and a (even stages; the 5th-order solution y_6 ends in
        a). The pad stops early when a step falls below ``h_min`` (``done[2]``, which stops every pad that sees it);
        after the run's last sample (target ≥ ``t_end``) it stays landed.
        """
        blk, lane = wp.tid()
        pad = blk // CLUSTER
        rank = blk % CLUSTER
        a = pad_patch_start[pad]
        n = pad_patch_start[pad + 1] - a
        lo = a + n * rank // CLUSTER  # this block's patches (global indices): lo … hi − 1
        hi = a + n * (rank + 1) // CLUSTER
        red = wp.tile_zeros(shape=(2, SLOTS), dtype=wp.float64, storage="shared")
        landed = mode[pad, M_LANDED]
        if landed == 0:
            if mode[pad, M_NEEDK1] != 0:  # k_0 at the state itself (the run's first trial)
                g = lo + lane
                while g < hi:
                    stage_eval(
                        g, pad, 0, inv_mass, k_diag, damping, normal_force, radius, nbr_start, nbr_index,
                        nbr_stiffness, pad_omega, pad_mu_scale, pad_slope, pad_decay, coeff, ctl, u_io, v_io, u_io,
                        v_io, ku, kv, u_b, v_b,
                    )  # fmt: skip
                    g += threads
            stage_one(lo, hi, lane, threads, pad, coeff, ctl, u_io, v_io, ku, kv, u_b, v_b)
        pad_sync()  # every block has read the mode before block 0 may change it
        if rank == 0 and lane == 0:
            mode[pad, M_NEEDK1] = 0
        stop = int(0)
        prow = prow0
        s = int(0)
        while s < samples and stop == 0:
            while landed == 0 and stop == 0:
                stage = int(1)
                while stage < STAGES:  # each evaluation also forms its patch's next stage state
                    if wp.static(lanes == 1):
                        g = lo + lane
                        while g < hi:
                            if stage % 2 == 1:
                                stage_eval(
                                    g, pad, stage, inv_mass, k_diag, damping, normal_force, radius, nbr_start,
                                    nbr_index, nbr_stiffness, pad_omega, pad_mu_scale, pad_slope, pad_decay, coeff,
                                    ctl, u_io, v_io, u_b, v_b, ku, kv, u_a, v_a,
                                )  # fmt: skip
                            else:
                                stage_eval(
                                    g, pad, stage, inv_mass, k_diag, damping, normal_force, radius, nbr_start,
                                    nbr_index, nbr_stiffness, pad_omega, pad_mu_scale, pad_slope, pad_decay, coeff,
                                    ctl, u_io, v_io, u_a, v_a, ku, kv, u_b, v_b,
                                )  # fmt: skip
                            g += threads
                    else:  # LANES threads per patch; every thread runs the same rounds (the shuffles need them all)
                        slots = threads // LANES
                        sub = lane % LANES
                        own = hi - lo
                        for r in range((own + slots - 1) // slots):
                            j = r * slots + lane // LANES
                            g = lo + j
                            fsum = T(0.0)
                            if j < own:
                                link = nbr_start[g] + sub
                                end = nbr_start[g + 1]
                                if GATHER == 0:
                                    end = link
                                if stage % 2 == 1:
                                    while link < end:
                                        fsum += nbr_stiffness[link] * u_b[nbr_index[link]]
                                        link += LANES
                                else:
                                    while link < end:
                                        fsum += nbr_stiffness[link] * u_a[nbr_index[link]]
                                        link += LANES
                            fsum = total(fsum)
                            if sub == 0 and j < own:
                                if stage % 2 == 1:
                                    stage_rest(
                                        g, pad, stage, fsum - k_diag[g] * u_b[g], inv_mass, damping, normal_force,
                                        radius, pad_omega, pad_mu_scale, pad_slope, pad_decay, coeff, ctl, u_io, v_io,
                                        v_b, ku, kv, u_a, v_a,
                                    )  # fmt: skip
                                else:
                                    stage_rest(
                                        g, pad, stage, fsum - k_diag[g] * u_a[g], inv_mass, damping, normal_force,
                                        radius, pad_omega, pad_mu_scale, pad_slope, pad_decay, coeff, ctl, u_io, v_io,
                                        v_a, ku, kv, u_b, v_b,
                                    )  # fmt: skip
                    if stage + 1 < STAGES and SYNC != 0:
                        pad_sync()
                    elif wp.static(lanes > 1):  # the error and the commit read k_6 of the block's patches, which
                        block_sync()  # other threads of the block wrote (with one lane per patch: the same thread)
                    stage += 1
                h = ctl[pad, C_TRIAL]
                part = wp.float64(0.0)
                g = lo + lane
                while g < hi:
                    e = patch_error(g, pad, h, tol, err_coeff, u_scale, v_scale, radius, pad_omega, pad_mu_scale,
                                    pad_slope, pad_decay, u_io, v_io, u_a, v_a, ku, kv)  # fmt: skip
                    part = wp.max(part, e)
                    g += threads
                err = wp.tile_max(wp.tile(part))[0]
                if wp.static(cluster > 1):  # the blocks' maxima into block 0's table
                    if lane == 0:
                        put_red_at(red, 0, rank, err, 0)
                    cluster_sync()
                if rank == 0 and lane == 0:
                    for q in range(1, CLUSTER):
                        err = wp.max(err, get_red(red, 0, q))
                    accepted = wp.float64(pi_control(pad, err, h_max, h_min, ctl, mode, stats, done))
                    halt = wp.float64(done[2])
                    for q in range(CLUSTER):
                        if wp.static(cluster > 1):
                            put_red_at(red, 1, 0, accepted, q)
                            put_red_at(red, 1, 1, halt, q)
                        else:
                            put_red(red, 1, 0, accepted)
                            put_red(red, 1, 1, halt)
                pad_sync()
                landed = mode[pad, M_LANDED]
                stop = int(get_red(red, 1, 1))
                g = lo + lane
                while g < hi:
                    if get_red(red, 1, 0) != wp.float64(0.0):  # accepted: y_6 is the state, k_6 the next k_0 (FSAL)
                        u_io[g] = u_a[g]
                        v_io[g] = v_a[g]
                        ku[0, g] = ku[STAGES - 1, g]
                        kv[0, g] = kv[STAGES - 1, g]
                    if landed == 0 and stop == 0:
                        stage_state(g, pad, 1, coeff, ctl, u_io, v_io, ku, kv, u_b, v_b)
                    g += threads
                pad_sync()  # the commit and the next first stage are complete, the flags read before block 0 rewrites
            if stop == 0:
                k = k0 + s
                if rank == 0 and RECORD != 0:
                    record_pad(
                        pad, lane, threads, row0 + s, k, pad_patch_start, normal_force, radius, pad_omega,
                        pad_mu_scale, pad_slope, pad_decay, pad_mu_pad, pad_load, pad_matrix_force, pad_matrix_radius,
                        inv_mass, k_t, x, y, u_io, v_io, globals_out, watch_bound, fault_out, fault_value_out,
                    )  # fmt: skip
                if patch_sample_due(k, first, last, every):
                    g = lo + lane
                    while g < hi:
                        velocity_out[prow, g] = v_io[g]
                        if displacement_out.shape[0] > 0:
                            displacement_out[prow, g] = u_io[g]
                        g += threads
                    prow += 1
                if rank == 0 and lane == 0 and ctl[pad, C_TARGET] < t_end * (wp.float64(1.0) - wp.float64(1.0e-12)):
                    open_interval(pad, sample_dt, ctl, mode)
                pad_sync()
                landed = mode[pad, M_LANDED]
                if landed == 0:
                    stage_one(lo, hi, lane, threads, pad, coeff, ctl, u_io, v_io, ku, kv, u_b, v_b)
                pad_sync()  # the first stage is complete and the mode read before block 0 may change it
                s += 1

    return onchip_dp5
