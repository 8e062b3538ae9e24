"""Warp device facts shared by HF and LF."""

from __future__ import annotations

import warp as wp


def block_threads(device: wp.Device, block_dim: int) -> int:
    """Threads a ``launch_tiled`` block of ``block_dim`` really runs: all on CUDA and with Warp's CPU fibers
    (``wp.config.enable_cpu_blocks``), else one (a CPU block is one thread)."""
    return block_dim if device.is_cuda or wp.config.enable_cpu_blocks else 1
