"""LF kernels of the order-fixed sums (docs/lf_model.md, "Reproducibility"): the alive patches grouped by cell and
by ring, each group in ascending slot order, and the sums that add the patches' contributions into their cells or
``glob`` in a fixed order, so that no float sum depends on the order in which GPU threads run.

Every sum adds its terms in ascending element order onto the target's value: the order in which the CPU, which
runs a kernel's threads one after the other, added them with atomic adds, so CPU results are unchanged.
"""

from __future__ import annotations

import warp as wp

wp.set_module_options({"enable_backward": False})


@wp.struct
class LFGroups:
    """The patches alive at the last grouping, by cell and by ring (:class:`aca_warp.lf.solver.LFSimulation` holds
    the arrays as ``group_count``, ``group_fill``, ``group_start``, ``group_cell``, ``group_ring``). Per cell (C,)
    int32: ``count`` the cell's patches, ``fill`` a cursor of the fill; ``start`` (C + 1,) the first entry of cell e
    in ``cell``, ``start[C]`` the total. Per slot (P,) int32: ``cell`` the slots of cell e at start[e] …
    start[e + 1] − 1, ascending; ``ring`` the same entries of ring k (start[k n_t] … start[(k + 1) n_t] − 1),
    ascending."""

    count: wp.array[wp.int32]
    fill: wp.array[wp.int32]
    start: wp.array[wp.int32]
    cell: wp.array[wp.int32]
    ring: wp.array[wp.int32]


@wp.kernel
def group_count(alive: wp.array[wp.int32], cell: wp.array[wp.int32], groups: LFGroups):
    """Patches per cell (dim = P; ``count`` zeroed before)."""
    i = wp.tid()
    if alive[i] != 0:
        wp.atomic_add(groups.count, cell[i], 1)


@wp.kernel
def group_fill(alive: wp.array[wp.int32], cell: wp.array[wp.int32], groups: LFGroups):
    """Each alive slot into its cell's range of ``cell`` (dim = P, ``fill`` zeroed before). The order inside a range
    depends on the threads; :func:`group_sort` fixes it."""
    i = wp.tid()
    if alive[i] == 0:
        return
    e = cell[i]
    groups.cell[groups.start[e] + wp.atomic_add(groups.fill, e, 1)] = i


@wp.func
def sort_range(a: wp.array[wp.int32], lo: int, hi: int):
    """Sort a[lo … hi − 1] ascending in place (insertion sort: the ranges are short)."""
    for q in range(lo + 1, hi):
        v = a[q]
        r = q
        while r > lo and a[r - 1] > v:
            a[r] = a[r - 1]
            r -= 1
        a[r] = v


@wp.kernel
def group_sort(groups: LFGroups):
    """Sort each cell's range of ``cell`` (dim = C)."""
    e = wp.tid()
    sort_range(groups.cell, groups.start[e], groups.start[e + 1])


@wp.kernel
def ring_order(cell: wp.array[wp.int32], n_t: wp.int32, groups: LFGroups):
    """Each grouped slot into its ring's range of ``ring`` at its rank: the ring's range of ``cell`` holds the same
    slots (its cells' ranges one after the other), and a slot's rank is the number of them below it, so that every
    ring's range is ascending (dim = P; the threads past ``start[C]`` do nothing). A thread counts over its whole
    ring (Σ over the rings of their squared sizes compares a step)."""
    q = wp.tid()
    if q >= groups.start[groups.start.shape[0] - 1]:
        return
    v = groups.cell[q]
    k = cell[v] // n_t
    lo = groups.start[k * n_t]
    rank = int(0)
    for u in range(lo, groups.start[(k + 1) * n_t]):
        if groups.cell[u] < v:
            rank += 1
    groups.ring[lo + rank] = v


@wp.kernel
def add_by_cell(groups: LFGroups, value: wp.array[wp.float64], out: wp.array[wp.float64]):
    """out[e] += value[i] over the grouped slots i of cell e, in ascending slot order; zero values are skipped
    (adding +0 changes no sum that starts at or above +0) (dim = C)."""
    e = wp.tid()
    lo = groups.start[e]
    hi = groups.start[e + 1]
    if lo == hi:
        return
    s = out[e]
    for q in range(lo, hi):
        v = value[groups.cell[q]]
        if v != wp.float64(0.0):
            s = s + v
    out[e] = s


@wp.kernel
def add_block_sums(partial: wp.array2d[wp.float64], slots: wp.vec4i, glob: wp.array[wp.float64]):
    """glob[slots[c]] += partial[b, c] over the blocks b in ascending order (dim = the columns used, ≤ 4)."""
    c = wp.tid()
    g = slots[c]
    s = glob[g]
    for b in range(partial.shape[0]):
        s = s + partial[b, c]
    glob[g] = s
