"""On-chip HF engine: one thread block (or a thread-block cluster) per pad advances many ``strang`` steps per launch.

The pad's displacement (double-buffered), staggered velocity and spring-force cache live in shared memory
for the whole launch, and the global outputs (μ, torque, friction radius, Σu̇, Σ|u̇|) and per-patch
histories are recorded in-kernel after every sample interval (:mod:`aca_warp.kernels.hf_onchip`). Patch
growth (varying-area scenes) runs in the kernel too. The general per-step path (:func:`aca_warp.hf.run_hf`)
stays for pads too large for one block's shared memory and for the other integrators; ``engine="auto"`` picks
between them (:func:`choose_engine`).

Same arithmetic as the general path: on the CPU (where Warp runs a block as one thread) μ(t) and the final
(u, u̇) are bit-identical to :func:`run_hf`; on CUDA the in-block reductions of the global outputs sum in a
different order and the CUDA compiler may contract differently, so results agree to rounding.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
import warp as wp

from aca_warp.common.errors import SceneError, SimulationFault
from aca_warp.hf.model import PadModel
from aca_warp.hf.solver import (
    DEFAULT_INTEGRATOR,
    WATCHDOG_FACTOR,
    Chunk,
    HFSolver,
    RunResult,
    _fault_from,
    _Recorder,
    block_threads,
    growth_events,
    run_hf,
    watchdog_bound,
)
from aca_warp.hf.state import HFState
from aca_warp.kernels import hf as K
from aca_warp.kernels.hf_onchip import onchip_kernel
from aca_warp.scene import Record

ENGINES = ("auto", "onchip", "general")
MAX_BLOCK = 1024  # threads per block
MAX_CLUSTER = 16  # blocks per pad (8 is the portable cluster size; H100/H200 launch 16 as "non-portable")
DEFAULT_BLOCK = 512  # threads per pad by default (1024 leaves 64 registers per thread: the fp64 kernel spills)
# threads per block of a growing pad on one block: the growth kernel wants more than the 128 registers per thread
# that 512 threads leave (H100 varying_area pad: 12.3 -> 11.4 us/step; docs/onchip.md)
GROWTH_BLOCK = 384
# threads of a (not growing) fp32 pad on one block: 96 registers, 3 patches per thread for hf1; H100, 1024 hf1 pads:
# 61.3 -> 55.3 us/step against 512 (576, 672, 704 threads: 66-68; 1024: 56.2; docs/onchip.md, "Block size")
FP32_BLOCK = 640
_SMEM_RESERVE = 8 * 1024  # bytes left for Warp's reduction scratch and static shared memory
_PATCH_BUFFER_BYTES = 256 * 2**20  # cap of the per-patch history buffers of one launch
# model arrays the on-chip growth reads and writes, in the kernel's argument order (float64 ones in _GROWTH_F64)
_GROWTH_ARRAYS = (
    "area", "sqrt_area", "k_n", "height", "nbr_inv_dist", "pad_kc", "pad_growth", "pad_k_t", "pad_k_n",
    "pad_mass_per_area", "pad_zeta", "pad_area", "pad_moment", "pad_k_m", "pad_gap",
)  # fmt: skip
_GROWTH_F64 = frozenset({"pad_area", "pad_moment", "pad_k_m", "pad_gap"})


def _itemsize(model: PadModel) -> int:
    return 8 if model.dtype == wp.float64 else 4


def _round_up(x: int, m: int) -> int:
    return max(m, -(-x // m) * m)


def pad_sizes(model: PadModel, cluster: int = 1) -> tuple[int, int]:
    """(most patches in one pad, most neighbour links of one block) of the batch, a pad split over ``cluster``
    blocks as the kernel splits it (block r: patches n·r // K … n·(r + 1) // K − 1)."""
    start = model.pad_patch_start_host
    nbr = model.host("nbr_start")
    n = np.diff(start)
    cuts = start[:-1, None] + n[:, None] * np.arange(cluster + 1)[None, :] // cluster
    return int(n.max()), int(np.diff(nbr[cuts], axis=1).max())


def csr_slots(model: PadModel, cluster: int = 1, threads: int = 1) -> int:
    """Length of a block's on-chip neighbour-list tiles in the kernel's bank-interleaved layout.

    Thread ``lane`` of a block of ``threads`` stores its patches' links one after another, link m at slot
    W·(s + m) + lane mod W (W = min(threads, 32); s: the links of the threads before it with the same lane mod W),
    so that the 32 lanes of a warp always read 32 different shared-memory banks. The tile needs W times the
    largest sum of links over the threads of one bank, over every block of the batch (a pad split over
    ``cluster`` blocks as the kernel splits it).
    """
    start = model.pad_patch_start_host
    deg = np.diff(model.host("nbr_start"))
    w = min(threads, 32)
    per_thread = -(-int(np.diff(start).max()) // threads) * threads
    banks = -(-threads // w) * w
    most = 0
    for p in range(model.pad_count):
        n = start[p + 1] - start[p]
        for r in range(cluster):
            d = np.zeros(per_thread, dtype=np.int64)
            part = deg[start[p] + n * r // cluster : start[p] + n * (r + 1) // cluster]
            d[: part.size] = part
            t = np.zeros(banks, dtype=np.int64)
            t[:threads] = d.reshape(-1, threads).sum(axis=0)  # links per thread
            most = max(most, int(t.reshape(-1, w).sum(axis=0).max()))  # links per bank
    return w * most


def tile_sizes(model: PadModel, cluster: int = 1, threads: int = 1) -> tuple[int, int]:
    """The kernel's tile sizes (patches, CSR slots) for blocks of ``threads`` threads: the most patches of a pad
    and :func:`csr_slots`, rounded up to whole warps (32)."""
    return _round_up(pad_sizes(model, cluster)[0], 32), _round_up(csr_slots(model, cluster, threads), 32)


def default_block(nmax: int, cluster: int, growth: bool, fp64: bool) -> int:
    """Threads per block for ``block_dim=None``: the block's part of an ``nmax``-patch pad rounded up to 32, at most
    ``DEFAULT_BLOCK``; on one block at most ``GROWTH_BLOCK`` for a growing pad, ``FP32_BLOCK`` for an fp32 one."""
    cap = DEFAULT_BLOCK
    if cluster == 1:
        cap = GROWTH_BLOCK if growth else (DEFAULT_BLOCK if fp64 else FP32_BLOCK)
    return min(cap, _round_up(-(-nmax // cluster), 32))


def shared_bytes(model: PadModel, csr_shared: bool, cluster: int = 1, threads: int = 1) -> int:
    """Shared memory one block of ``threads`` threads needs [bytes]: u (×2), w, F_s per patch of the pad, the
    cluster's table of sample sums and, on a cluster, the u exchange's two mbarriers and its per-patch mask of
    receiving blocks, plus the block's part of the CSR (:func:`csr_slots`) when kept on chip."""
    nmax, slots = tile_sizes(model, cluster, threads)
    b = 4 * nmax * _itemsize(model) + 64 * cluster
    if cluster > 1:
        b += 16 + 4 * (nmax // cluster + 1)
    if csr_shared:
        b += slots * (2 + _itemsize(model))  # int16 local index, k_ij in the state precision
    return b


def default_cluster(pads: int, sm_count: int, split_fits_csr: bool = False) -> int:
    """Blocks per pad for ``cluster=None`` on a CUDA device of compute capability 9.0+ (growing pads too).

    A cluster's blocks run on the SMs of one GPC, and the batch should run in one wave: every cluster resident at
    once (one hf1 block per SM). Measured on an H100 (132 SMs; hf1 fp32, 2026-11-25,
    docs/benchmarks/onchip_h100/cluster_waves_*.md): 14 clusters of 8, 28 of 4 and 66 of 2 run in one wave, 16, 32
    and 68 need a second one (a step then takes 1.6–1.9× as long). Whole GPCs of 18 SMs (sm_count // 18 of them)
    hold 18 // K clusters of 4 or 8, and pairs fill every SM; so K is the largest of 8, 4 with pads ≤
    (sm_count // 18) · (18 // K), else 2 with pads ≤ sm_count // 2; otherwise 1, or 2 when only a pad split in two
    keeps its neighbour lists in shared memory (fp64 hf1 pads: 2 blocks fastest, or within 2 %, from 57 to 1024
    pads). Once the batch fills the GPU, a cluster loses (it repeats the u update of the whole pad in every block):
    fp32 pads 67–1024 run fastest on one block each (64 pads: 7.2 µs/step on K = 1, 4.5 on K = 2; 100 pads: 7.5
    against 8.3). One pad: 6.3 → 1.8 µs/step fp32 (K = 1 → 8) and 18.4 → 2.6 fp64
    (docs/benchmarks/onchip_h100/bench_cluster.md); the growing varying_area pad (an event every 20 steps):
    11.4 → 2.7 µs/step fp32 (K = 1 → 8; K = 4: 3.5; docs/benchmarks/onchip_h100/cluster_exchange_ab.md).
    """
    gpcs = max(sm_count // 18, 1)
    for k in (8, 4):
        if pads <= gpcs * (18 // k):
            return k
    if pads <= sm_count // 2:
        return 2
    return 2 if split_fits_csr else 1


def smem_limit(model: PadModel, per_block: int | None = None) -> int:
    """Shared memory a block's tiles may use [bytes]: ``per_block`` (default: the model device's opt-in limit per
    block; Warp's CPU tile arena on the CPU) less the reserve for Warp's own scratch."""
    if per_block is None:
        dev = model.device
        per_block = 256 * 1024 if dev.is_cpu else int(dev.max_shared_memory_per_block)  # CPU: native/tile.h arena
    return per_block - _SMEM_RESERVE


def block_config(
    model: PadModel, cluster: int, block_dim: int | None = None, csr_shared: bool | None = None
) -> tuple[int, int, bool]:
    """(block size, threads the device runs per block, CSR on chip) of a launch with ``cluster`` blocks per pad:
    ``block_dim`` or :func:`default_block`; ``csr_shared`` or, when None, whether the neighbour lists fit shared
    memory beside the state. Raises :class:`SceneError` for a block size out of range or a CSR asked on chip that
    does not fit."""
    nmax = pad_sizes(model, cluster)[0]
    if block_dim is None:
        block_dim = default_block(nmax, cluster, "pad_growth" in model.arrays, model.dtype == wp.float64)
    if not 1 <= block_dim <= MAX_BLOCK:
        raise SceneError(f"block_dim must be in [1, {MAX_BLOCK}], got {block_dim}")
    threads = block_threads(model.device, block_dim)
    fits = shared_bytes(model, True, cluster, threads) <= smem_limit(model)
    if csr_shared and not fits:
        raise SceneError(f"the neighbour lists of a {nmax}-patch pad do not fit shared memory with the state")
    return block_dim, threads, fits if csr_shared is None else bool(csr_shared)


def unsupported(model: PadModel, integrator: str = DEFAULT_INTEGRATOR) -> str | None:
    """Why the on-chip engine cannot run this model (None when it can)."""
    if integrator != "strang":
        return f"the on-chip engine implements the strang integrator only (got {integrator})"
    need, limit = shared_bytes(model, False), smem_limit(model)
    if need > limit:
        return (
            f"a pad of {pad_sizes(model)[0]} patches needs {need} B of shared memory per block, "
            f"the device offers {limit} B"
        )
    return None


def choose_engine(model: PadModel, engine: str, integrator: str = DEFAULT_INTEGRATOR) -> str:
    """Resolve ``engine`` (auto, onchip, general) for a model; ``onchip`` on an unsupported model is an error.

    ``auto`` picks ``onchip`` on CUDA when the model allows it (faster there, docs/onchip.md) and ``general`` on
    the CPU (Warp runs a block as one thread there, so the on-chip kernel is no faster), growing models included
    (their in-kernel growth passes ``scripts/onchip_gpu_check.py --growth`` on an H100; docs/onchip.md).
    """
    if engine not in ENGINES:
        raise SceneError(f"unknown engine {engine!r}; choose from {', '.join(ENGINES)}")
    why = unsupported(model, integrator)
    if engine == "onchip":
        if why is not None:
            raise SceneError(f"--engine onchip: {why}")
        return "onchip"
    if engine == "general" or why is not None or model.device.is_cpu:
        return "general"
    return "onchip"


def _due(k: int, first: int, last: int, every: int) -> bool:
    """Whether global sample k also records per-patch histories (``patch_sample_due`` of kernels.hf)."""
    return first <= k <= last and (k - first) % every == 0


def run_onchip(
    model: PadModel,
    state: HFState,
    *,
    duration: float,
    dt: float | None = None,
    force: bool = False,
    record: Record | None = None,
    sink: Callable[[Chunk], None] | None = None,
    progress: bool = False,
    block_dim: int | None = None,
    csr_shared: bool | None = None,
    samples_per_launch: int | None = None,
    watchdog_factor: float | None = WATCHDOG_FACTOR,
    ablate: frozenset[str] = frozenset(),
    fast_math: bool = False,
    cluster: int | None = None,
) -> RunResult:
    """Advance all pads from ``state`` for ``duration`` [s] with the on-chip ``strang`` kernel.

    Same contract as :func:`aca_warp.hf.run_hf` with ``integrator="strang"`` (step shortened so that a whole
    number of steps fits a sample interval; samples go to ``sink`` or the result's chunks; the state is left
    synchronous; the same watchdog, ``watchdog_factor``). ``block_dim``: threads per block (default:
    :func:`default_block`);
    ``csr_shared``: keep the neighbour lists in shared memory (default: when they fit);
    ``samples_per_launch``: sample intervals per kernel launch (default: as many as fit ~20k steps).
    ``ablate``: profiling only (``scripts/profile_onchip.py``): parts of the step left out, results wrong
    (:func:`aca_warp.kernels.hf_onchip.onchip_kernel`).
    ``fast_math``: compile with CUDA fast math (approximate division and transcendentals; profiling).
    ``cluster``: blocks per pad, a thread-block cluster of 1–16 (CUDA sm_90+; above 8 a "non-portable" size,
    refused where the device cannot launch it; default: :func:`default_cluster` there, at most 8, else 1;
    docs/onchip.md: 16 blocks are a few per cent faster than 8 for one hf1 pad (fp64 ≈ 7 %), and keep twice as
    large a pad's CSR on chip).
    On the CPU a block is one thread unless ``wp.config.enable_cpu_blocks`` is set (Warp's cooperative CPU
    fibers: ``block_dim`` threads per block with real barriers, used by the tests to exercise multi-thread blocks).
    """
    t_compile = time.perf_counter()
    record = record or model.scenes[0].record
    why = unsupported(model)
    if why is not None:
        raise SceneError(f"on-chip engine: {why}")
    if not (duration > 0 and math.isfinite(duration)):
        raise SceneError(f"duration must be a positive number of seconds, got {duration}")
    if record.sample_dt > duration * (1 + 1e-12):
        raise SceneError(f"sample interval {record.sample_dt:g} s exceeds the duration {duration:g} s")
    n_samples = max(1, round(duration / record.sample_dt))
    solver = HFSolver(model, "strang", dt, force=force)
    sps = max(1, math.ceil(record.sample_dt / solver.dt - 1e-9))
    h = record.sample_dt / sps
    dev = model.device
    growth = "pad_growth" in model.arrays
    if cluster is None:
        cluster = 1
        if dev.is_cuda and dev.arch >= 90:
            split = not block_config(model, 1)[2] and block_config(model, 2)[2]  # the CSR fits only when split
            cluster = default_cluster(model.pad_count, dev.sm_count, split)
    if not 1 <= cluster <= MAX_CLUSTER:
        raise SceneError(f"cluster must be in [1, {MAX_CLUSTER}] blocks per pad, got {cluster}")
    if cluster > 1 and (dev.is_cpu or dev.arch < 90):
        raise SceneError(f"a cluster of {cluster} blocks per pad needs a CUDA device of compute capability 9.0+")
    block_dim, threads, csr_shared = block_config(model, cluster, block_dim, csr_shared)

    probe = _Recorder(model, record, 1, n_samples)
    per_row = (int(probe.want_v) + int(probe.want_u)) * model.patch_count * _itemsize(model)
    if samples_per_launch is None:
        samples_per_launch = max(1, 20_000 // sps)
    spl = max(1, min(samples_per_launch, n_samples))
    if per_row:
        spl = max(1, min(spl, _PATCH_BUFFER_BYTES // per_row))
    rec = _Recorder(model, record, spl + 1, n_samples)
    bounds = (
        np.full(model.pad_count, np.inf) if watchdog_factor is None else watchdog_bound(model, state, watchdog_factor)
    )
    rec.watch_bound.assign(bounds)
    kernel = onchip_kernel(
        model.dtype,
        *tile_sizes(model, cluster, threads),
        bool(csr_shared),
        block_dim,
        frozenset(ablate),
        fast_math,
        growth,
        cluster,
        min(threads, 32),
    )
    if cluster > 1 and wp.get_cuda_max_cluster_dim(kernel, dev, block_dim=block_dim) < cluster:
        raise SceneError(f"{dev.name} cannot launch a cluster of {cluster} blocks of {block_dim} threads per pad")
    stages = [
        "contact",
        "neighbours" if model.has_coupling else "no-coupling",
        "step:strang:onchip",
        "record:globals",
    ] + (["record:patches"] if rec.patch_stage else [])
    if growth:
        stages.append("growth")
        growth_every, growth_per_event = growth_events(model, h)
        arrays = {**model.arrays, "pad_growth": growth_per_event}  # the increment per event, not per interval
        grown = [arrays[k] for k in _GROWTH_ARRAYS]
    else:  # the growth arguments are not read: empty arrays of the kernel's types
        growth_every = 1
        grown = [wp.empty(0, dtype=wp.float64 if k in _GROWTH_F64 else model.dtype, device=dev) for k in _GROWTH_ARRAYS]
    out: list[Chunk] = []
    emit = sink or out.append
    cause = (
        f"step {h:.3g} s beyond the stable estimate {solver.estimate.limit('strang'):.3g} s"
        if h > solver.estimate.limit("strang")
        else "extreme scene parameters (check loads, areas, speeds)"
    )
    m = model
    T = model.dtype
    solver.prepare(state)
    rec.launch(state.u, state.v, conditional=False)  # sample 0: the initial state (general kernels)
    k_next, rows, prows = 1, 1, int(_due(0, rec.first, rec.last, rec.every))
    done_samples = 0

    def launch(samples: int, opening: bool) -> None:
        wp.launch_tiled(
            kernel,
            dim=[m.pad_count * cluster],
            block_dim=block_dim,
            device=dev,
            inputs=[
                m.pad_patch_start,
                m.inv_mass,
                m.k_diag,
                m.damping,
                m.normal_force,
                m.radius,
                m.nbr_start,
                m.nbr_index,
                m.nbr_stiffness,
                m.pad_omega,
                m.pad_mu_scale,
                m.pad_slope,
                m.pad_decay,
                m.pad_mu_pad,
                m.pad_load,
                m.pad_matrix_force,
                m.pad_matrix_radius,
                m.k_t,
                *grown,
                growth_every,
                done_samples * sps % growth_every,  # steps so far (growth events count from the run's start)
                threads,
                T(h),
                solver.newton_tol,
                sps,
                samples,
                int(opening),
                k_next,
                rows,
                prows,
                rec.first,
                rec.last,
                rec.every,
                state.u,
                state.v,
                state.force,
                rec.globals,
                rec.watch_bound,
                rec.fault,
                rec.fault_value,
                rec.velocity,
                rec.displacement,
            ],
        )

    wp.load_module(kernel.module, device=dev)
    wp.load_module(K, device=dev)
    compile_time = time.perf_counter() - t_compile
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n_samples * record.sample_dt, unit="s", unit_scale=True, dynamic_ncols=True)
    t0 = time.perf_counter()
    fault: SimulationFault | None = None
    started = False
    try:
        while True:
            reps = min(spl, n_samples - done_samples)
            launch(reps, not started)
            started = True
            due = sum(1 for k in range(k_next, k_next + reps) if _due(k, rec.first, rec.last, rec.every))
            k_next += reps
            rows += reps
            prows += due
            done_samples += reps
            sim_t = done_samples * record.sample_dt
            rec.counters.assign(np.array([k_next, rows, prows, 0], dtype=np.int32))
            chunk, table = rec.flush()
            rows = prows = 0
            fault = _fault_from(table, model, record.sample_dt, cause, rec.fault_value.numpy(), bounds)
            if fault is not None:
                chunk = chunk.before(fault.time - 0.5 * record.sample_dt)
            emit(chunk)
            if bar is not None:
                bar.update(sim_t - bar.n)
            if fault is not None or done_samples >= n_samples:
                break
    finally:
        if bar is not None:
            bar.close()
        if started:
            solver.finish(state, h)
    wp.synchronize_device(dev)
    wall = time.perf_counter() - t0
    return RunResult(
        complete=fault is None,
        fault=fault,
        steps=done_samples * sps,
        rejected=0,
        sim_time=done_samples * record.sample_dt,
        wall_time=wall,
        compile_time=compile_time,
        dt=h,
        estimate=solver.estimate,
        stages=stages,
        chunks=out,
        blocks_per_pad=cluster,
    )


def run(
    model: PadModel,
    state: HFState,
    *,
    engine: str = "auto",
    integrator: str = DEFAULT_INTEGRATOR,
    **kwargs,
) -> RunResult:
    """:func:`run_onchip` or :func:`aca_warp.hf.run_hf`, as :func:`choose_engine` resolves ``engine``.

    Checkpointed or resumed runs (``checkpoint_every``/``resume``) always take the general path.
    """
    wants_general = kwargs.get("resume") is not None or kwargs.get("checkpoint_every") is not None
    if wants_general and engine == "onchip":
        raise SceneError("--engine onchip: checkpoints and resume need the general engine")
    if not wants_general and choose_engine(model, engine, integrator) == "onchip":
        kwargs.pop("tolerance", None)
        kwargs.pop("use_graph", None)
        kwargs.pop("max_graph_steps", None)
        return run_onchip(model, state, **kwargs)
    return run_hf(model, state, integrator=integrator, **kwargs)
