"""Analysis of run files: spectra, time-frequency transforms, the Synchronization Index (paper §2.2), saturation."""

from .saturation import (
    SaturationResult,
    common_start,
    coupled_growth_rates,
    friction_slope,
    growth_rate_summary,
    predicted_growth_rate,
    saturation,
)
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
    "SaturationResult",
    "SyncBins",
    "SyncResult",
    "amplitude_spectrum",
    "common_start",
    "complex_spectrum",
    "coupled_growth_rates",
    "cwt_morlet",
    "drop_low_frequencies",
    "friction_slope",
    "growth_rate_summary",
    "peak",
    "predicted_growth_rate",
    "saturation",
    "stft",
    "sync_index",
    "sync_index_from_bins",
    "sync_index_from_signals",
    "sync_null_level",
]
