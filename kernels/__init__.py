"""Warp kernels of aca_warp, one module per stage, each kernel beside its thin launch wrapper.

Shipped as the subpackage ``aca_warp.kernels`` (see pyproject.toml). The physics that the HF engines' kernels share
are Warp functions with one home each in ``physics`` (friction law and sub-step, per-patch terms, contact, sample
sums). Every module sets
``enable_backward=False``; kernel parameters come in the groups model, control (steps, tolerances, counters),
state in, state out. Kernels generic in the state precision T (``Any`` in their annotations) get their float32
and float64 overloads from :func:`precision_overloads`.
"""

from __future__ import annotations

from typing import Any

import warp as wp


def _concrete(annotation: Any, T: Any) -> Any:
    """``annotation`` with the precision placeholder ``Any`` replaced by ``T`` (scalars and array dtypes)."""
    if annotation is Any:
        return T
    if wp.types.is_array(annotation) and annotation.dtype is Any:
        return type(annotation)(dtype=T, ndim=annotation.ndim)
    return annotation


def precision_overloads(*kernels: Any) -> None:
    """Declare the float32 and float64 overloads of generic kernels, read from their own annotations."""
    for kernel in kernels:
        for T in (wp.float32, wp.float64):
            wp.overload(kernel, {name: _concrete(t, T) for name, t in kernel.adj.arg_types.items()})
