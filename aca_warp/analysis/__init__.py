"""Analysis of run files: spectra, time-frequency transforms and the Synchronization Index (paper §2.2)."""

from .spectra import amplitude_spectrum, complex_spectrum, drop_low_frequencies, peak
from .sync import (
    SyncBins,
    SyncResult,
    sync_index,
    sync_index_from_bins,
    sync_index_from_signals,
    sync_null_level,
)
from .timefreq import cwt_morlet, stft

__all__ = [
    "SyncBins",
    "SyncResult",
    "amplitude_spectrum",
    "complex_spectrum",
    "cwt_morlet",
    "drop_low_frequencies",
    "peak",
    "stft",
    "sync_index",
    "sync_index_from_bins",
    "sync_index_from_signals",
    "sync_null_level",
]
