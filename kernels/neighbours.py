"""Neighbour search: ``wp.HashGrid`` → CSR list of all patch pairs within the coupling radius.

Built once per patch set (never queried in the step loop). Points are pad-local float64 coordinates;
pads of a batch are kept apart by the grid's groups (``patch_pad``), not by coordinate offsets.
Rows list neighbours in hash-grid order (cell-sorted, deterministic); indices are global patch indices.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import warp as wp

wp.set_module_options({"enable_backward": False})


@wp.kernel
def _neighbours(
    # Model:
    grid: wp.uint64,
    patch_pos: wp.array[wp.vec3d],
    patch_pad: wp.array[wp.int32],
    radius: wp.array[wp.float64],
    nbr_start: wp.array[wp.int32],
    fill: int,
    # Out:
    count_out: wp.array[wp.int32],
    nbr_index_out: wp.array[wp.int32],
    nbr_inv_dist_out: wp.array[wp.float64],
):
    """The neighbours of patch i within its pad's radius, in hash-grid order: ``fill`` = 0, their number into
    ``count_out``; ``fill`` = 1, their indices and 1/D0 into the CSR row from ``nbr_start[i]``. Both passes take
    the same hits, so a row holds exactly the links counted for it."""
    i = wp.tid()
    p = patch_pos[i]
    pad = patch_pad[i]
    r = radius[pad]
    k = int(0)
    if fill != 0:
        k = nbr_start[i]
    for j in wp.hash_grid_query(grid, p, r, pad):
        d2 = wp.length_sq(patch_pos[j] - p)
        if j != i and d2 <= r * r:
            if fill != 0:
                nbr_index_out[k] = j
                nbr_inv_dist_out[k] = wp.float64(1.0) / wp.sqrt(d2)
            k += 1
    if fill == 0:
        count_out[i] = k


def build_neighbours(
    x: np.ndarray,
    y: np.ndarray,
    patch_pad: np.ndarray,
    radius: np.ndarray,
    device: wp.Device | str,
    check: Callable[[int], None] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CSR neighbour list of all patch pairs of the same pad within that pad's coupling radius.

    Args:
        x, y: Pad-local patch centres [m], shape (n,).
        patch_pad: Pad index of every patch, shape (n,), int.
        radius: Coupling radius of every pad [m], shape (pads,).
        device: Warp device for the search.
        check: Called with the number of links (summed in int64) after they are counted and before the int32 row
            offsets and the link arrays are made; raises to refuse them (:mod:`aca_warp.hf.limits`).

    Returns:
        (nbr_start (n+1,) int32, nbr_index (nnz,) int32, nbr_inv_dist (nnz,) float64 [1/m]): row offsets,
        neighbour indices and inverse centre distances 1/D0_ij.
    """
    n = len(x)
    radius = np.asarray(radius, dtype=np.float64)
    if n == 0 or radius.max() <= 0.0:
        return np.zeros(n + 1, np.int32), np.zeros(0, np.int32), np.zeros(0, np.float64)
    cell = float(radius.max())
    span = max(float(np.ptp(x)), float(np.ptp(y)), cell)
    dim = int(min(max(np.ceil(span / cell) + 1, 1), 4096))
    pos = np.zeros((n, 3))
    pos[:, 0] = x  # unshifted: 1/D0 of a pad must not depend on the other pads of its batch
    pos[:, 1] = y
    pos_d = wp.array(pos, dtype=wp.vec3d, device=device)
    pad_d = wp.array(np.asarray(patch_pad, dtype=np.int32), dtype=wp.int32, device=device)
    rad_d = wp.array(radius, dtype=wp.float64, device=device)
    grid = wp.HashGrid(dim, dim, 1, device=device, dtype=wp.float64)
    grid.build(pos_d, cell, groups=pad_d)
    counts = wp.zeros(n + 1, dtype=wp.int32, device=device)
    start = wp.zeros(n + 1, dtype=wp.int32, device=device)
    model = [grid.id, pos_d, pad_d, rad_d, start]
    no_links = [wp.empty(0, dtype=wp.int32, device=device), wp.empty(0, dtype=wp.float64, device=device)]
    wp.launch(_neighbours, dim=n, inputs=[*model, 0], outputs=[counts, *no_links], device=device)
    if check is not None:
        check(int(counts.numpy().astype(np.int64).sum()))  # each count < n fits int32; their sum may not
    wp.utils.array_scan(counts, start, inclusive=False)
    nnz = int(start.numpy()[-1])
    index = wp.zeros(max(nnz, 1), dtype=wp.int32, device=device)
    inv_d = wp.zeros(max(nnz, 1), dtype=wp.float64, device=device)
    wp.launch(_neighbours, dim=n, inputs=[*model, 1], outputs=[counts, index, inv_d], device=device)
    return start.numpy(), index.numpy()[:nnz], inv_d.numpy()[:nnz]
