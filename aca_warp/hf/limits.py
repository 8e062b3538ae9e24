"""Sizes and counts of an HF run checked against the integers and the memory they land in, before anything is built.

The kernels index patches, neighbour links (CSR offsets), samples, steps per sample and growth intervals with 32-bit
integers (``wp.int32`` arrays and ``int`` kernel arguments); a value past 2^31 − 1 wraps to a negative or zero
count (a segmentation fault, or SIGFPE from a modulo by zero) instead of an error. A valid scene can also ask for
more neighbour links than any memory holds: 50 000 patches with a 0.5 m coupling radius are 2.5e9 links (≈ 250 GB).
The functions here refuse such runs with one line (:class:`~aca_warp.common.errors.SceneError`) naming the limit or
the memory estimate:

* :func:`check_int32` — a count against 2^31 − 1;
* :func:`links_lower_bound` — a cheap lower bound of the neighbour links (patches sharing a square cell of side
  r/√2 are within r of each other), so that an absurd coupling radius is refused without counting its pairs;
* :func:`check_model_memory` — patches and links against the memory of the device (and of the host, which holds
  copies while the model is built).

The CSR offsets stay 32-bit: a scene that needs more than 2^31 − 1 links needs about 170 GB for its links alone
(:data:`BYTES_PER_LINK`), beyond any one device, so 64-bit offsets would buy nothing but slower kernels.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from aca_warp.common.bounds import available_memory
from aca_warp.common.errors import SceneError

INT32_MAX = 2**31 - 1
# bytes per patch: ~25 device arrays of the model, state and recorder (8 bytes each in fp64) and the host copies
# made while the model is built
BYTES_PER_PATCH = 600
# bytes per directed neighbour link: index (4), 1/D0 (8) and k_ij (8) on the device, plus the host copies and
# temporaries of build_model and stable_step (rows, gathers, products); measured peak RSS 55 B per link for
# build_model + stable_step of 20 000 patches with 3.7e7 links (CPU); 80 leaves room for the engine's copies
BYTES_PER_LINK = 80


def check_int32(name: str, value: int | float, hint: str) -> None:
    """Refuse ``value`` of the count ``name`` when it exceeds 2^31 − 1 (one line with ``hint``)."""
    if value > INT32_MAX:
        shown = str(value) if isinstance(value, int) else f"{value:.3g}"
        raise SceneError(f"{name} = {shown} exceeds {INT32_MAX} (2^31 - 1, the kernels count it in int32); {hint}")


def links_lower_bound(x: np.ndarray, y: np.ndarray, pad_of: np.ndarray, radius: np.ndarray) -> int:
    """A lower bound of the directed neighbour links: Σ over square cells of side r/√2 (per pad) of n_c (n_c − 1).

    Two patches in one such cell are at most r apart, so each of these pairs is a link. Exact for a radius beyond √2
    times the pad's span (one cell); O(n log n).

    Args:
        x, y: Patch centres [m], shape (n,).
        pad_of: Pad of each patch, shape (n,), int.
        radius: Coupling radius of each pad [m], shape (pads,).
    """
    r = np.asarray(radius, dtype=np.float64)[pad_of]
    ok = r > 0
    if not ok.any():
        return 0
    cell = r[ok] / math.sqrt(2.0)
    xs, ys = x[ok] - x[ok].min(), y[ok] - y[ok].min()  # cells from the lowest corner
    # cell indices, clipped so that a huge coordinate over a tiny cell cannot overflow int64
    kx = np.clip(np.floor(xs / cell), 0, 2.0**40).astype(np.int64)
    ky = np.clip(np.floor(ys / cell), 0, 2.0**40).astype(np.int64)
    pads = np.asarray(pad_of)[ok].astype(np.int64)
    nx, ny = int(kx.max()) + 1, int(ky.max()) + 1
    if (int(pads.max()) + 1) * nx * ny < 2**62:  # one int64 key per cell: a 1-D sort (a row-wise unique is ~20× slower)
        _, counts = np.unique((pads * nx + kx) * ny + ky, return_counts=True)
    else:
        _, counts = np.unique(np.stack([pads, kx, ky], axis=1), axis=0, return_counts=True)
    counts = counts.astype(np.int64)
    return int(np.sum(counts * (counts - 1)))


def model_bytes(patches: int, links: int) -> int:
    """Estimated peak memory of a model of ``patches`` patches and ``links`` directed links [bytes]."""
    return BYTES_PER_PATCH * int(patches) + BYTES_PER_LINK * int(links)


def check_model_memory(patches: int, links: int, device: Any, radius: float, *, exact: bool) -> None:
    """Refuse a model whose estimated memory exceeds what ``device`` has, or whose links exceed int32 (one line;
    ``exact``: ``links`` is the count, else a lower bound)."""
    what = "" if exact else "at least "
    need = model_bytes(patches, links)
    have = available_memory(device)
    if need > have:
        raise SceneError(
            f"the model needs about {need / 1e9:.3g} GB ({patches} patches, {what}{links:.3g} neighbour links within "
            f"material.coupling_radius = {radius:g} m), more than the {have / 1e9:.3g} GB available on {device}; "
            "reduce patches.count or material.coupling_radius"
        )
    check_int32(
        f"the neighbour links ({what}{links:.3g}) of {patches} patches within material.coupling_radius = {radius:g} m",
        links,
        "reduce patches.count or material.coupling_radius",
    )
