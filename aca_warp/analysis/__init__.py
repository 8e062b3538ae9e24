"""Analysis of run files: spectra, time-frequency transforms and the Synchronization Index (paper §2.2).

The names below load their modules (and SciPy) when first used, so that the command line starts fast.
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

_PUBLIC = {
    "amplitude_spectrum": "spectra",
    "complex_spectrum": "spectra",
    "drop_low_frequencies": "spectra",
    "peak": "spectra",
    "SyncBins": "sync",
    "SyncResult": "sync",
    "sync_index": "sync",
    "sync_index_from_bins": "sync",
    "sync_index_from_signals": "sync",
    "sync_null_level": "sync",
    "cwt_morlet": "timefreq",
    "stft": "timefreq",
}
__all__ = sorted(_PUBLIC)


def __getattr__(name: str) -> Any:
    if name in _PUBLIC:
        return getattr(import_module(f"{__name__}.{_PUBLIC[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
