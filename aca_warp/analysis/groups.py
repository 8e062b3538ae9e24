"""The in-memory analysis group and the facts of a run file every group of ``/analysis`` is computed from.

:class:`Group` is what the ``compute_*`` functions of :mod:`aca_warp.analysis.report` (the global outputs) and
:mod:`aca_warp.analysis.patch_report` (the per-patch velocities) return and what ``/analysis`` stores;
:func:`sample_interval` and :func:`has_patch_velocity` read the run file they start from.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import h5py
import numpy as np

from aca_warp.common.errors import SceneError

DEFAULT_BAND_TOP = 200.0e3
"""Upper edge of the default analysis band of the Synchronization Index and the CWT [Hz]."""

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


def has_patch_velocity(f: h5py.File) -> bool:
    """True when the run recorded per-patch velocities (with at least 8 rows)."""
    return "patches/velocity" in f and "patches/time" in f and f["patches/velocity"].shape[0] >= 8
