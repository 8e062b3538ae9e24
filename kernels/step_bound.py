"""Row sums of the coupling springs for the stable-step estimate (``aca_warp.hf.solver.stable_step``).

Per patch i, over its CSR row in link order: Σ_j k_ij and Σ_j k_ij / √(m_i m_j). One CPU thread per row adds in
the order ``np.bincount`` adds its weights, from 0.0, each term rounded as NumPy rounds it (a product, a square
root, a quotient, a sum: no contraction applies), so the sums are NumPy's bit for bit, without the link-sized
temporaries that NumPy makes (about 4× faster for a batch of 256 hf1 pads).
"""

from __future__ import annotations

import numpy as np
import warp as wp

wp.set_module_options({"enable_backward": False})


@wp.kernel
def _row_sums(
    start: wp.array[wp.int32],
    index: wp.array[wp.int32],
    k_ij: wp.array[wp.float64],
    mass: wp.array[wp.float64],
    k_sum_out: wp.array[wp.float64],
    off_out: wp.array[wp.float64],
):
    """Σ_j k_ij and Σ_j k_ij / √(m_i m_j) over row i."""
    i = wp.tid()
    mi = mass[i]
    ks = wp.float64(0.0)
    off = wp.float64(0.0)
    for e in range(start[i], start[i + 1]):
        k = k_ij[e]
        ks = ks + k
        off = off + k / wp.sqrt(mi * mass[index[e]])
    k_sum_out[i] = ks
    off_out[i] = off


def spring_row_sums(
    start: np.ndarray, index: np.ndarray, k_ij: np.ndarray, mass: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(Σ_j k_ij [N/m], Σ_j k_ij / √(m_i m_j) [1/s²]) per patch, each shape (n,) float64, summed on the CPU.

    Args:
        start: CSR row offsets, shape (n+1,), int.
        index: Neighbour of each link, shape (≥ start[-1],), int.
        k_ij: Coupling stiffness of each link [N/m], shape (≥ start[-1],).
        mass: Patch masses [kg], shape (n,).
    """
    n = len(mass)
    k_sum, off = np.zeros(n), np.zeros(n)
    links = int(start[-1]) if n else 0
    if links == 0:
        return k_sum, off
    host = lambda a, np_type, wp_type: wp.array(  # noqa: E731  (the host arrays themselves where they fit)
        np.ascontiguousarray(a, dtype=np_type), dtype=wp_type, device="cpu", copy=False
    )
    inputs = [
        host(start, np.int32, wp.int32),
        host(index[:links], np.int32, wp.int32),
        host(k_ij[:links], np.float64, wp.float64),
        host(mass, np.float64, wp.float64),
    ]
    outputs = [host(k_sum, np.float64, wp.float64), host(off, np.float64, wp.float64)]
    wp.launch(_row_sums, dim=n, inputs=inputs, outputs=outputs, device="cpu")
    return k_sum, off
