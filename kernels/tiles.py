"""Barrier-aware helpers for shared-memory tiles (used by the on-chip HF kernel and the LF block kernels).

Barrier rule (CUDA): every block-cooperative op (``tile_zeros``, ``wp.tile``, ``tile_sum``/``tile_min``,
:func:`block_sync`, and Warp's ``tile[i] = x``, which ends in ``__syncthreads()``) must be reached by all threads
of the block equally often, so none may sit inside per-thread loops or branches. Per-thread stores into shared
tiles use the barrier-free ``put`` helpers made here; reads ``t[i]`` of a shared tile need no barrier, and the
``get`` helpers read without Warp's negative-index wrap (``t[i]`` adds a compare, an add and a select per index so
that ``t[-1]`` works; in the on-chip gather that was about a third of its instructions, docs/onchip.md).

The helpers are native snippets typed per tile shape; this module keeps its annotations eager (no ``from
__future__ import annotations``) so that the stubs made in the factories carry real tile types.
"""

from typing import Any

import warp as wp

wp.set_module_options({"enable_backward": False})


@wp.func_native("WP_TILE_SYNC();\n")
def block_sync(): ...


@wp.func_native(
    """
#if defined(__CUDA_ARCH__)
    return 0;
#else
    return 1;
#endif
"""
)
def cpu_build() -> int:
    """1 in the code compiled for the CPU, 0 in CUDA code: a constant the compilers fold, so a branch on it leaves
    the other device's code as it would be without the branch."""
    ...


def lane_sum(dtype: Any, width: int) -> Any:
    """``total(x)``: the sum of ``x`` over each group of ``width`` consecutive lanes of a warp (a power of two ≤ 32),
    returned to every lane of the group, by warp shuffles (a tree); every lane of the warp must call it. On the CPU
    it returns ``x`` (use ``width`` 1 there)."""
    ctype = {4: "float", 8: "double"}[wp.types.type_size_in_bytes(dtype)]
    snippet = f"""
#if defined(__CUDA_ARCH__)
    {ctype} s = x;
    for (int o = {width} / 2; o > 0; o >>= 1) s += __shfl_xor_sync(0xffffffffu, s, o, {width});
    return s;
#else
    return x;
#endif
"""

    @wp.func_native(snippet)
    def total(x: dtype) -> dtype: ...

    return total


def warp_sum(dtype: Any) -> Any:
    """``total(x)``: the sum of ``x`` (a scalar or vector ``dtype``) over the warp, in lane 0, in the order of the
    warp stage of Warp's block reductions (``wp::warp_reduce`` with ``add`` over the warp's existing lanes, as
    ``tile_sum`` takes it): adding the warps' sums in warp order then gives ``tile_sum``'s result to the bit. Every
    lane of the warp must call it. On the CPU, where a block's threads are not warps, it returns ``x``."""
    snippet = """
#if defined(__CUDA_ARCH__)
    const wp_tile_lane_mask_bits_t mask = __ballot_sync(WP_TILE_LANE_MASK_ALL, true);
    return wp::warp_reduce(x, [](auto a, auto b) { return wp::add(a, b); }, mask);
#else
    return x;
#endif
"""

    @wp.func_native(snippet)
    def total(x: dtype) -> dtype: ...

    return total


@wp.func_native(
    """
#if defined(__CUDA_ARCH__)
    const wp_tile_lane_mask_bits_t mask = __ballot_sync(WP_TILE_LANE_MASK_ALL, true);
#if __CUDA_ARCH__ >= 800
    return __reduce_min_sync(mask, x);
#else
    const int least = wp::warp_reduce(x, [](int a, int b) { return a < b ? a : b; }, mask);
    return __shfl_sync(mask, least, __ffs(mask) - 1);
#endif
#else
    return x;
#endif
"""
)
def warp_min(x: int) -> int:
    """The least ``x`` over the warp, to every lane (every lane of the warp must call it); on the CPU ``x``. The
    warp's own reduction from sm_80, shuffles below (``wp::warp_reduce``, its result broadcast from its first
    lane)."""
    ...


@wp.func_native(
    """
#if defined(__CUDA_ARCH__)
    const wp_tile_lane_mask_bits_t mask = __ballot_sync(WP_TILE_LANE_MASK_ALL, true);
    const wp_tile_lane_mask_bits_t from = __ballot_sync(mask, mine != 0);
    return from == 0 ? x : __shfl_sync(mask, x, __ffs(from) - 1);
#else
    return x;
#endif
"""
)
def warp_pick(mine: int, x: wp.float64) -> wp.float64:
    """``x`` of the first lane of the warp whose ``mine`` ≠ 0 (its own ``x`` where none is), to every lane (every
    lane of the warp must call it); on the CPU ``x``."""
    ...


@wp.func_native(
    """
#if defined(__CUDA_ARCH__)
    return lane / WP_TILE_WARP_SIZE;
#else
    return lane;
#endif
"""
)
def warp_index(lane: int) -> int:
    """The warp of thread ``lane`` of a block (on the CPU each thread of a block is a warp of its own)."""
    ...


@wp.func_native(
    """
#if defined(__CUDA_ARCH__)
    return lane % WP_TILE_WARP_SIZE == 0 ? 1 : 0;
#else
    return 1;
#endif
"""
)
def warp_leader(lane: int) -> int:
    """1 for the first lane of a warp (every thread on the CPU), else 0."""
    ...


def lane_first(dtype: Any, width: int) -> Any:
    """``first(x)``: the ``x`` of the first lane of each group of ``width`` consecutive lanes of a warp, to every
    lane of the group (a warp shuffle; every lane of the warp must call it). On the CPU it returns ``x``."""
    ctype = {4: "float", 8: "double"}[wp.types.type_size_in_bytes(dtype)]
    snippet = f"""
#if defined(__CUDA_ARCH__)
    return __shfl_sync(0xffffffffu, ({ctype})x, 0, {width});
#else
    return x;
#endif
"""

    @wp.func_native(snippet)
    def first(x: dtype) -> dtype: ...

    return first


def tile_store_1d(dtype: Any, size: int) -> Any:
    """``put(t, i, x)``: ``t[i] = x`` for one thread, no block barrier (t a tile of shape (size,))."""

    @wp.func_native("t.data(wp::tile_coord(i)) = x;\n")
    def put(t: wp.tile[dtype, size], i: int, x: dtype): ...

    return put


def tile_store_rows(dtype: Any, rows: int, size: int) -> Any:
    """``put(t, r, i, x)``: ``t[r, i] = x`` for one thread, no block barrier (t a tile of shape (rows, size))."""

    @wp.func_native("t.data(wp::tile_coord(r, i)) = x;\n")
    def put(t: wp.tile[dtype, rows, size], r: int, i: int, x: dtype): ...

    return put


def tile_load_1d(dtype: Any, size: int) -> Any:
    """``get(t, i)``: ``t[i]`` for 0 ≤ i < size, without the negative-index wrap (t a tile of shape (size,))."""

    @wp.func_native("return t.data(wp::tile_coord(i));\n")
    def get(t: wp.tile[dtype, size], i: int) -> dtype: ...

    return get


def tile_load_rows(dtype: Any, rows: int, size: int) -> Any:
    """``get(t, r, i)``: ``t[r, i]`` for 0 ≤ r < rows, 0 ≤ i < size, without the negative-index wrap."""

    @wp.func_native("return t.data(wp::tile_coord(r, i));\n")
    def get(t: wp.tile[dtype, rows, size], r: int, i: int) -> dtype: ...

    return get


@wp.func
def block_put(a: wp.array2d[wp.float64], row: int, col: int, x: wp.float64, lane: int):
    """``a[row, col] = Σ x`` over the block: a block-wide sum (a fixed order), stored by thread 0 (all threads must
    call). The blocks' sums are then added in block order by one thread (``lf_sums.add_block_sums``)."""
    s = wp.tile_sum(wp.tile(x))[0]
    if lane == 0:
        a[row, col] = s


# Thread-block clusters (sm_90+): a cluster's blocks share a barrier and can store into each other's shared memory.
# On the CPU and below sm_90 a cluster is one block: the barrier is the block barrier and "remote" means this block.


@wp.func_native(
    """
#if defined(__CUDA_ARCH__) && (__CUDA_ARCH__ >= 900)
    asm volatile("barrier.cluster.arrive.release.aligned;\\n\\tbarrier.cluster.wait.acquire.aligned;" ::: "memory");
#else
    WP_TILE_SYNC();
#endif
"""
)
def cluster_sync():
    """Barrier of all threads of the thread-block cluster, with release/acquire of shared memory across it."""
    ...


def tile_store_rows_remote(dtype: Any, rows: int, size: int) -> Any:
    """``put(t, r, i, x, rank)``: ``t[r, i] = x`` in the shared tile ``t`` of cluster block ``rank``, one thread,
    no barrier (``mapa`` + ``st.shared::cluster``; visible to that block after the next :func:`cluster_sync`)."""

    bits, reg, cast = {4: ("b32", "r", "__float_as_uint"), 8: ("b64", "l", "__double_as_longlong")}[
        wp.types.type_size_in_bytes(dtype)
    ]
    snippet = f"""
#if defined(__CUDA_ARCH__) && (__CUDA_ARCH__ >= 900)
    const unsigned local = static_cast<unsigned>(__cvta_generic_to_shared(&t.data(wp::tile_coord(r, i))));
    unsigned remote;
    asm volatile("mapa.shared::cluster.u32 %0, %1, %2;" : "=r"(remote) : "r"(local), "r"(rank));
    asm volatile("st.shared::cluster.{bits} [%0], %1;" :: "r"(remote), "{reg}"({cast}(x)) : "memory");
#else
    t.data(wp::tile_coord(r, i)) = x;
#endif
"""

    @wp.func_native(snippet)
    def put(t: wp.tile[dtype, rows, size], r: int, i: int, x: dtype, rank: int): ...

    return put


@wp.func_native(
    """
#if defined(__CUDA_ARCH__)
    return __ffs(m) - 1;
#else
    return __builtin_ctz(static_cast<unsigned>(m));
#endif
"""
)
def lowest_bit(m: int) -> int:
    """Index of the lowest set bit of ``m`` (m ≠ 0)."""
    ...


# Transaction barriers (sm_90+): a block waits for the bytes that the other blocks of its cluster store into its
# shared memory with ``st.async`` instead of meeting them all at a cluster barrier. ``bars`` is a shared int64 tile
# of ``n`` mbarriers; on the CPU and below sm_90 (one-block clusters) these are no-ops and the store is local.

_MBAR_ADDR = "static_cast<unsigned>(__cvta_generic_to_shared(&bars.data(wp::tile_coord(k))))"


def mbarrier_ops(n: int) -> tuple[Any, Any, Any]:
    """(``init(bars, lane)``, ``expect(bars, k, nbytes)``, ``wait(bars, k, parity)``) for a tile of ``n`` mbarriers.

    ``init``: thread 0 sets each mbarrier to one expected arrival, then fences the init for the cluster (follow it
    with :func:`cluster_sync` before any block stores into another). ``expect``: one thread per phase arrives on
    mbarrier ``k`` and adds ``nbytes`` to the bytes the phase waits for (the stores may land before or after).
    ``wait``: every thread spins until the phase of parity ``parity`` of mbarrier ``k`` has completed (acquire:
    the bytes stored into this block are then visible).
    """
    init_src = f"""
#if defined(__CUDA_ARCH__) && (__CUDA_ARCH__ >= 900)
    if (lane == 0) {{
        for (int k = 0; k < {n}; ++k)
            asm volatile("mbarrier.init.shared::cta.b64 [%0], 1;" :: "r"({_MBAR_ADDR}) : "memory");
        asm volatile("fence.mbarrier_init.release.cluster;" ::: "memory");
    }}
#endif
"""
    expect_src = f"""
#if defined(__CUDA_ARCH__) && (__CUDA_ARCH__ >= 900)
    asm volatile("mbarrier.arrive.expect_tx.shared::cta.b64 _, [%0], %1;" :: "r"({_MBAR_ADDR}), "r"(nbytes)
                 : "memory");
#endif
"""
    wait_src = f"""
#if defined(__CUDA_ARCH__) && (__CUDA_ARCH__ >= 900)
    const unsigned addr = {_MBAR_ADDR};
    unsigned done = 0;
    while (!done) {{
        asm volatile("{{\\n\\t.reg .pred p;\\n\\tmbarrier.try_wait.parity.shared::cta.b64 p, [%1], %2;\\n\\t"
                     "selp.u32 %0, 1, 0, p;\\n\\t}}" : "=r"(done) : "r"(addr), "r"(parity) : "memory");
    }}
#endif
"""

    @wp.func_native(init_src)
    def init(bars: wp.tile[wp.int64, n], lane: int): ...

    @wp.func_native(expect_src)
    def expect(bars: wp.tile[wp.int64, n], k: int, nbytes: int): ...

    @wp.func_native(wait_src)
    def wait(bars: wp.tile[wp.int64, n], k: int, parity: int): ...

    return init, expect, wait


def tile_store_rows_async(dtype: Any, rows: int, size: int, n: int) -> Any:
    """``put(t, r, i, x, rank, bars, k)``: ``t[r, i] = x`` in the shared tile ``t`` of cluster block ``rank`` by
    ``st.async``, completing ``sizeof(x)`` bytes of that block's mbarrier ``k`` (of the ``n`` in ``bars``) when it
    lands (:func:`mbarrier_ops`; local store below sm_90)."""

    bits, reg, cast = {4: ("b32", "r", "__float_as_uint"), 8: ("b64", "l", "__double_as_longlong")}[
        wp.types.type_size_in_bytes(dtype)
    ]
    snippet = f"""
#if defined(__CUDA_ARCH__) && (__CUDA_ARCH__ >= 900)
    const unsigned local = static_cast<unsigned>(__cvta_generic_to_shared(&t.data(wp::tile_coord(r, i))));
    unsigned remote, rbar;
    asm volatile("mapa.shared::cluster.u32 %0, %1, %2;" : "=r"(remote) : "r"(local), "r"(rank));
    asm volatile("mapa.shared::cluster.u32 %0, %1, %2;" : "=r"(rbar) : "r"({_MBAR_ADDR}), "r"(rank));
    asm volatile("st.async.shared::cluster.mbarrier::complete_tx::bytes.{bits} [%0], %1, [%2];"
                 :: "r"(remote), "{reg}"({cast}(x)), "r"(rbar) : "memory");
#else
    t.data(wp::tile_coord(r, i)) = x;
#endif
"""

    @wp.func_native(snippet)
    def put(t: wp.tile[dtype, rows, size], r: int, i: int, x: dtype, rank: int, bars: wp.tile[wp.int64, n], k: int): ...

    return put
