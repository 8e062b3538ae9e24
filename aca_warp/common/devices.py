"""Warp start-up and device facts shared by HF and LF: a quiet initialisation, the device by name (a clear error for
one this machine lacks), kernel loading with a first-run note, and the threads a tiled block runs.

Warp prints its native CUDA-driver warning on every machine without a GPU and a line per module load; aca_warp keeps
both off unless asked (``aca-warp --verbose``, or ``ACA_WARP_VERBOSE=1`` for the Python API), and says "compiling
kernels (once per machine, the on-chip ones once per pad size)…" before a compile that would otherwise leave the
terminal silent.
"""

from __future__ import annotations

import os
import sys
import tempfile
import threading
from collections.abc import Callable, Iterable
from types import ModuleType

import warp as wp

from aca_warp.common.errors import SceneError

_CUDA_DRIVER_WARNING = "Could not find or load the NVIDIA CUDA driver"
_state = {"initialised": False, "compiling_said": False}
_init_lock = threading.Lock()  # a thread that finds Warp initialising waits for it (sweep tasks, generators)


def verbose() -> bool:
    """Whether Warp's own messages are wanted (``ACA_WARP_VERBOSE`` set to anything but 0/empty)."""
    return os.environ.get("ACA_WARP_VERBOSE", "") not in ("", "0")


def init_warp() -> None:
    """Initialise Warp once, quietly unless :func:`verbose`: its log level at warnings, and its native start-up
    message about a missing CUDA driver dropped (any other native message is passed on to stderr). Safe to call
    from several threads: the first initialises, the others wait for it."""
    if _state["initialised"]:
        return
    with _init_lock:
        if not _state["initialised"]:
            _init_quietly()
            _state["initialised"] = True


def _init_quietly() -> None:
    """``wp.init()`` as :func:`init_warp` describes it."""
    if verbose():
        wp.init()
        return
    wp.config.log_level = wp.LOG_WARNING
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            wp.init()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        tmp.seek(0)
        text = tmp.read().decode(errors="replace")
    kept = [line for line in text.splitlines() if _CUDA_DRIVER_WARNING not in line]
    if kept:
        print("\n".join(kept), file=sys.stderr)


def get_device(device: str | wp.Device) -> wp.Device:
    """The Warp device ``device`` ("cpu", "cuda:N" or a device), Warp initialised first; SceneError, naming the
    devices this machine has, for one it lacks."""
    init_warp()
    if isinstance(device, str) and device.startswith("cuda") and not wp.is_cuda_available():
        # asked before Warp's own lookup, which prints native CUDA errors for "cuda" on a machine without a driver
        raise SceneError(f"device {device!r} is not available here: no usable CUDA GPU (this machine has: {_have()})")
    try:
        return wp.get_device(device)
    except (ValueError, RuntimeError) as e:
        raise SceneError(f"device {device!r} is not available here ({e}; this machine has: {_have()})") from None


def _have() -> str:
    """The devices this machine has, for a message: "cpu, cuda:0"."""
    return ", ".join(str(d) for d in wp.get_devices())


# what load_kernels takes: a Python module of kernels, a kernel (its module, e.g. one of its own), or either with the
# block size its launches take (Warp compiles a module once per block size)
Kernels = ModuleType | wp.Kernel | tuple[ModuleType | wp.Kernel, int]


def _cached(module: wp.Module, threads: int) -> bool:
    """Whether ``module``'s kernels compiled for blocks of ``threads`` threads are in Warp's kernel cache (a heuristic:
    its cache folder exists)."""
    try:
        ident = module.get_module_identifier(threads)
    except Exception:  # noqa: BLE001 (a Warp internal; when it fails, assume a compile is coming)
        return False
    return os.path.isdir(os.path.join(wp.config.kernel_cache_dir, ident))


def load_kernels(modules: Iterable[Kernels], device: wp.Device | str, say: Callable[[str], None] | None = None) -> None:
    """Load (compile, or fetch from the kernel cache) kernel ``modules`` on ``device``: each a Python module, a
    kernel (its module, e.g. a kernel made in a module of its own) or either with the block size [threads] of the
    launches that take it (a module is compiled once per block size: ``wp.launch_tiled`` with ``block_dim`` B needs
    the variant of B); without a size, the variant of a plain launch (one thread on the CPU, the module's own size
    on CUDA). Before the first compile of the process, ``say`` (default: a line on stderr) "compiling kernels…"."""
    init_warp()
    device = wp.get_device(device)
    for entry in modules:
        item, block_dim = entry if isinstance(entry, tuple) else (entry, None)
        module = item.module if isinstance(item, wp.Kernel) else wp.get_module(item.__name__)
        if block_dim is None:
            threads = 1 if device.is_cpu else int(module.options["block_dim"])
        else:
            threads = block_threads(device, block_dim)
        if not _cached(module, threads) and not _state["compiling_said"]:
            _state["compiling_said"] = True
            (say or (lambda s: print(s, file=sys.stderr, flush=True)))(
                "compiling kernels (once per machine, the on-chip ones once per pad size; cached in "
                f"{wp.config.kernel_cache_dir})…"
            )
        wp.load_module(module, device=device, block_dim=threads)


def block_threads(device: wp.Device, block_dim: int) -> int:
    """Threads a ``launch_tiled`` block of ``block_dim`` really runs: all on CUDA and with Warp's CPU fibers
    (``wp.config.enable_cpu_blocks``), else one (a CPU block is one thread)."""
    return block_dim if device.is_cuda or wp.config.enable_cpu_blocks else 1
