"""Kernel launches packed once and replayed, on the CPU.

``wp.launch`` resolves and packs every argument on every call: 27 µs on this project's 2-core CPU container for a
kernel of a model struct and two arrays, more than the kernel itself for a pad of a few dozen patches; through a
:class:`Launcher` 4.4 µs (``scripts/launch_cost.py``, docs/benchmarks/launch_cost_cpu.json). A launch recorded with
``record_cmd=True`` (a ``wp.Launch``) keeps its packed arguments and replays them with the same kernel, the same
launch dimensions and the same argument values, so the results are the same bit for bit (inside a CPU graph capture
the replay is recorded into the graph as ``wp.launch`` would be).
:class:`Launcher` records each distinct launch (kernel, dimensions, arguments) once and replays it afterwards.
Arrays and structs are told apart by identity (their contents may change between launches: the packed pointers
stay valid), numbers by type and value; the launcher keeps the arguments it has recorded alive, so that no other
object takes an identity it knows. A struct's fields must not be reassigned after its first launch (every struct of
the engines is built once, from arrays updated in place). On CUDA devices the engines step through captured graphs
and a launcher launches as ``wp.launch`` does.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import warp as wp

_NUMBERS = (bool, int, float, np.generic)
_WARP_SCALARS = (wp.float16, wp.float32, wp.float64, wp.int8, wp.uint8, wp.int16, wp.uint16, wp.int32, wp.uint32)
_WARP_SCALARS += (wp.int64, wp.uint64)


MAX_RECORDED = 256
"""Launches a :class:`Launcher` keeps at most (an engine has a few dozen distinct ones)."""


def _key(value: Any) -> tuple:
    """What tells one launch argument from another: a number (Python, NumPy or a Warp scalar such as
    ``wp.float32(h)``) by its type and value, anything else by identity."""
    if isinstance(value, _NUMBERS):
        return (type(value), value)
    if isinstance(value, _WARP_SCALARS):
        return (type(value), value.value)
    return (None, id(value))


class Launcher:
    """``wp.launch`` / ``wp.launch_tiled`` on one device, each distinct launch recorded once and replayed on the CPU
    (module docstring); one per engine or solver, so that what it keeps goes with it."""

    def __init__(self, device: wp.Device) -> None:
        self.device = device
        self.recorded: dict[tuple, tuple[Any, list]] | None = {} if device.is_cpu else None

    def __call__(
        self, kernel: Any, dim: int | Sequence[int], inputs: Sequence[Any], *, block_dim: int | None = None
    ) -> None:
        """Launch ``kernel`` over ``dim`` threads with ``inputs`` (``block_dim``: as ``wp.launch_tiled``, ``dim``
        then the grid of blocks)."""
        if self.recorded is None:
            self._launch(kernel, dim, inputs, block_dim, record=False)
            return
        key = (kernel, dim if isinstance(dim, int) else tuple(dim), block_dim, *map(_key, inputs))
        entry = self.recorded.get(key)
        if entry is None:
            if len(self.recorded) >= MAX_RECORDED:  # a caller that passes new objects every time: start again
                self.recorded.clear()
            entry = self.recorded[key] = (self._launch(kernel, dim, inputs, block_dim, record=True), list(inputs))
        entry[0].launch()

    def _launch(self, kernel: Any, dim: Any, inputs: Sequence[Any], block_dim: int | None, *, record: bool) -> Any:
        if block_dim is None:
            return wp.launch(kernel, dim=dim, inputs=list(inputs), device=self.device, record_cmd=record)
        return wp.launch_tiled(
            kernel, dim=dim, block_dim=block_dim, inputs=list(inputs), device=self.device, record_cmd=record
        )
