"""On-chip HF kernel: one thread block (or a thread-block cluster) per pad, many ``strang`` steps per launch, a
sample's sums reduced per warp in the kernel and per pad after the launch (:func:`pad_samples_kernel`).

Each block keeps its pad's state in shared memory (Warp tiles with ``storage="shared"``):

* ``u`` twice (double buffer: step n reads buffer n mod 2 and writes the other, so one block barrier per step
  suffices: the drift of step n+1 writes the buffer that the gathers of step n do not read),
* the staggered velocity ``w`` and the cached spring force F_s(u), both touched only by the owning thread,
* optionally (``csr_shared``) the pad's neighbour lists (local index int16, k_ij in T), bank-interleaved:
  each thread's links one after another, link m at slot W·(s + m) + lane mod W (W = 32 on CUDA; s: the links of
  the earlier threads with the same lane mod W, :func:`aca_warp.hf.onchip.csr_slots`), so the lanes of a warp read
  32 different banks whatever their rows' lengths; otherwise the CSR is read from global memory (read-only,
  L1/L2 cached).

Per-patch constants (1/m, c, F_N, r, k_diag) stay in global memory (read-only, cached). Thread ``lane`` owns patches
lane, lane + B, lane + 2B, … of its pad (B the block size; 1 on the CPU, where Warp runs a block as one thread). The
arithmetic per patch is that of the general path's kernels (:mod:`aca_warp.kernels.hf`): the same ``wp.func`` s
(``strang_velocity``, ``strang_sample_velocity``, the gather order of ``spring_force``, the sample sums of
:mod:`aca_warp.kernels.physics`), so on the CPU the results are bit-identical to the general per-step path; on the GPU
a sample's sums are taken in another order (a tree over each warp's threads, then the warps and blocks in order), so
the global outputs differ in the last bits. With a cluster of K blocks per pad (sm_90+), each block owns 1/K of the
patches and keeps a full copy of ``u`` (:func:`onchip_kernel`).

Kernels are made per configuration (precision, max patches per pad, max links per block, csr_shared, block
size, ablations, fast math, growth, cluster size) by :func:`onchip_kernel`: tile shapes are compile-time
constants.

Barrier rule: see :mod:`aca_warp.kernels.tiles` (no block-cooperative op inside the per-thread
``while i < n`` loops, whose trip counts differ between threads); per-thread stores into the shared tiles use
its barrier-free ``put`` helpers: a ``tile[i] = x`` there made the kernel hang on an H100 (docs/onchip.md,
"History: the CUDA hang").
"""

# Annotations stay eager (no ``from __future__ import annotations``): the kernel made in the factory is typed by the
# factory's model struct, which string annotations could not see.
from functools import cache
from typing import Any

import warp as wp
from aca_warp.kernels.hf_onchip_gather import tile_gather
from aca_warp.kernels.hf_types import HFModel, HFRecorder
from aca_warp.kernels.physics import (
    SampleSums,
    contact_block,
    contact_block_from,
    energy_speed2,
    flag_fault,
    grow_patch,
    grown_area,
    instant_velocity,
    link_stiffness,
    link_stiffness4,
    patch_sample,
    patch_sample_due,
    store_grown_patch,
    store_patch_sample,
    strang_sample_velocity,
    strang_velocity,
    write_globals,
)
from aca_warp.kernels.tiles import (
    block_sync,
    cluster_sync,
    lowest_bit,
    mbarrier_ops,
    tile_load_1d,
    tile_load_rows,
    tile_store_1d,
    tile_store_rows,
    tile_store_rows_async,
    tile_store_rows_remote,
    warp_index,
    warp_leader,
    warp_min,
    warp_pick,
    warp_sum,
)

wp.set_module_options({"enable_backward": False})


@wp.func
def readers(g: int, a: int, n: int, k: int, nbr_start: wp.array[wp.int32], nbr_index: wp.array[wp.int32]) -> int:
    """Bit mask of the blocks of a k-block cluster that own a neighbour of patch g (pad start a, n patches; block
    r owns n·r // k … n·(r + 1) // k − 1): the blocks that read u_g in their gather."""
    m = int(0)
    for e in range(nbr_start[g], nbr_start[g + 1]):
        j = nbr_index[e] - a
        r = j * k // n
        while n * (r + 1) // k <= j:
            r += 1
        while n * r // k > j:
            r -= 1
        m = m | (1 << r)
    return m


ABLATIONS = frozenset(
    {
        "friction",
        "gather",
        "sync",
        "coupling",
        "contact",
        "gather_half",
        "sample",
    }
)
# a block's float64 sums of a sample: the six SampleSums (kernels.physics), then Σ u (for the watchdog)
PadSums = wp.types.vector(length=7, dtype=wp.float64)
# entries of a warp's part of a sample (float64, the last axis of the kernel's ``parts``): the seven PadSums, its
# first non-finite patch, its first runaway patch (n: none) and that patch's energy speed [m/s]; in the first warp
# of a pad's first block also the pad's matrix force [N] and radius [m] at the sample (growth changes them)
PART = 12


@cache
def onchip_kernel(
    dtype: Any,
    nmax: int,
    emax: int,
    csr_shared: bool,
    block_dim: int,
    ablate: frozenset[str] = frozenset(),
    fast_math: bool = False,
    growth: bool = False,
    cluster: int = 1,
    lanes: int = 32,
    grown_tiles: bool = False,
    crossing: bool = False,
) -> wp.Kernel:
    """The on-chip strang kernel for pads of at most ``nmax`` patches (``emax`` CSR slots when ``csr_shared``).

    ``growth``: patch growth (paper Eq. 10) in the kernel: after every ``growth_every``-th step the block grows
    its patches (``grow_patch``), recomputes their coupling stiffnesses (``patch_coupling``, and the shared copy
    of the CSR) and re-solves the pad's contact (``contact_block``), in the order of the general path's
    ``grow_patches`` (areas, then stiffnesses) → ``contact_flat`` after ``strang_advance`` (the cached spring force
    keeps the stiffness of before the event, as there). The growth arrays are ignored (may be empty) otherwise.

    ``ablate`` (profiling only, ``scripts/profile_onchip.py``; the results are then wrong) drops parts of the
    step to time the rest: ``friction`` (the implicit friction solve becomes an explicit kick), ``gather`` (the
    neighbour sum), ``gather_half`` (the second half of every row's links), ``sync`` (the block barrier) or
    ``sample`` (a sample's per-patch work but its solve, which the next step's friction shares: the sums, watchdog
    and per-patch histories; the warps still combine and store their parts, of zero sums); with ``growth``,
    ``coupling`` (the stiffness update after an event) and ``contact`` (the contact re-solve after an event).
    ``fast_math``: compile with CUDA fast math (approximate division and transcendental functions; changes the
    results in the last bits).

    ``cluster`` = K > 1 (CUDA sm_90+): a pad is advanced by a thread-block cluster of K blocks; block ``rank`` owns
    the patches ``n·rank // K`` … ``n·(rank + 1) // K − 1`` (and their CSR rows, ``emax`` is then
    :func:`aca_warp.hf.onchip.csr_slots` of one part), every block keeps a full copy of u, the drift stores each new
    u_i into its own copy and, by ``st.async``, into those of the blocks that own a neighbour of i (:func:`readers`;
    distributed shared memory), and instead of a cluster barrier each block waits for the bytes of u that the others
    send it (a transaction mbarrier per u buffer; ``sync`` ablated: plain remote stores and no wait). A growth event
    there (with ``grown_tiles``, below): each block grows its copies of the whole pad's areas, √A and k_N and stores
    its own patches' grown values into the model, updates its own CSR rows from its copies, and re-solves the whole
    pad's contact from them (every block the same sums in the same order, so the same gap; cheaper than a cluster
    barrier per Newton iteration) and keeps its own patches' normal forces: no block reads what another wrote, so an
    event needs no cluster barrier.

    ``crossing``: steps that cross zero slip take the friction's mean along their slip segment, and samples read
    a crossing patch's friction at an instant of that sub-step (``RunOptions.crossing`` "mean":
    :func:`~aca_warp.kernels.physics.friction_substep`, :func:`~aca_warp.kernels.physics.instant_velocity`).

    ``lanes``: min(threads, 32), the banks of the on-chip CSR layout (:func:`aca_warp.hf.onchip.csr_slots`).

    ``grown_tiles`` (with ``growth``; :func:`aca_warp.hf.onchip_layout.grown_tiles`, on a cluster): every block keeps
    its own copies of the whole pad's areas, √A and k_N in shared memory and grows all of them at an event (the
    same operations as ``grow_patch``, so the same values in every block), stores its own patches' grown values into
    the model, and reads the neighbours' √A (stiffness update) and every area and k_N (contact re-solve) from its
    copies: an event then needs no cluster barrier, and its reads wait for shared memory instead of L2.

    A sample is the merged friction sub-step of the step that follows it, solved once for both
    (:func:`~aca_warp.kernels.physics.strang_sample_velocity`; docs/numerics.md, "Samples"), in the one sample
    block of the kernel, which also opens a started launch (solving, not recording), so that every step's friction
    comes from the same code whatever the launches' lengths. It is recorded without a barrier: each thread sums its
    patches' terms (the sample's velocity V, the sums
    of :func:`~aca_warp.kernels.physics.patch_sample`, the watchdog's first runaway and first non-finite patch),
    each warp combines its threads' by shuffles in the order of Warp's block reduction
    (:func:`~aca_warp.kernels.tiles.warp_sum`) and its first lane stores the warp's part into ``parts[s, block,
    warp]`` (:data:`PART`; on the CPU, where a block's threads are not warps, each thread its own). The globals rows
    and the watchdog's verdicts are made from them after the launch (:func:`pad_samples_kernel`): the warps' sums in
    warp order, then the blocks' in rank order, which is the order the block reductions and block 0 of a cluster
    took before, while a sample's work overlaps the next step's. (The step's arithmetic is unchanged by this, but
    the CUDA compiler may build an fp32 step otherwise: docs/onchip.md, "Outputs".)

    Launch with ``wp.launch_tiled(kernel, dim=[pads · K], block_dim=B, ...)`` (K = ``cluster``); ``threads``
    must be the block size the device really runs (B on CUDA or with CPU fibers, else 1 on the CPU). The kernel
    is compiled with ``__launch_bounds__(block_dim)`` so that a block of ``block_dim`` threads gets the registers
    it may use.
    """
    if nmax >= 2**15:
        raise ValueError(f"on-chip pads hold fewer than 32768 patches (int16 neighbour indices), got {nmax}")
    T = dtype
    Model = HFModel(T)
    Recorder = HFRecorder(T)
    NMAX = wp.constant(nmax)
    ne = emax if csr_shared else 1
    EMAX = wp.constant(ne)
    CSR_SHARED = wp.constant(1 if csr_shared else 0)
    if not ablate <= ABLATIONS:
        raise ValueError(f"unknown ablations {sorted(ablate - ABLATIONS)}")
    FRICTION = wp.constant(0 if "friction" in ablate else 1)
    GATHER = wp.constant(0 if "gather" in ablate else 1)
    HALF = wp.constant(1 if "gather_half" in ablate else 0)
    SYNC = wp.constant(0 if "sync" in ablate else 1)
    COUPLING = wp.constant(0 if "coupling" in ablate else 1)
    CONTACT = wp.constant(0 if "contact" in ablate else 1)
    SAMPLE = wp.constant(0 if "sample" in ablate else 1)
    GROWTH = wp.constant(1 if growth else 0)
    CROSSING = wp.constant(1 if crossing else 0)
    GTILES = wp.constant(1 if growth and grown_tiles else 0)
    CLUSTER = wp.constant(cluster)
    # a cluster exchanges u by st.async into the blocks that read it and mbarrier waits (no cluster barrier per step)
    ASYNC = wp.constant(1 if cluster > 1 and "sync" not in ablate else 0)
    TBYTES = wp.constant(wp.types.type_size_in_bytes(dtype))
    NW = wp.constant(lanes)  # banks of the on-chip CSR: min(threads, 32), a constant so that slot steps fold

    # Per-thread element stores into the shared tiles. ``tile[i] = x`` in Warp is a block-cooperative op (it ends
    # in WP_TILE_SYNC(), i.e. __syncthreads()), which inside the per-thread ``while i < n`` loops deadlocks on CUDA
    # (threads own different numbers of patches); these store without a barrier (docs/onchip.md).
    pmax = nmax // cluster + 1  # a block's own patches at most
    PMAX = wp.constant(pmax)
    put_d = tile_store_1d(wp.int32, pmax)  # the ranks that read a patch's u (halo exchange)
    get_d = tile_load_1d(wp.int32, pmax)
    put_n = tile_store_1d(T, nmax)
    put_u = tile_store_rows(T, 2, nmax)
    put_ei = tile_store_1d(wp.int16, ne)  # local neighbour index (nmax < 2**15, asserted above)
    put_ek = tile_store_1d(T, ne)
    put_u_at = tile_store_rows_remote(T, 2, nmax)  # into the u copy of another block of the cluster
    put_u_async = tile_store_rows_async(T, 2, nmax, 2)  # the same by st.async, counted by that block's mbarrier
    mb_init, mb_expect, mb_wait = mbarrier_ops(2)  # one mbarrier per u buffer
    # reads without Warp's negative-index wrap (a compare, add and select per index; docs/onchip.md)
    get_n = tile_load_1d(T, nmax)
    get_u = tile_load_rows(T, 2, nmax)
    get_ei = tile_load_1d(wp.int16, ne)
    # the neighbour sums (four on-chip links per pass: more shared loads in flight, H100: 8.6 -> 8.3 us)
    gather = tile_gather(T, nmax, ne, csr_shared, lanes, 4)
    warp_pad_sums = warp_sum(PadSums)
    # the barrier of all threads that advance a pad (a plain block barrier for one block: on sm_90 cluster_sync
    # would issue a cluster barrier for a one-block cluster)
    pad_sync = block_sync if cluster == 1 else cluster_sync

    @wp.func
    def sample_velocity(
        ws: Any,
        fsi: Any,
        g: int,
        model: Any,
        omega: Any,
        dt: Any,
        mu_scale: Any,
        slope: Any,
        decay: Any,
        tol: Any,
    ):
        """A sample's velocity V of patch g and the next step's drift velocity w⁺ from its staggered ``ws`` and F_s
        ``fsi`` (``strang_sample_velocity``)."""
        return strang_sample_velocity(
            ws, fsi, dt, model.inv_mass[g], model.damping[g], model.normal_force[g], omega * model.radius[g], mu_scale,
            slope, decay, tol, CROSSING,
        )  # fmt: skip

    @wp.func
    def link_neighbour(e: int, p: int, m: int, a: int, sidx: wp.tile[wp.int16, ne], model: Any) -> int:
        """The global index of link m of a row (its first link CSR entry e, on-chip slot p)."""
        if wp.static(csr_shared):
            return a + int(get_ei(sidx, p + m * NW))
        return model.nbr_index[e + m]

    @wp.func
    def couple(
        g: int,
        pad: int,
        a: int,
        p: int,
        sidx: wp.tile[wp.int16, ne],
        sk: wp.tile[T, ne],
        model: Any,
        sqa: Any,
        off: int,
    ) -> int:
        """``patch_coupling`` of patch g with √A of patch j at ``sqa[j − off]`` (the model's array, ``off`` 0, or the
        block's copy of the pad's, ``off`` its first patch) and, with the CSR on chip, the neighbour indices from the
        shared copy (the row's first link at slot ``p``; the new k_ij into that copy too); returns the slot after the
        row. Four links at a time (``link_stiffness4``), the diagonal summed in link order (as ``patch_coupling``)."""
        ki = model.pad_kc[pad] * sqa[g - off]
        d = model.k_t[g]
        e = model.nbr_start[g]
        end = model.nbr_start[g + 1]
        while e + 3 < end:
            j0 = link_neighbour(e, p, 0, a, sidx, model)
            j1 = link_neighbour(e, p, 1, a, sidx, model)
            j2 = link_neighbour(e, p, 2, a, sidx, model)
            j3 = link_neighbour(e, p, 3, a, sidx, model)
            k0, k1, k2, k3 = link_stiffness4(ki, sqa, off, j0, j1, j2, j3, e, model)
            if wp.static(csr_shared):
                put_ek(sk, p, k0)
                put_ek(sk, p + NW, k1)
                put_ek(sk, p + 2 * NW, k2)
                put_ek(sk, p + 3 * NW, k3)
                p += 4 * NW
            d += k0
            d += k1
            d += k2
            d += k3
            e += 4
        while e < end:
            kij = link_stiffness(ki, sqa[link_neighbour(e, p, 0, a, sidx, model) - off], model.nbr_inv_dist[e])
            model.nbr_stiffness[e] = kij
            if wp.static(csr_shared):
                put_ek(sk, p, kij)
                p += NW
            d += kij
            e += 1
        model.k_diag[g] = d
        return p

    @wp.kernel(
        enable_backward=False,
        module="unique",
        launch_bounds=(block_dim, 1),
        cluster_dim=cluster,
        module_options={"fast_math": fast_math},
    )
    def onchip_strang(
        model: Model,  # growth fields read only with growth (pad_growth: the increment per event)
        rec: Recorder,
        # Growth:
        growth_every: int,
        growth_step0: int,
        # Stepping:
        threads: int,
        dt: T,
        tol: T,
        steps_per_sample: int,
        samples: int,
        opening: int,
        # Recording:
        k0: int,
        prow0: int,
        # State in/out (staggered w, cached F_s between launches):
        u_io: wp.array[T],
        v_io: wp.array[T],
        force_io: wp.array[T],
        # Out: the blocks' parts of the samples (pad_samples_kernel)
        parts: wp.array4d[wp.float64],
    ):
        """Advance pad ``pad`` by ``samples`` × ``steps_per_sample`` strang steps, recording after each sample.

        ``opening`` = 1: the state is synchronous, the first step is the opening half step (``strang_velocity``);
        0: the state is staggered (w, before the merged friction sub-step of its first step, which the sample block
        solves). Sample s is the run's sample ``k0 + s`` (its parts: ``parts[s]``); per-patch rows start at
        ``prow0``. With growth, steps are counted from ``growth_step0`` (steps done before the launch, modulo
        ``growth_every``).
        """
        blk, lane = wp.tid()
        pad = blk // CLUSTER
        rank = blk % CLUSTER  # the block's rank in its cluster (clusters are CLUSTER consecutive blocks)
        a = model.pad_patch_start[pad]
        n = model.pad_patch_start[pad + 1] - a
        lo = n * rank // CLUSTER  # this block's patches: lo … hi - 1
        hi = n * (rank + 1) // CLUSTER
        u2 = wp.tile_zeros(shape=(2, NMAX), dtype=T, storage="shared")
        w = wp.tile_zeros(shape=NMAX, dtype=T, storage="shared")
        fs = wp.tile_zeros(shape=NMAX, dtype=T, storage="shared")
        sidx = wp.tile_zeros(shape=EMAX, dtype=wp.int16, storage="shared")
        sk = wp.tile_zeros(shape=EMAX, dtype=T, storage="shared")
        if wp.static(GTILES != 0):  # the block's copies of the pad's areas, √A and k_N (see the factory)
            garea = wp.tile_zeros(shape=NMAX, dtype=T, storage="shared")
            gsqrt = wp.tile_zeros(shape=NMAX, dtype=T, storage="shared")
            gkn = wp.tile_zeros(shape=NMAX, dtype=T, storage="shared")
        nbytes = int(0)  # bytes of u the other blocks store into this one per step
        if wp.static(ASYNC != 0):  # static: a one-block kernel carries none of the exchange (registers)
            bars = wp.tile_zeros(shape=2, dtype=wp.int64, storage="shared")
            mb_init(bars, lane)
            # The halo: patch i's u goes to the blocks that own a neighbour of i (bit r of readers(i)); this block
            # receives the u of every other block's patch with a neighbour here. Both sides test the same row, so
            # the bytes expected are the bytes sent (and with symmetric lists a block sends to those it reads from).
            dest = wp.tile_zeros(shape=PMAX, dtype=wp.int32, storage="shared")
            count = int(0)
            i = lane
            while i < n:
                m = readers(a + i, a, n, CLUSTER, model.nbr_start, model.nbr_index)
                if i >= lo and i < hi:
                    put_d(dest, i - lo, m - (m & (1 << rank)))
                elif (m >> rank) & 1 != 0:
                    count += 1
                i += threads
            nbytes = wp.tile_sum(wp.tile(count))[0] * TBYTES
        gap = wp.float64(0.0)
        if GROWTH != 0:
            gap = model.pad_gap[pad]  # the contact's warm start, kept here and stored by block 0 at the end
        i = lane
        while i < n:  # every block holds all of u
            put_u(u2, 0, i, u_io[a + i])
            if wp.static(GTILES != 0):
                put_n(garea, i, model.area[a + i])
                put_n(gsqrt, i, model.sqrt_area[a + i])
                put_n(gkn, i, model.k_n[a + i])
            i += threads
        i = lo + lane
        while i < hi:
            put_n(w, i, v_io[a + i])
            put_n(fs, i, force_io[a + i])
            i += threads
        # on-chip CSR, bank-interleaved (aca_warp.hf.onchip.csr_slots): the thread's links one after another, link m
        # at slot nw·(m0 + m) + bank, so the lanes of a warp always read different banks (nw = 32 on CUDA)
        nw = NW
        bank = lane % nw
        m0 = int(0)  # links of the block's threads before this one with the same bank
        if CSR_SHARED != 0:
            q = bank
            while q < lane:
                i = lo + q
                while i < hi:
                    m0 += model.nbr_start[a + i + 1] - model.nbr_start[a + i]
                    i += threads
                q += nw
        p0 = nw * m0 + bank  # the thread's first on-chip link slot
        if CSR_SHARED != 0:
            p = p0
            i = lo + lane
            while i < hi:
                for e in range(model.nbr_start[a + i], model.nbr_start[a + i + 1]):
                    put_ei(sidx, p, wp.int16(model.nbr_index[e] - a))
                    put_ek(sk, p, model.nbr_stiffness[e])
                    p += nw
                i += threads
        # the whole cluster is set up (tiles zeroed, mbarriers initialised) before any block stores into another
        pad_sync()

        omega = model.pad_omega[pad]
        mu_scale = model.pad_mu_scale[pad]
        slope = model.pad_slope[pad]
        decay = model.pad_decay[pad]
        bound2 = rec.watch_bound[pad] * rec.watch_bound[pad]
        cur = int(0)
        nstep = int(0)  # steps of this launch (the phase parity of the mbarrier of u buffer nxt: nstep // 2 % 2)
        prow = prow0
        first_step = opening
        steps_done = growth_step0
        for s in range(samples + 1):
            # the sample block (the kernel's one site of it): the merged friction sub-step of the step after a sample,
            # solved once for sample s - 1 (its velocity V, strang_sample_velocity) and for that step (its drift
            # velocity w+ into w, which every interval's first step but the run's opening one takes as solved); at
            # the start of a started launch (s = 0) it only solves (the launch before recorded that sample), and
            # after the launch's last sample it keeps w, the state written back
            if s > 0 or opening == 0:
                record = s > 0
                k = k0 + s - 1
                due = False
                if record:
                    due = patch_sample_due(rec, k)
                sums = SampleSums()
                usum = wp.float64(0.0)
                runaway = n  # the thread's first patch whose energy speed exceeds the watchdog bound (n: none)
                value = wp.float64(0.0)  # its energy speed [m/s]
                bad = n  # the thread's first patch with a non-finite u or u̇ (n: none)
                i = lo + lane
                while i < hi:
                    g = a + i
                    ws = get_n(w, i)
                    if FRICTION == 0:  # profiling: the explicit kick of the steps' ablation
                        vs = ws
                        w1 = ws + dt * model.inv_mass[g] * get_n(fs, i)
                    else:
                        vs, w1 = sample_velocity(ws, get_n(fs, i), g, model, omega, dt, mu_scale, slope, decay, tol)
                    if s < samples:
                        put_n(w, i, w1)
                    if record and SAMPLE != 0:
                        uu = get_u(u2, cur, i)
                        vf = instant_velocity(vs, ws, w1, omega * model.radius[g], CROSSING, k, i)
                        sums += patch_sample(
                            vs, vf, model.normal_force[g], model.radius[g], model.x[g], model.y[g], omega, mu_scale,
                            slope, decay,
                        )  # fmt: skip
                        usum += wp.float64(uu)
                        e2 = energy_speed2(vs, uu, model.k_t[g], model.inv_mass[g])
                        if e2 > bound2 and runaway == n:
                            runaway = i
                            value = wp.sqrt(e2)
                        if bad == n and not (wp.isfinite(vs) and wp.isfinite(uu)):
                            bad = i
                        if due:
                            store_patch_sample(rec, prow, g, vs, uu)
                    i += threads
                if record:
                    # the warp's sums (in the order of Warp's block reduction), its first non-finite and runaway
                    # patches and the energy speed of that runaway patch, into the block's part of the sample
                    # (pad_samples combines them after the launch): no block barrier, so a sample's work overlaps
                    # the next step's
                    tot = warp_pad_sums(PadSums(sums[0], sums[1], sums[2], sums[3], sums[4], sums[5], usum))
                    first_bad = warp_min(bad)
                    first_runaway = warp_min(runaway)
                    value = warp_pick(int(runaway == first_runaway and runaway < n), value)
                    if warp_leader(lane) != 0:
                        slot = warp_index(lane)
                        for c in range(7):
                            parts[s - 1, blk, slot, c] = tot[c]
                        parts[s - 1, blk, slot, 7] = wp.float64(first_bad)
                        parts[s - 1, blk, slot, 8] = wp.float64(first_runaway)
                        parts[s - 1, blk, slot, 9] = value
                        if lane == 0 and rank == 0:  # the thread that stores them at a growth event (contact_block)
                            parts[s - 1, blk, 0, 10] = wp.float64(model.pad_matrix_force[pad])
                            parts[s - 1, blk, 0, 11] = wp.float64(model.pad_matrix_radius[pad])
                    if due:
                        prow += 1
            if s == samples:
                break
            for j in range(steps_per_sample):
                nxt = 1 - cur
                # friction + kicks + drift (strang_velocity), own patches only
                i = lo + lane
                while i < hi:
                    g = a + i
                    im = model.inv_mass[g]
                    vd = omega * model.radius[g]
                    if j == 0 and first_step == 0:  # the sample block solved this step's friction
                        v = get_n(w, i)
                    elif FRICTION == 0:
                        v = get_n(w, i) + dt * im * get_n(fs, i)
                    else:
                        v = strang_velocity(
                            first_step, get_n(w, i), get_n(fs, i), dt, im, model.damping[g], model.normal_force[g], vd,
                            mu_scale, slope, decay, tol, CROSSING,
                        )  # fmt: skip
                    put_n(w, i, v)
                    un = get_u(u2, cur, i) + dt * v
                    if CLUSTER == 1:
                        put_u(u2, nxt, i, un)
                    elif wp.static(ASYNC != 0):
                        put_u(u2, nxt, i, un)
                        m = get_d(dest, i - lo)  # the other blocks that read u_i
                        while m != 0:
                            put_u_async(u2, nxt, i, un, lowest_bit(m), bars, nxt)
                            m = m & (m - 1)
                    else:
                        for q in range(CLUSTER):
                            put_u_at(u2, nxt, i, un, q)
                    i += threads
                first_step = 0
                if wp.static(ASYNC != 0):
                    # Wait for the other blocks' u of this step (each block sends u before it can wait for the
                    # next step's, so a block can neither overwrite a buffer that another still gathers from nor
                    # complete a phase early: docs/onchip.md, "Exchange of u on a cluster").
                    if lane == 0:
                        mb_expect(bars, nxt, nbytes)
                    block_sync()  # the own block's stores into its copy
                    mb_wait(bars, nxt, nstep // 2 % 2)
                    nstep += 1
                elif SYNC != 0:
                    pad_sync()
                # spring forces at the new u (spring_force of kernels.physics: same two partial sums, same order)
                p = p0
                i = lo + lane
                while i < hi:
                    g = a + i
                    e = model.nbr_start[g]
                    end = model.nbr_start[g + 1]
                    if GATHER == 0:
                        end = e
                    if wp.static(HALF != 0):  # profiling: the first half of the row's links only
                        row_end = p + nw * (end - e)  # the next row's first on-chip slot
                        end = e + (end - e + 1) // 2
                    links, p = gather(e, end, p, nxt, a, u2, sidx, sk, model.nbr_index, model.nbr_stiffness)
                    if wp.static(HALF != 0):
                        p = row_end
                    put_n(fs, i, links - model.k_diag[g] * get_u(u2, nxt, i))
                    i += threads
                cur = nxt
                if GROWTH != 0:
                    steps_done += 1
                    if steps_done % growth_every == 0:  # the same for every thread of the cluster
                        if wp.static(GTILES != 0):
                            i = lane
                            while i < n:  # the block's copies of the whole pad grown (grow_patch's operations)
                                ar, sq = grown_area(get_n(garea, i), model.pad_growth[pad])
                                put_n(garea, i, ar)
                                put_n(gsqrt, i, sq)
                                put_n(gkn, i, model.pad_k_n[pad] * sq)
                                i += threads
                            block_sync()  # the links and the contact below read every patch's copies
                            i = lo + lane
                            while i < hi:
                                store_grown_patch(a + i, pad, model, get_n(garea, i), get_n(gsqrt, i))
                                i += threads
                        else:
                            i = lo + lane
                            while i < hi:
                                grow_patch(a + i, pad, model)
                                i += threads
                            pad_sync()  # the links below read the neighbours' new √A, the contact every area and k_N
                        i = lo + lane
                        if COUPLING == 0:
                            i = hi
                        p = p0
                        while i < hi:
                            if wp.static(GTILES != 0):
                                p = couple(a + i, pad, a, p, sidx, sk, model, gsqrt, a)
                            else:
                                p = couple(a + i, pad, a, p, sidx, sk, model, model.sqrt_area, 0)
                            i += threads
                        if CONTACT != 0:  # every block solves the pad's contact, keeps its own patches' forces
                            if wp.static(GTILES != 0):
                                gap = contact_block_from(
                                    pad, lane, threads, model, garea, gkn, a, gap, a + lo, a + hi, rank == 0
                                )
                            else:
                                gap = contact_block(pad, lane, threads, model, gap, a + lo, a + hi, rank == 0)
        # write back the staggered state and the force cache (own patches)
        i = lo + lane
        while i < hi:
            u_io[a + i] = get_u(u2, cur, i)
            v_io[a + i] = get_n(w, i)
            force_io[a + i] = get_n(fs, i)
            i += threads
        if CLUSTER > 1:
            cluster_sync()  # no block leaves while another may still address its shared memory (or read the gap)
        if GROWTH != 0 and rank == 0 and lane == 0:
            model.pad_gap[pad] = gap

    return onchip_strang


# a pad's verdict on one sample (pad_samples_kernel → flag_fault): broken (1: a patch with a non-finite u or u̇) or
# not (0), its first non-finite patch (−1: none), its first runaway patch (n: none) and that patch's energy speed [m/s]
Verdict = wp.types.vector(length=4, dtype=wp.float64)


@cache
def pad_samples_kernel(dtype: Any) -> tuple[wp.Kernel, wp.Kernel]:
    """The two kernels that make the samples of a launch of :func:`onchip_kernel` from its ``parts``:
    ``sample_rows`` (one thread per sample and pad, ``dim=(samples, pads)``) writes globals row ``row0 + s``
    (:func:`write_globals`) and the pad's verdict on sample s into ``verdicts[s, pad]`` (:data:`Verdict`);
    ``sample_faults`` (one thread per pad) gives the watchdog the pad's first sample of a fault among the launch's
    ``samples`` (:func:`flag_fault`, sample ``k0 + s``). Each in a module of its own (per ``dtype``).

    ``parts[s, b, w]`` holds warp w's part of sample s of block b (pad b // ``cluster``; :data:`PART`); a block's
    sums are its warps' in warp order, the sums of Warp's block reduction to the bit (the warp stage was
    :func:`~aca_warp.kernels.tiles.warp_sum`), and a pad's are its blocks' in rank order, added to zero on a
    cluster: the sums a block reduction and block 0 of the cluster made in the kernel before, to the bit. A pad is
    broken where one of its patches has a non-finite u or u̇ (its first such patch named), whether or not its sums
    are finite: the general engine's rule (:func:`~aca_warp.kernels.physics.record_pad`); a pad's runaway patch is
    its first, with its energy speed; the matrix's force and radius are those the pad had at the sample
    (kept in the first part: growth changes them); ``warps`` the parts per block."""
    Model = HFModel(dtype)
    Recorder = HFRecorder(dtype)

    @wp.func
    def block_part(parts: wp.array4d[wp.float64], s: int, b: int, warps: int, n: int):
        """(sums, first non-finite patch or −1, first runaway patch or ``n``, its energy speed) of block b."""
        tot = PadSums()
        for c in range(7):
            tot[c] = parts[s, b, 0, c]
        bad = int(parts[s, b, 0, 7])
        runaway = int(parts[s, b, 0, 8])
        value = parts[s, b, 0, 9]
        for q in range(1, warps):
            for c in range(7):
                tot[c] = tot[c] + parts[s, b, q, c]
            bad = wp.min(bad, int(parts[s, b, q, 7]))
            r = int(parts[s, b, q, 8])
            if r < runaway:
                runaway = r
                value = parts[s, b, q, 9]
        if bad >= n:
            bad = -1
        return tot, bad, runaway, value

    @wp.kernel(enable_backward=False, module="unique")
    def sample_rows(
        model: Model,
        rec: Recorder,
        parts: wp.array4d[wp.float64],
        cluster: int,
        warps: int,
        row0: int,
        verdicts: wp.array2d[Verdict],
    ):
        s, pad = wp.tid()
        n = model.pad_patch_start[pad + 1] - model.pad_patch_start[pad]
        tot = PadSums()
        bad = int(-1)
        runaway = n
        value = wp.float64(0.0)
        for q in range(cluster):
            tq, bq, rq, vq = block_part(parts, s, pad * cluster + q, warps, n)
            if cluster == 1:
                tot = tq  # one block: its sums as they are
            else:  # the blocks' sums in rank order, added to zero
                for c in range(7):
                    tot[c] = tot[c] + tq[c]
            if rq < runaway:
                runaway = rq
                value = vq
            if bad < 0 and bq >= 0:
                bad = bq
        first = pad * cluster
        write_globals(
            rec, row0 + s, pad, tot, model.pad_omega[pad], model.pad_mu_pad[pad], dtype(parts[s, first, 0, 10]),
            dtype(parts[s, first, 0, 11]), model.pad_load[pad],
        )  # fmt: skip
        broken = wp.float64(0.0)
        if bad >= 0:
            broken = wp.float64(1.0)
        verdicts[s, pad] = Verdict(broken, wp.float64(bad), wp.float64(runaway), value)

    @wp.kernel(enable_backward=False, module="unique")
    def sample_faults(model: Model, rec: Recorder, verdicts: wp.array2d[Verdict], samples: int, k0: int):
        pad = wp.tid()
        n = model.pad_patch_start[pad + 1] - model.pad_patch_start[pad]
        s = int(0)
        while s < samples and rec.fault[pad, 0] < 0:
            v = verdicts[s, pad]
            flag_fault(rec, pad, k0 + s, v[0] != wp.float64(0.0), int(v[1]), int(v[2]), n, v[3])
            s += 1

    return sample_rows, sample_faults
