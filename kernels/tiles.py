"""Barrier-aware helpers for shared-memory tiles (used by the on-chip HF kernel and the LF block kernels).

Barrier rule (CUDA): every block-cooperative op (``tile_zeros``, ``wp.tile``, ``tile_sum``/``tile_min``,
:func:`block_sync`, and Warp's ``tile[i] = x``, which ends in ``__syncthreads()``) must be reached by all threads
of the block equally often, so none may sit inside per-thread loops or branches. Per-thread stores into shared
tiles use the barrier-free ``put`` helpers made here; reads ``t[i]`` of a shared tile need no barrier.
"""

from __future__ import annotations

from typing import Any

import warp as wp

wp.set_module_options({"enable_backward": False})


@wp.func_native("WP_TILE_SYNC();\n")
def block_sync(): ...


def tile_store_1d(dtype: Any, size: int) -> Any:
    """``put(t, i, x)``: ``t[i] = x`` for one thread, no block barrier (t a tile of shape (size,))."""

    def put(t, i, x): ...

    put.__annotations__ = {"t": wp.tile[dtype, size], "i": int, "x": dtype}  # real types: closures need no eval
    return wp.func_native("t.data(wp::tile_coord(i)) = x;\n")(put)


def tile_store_rows(dtype: Any, rows: int, size: int) -> Any:
    """``put(t, r, i, x)``: ``t[r, i] = x`` for one thread, no block barrier (t a tile of shape (rows, size))."""

    def put(t, r, i, x): ...

    put.__annotations__ = {"t": wp.tile[dtype, rows, size], "r": int, "i": int, "x": dtype}
    return wp.func_native("t.data(wp::tile_coord(r, i)) = x;\n")(put)


@wp.func
def block_add(a: wp.array[wp.float64], i: int, x: wp.float64, lane: int):
    """``a[i] += Σ x`` over the block: a block-wide sum, then one atomic add by thread 0 (all threads must call)."""
    s = wp.tile_sum(wp.tile(x))[0]
    if lane == 0:
        wp.atomic_add(a, i, s)
