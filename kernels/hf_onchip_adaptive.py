"""On-chip kernel of the ``adaptive`` integrator: one thread block, or a thread-block cluster, per pad runs its
Dormand–Prince 5(4) trials, step control and samples for many sample intervals per launch.

Block ``rank`` of a K-block cluster owns patches n·rank // K … n·(rank + 1) // K − 1 of the pad; its threads own
every B-th of them (B threads; one on the CPU, where Warp runs a block as one thread). A trial is six stage
evaluations separated by barriers of the pad (a stage reads its neighbours' stage displacements, written by other
threads and blocks), the pad's error as a maximum over its blocks (each block's maximum stored into every block's
shared table), the step decision (:func:`~aca_warp.kernels.hf_adaptive.pi_decide`), taken alike by thread 0 of
every block on its own copy of the pad's control (block 0 writes it to ``ctl``/``mode`` for the host and the
checkpoints), the commit and the next trial's first stage state. On landing, block 0 records the
sample (:func:`~aca_warp.kernels.physics.record_pad`, the per-patch histories) and opens the next interval; a growing
pad also lands on its growth events and grows there (the factory's ``growth``). Every block
keeps the pad's stage displacements in shared memory, two rows (odd and even stages), and each new stage
displacement is stored into every block of the cluster (distributed shared memory, released and acquired by the
cluster barrier that follows), so the neighbour gathers read shared memory only; the block's neighbour lists are
kept there too where they fit. The state, the stages, the stage velocities and the control stay in the general
engine's arrays in global memory, so a pad's step is its own, no launch waits for another pad and checkpoints hold
what the general engine's hold.

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
from aca_warp.kernels.hf_adaptive import (
    C_TARGET,
    C_TRIAL,
    M_LANDED,
    M_NEEDK1,
    STAGES,
    at_event,
    at_sample,
    commit_patch,
    count_trial,
    load_control,
    open_decide,
    open_growth_decide,
    patch_error,
    pi_decide,
    stage_k,
    stage_state_h,
    store_control,
)
from aca_warp.kernels.hf_onchip_gather import tile_gather
from aca_warp.kernels.hf_types import HFAdaptive, HFModel, HFRecorder
from aca_warp.kernels.physics import (
    contact_block,
    grow_patch,
    patch_coupling,
    patch_sample_due,
    record_pad,
    spring_force,
    store_patch_sample,
)
from aca_warp.kernels.tiles import (
    block_sync,
    cluster_sync,
    lane_first,
    lane_sum,
    tile_load_1d,
    tile_load_rows,
    tile_store_1d,
    tile_store_rows,
    tile_store_rows_remote,
)

wp.set_module_options({"enable_backward": False})


ABLATIONS = frozenset({"gather", "record", "sync"})


@cache
def onchip_dp5_kernel(
    dtype: Any,
    cluster: int = 1,
    block_dim: int = 256,
    lanes: int = 1,
    nmax: int = 32,
    emax: int = 0,
    ablate: frozenset[str] = frozenset(),
    growth: bool = False,
) -> wp.Kernel:
    """The on-chip DP5 kernel in precision ``dtype`` on ``cluster`` blocks per pad (CUDA sm_90+ for more than one)
    of ``block_dim`` threads, for pads of at most ``nmax`` patches. Launch with ``wp.launch_tiled(kernel,
    dim=[pads · cluster], block_dim=block_dim)``; ``threads`` must be the block size the device really runs
    (``block_dim`` on CUDA or with CPU fibers, else 1).

    Every block keeps the stage displacements of the whole pad in shared memory (two rows, ``nmax`` each: the odd
    and the even stages), and each new stage displacement is stored into every block of the cluster (distributed
    shared memory; visible after the next cluster barrier), so a stage's neighbour gathers read shared memory only.
    ``emax`` > 0: the block's own neighbour lists (at most ``emax`` links, local int16 indices and k_ij) are kept
    in shared memory too; 0: read from global memory.

    ``lanes`` (CUDA only, a power of two ≤ 32 dividing ``block_dim``): threads per patch of a stage evaluation;
    lane l of a patch sums its links l, l + lanes, … and the lanes add their sums by warp shuffles
    (:func:`~aca_warp.kernels.tiles.lane_sum`). 1: one thread per patch, the general engine's sums in its order
    (bit-identical on the CPU).

    ``growth``: growth events (paper Eq. 10) at their times j·``interval``, landed on like the samples: a pad
    landed on one grows its patches (``grow_patch``, each block its own), recomputes their coupling stiffnesses
    (``patch_coupling``, and the block's shared copy of them), re-solves its contact in every block
    (``contact_block``, each block keeping its own patches' normal forces) and evaluates its first stage again, as
    the general engine's growth launches and its next trial do; at an event that is also a sample time the event
    comes first. Without it the growth arrays are not read (may be empty).

    ``ablate`` (profiling only, ``scripts/profile_onchip_adaptive.py``; the results are then wrong) leaves out
    ``gather`` (the neighbour sums of the stage evaluations with lanes), ``record`` (the samples' global outputs)
    or ``sync`` (the barriers between stages)."""
    if not ablate <= ABLATIONS:
        raise ValueError(f"unknown ablations {sorted(ablate - ABLATIONS)}")
    if nmax >= 2**15:
        raise ValueError(f"on-chip pads hold fewer than 32768 patches (int16 neighbour indices), got {nmax}")
    T = dtype
    Model = HFModel(T)
    Recorder = HFRecorder(T)
    Adaptive = HFAdaptive(T)
    GATHER = wp.constant(0 if "gather" in ablate else 1)
    RECORD = wp.constant(0 if "record" in ablate else 1)
    SYNC = wp.constant(0 if "sync" in ablate else 1)
    CLUSTER = wp.constant(cluster)
    LANES = wp.constant(lanes)
    NMAX = wp.constant(nmax)
    EMAX = wp.constant(max(emax, 1))
    total = lane_sum(dtype, lanes)
    first_lane = lane_first(dtype, lanes)
    slots = max(cluster, 6)
    SLOTS = wp.constant(slots)
    # row 0: the blocks' error maxima; row 1: the decision [accepted, step underflow, trial step, landed] and, on
    # landing, what the target is [event, sample]
    put_red = tile_store_rows(wp.float64, 2, slots)
    put_red_at = tile_store_rows_remote(wp.float64, 2, slots)
    get_red = tile_load_rows(wp.float64, 2, slots)
    put_u = tile_store_rows(dtype, 2, nmax)
    put_u_at = tile_store_rows_remote(dtype, 2, nmax)
    get_u = tile_load_rows(dtype, 2, nmax)
    put_ei = tile_store_1d(wp.int16, max(emax, 1))
    get_ei = tile_load_1d(wp.int16, max(emax, 1))
    put_ek = tile_store_1d(dtype, max(emax, 1))
    get_ek = tile_load_1d(dtype, max(emax, 1))
    pad_sync = block_sync if cluster == 1 else cluster_sync  # (a one-block "cluster" barrier would be dearer)
    links_sum = tile_gather(T, nmax, max(emax, 1), emax > 0, 1, 2)  # the neighbour sums, two links per pass

    @wp.func
    def share(us: wp.tile[T, 2, NMAX], row: int, i: int, x: T, q0: int, dq: int):
        """Stage displacement ``x`` of local patch i into row ``row`` of the blocks q0, q0 + dq, … of the cluster."""
        if wp.static(cluster == 1):
            if q0 == 0:
                put_u(us, row, i, x)
        else:
            q = q0
            while q < CLUSTER:
                put_u_at(us, row, i, x, q)
                q += dq

    @wp.func
    def open_trial(
        lo: int,
        hi: int,
        a: int,
        lane: int,
        threads: int,
        pad: int,
        need_k0: bool,
        model: Model,
        dp5: Adaptive,
        h: wp.float64,
        u_io: wp.array[T],
        v_io: wp.array[T],
        us: wp.tile[T, 2, NMAX],
    ):
        """The start of a trial of step ``h`` [s] for the block's patches lo … hi − 1 (global indices, pad from
        ``a``): with ``need_k0`` their k_0 at the state itself, from the displacements in global memory (the run's
        first trial, or after a growth event: FSAL's k_0 is of the patches before it); then their first stage state
        y_1 into buffer b, its displacements shared with every block (row 1)."""
        if need_k0:
            g = lo + lane
            while g < hi:
                fs = spring_force(g, u_io, model)
                stage_k(g, pad, 0, fs, model, dp5, h, u_io, v_io, v_io, dp5.u_b, dp5.v_b)
                g += threads
        g = lo + lane
        while g < hi:
            stage_state_h(g, 1, dp5, h, u_io, v_io, dp5.u_b, dp5.v_b)
            share(us, 1, g - a, dp5.u_b[g], 0, 1)
            g += threads

    @wp.func
    def stage_next(
        g: int, pad: int, stage: int, row: int, fs: T, model: Model, dp5: Adaptive, h: wp.float64, u_io: wp.array[T],
        v_io: wp.array[T],
    ) -> T:  # fmt: skip
        """k_s of patch g (elastic force ``fs`` [N]) at its stage state in row ``row``'s buffer (1: b, the odd
        stages; 0: a, the even ones) and its next stage state into the other buffer; returns the next stage
        displacement (0 after the last stage)."""
        un = T(0.0)
        if row == 1:
            stage_k(g, pad, stage, fs, model, dp5, h, u_io, v_io, dp5.v_b, dp5.u_a, dp5.v_a)
            if stage + 1 < STAGES:
                un = dp5.u_a[g]
        else:
            stage_k(g, pad, stage, fs, model, dp5, h, u_io, v_io, dp5.v_a, dp5.u_b, dp5.v_b)
            if stage + 1 < STAGES:
                un = dp5.u_b[g]
        return un

    @wp.func
    def grow(
        lo: int,
        hi: int,
        lane: int,
        threads: int,
        pad: int,
        rank: int,
        base: int,
        gap: wp.float64,
        sk: wp.tile[T, EMAX],
        model: Model,
    ) -> wp.float64:
        """A growth event of the pad (see the factory): its new contact gap [m]; on return every block of the pad has
        its patches' new areas, stiffnesses and normal forces in global memory (a pad barrier follows)."""
        g = lo + lane
        while g < hi:
            grow_patch(g, pad, model)
            g += threads
        pad_sync()  # the links below read the neighbours' new √A, the contact every new area and k_N
        g = lo + lane
        while g < hi:
            patch_coupling(g, pad, model)
            if wp.static(emax > 0):
                for e in range(model.nbr_start[g], model.nbr_start[g + 1]):
                    put_ek(sk, e - base, model.nbr_stiffness[e])
            g += threads
        gap = contact_block(pad, lane, threads, model, gap, lo, hi, rank == 0)
        pad_sync()  # the sample reads every new normal force, k_0 the new stiffnesses
        return gap

    @wp.func
    def lane_gather(
        g: int,
        a: int,
        base: int,
        row: int,
        sub: int,
        us: wp.tile[T, 2, NMAX],
        sidx: wp.tile[wp.int16, EMAX],
        sk: wp.tile[T, EMAX],
        model: Model,
    ):
        """Lane ``sub``'s part of the neighbour sum of patch g: its links sub, sub + LANES, …"""
        part = T(0.0)
        link = model.nbr_start[g] + sub
        end = model.nbr_start[g + 1]
        if GATHER == 0:
            end = link
        if wp.static(emax > 0):
            while link < end:
                part += get_ek(sk, link - base) * get_u(us, row, int(get_ei(sidx, link - base)))
                link += LANES
        else:
            while link < end:
                part += model.nbr_stiffness[link] * get_u(us, row, model.nbr_index[link] - a)
                link += LANES
        return part

    @wp.kernel(enable_backward=False, module="unique", launch_bounds=(block_dim, 1), cluster_dim=cluster)
    def onchip_dp5(
        model: Model,  # growth fields read only with growth (pad_growth: the increment per event)
        rec: Recorder,
        dp5: Adaptive,
        # Control:
        threads: int,
        samples: int,
        k0: int,
        row0: int,
        prow0: int,
        # State in/out:
        u_io: wp.array[T],
        v_io: wp.array[T],
    ):
        """Advance pad ``pad`` through ``samples`` sample intervals (its interval is open unless the run is over),
        recording sample ``k0 + s`` into globals row ``row0 + s`` and, when due, per-patch rows from ``prow0``.

        Stage states alternate between buffer b (odd stages; shared row 1) and a (even stages, row 0; the
        5th-order solution y_6 ends in a). The pad stops early when its step falls below ``dp5.h_min`` (block 0 sets
        ``dp5.done[2]``); after the run's last sample (target ≥ ``dp5.t_end``) it stays landed.
        """
        blk, lane = wp.tid()
        pad = blk // CLUSTER
        rank = blk % CLUSTER
        a = model.pad_patch_start[pad]
        n = model.pad_patch_start[pad + 1] - a
        lo = a + n * rank // CLUSTER  # this block's patches (global indices): lo … hi − 1
        hi = a + n * (rank + 1) // CLUSTER
        base = model.nbr_start[lo]  # the block's first link
        red = wp.tile_zeros(shape=(2, SLOTS), dtype=wp.float64, storage="shared")
        us = wp.tile_zeros(shape=(2, NMAX), dtype=T, storage="shared")
        sidx = wp.tile_zeros(shape=EMAX, dtype=wp.int16, storage="shared")
        sk = wp.tile_zeros(shape=EMAX, dtype=T, storage="shared")
        if wp.static(emax > 0):
            link = base + lane
            while link < model.nbr_start[hi]:
                put_ei(sidx, link - base, wp.int16(model.nbr_index[link] - a))
                put_ek(sk, link - base, model.nbr_stiffness[link])
                link += threads
        pad_sync()  # every block's tiles are zeroed before another stores into them
        # Every block keeps the pad's control (clock, steps, mode) and takes the same decisions on it; block 0 also
        # writes it to ctl and mode (the checkpoint's and the host's copy), which no block reads during the launch.
        c, m = load_control(pad, dp5)
        h = c[C_TRIAL]
        landed = m[M_LANDED]
        gap = wp.float64(0.0)
        if wp.static(growth):
            gap = model.pad_gap[pad]  # the contact's warm start, kept here and stored by block 0 at the end
        if landed == 0:  # k_0 at the state itself when the run starts here
            open_trial(lo, hi, a, lane, threads, pad, m[M_NEEDK1] != 0, model, dp5, h, u_io, v_io, us)
        m[M_NEEDK1] = 0
        pad_sync()  # every block has read ctl and mode before block 0 writes them
        stop = int(0)
        prow = prow0
        s = int(0)
        while s < samples and stop == 0:
            while landed == 0 and stop == 0:
                stage = int(1)
                while stage < STAGES:  # each evaluation also forms its patch's next stage state
                    row = stage % 2  # odd stages in row 1 (buffer b), even ones in row 0 (buffer a)
                    if wp.static(lanes == 1):
                        g = lo + lane
                        while g < hi:
                            first_link = model.nbr_start[g]  # the links in spring_force's order (tile_gather)
                            links, _p = links_sum(
                                first_link, model.nbr_start[g + 1], first_link - base, row, a, us, sidx, sk,
                                model.nbr_index, model.nbr_stiffness,
                            )  # fmt: skip
                            fs = links - model.k_diag[g] * get_u(us, row, g - a)
                            un = stage_next(g, pad, stage, row, fs, model, dp5, h, u_io, v_io)
                            if stage + 1 < STAGES:
                                share(us, 1 - row, g - a, un, 0, 1)
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
                                fsum = lane_gather(g, a, base, row, sub, us, sidx, sk, model)
                            fsum = total(fsum)
                            un = T(0.0)
                            if sub == 0 and j < own:
                                fs = fsum - model.k_diag[g] * get_u(us, row, j + lo - a)
                                un = stage_next(g, pad, stage, row, fs, model, dp5, h, u_io, v_io)
                            un = first_lane(un)  # the lanes of the patch share its stores into the cluster
                            if j < own and stage + 1 < STAGES:
                                share(us, 1 - row, j + lo - a, un, sub, LANES)
                    if stage + 1 < STAGES and SYNC != 0:
                        pad_sync()
                    elif wp.static(lanes > 1):  # the error and the commit read k_6 of the block's patches, which
                        block_sync()  # other threads of the block wrote (with one lane per patch: the same thread)
                    stage += 1
                part = wp.float64(0.0)
                g = lo + lane
                while g < hi:
                    e = patch_error(g, pad, h, model, dp5, u_io, v_io, dp5.u_a, dp5.v_a)
                    part = wp.max(part, e)
                    g += threads
                err = wp.tile_max(wp.tile(part))[0]
                if wp.static(cluster > 1):  # every block's maximum into every block's table
                    if lane == 0:
                        for q in range(CLUSTER):
                            put_red_at(red, 0, rank, err, q)
                    cluster_sync()
                if lane == 0:  # the same decision in every block (every block's maximum, in rank order: the same err)
                    if wp.static(cluster > 1):
                        err = get_red(red, 0, 0)
                        for q in range(1, CLUSTER):
                            err = wp.max(err, get_red(red, 0, q))
                    c, m, accepted, underflow = pi_decide(c, m, err, dp5.h_max, dp5.h_min)
                    if rank == 0:
                        store_control(pad, c, m, dp5)
                        count_trial(pad, accepted, underflow, dp5)
                    put_red(red, 1, 0, wp.float64(accepted))
                    put_red(red, 1, 1, wp.float64(underflow))
                    put_red(red, 1, 2, c[C_TRIAL])
                    put_red(red, 1, 3, wp.float64(m[M_LANDED]))
                block_sync()
                stop = int(get_red(red, 1, 1))
                h = get_red(red, 1, 2)
                landed = int(get_red(red, 1, 3))
                g = lo + lane
                while g < hi:
                    if get_red(red, 1, 0) != wp.float64(0.0):  # accepted: y_6 is the state, k_6 the next k_0 (FSAL)
                        commit_patch(g, dp5, dp5.u_a, dp5.v_a, u_io, v_io)
                    if landed == 0 and stop == 0:
                        stage_state_h(g, 1, dp5, h, u_io, v_io, dp5.u_b, dp5.v_b)
                        share(us, 1, g - a, dp5.u_b[g], 0, 1)
                    g += threads
                pad_sync()  # the commit and the next first stage are complete, the flags read before lane 0 rewrites
            if stop == 0:
                event = int(0)
                sample = int(1)
                if wp.static(growth):  # what the pad landed on: an event time, a sample time or both
                    if lane == 0:
                        put_red(red, 1, 4, wp.float64(int(at_event(c, m, dp5.sample_dt, dp5.interval))))
                        put_red(red, 1, 5, wp.float64(int(at_sample(c, m, dp5.sample_dt, dp5.interval))))
                    block_sync()
                    event = int(get_red(red, 1, 4))
                    sample = int(get_red(red, 1, 5))
                    if event != 0:  # before a sample at the same time, which sees the grown patches
                        gap = grow(lo, hi, lane, threads, pad, rank, base, gap, sk, model)
                if sample != 0:
                    k = k0 + s
                    if rank == 0 and RECORD != 0:
                        record_pad(pad, lane, threads, row0 + s, k, model, u_io, v_io, v_io, v_io, 0, rec)
                    if patch_sample_due(rec, k):
                        g = lo + lane
                        while g < hi:
                            store_patch_sample(rec, prow, g, v_io[g], u_io[g])
                            g += threads
                        prow += 1
                if lane == 0:
                    if sample == 0 or c[C_TARGET] < dp5.t_end * (wp.float64(1.0) - wp.float64(1.0e-12)):
                        if wp.static(growth):
                            c, m = open_growth_decide(c, m, dp5.sample_dt, dp5.interval)
                        else:
                            c, m = open_decide(c, m, dp5.sample_dt)
                        if rank == 0:
                            store_control(pad, c, m, dp5)
                    put_red(red, 1, 2, c[C_TRIAL])
                    put_red(red, 1, 3, wp.float64(m[M_LANDED]))
                block_sync()
                h = get_red(red, 1, 2)
                landed = int(get_red(red, 1, 3))
                if landed == 0:  # k_0 again after a growth event
                    open_trial(lo, hi, a, lane, threads, pad, event != 0, model, dp5, h, u_io, v_io, us)
                pad_sync()  # the first stage is complete (and shared), the flags read before lane 0 rewrites them
                s += sample
        if wp.static(cluster > 1):
            cluster_sync()  # no block leaves while another may still store into its shared memory
        if wp.static(growth):
            if rank == 0 and lane == 0:
                model.pad_gap[pad] = gap

    return onchip_dp5
