"""The in-memory analysis group and the facts of a run file every group of ``/analysis`` is computed from.

:class:`Group` is what the ``compute_*`` functions of :mod:`aca_warp.analysis.report` (the global outputs) and
:mod:`aca_warp.analysis.patch_report` (the per-patch velocities) return and what ``/analysis`` stores;
:func:`sample_interval` and :func:`has_patch_velocity` read the run file they start from.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from aca_warp.common.errors import SceneError

DEFAULT_BAND_TOP = 200.0e3
"""Upper edge of the default analysis band of the Synchronization Index and the CWT [Hz]."""

MIN_SAMPLES = 8
"""Samples the analysis needs: its spectra, time-frequency maps and Synchronization Index (and the per-patch rows
for the latter)."""

GROUP = "analysis"
"""The group of a run file that holds its analysis (``aca-warp analyze``); a resumed run drops it."""
TMP_GROUP = "_analysis_new"
"""Where an analysis is written before it replaces :data:`GROUP` whole."""


@dataclass
class Group:
    """One analysis group in memory: group attributes and datasets with their attributes.

    Attributes:
        attrs: Attributes of the group (str, numbers, bools, lists of numbers).
        datasets: name -> (array, attributes); every dataset's attributes include ``unit``.
    """

    attrs: dict[str, Any] = field(default_factory=dict)
    datasets: dict[str, tuple[np.ndarray, dict[str, Any]]] = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.datasets[name][0]

    def __contains__(self, name: object) -> bool:
        return name in self.datasets

    def meta(self, name: str) -> dict[str, Any]:
        """Attributes of dataset ``name``."""
        return self.datasets[name][1]

    def add(self, name: str, data: Any, unit: str, **attrs: Any) -> None:
        """Add dataset ``name`` with its ``unit`` and further attributes."""
        self.datasets[name] = (np.asarray(data), {"unit": unit, **attrs})


def sample_interval(time: np.ndarray, what: str = "/global/time") -> float:
    """Uniform sampling interval of ``time`` [s]; :class:`SceneError` if the samples are not uniform."""
    time = np.asarray(time, dtype=np.float64)
    if time.size < 2:
        raise SceneError(f"{what} holds {time.size} sample(s); need at least 2")
    dt = (time[-1] - time[0]) / (time.size - 1)
    if not dt > 0 or np.max(np.abs(np.diff(time) - dt)) > 1e-6 * dt:
        raise SceneError(f"{what} is not uniformly sampled; the spectra need uniform samples")
    return float(dt)


def patch_rows(f: h5py.File) -> int:
    """The rows (samples) of the run's per-patch velocities; 0 where it recorded none."""
    return int(f["patches/velocity"].shape[0]) if "patches/velocity" in f and "patches/time" in f else 0


def has_patch_velocity(f: h5py.File) -> bool:
    """True when the run recorded per-patch velocities, at least :data:`MIN_SAMPLES` rows of them."""
    return patch_rows(f) >= MIN_SAMPLES


def missing_run_message(path: str | Path) -> str | None:
    """For a run file ``path`` that does not exist, the message naming its ``.partial`` when that exists (a run still
    being written, or one that was stopped or killed) and what to do; for a folder, that it is one (a sweep's: how
    to read it); for anything else that is not a regular file (a pipe, a device), that it is not one, so that
    nothing opens it (a pipe would block the first read); else None."""
    from aca_warp.common.files import partial_path, recovery

    p = Path(path)
    if p.is_dir() and (p / "manifest.json").is_file():  # a sweep's folder (aca_warp.sweep.manifest.MANIFEST)
        shard = next(iter(sorted(p.glob("shard-*.h5"))), p / "shard-00000.h5")
        return (
            f"{p} is a sweep's folder, not a run file: take one pad of a shard (e.g. {shard} --pad K), or read the "
            f"whole sweep in Python with aca_warp.sweep.load_sweep({str(p)!r})"
        )
    if p.is_dir():
        return f"{p} is a folder, not a run file: name the run file (RUN.h5) inside it"
    if p.exists():
        return None if p.is_file() else f"{p} is not a regular file (expected a run file)"
    partial = partial_path(p)
    if partial.is_file():
        return (
            f"run file not found: {p}; {partial} exists (a run still being written, or one stopped or killed before "
            f"it completed): analyse or plot {partial} itself, or {recovery(p)}"
        )
    return None


def open_h5_run(path: str | Path, mode: str = "r") -> h5py.File:
    """``open_h5`` of a run file (which names a file another process holds open), with one line for a missing file
    that has a ``.partial`` (:func:`missing_run_message`)."""
    from aca_warp.common.files import open_h5

    said = missing_run_message(path)
    if said is not None:
        raise SceneError(said)
    return open_h5(path, "run file", mode=mode)
