"""Launch layout of the on-chip HF engine: block size, cluster size, shared-memory tiles, and the engine choice.

A pad lives in the shared memory of one thread block, or of a thread-block cluster of up to 16 blocks (CUDA
sm_90+), for the whole launch (:mod:`aca_warp.hf.onchip`). These functions size the tiles (patches, the
bank-interleaved neighbour lists), pick the threads per block and blocks per pad from measurements
(docs/onchip.md), and decide whether a model runs on chip at all (:func:`choose_engine`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import warp as wp

from aca_warp.common.devices import block_threads
from aca_warp.common.errors import SceneError, option
from aca_warp.hf.model import PadModel
from aca_warp.hf.options import ENGINES, ONCHIP_INTEGRATORS, fast_math_unfit

MAX_BLOCK = 1024  # threads per block
MAX_CLUSTER = 16  # blocks per pad (8 is the portable cluster size; H100/H200 launch 16 as "non-portable")
DEFAULT_BLOCK = 512  # threads per pad by default (1024 leaves 64 registers per thread: the fp64 kernel spills)
# On a cluster an fp32 pad takes one thread per patch of its block's part instead where that fits MAX_BLOCK threads
# (a larger part keeps DEFAULT_BLOCK): 64 hf1 pads on
# clusters of 2 (879 patches per block) take 9.8 % less time per step with 896 threads (72 registers) than with 512
# (128 registers, two patches per thread), 32 growing varying_area pads with events 5 us apart 13 %, every result
# bit for bit the same where compared. fp64 gains 2.7-3.1 % but its sample sums, added in another order, change in
# their last bits (H200, docs/benchmarks/onchip_h200_64pads/one_patch_per_thread/)
# threads per block of a growing pad on one block: the growth kernel wants more than the 128 registers per thread
# that 512 threads leave (H100 varying_area pad: 12.3 -> 11.4 us/step; docs/onchip.md)
GROWTH_BLOCK = 384
# threads of a (not growing) fp32 pad on one block: 96 registers, 3 patches per thread for hf1; H100, 1024 hf1 pads:
# 61.3 -> 55.3 us/step against 512 (576, 672, 704 threads: 66-68; 1024: 56.2; docs/onchip.md, "Block size")
FP32_BLOCK = 640
_SMEM_RESERVE = 8 * 1024  # bytes left for Warp's reduction scratch and static shared memory
_SM_THREADS, _SM_BLOCKS = 2048, 32  # resident threads and blocks per SM (sm_80–sm_90)


def itemsize(model: PadModel) -> int:
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


def thread_links(model: PadModel, cluster: int = 1, threads: int = 1) -> np.ndarray:
    """The neighbour links each thread gathers per step, shape (pads · ``cluster`` blocks, ``threads``): thread t of
    a block owns its part's patches t, t + ``threads``, … (a pad split over ``cluster`` blocks as the kernel splits
    it: block r, patches n·r // K … n·(r + 1) // K − 1)."""
    start = model.pad_patch_start_host
    deg = np.diff(model.host("nbr_start"))
    per_thread = -(-int(np.diff(start).max()) // threads) * threads
    rows = []
    for p in range(model.pad_count):
        n = start[p + 1] - start[p]
        for r in range(cluster):
            d = np.zeros(per_thread, dtype=np.int64)
            part = deg[start[p] + n * r // cluster : start[p] + n * (r + 1) // cluster]
            d[: part.size] = part
            rows.append(d.reshape(-1, threads).sum(axis=0))
    return np.array(rows, dtype=np.int64)


def csr_slots(model: PadModel, cluster: int = 1, threads: int = 1) -> int:
    """Length of a block's on-chip neighbour-list tiles in the kernel's bank-interleaved layout.

    Thread ``lane`` of a block of ``threads`` stores its patches' links one after another, link m at slot
    W·(s + m) + lane mod W (W = min(threads, 32); s: the links of the threads before it with the same lane mod W),
    so that the 32 lanes of a warp always read 32 different shared-memory banks. The tile needs W times the
    largest sum of links over the threads of one bank (:func:`thread_links`), over every block of the batch.
    """
    w = min(threads, 32)
    banks = -(-threads // w) * w
    t = thread_links(model, cluster, threads)
    t = np.pad(t, ((0, 0), (0, banks - threads)))  # lanes beyond the block's threads hold no links
    return w * int(t.reshape(t.shape[0], -1, w).sum(axis=1).max())  # links per bank, most over the blocks


def tile_sizes(model: PadModel, cluster: int = 1, threads: int = 1) -> tuple[int, int]:
    """The kernel's tile sizes (patches, CSR slots) for blocks of ``threads`` threads: the most patches of a pad
    and :func:`csr_slots`, rounded up to whole warps (32); worked out once per model (they depend on its neighbour
    lists alone, which no run changes)."""
    key = ("tile_sizes", cluster, threads)
    if key not in model.memo:
        model.memo[key] = _round_up(pad_sizes(model, cluster)[0], 32), _round_up(csr_slots(model, cluster, threads), 32)
    return model.memo[key]


def _bucket(x: int) -> int:
    """``x`` rounded up to a multiple of 2^(⌊log2 x⌋ − 4) and of 32: at most 1/16 above ``x`` (or a warp above it,
    below 512), the same value for sizes a few percent apart."""
    return _round_up(x, max(32, 1 << max(0, x.bit_length() - 5)))


def kernel_tiles(model: PadModel, cluster: int = 1, threads: int = 1, per_block: int | None = None) -> tuple[int, int]:
    """The on-chip ``strang`` kernel's tile sizes (patches, CSR slots): :func:`tile_sizes` rounded up to buckets
    (:func:`_bucket`, at most 1/16 more), so that batches of different pads of about the same size, e.g. the shards
    of a sweep over patch seeds, share one compiled kernel instead of compiling one each. The tiles are only the
    kernel's storage: the results do not depend on them. The warp-rounded sizes stay where the buckets would not fit
    the shared memory (``per_block``: :func:`smem_limit`'s) that they fit, with the neighbour lists on chip or else
    without, and on CUDA where the buckets would leave fewer blocks resident per SM by an estimate (the per-block
    limit taken for an SM's shared memory, its threads and blocks; registers not counted)."""
    exact = tile_sizes(model, cluster, threads)
    bucketed = (_bucket(exact[0]), _bucket(exact[1]))
    limit = smem_limit(model, per_block)
    for csr in (True, False):
        need = _block_bytes(model, *exact, csr, cluster, per_block)
        if need <= limit:  # the placement the exact tiles allow: the buckets must keep it
            more = _block_bytes(model, *bucketed, csr, cluster, per_block)
            same = _resident(model, more, threads, limit) == _resident(model, need, threads, limit)
            return bucketed if same else exact  # the same count (≥ 1): the buckets fit too
    return exact


def _resident(model: PadModel, nbytes: int, threads: int, limit: int) -> int:
    """Blocks of ``nbytes`` of shared memory and ``threads`` threads resident per SM, estimated (``limit`` taken for
    an SM's shared memory; registers not counted); on the CPU, where a block is a thread or a group of fibers and
    there are no SMs, 1 if the block fits ``limit``, else 0."""
    if model.device.is_cpu:
        return int(nbytes <= limit)
    return min(limit // nbytes, _SM_THREADS // threads, _SM_BLOCKS)


def default_block(nmax: int, cluster: int, growth: bool, fp64: bool) -> int:
    """Threads per block for ``block_dim=None``: the block's part of an ``nmax``-patch pad rounded up to 32, at most
    ``DEFAULT_BLOCK``; on one block at most ``GROWTH_BLOCK`` for a growing pad, ``FP32_BLOCK`` for an fp32 one; on a
    cluster, an fp32 pad takes one thread per patch of its part where that part fits ``MAX_BLOCK`` threads (a larger
    part, and fp64, at most ``DEFAULT_BLOCK``)."""
    part = _round_up(-(-nmax // cluster), 32)
    if cluster == 1:
        return min(GROWTH_BLOCK if growth else (DEFAULT_BLOCK if fp64 else FP32_BLOCK), part)
    if not fp64 and part <= MAX_BLOCK:
        return part
    return min(DEFAULT_BLOCK, part)


def shared_bytes(
    model: PadModel, csr_shared: bool, cluster: int = 1, threads: int = 1, per_block: int | None = None
) -> int:
    """Shared memory one block of ``threads`` threads of the on-chip ``strang`` kernel needs [bytes], its tiles
    :func:`kernel_tiles` (for the limit ``per_block``, default the device's; :func:`_block_bytes`)."""
    return _block_bytes(model, *kernel_tiles(model, cluster, threads, per_block), csr_shared, cluster, per_block)


def grown_tiles(model: PadModel, cluster: int, per_block: int | None = None) -> bool:
    """Whether the on-chip ``strang`` kernel keeps each block's own copies of a growing pad's areas, √A and k_N
    (``onchip_kernel(grown_tiles=...)``): on a cluster, where it spares every growth event a cluster barrier and
    its reads from L2 (docs/onchip.md, "Growth on a cluster"), when the copies fit beside the state in the shared
    memory of ``per_block`` (:func:`smem_limit`; with the largest tiles :func:`kernel_tiles` may give). A pad too
    large for them grows from the model's arrays with a cluster barrier, as on one block, where the state's reads
    keep the L1 the copies would take."""
    if "pad_growth" not in model.arrays or cluster < 2:
        return False
    nmax = _bucket(_round_up(pad_sizes(model)[0], 32))
    return _state_bytes(model, nmax, cluster) + 3 * nmax * itemsize(model) <= smem_limit(model, per_block)


def _state_bytes(model: PadModel, nmax: int, cluster: int) -> int:
    """Shared memory [bytes] of a block's state tiles of ``nmax`` patches: u (×2), w, F_s per patch of the pad and,
    on a cluster, the u exchange's two mbarriers and its per-patch mask of receiving blocks."""
    b = 4 * nmax * itemsize(model)
    if cluster > 1:
        b += 16 + 4 * (nmax // cluster + 1)
    return b


def _block_bytes(
    model: PadModel, nmax: int, slots: int, csr_shared: bool, cluster: int, per_block: int | None = None
) -> int:
    """Shared memory [bytes] of a block with tiles of ``nmax`` patches and ``slots`` CSR slots: the state
    (:func:`_state_bytes`), with :func:`grown_tiles` (for ``per_block``) the three copies of a growing pad, plus
    the block's part of the CSR when kept on chip (``csr_shared``)."""
    b = _state_bytes(model, nmax, cluster)
    if grown_tiles(model, cluster, per_block):
        b += 3 * nmax * itemsize(model)
    if csr_shared:
        b += slots * (2 + itemsize(model))  # int16 local index, k_ij in the state precision
    return b


def adaptive_shared_bytes(model: PadModel, cluster: int = 1, links: int = 0) -> int:
    """Shared memory one block of the on-chip ``adaptive`` kernel needs [bytes]: the pad's stage displacements (two
    rows of the largest pad rounded up to 32), its decision table (2 × max(cluster, 6) float64) and, when ``links``
    > 0, that many neighbour links of its own (int16 local index, k_ij in the state precision)."""
    b = itemsize(model)
    return 2 * _round_up(pad_sizes(model)[0], 32) * b + 16 * max(cluster, 6) + links * (2 + b)


def default_cluster(pads: int, sm_count: int, split_fits_csr: bool = False) -> int:
    """Blocks per pad for ``cluster=None`` on a CUDA device of compute capability 9.0+ (growing pads too).

    A cluster's blocks run on the SMs of one GPC, and the batch should run in one wave: every cluster resident at
    once (one hf1 block per SM). Measured on an H100 (132 SMs; hf1 fp32, 2026-11-25,
    docs/benchmarks/onchip_h100/cluster_waves_*.md): 14 clusters of 8, 28 of 4 and 66 of 2 run in one wave, 16, 32
    and 68 need a second one (a step then takes 1.6–1.9× as long). Whole GPCs of 18 SMs (sm_count // 18 of them)
    hold 18 // K clusters of 4, 5 or 8, and pairs fill every SM; so K is the largest of 8, 5, 4 with pads ≤
    (sm_count // 18) · (18 // K), else 2 with pads ≤ sm_count // 2; otherwise 1, or 2 when only a pad split in two
    keeps its neighbour lists in shared memory (fp64 hf1 pads: 2 blocks fastest, or within 2 %, from 57 to 1024
    pads). Once the batch fills the GPU, a cluster loses (it repeats the u update of the whole pad in every block):
    fp32 pads 67–1024 run fastest on one block each (64 pads: 7.2 µs/step on K = 1, 4.5 on K = 2; 100 pads: 7.5
    against 8.3). One pad: 6.3 → 1.8 µs/step fp32 (K = 1 → 8) and 18.4 → 2.6 fp64
    (docs/benchmarks/onchip_h100/bench_cluster.md); the growing varying_area pad (an event every 20 steps):
    11.4 → 2.7 µs/step fp32 (K = 1 → 8; K = 4: 3.5; docs/benchmarks/onchip_h100/cluster_exchange_ab.md). Clusters
    of 5 (15–21 pads on 132 SMs; 21 run in one wave, 24 do not) step 16–27 % faster than 4 there on an H200: hf1
    fp32 2.47–2.79 against 3.16–3.37 µs/step, 16 growing varying_area pads 3.45 against 4.10
    (docs/benchmarks/onchip_h200_cluster5/).
    """
    gpcs = max(sm_count // 18, 1)
    for k in (8, 5, 4):
        if pads <= gpcs * (18 // k):
            return k
    if pads <= sm_count // 2:
        return 2
    return 2 if split_fits_csr else 1


WIDER_CLUSTERS = (8, 16)  # the cluster sizes a batch of few pads widens to for its neighbour lists
WIDEN_FROM = 4  # the smallest cluster the rule gives a batch of few pads (≤ 28 on 132 SMs) that may widen


def widen_for_csr(cluster: int, fits: Callable[[int], bool]) -> int:
    """Blocks per pad for a batch of few pads (``cluster`` ≥ :data:`WIDEN_FROM`, one wave) whose neighbour lists do
    not fit shared memory at ``cluster`` (``fits(k)``: whether they do on k blocks per pad): the smallest of
    :data:`WIDER_CLUSTERS` above it at which they fit, else ``cluster``. The engine asks :func:`block_config`, the
    validation's cost model its own estimate of the same bytes.

    Off chip every gather reads global memory, ≈ 5× the on-chip gather time (cost.OFF_CHIP); a wider cluster costs
    waves instead (7 clusters of 16 at once on 132 SMs by the rule of :func:`default_cluster`, one per GPC: not
    measured), fewer than that for the batches it is taken for. The validation's 16 pads of dense LF states
    (ms_short, ms_app3: up to 2967 patches, 220 652 links in one pad) took 42.5 µs per step on clusters of 5 with
    their lists off chip, 11.8 on clusters of 16 with them on chip, against 8.4 for 8 pads of up to 4329 patches
    and 32 links per patch on chip (NVIDIA H200; docs/validation.md, docs/benchmarks/lf_batches_h200/)."""
    if cluster < WIDEN_FROM or fits(cluster):
        return cluster
    return next((wider for wider in WIDER_CLUSTERS if wider > cluster and fits(wider)), cluster)


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


def unsupported(model: PadModel, integrator: str) -> str | None:
    """Why the on-chip engine cannot run this model with ``integrator`` (None when it can): ``strang`` keeps a pad in
    shared memory; ``adaptive`` keeps a pad's stage displacements there (:func:`adaptive_shared_bytes`)."""
    if integrator == "adaptive":
        need = adaptive_shared_bytes(model)
        if need > smem_limit(model):
            return f"the stage displacements of a {pad_sizes(model)[0]}-patch pad need {need} B of shared memory"
        return None
    if integrator not in ONCHIP_INTEGRATORS:
        return f"the on-chip engine implements the strang and adaptive integrators only (got {integrator})"
    need, limit = shared_bytes(model, False), smem_limit(model)
    if need > limit:
        return (
            f"a pad of {pad_sizes(model)[0]} patches needs {need} B of shared memory per block, "
            f"the device offers {limit} B"
        )
    return None


def fast_math_refusal(model: PadModel, engine: str, integrator: str) -> str | None:
    """Why a run on ``engine`` (resolved: onchip or general) cannot take CUDA fast math (None when it can).

    Fast math is a compile option of the on-chip ``strang`` kernel and changes single-precision operations only
    (:func:`~aca_warp.hf.options.fast_math_unfit`); Warp's CPU build ignores it (a CPU run would be the exact one),
    so it is offered where it acts: fp32 on a CUDA device, on chip. Its statistics were measured against the exact
    kernel's (docs/onchip.md, "Fast math")."""
    why = fast_math_unfit(integrator, "fp64" if model.dtype == wp.float64 else "fp32")
    if why is None and engine != "onchip":
        reason = unsupported(model, integrator) or "the general engine asked for"
        why = f"it compiles the on-chip strang kernel only ({reason})"
    if why is None and model.device.is_cpu:
        why = "it applies to CUDA devices only (Warp's CPU build has no fast math: the run would be the exact one)"
    return why


def choose_engine(model: PadModel, engine: str, integrator: str, fast_math: bool = False) -> str:
    """Resolve ``engine`` (auto, onchip, general) for a model; ``onchip`` on an unsupported model is an error, and
    so is ``fast_math`` where :func:`fast_math_refusal` gives a reason.

    ``auto`` picks ``onchip`` when the model allows it, growing models included (their in-kernel growth passes
    ``scripts/onchip_gpu_check.py --growth`` on an H100; docs/onchip.md): faster on CUDA (docs/onchip.md) and on the
    CPU, where Warp runs a block as one thread and a launch covers many steps instead of several launches per step
    (``scripts/bench_cpu_engines.py``: ``strang`` 1.0–1.2× as fast on a whole hf1 pad, 1.5–2× on 60–150 patches;
    ``adaptive`` one launch per chunk instead of 14 per trial, hf1, 1 ms, tolerance 1e-5: 1.03 s against 1.84 s on
    the 2-core host of docs/time_to_solution.md). On the CPU both engines give the same bits.
    """
    if engine not in ENGINES:
        raise SceneError(f"unknown engine {engine!r}; choose from {', '.join(ENGINES)}")
    why = unsupported(model, integrator)
    if engine == "onchip" and why is not None:
        given = option("engine='onchip'", "--engine onchip")
        raise SceneError(f"{given}: {why}")
    resolved = "general" if engine == "general" or why is not None else "onchip"
    refusal = fast_math_refusal(model, resolved, integrator) if fast_math else None
    if refusal is not None:
        raise SceneError(f"{option('fast_math=True', '--fast-math')}: {refusal}")
    return resolved
