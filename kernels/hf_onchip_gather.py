"""The coupling gather of the two on-chip HF kernels: Σ_j k_ij u_j of one patch from the pad's displacements in a
shared-memory tile (the strang kernel's u double buffer, the adaptive kernel's odd/even stage rows).

The links are summed in the order of :func:`~aca_warp.kernels.physics.spring_force` (the general engine's CSR
gather): the row's even links into one partial sum, its odd links into another, then their sum; so on the CPU both
on-chip kernels stay bit-identical to the general engine. The neighbour lists are read either from global memory
(the CSR) or from a shared-memory copy: local int16 neighbour indices and k_ij, link m of a row at slot
p + m · ``stride`` (the strang kernel's bank-interleaved layout, ``stride`` = the CSR banks; the adaptive kernel's
contiguous one, ``stride`` = 1).

Annotations stay eager (no ``from __future__ import annotations``): the function made in the factory is typed by its
tile shapes.
"""

from functools import cache
from typing import Any

import warp as wp
from aca_warp.kernels.tiles import tile_load_1d, tile_load_rows

wp.set_module_options({"enable_backward": False})


@cache
def tile_gather(dtype: Any, nmax: int, slots: int, shared_csr: bool, stride: int, unroll: int) -> Any:
    """``gather(e, end, p, row, a, us, sidx, sk, nbr_index, nbr_stiffness)`` → (Σ k_ij u_j [N], next slot).

    Sums the links e … end − 1 of a patch of the pad starting at global patch ``a``, with u_j from row ``row`` of
    the tile ``us`` (shape (2, ``nmax``)). ``shared_csr``: the links from the shared copy (``sidx``, ``sk``, each
    of ``slots`` entries), the row's first at slot ``p``, then every ``stride``-th; ``unroll`` (2 or 4) links per
    pass (four keep more shared loads in flight; the order of the sums is the same). Otherwise from the CSR
    (``nbr_index``, ``nbr_stiffness``). Returns the sum and the slot after the row's last link (``p`` unchanged
    without ``shared_csr``).
    """
    if unroll not in (2, 4):
        raise ValueError(f"unroll is 2 or 4, got {unroll}")
    get_u = tile_load_rows(dtype, 2, nmax)
    get_ei = tile_load_1d(wp.int16, slots)
    get_ek = tile_load_1d(dtype, slots)
    S = wp.constant(stride)

    @wp.func
    def gather(
        e: int,
        end: int,
        p: int,
        row: int,
        a: int,
        us: wp.tile[dtype, 2, nmax],
        sidx: wp.tile[wp.int16, slots],
        sk: wp.tile[dtype, slots],
        nbr_index: wp.array[wp.int32],
        nbr_stiffness: wp.array[dtype],
    ):
        a0 = dtype(0.0)
        a1 = dtype(0.0)
        if wp.static(shared_csr):
            pe = p + S * (end - e)
            if wp.static(unroll == 4):
                while p + 3 * S < pe:
                    a0 += get_ek(sk, p) * get_u(us, row, int(get_ei(sidx, p)))
                    a1 += get_ek(sk, p + S) * get_u(us, row, int(get_ei(sidx, p + S)))
                    a0 += get_ek(sk, p + 2 * S) * get_u(us, row, int(get_ei(sidx, p + 2 * S)))
                    a1 += get_ek(sk, p + 3 * S) * get_u(us, row, int(get_ei(sidx, p + 3 * S)))
                    p += 4 * S
                if p + S < pe:
                    a0 += get_ek(sk, p) * get_u(us, row, int(get_ei(sidx, p)))
                    a1 += get_ek(sk, p + S) * get_u(us, row, int(get_ei(sidx, p + S)))
                    p += 2 * S
            else:
                while p + S < pe:
                    a0 += get_ek(sk, p) * get_u(us, row, int(get_ei(sidx, p)))
                    a1 += get_ek(sk, p + S) * get_u(us, row, int(get_ei(sidx, p + S)))
                    p += 2 * S
            if p < pe:
                a0 += get_ek(sk, p) * get_u(us, row, int(get_ei(sidx, p)))
                p += S
        else:
            while e + 1 < end:
                a0 += nbr_stiffness[e] * get_u(us, row, nbr_index[e] - a)
                a1 += nbr_stiffness[e + 1] * get_u(us, row, nbr_index[e + 1] - a)
                e += 2
            if e < end:
                a0 += nbr_stiffness[e] * get_u(us, row, nbr_index[e] - a)
        return a0 + a1, p

    return gather
