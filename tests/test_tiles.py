"""The barrier-free shared-tile helpers of aca_warp.kernels.tiles (CPU): ``get`` reads the element ``t[i]`` reads
(without the negative-index wrap), ``put`` writes the element ``t[i] = x`` writes; the sample sums' and the contact
solve's one block reduction of a vector (kernels.physics.block_sums) against one scalar reduction per component."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp
from aca_warp.kernels.physics import block_sums
from aca_warp.kernels.tiles import lowest_bit, tile_load_1d, tile_load_rows, tile_store_1d, tile_store_rows

N = 48
get_i = tile_load_1d(wp.int16, N)
get_r = tile_load_rows(wp.float32, 2, N)
put_i = tile_store_1d(wp.int16, N)
put_r = tile_store_rows(wp.float32, 2, N)


@wp.kernel(enable_backward=False, module="unique")
def _copy_through_tiles(
    idx: wp.array[wp.int16], rows: wp.array2d[wp.float32], out_i: wp.array[wp.int16], out_r: wp.array2d[wp.float32]
):
    _blk, lane = wp.tid()
    ti = wp.tile_load(idx, shape=N, storage="shared")
    tr = wp.tile_load(rows, shape=(2, N), storage="shared")
    si = wp.tile_zeros(shape=N, dtype=wp.int16, storage="shared")
    sr = wp.tile_zeros(shape=(2, N), dtype=wp.float32, storage="shared")
    if lane == 0:
        for i in range(N):
            j = int(get_i(ti, i))  # a permutation: row entries read at scattered places
            put_i(si, i, get_i(ti, j))
            put_r(sr, 0, i, get_r(tr, 1, j) - tr[1, j])  # 0 when get reads what indexing reads
            put_r(sr, 1, N - 1 - i, get_r(tr, 0, i))
    wp.tile_store(out_i, si)
    wp.tile_store(out_r, sr)


def test_tile_get_put_match_indexing():
    rng = np.random.default_rng(3)
    perm = rng.permutation(N).astype(np.int16)
    rows = rng.standard_normal((2, N)).astype(np.float32)
    out_i = wp.zeros(N, dtype=wp.int16, device="cpu")
    out_r = wp.zeros((2, N), dtype=wp.float32, device="cpu")
    wp.launch_tiled(
        _copy_through_tiles,
        dim=[1],
        inputs=[wp.array(perm, device="cpu"), wp.array(rows, device="cpu"), out_i, out_r],
        block_dim=1,
        device="cpu",
    )
    np.testing.assert_array_equal(out_i.numpy(), perm[perm])
    np.testing.assert_array_equal(out_r.numpy()[0], np.zeros(N, np.float32))
    np.testing.assert_array_equal(out_r.numpy()[1], rows[0][::-1])


def test_barrier_rounds_kernel_on_cpu_blocks():
    """scripts/bench_cluster_barrier.py's round (store into the u copies, barrier, read the next lane's value) on a
    CPU block of 32 fiber threads with real barriers: lane l sums (l + 1) mod 32 + s over the rounds s, which holds
    only when every store lands before the barrier releases the read; the script refuses a CPU device."""
    from scriptload import load_script

    bench = load_script("bench_cluster_barrier")
    steps, lanes = 7, 32
    old = wp.config.enable_cpu_blocks
    try:
        wp.config.enable_cpu_blocks = True
        out = wp.zeros((1, lanes), dtype=wp.float32, device="cpu")
        kernel = bench.barrier_kernel(1, lanes, "stores")
        wp.launch_tiled(kernel, dim=[1], block_dim=lanes, inputs=[steps, out], device="cpu")
    finally:
        wp.config.enable_cpu_blocks = old
    lane = np.arange(lanes)
    expected = steps * ((lane + 1) % lanes) + steps * (steps - 1) / 2
    np.testing.assert_array_equal(out.numpy()[0], expected)
    assert bench.main(["--device", "cpu"]) == 2


@wp.kernel(enable_backward=False, module="unique")
def _lowest_bits(m: wp.array[wp.int32], out: wp.array[wp.int32]):
    i = wp.tid()
    out[i] = lowest_bit(m[i])


def test_lowest_bit():
    """``lowest_bit`` (the halo exchange walks its masks of receiving blocks with it): the lowest set bit's index."""
    values = np.array([1, 2, 3, 6, 8, 0x500, 0x8000, 0x7FFF0000, -(2**31)], dtype=np.int32)
    out = wp.zeros(len(values), dtype=wp.int32, device="cpu")
    wp.launch(_lowest_bits, dim=len(values), inputs=[wp.array(values, device="cpu"), out], device="cpu")
    want = [int(v & -v).bit_length() - 1 for v in values.astype(np.int64) % 2**32]
    np.testing.assert_array_equal(out.numpy(), want)


LANES = 96


def _block_sums_both_ways(length: int):
    """A kernel that reduces a block's float64 vectors of ``length`` components both ways: 7 as the on-chip kernel's
    sample sums (SampleSums, then Σ u), 3 and 2 as the contact solve's."""
    Vec = wp.types.vector(length=length, dtype=wp.float64)
    L = wp.constant(length)

    @wp.kernel(enable_backward=False, module="unique")
    def both_ways(x: wp.array3d[wp.float64], fused: wp.array2d[wp.float64], scalar: wp.array2d[wp.float64]):
        blk, lane = wp.tid()
        s = Vec()
        for c in range(L):
            s[c] = x[blk, c, lane]
        t = block_sums(s)
        for c in range(L):
            r = wp.tile_sum(wp.tile(s[c]))[0]
            if lane == 0:
                fused[blk, c] = t[c]
                scalar[blk, c] = r

    return both_ways


@pytest.mark.parametrize("length", [7, 3, 2])
def test_block_sums_is_one_scalar_reduction_per_component(length: int):
    """A block of 96 fiber threads: every component of the one vector reduction is bit for bit the scalar
    ``tile_sum`` of that component (the same additions in the same order), on terms whose sum depends on the
    order (they differ from numpy's sum)."""
    rng = np.random.default_rng(5)
    x = rng.standard_normal((2, length, LANES)) * 10.0 ** rng.integers(-8, 9, (2, length, LANES))
    fused = wp.zeros((2, length), dtype=wp.float64, device="cpu")
    scalar = wp.zeros((2, length), dtype=wp.float64, device="cpu")
    old = wp.config.enable_cpu_blocks
    try:
        wp.config.enable_cpu_blocks = True
        wp.launch_tiled(
            _block_sums_both_ways(length),
            dim=[2],
            inputs=[wp.array(x, dtype=wp.float64, device="cpu"), fused, scalar],
            block_dim=LANES,
            device="cpu",
        )
    finally:
        wp.config.enable_cpu_blocks = old
    np.testing.assert_array_equal(fused.numpy(), scalar.numpy())
    assert np.all(np.abs(fused.numpy() - x.sum(axis=2)) <= 1e-13 * np.abs(x).sum(axis=2))
    assert np.any(fused.numpy() != x.sum(axis=2))
