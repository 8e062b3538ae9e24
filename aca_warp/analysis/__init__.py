"""Analysis of run files: spectra, time-frequency maps, Synchronization Index (paper §2.2), saturation, measures.

The names below load their modules (and SciPy) when first used, so that the command line starts fast.
"""

from __future__ import annotations

from aca_warp.common.lazy import lazy_names

_MODULES = {
    "measures": (
        "CorrelationLength", "EnsembleInterval", "EqualPrevalence", "LineTrend", "PeakContrast", "PeakWidth",
        "PlateauExcess", "PrevalenceTable", "SharedFraction", "SharedPeak", "SpectralOverlap", "StftPeak",
        "ensemble_interval", "equal_prevalence_difference", "first_peak", "line_trend", "peak_to_floor", "peak_track",
        "peak_width", "phase_correlation_length", "plateau_excess", "prevalence_classes", "shared_peak_fraction",
        "shared_peaks", "spectral_agreement", "spectral_overlap", "stft_peak", "stft_peaks", "sync_by_prevalence",
    ),
    "saturation": (
        "SaturationResult", "common_start", "coupled_growth_rates", "friction_slope", "growth_rate_summary",
        "predicted_growth_rate", "saturation",
    ),
    "spectra": ("amplitude_spectrum", "complex_spectrum", "drop_low_frequencies", "peak"),
    "sync": (
        "SyncBins", "SyncResult", "sync_index", "sync_index_from_bins", "sync_index_from_signals", "sync_null_level",
    ),
    "timefreq": ("cwt_morlet", "stft"),
}  # fmt: skip
_PUBLIC = {name: f"{__name__}.{module}" for module, names in _MODULES.items() for name in names}
__all__ = sorted(_PUBLIC)


__getattr__, __dir__ = lazy_names(__name__, _PUBLIC)
