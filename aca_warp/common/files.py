"""Files shared by HF and LF runs: output paths, the ``.partial`` convention, opening HDF5 files, provenance."""

from __future__ import annotations

import os
import platform
from pathlib import Path
from typing import Any

import h5py

from aca_warp.common.checkpoint import has_checkpoint
from aca_warp.common.errors import SceneError


def versions() -> dict[str, str]:
    """Versions of Python and of the packages a run depends on."""
    import importlib.metadata as md

    out = {"python": platform.python_version()}
    for pkg in ("aca-warp", "warp-lang", "numpy", "scipy", "h5py", "matplotlib"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            out[pkg] = "not installed"
    return out


def machine(device: Any) -> dict[str, str]:
    """The device and host that ran something: ``device`` (Warp alias), ``device_name``, ``host``, ``platform``."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    host = f"{cpu}, {os.cpu_count()} cores"
    name = device.name if device.is_cuda else f"CPU ({host}; Warp CPU kernels run on one thread)"
    return {"device": str(device), "device_name": name, "host": host, "platform": platform.platform()}


def partial_path(path: str | Path) -> Path:
    """The name a run file has while it is written: ``NAME.partial``."""
    p = Path(path)
    return p.with_name(p.name + ".partial")


def check_output_path(path: str | Path, *, overwrite: bool) -> Path:
    """Refuse to clobber an existing file (or a killed run's ``NAME.partial``) unless ``overwrite``; the folder
    must exist and ``path`` must not be a folder."""
    p = Path(path)
    if p.is_dir():
        raise SceneError(f"output {p} is a folder; give a file name such as {p / 'run.h5'}")
    if p.exists() and not overwrite:
        raise SceneError(f"output file {p} exists; pass --overwrite to replace it")
    part = partial_path(p)
    if part.exists() and not overwrite:
        raise SceneError(
            f"{part} exists (an unfinished run); continue it with 'aca-warp hf --resume {p}' or pass --overwrite"
        )
    if not p.parent.exists():
        raise SceneError(f"output folder {p.parent} does not exist")
    return p


def open_h5(path: str | Path, what: str) -> h5py.File:
    """Open an existing HDF5 file read-only; :class:`SceneError` naming ``what`` ("run file", …) when it is missing
    or cannot be opened."""
    p = Path(path)
    if not p.is_file():
        raise SceneError(f"{what} not found: {p}")
    try:
        return h5py.File(p, "r")
    except OSError as e:
        raise SceneError(f"cannot open {what} {p}: {e}") from None


def version_changes(stored: dict[str, str]) -> list[str]:
    """``name old -> new`` for every package whose version differs from the run file's."""
    now = versions()
    return [f"{k} {v} -> {now.get(k, 'missing')}" for k, v in stored.items() if now.get(k) != v]


def find_resumable(path: str | Path) -> tuple[Path, Path]:
    """(run file, its ``.partial``) of the run ``path`` names: ``NAME``, ``NAME.partial`` or a stopped ``NAME``.

    A killed run left ``NAME.partial``; a run stopped by Ctrl-C or a fault was moved to ``NAME`` (incomplete)
    and keeps its checkpoint. Raises SceneError when there is nothing to resume.
    """
    p = Path(path)
    if p.name.endswith(".partial"):
        final, part = p.with_name(p.name.removesuffix(".partial")), p
    else:
        final, part = p, partial_path(p)
    if part.exists():
        if final.exists():
            raise SceneError(f"both {final} and {part} exist; move the one you do not want to resume away")
        return final, part
    if not final.exists():
        raise SceneError(f"nothing to resume: neither {final} nor {part} exists")
    try:
        with h5py.File(final, "r") as f:
            complete = bool(f.attrs.get("complete", False))
            resumable = has_checkpoint(f)
    except OSError as e:
        raise SceneError(f"cannot open run file {final}: {e}") from None
    if complete:
        raise SceneError(f"{final} is a complete run; nothing to resume")
    if not resumable:
        raise SceneError(f"{final} holds no checkpoint (run without checkpoint_interval); use 'aca-warp rerun'")
    return final, part
