"""Scalar measures for the paper's statements about the saturated HF state (paper §3; docs/analysis.md).

Each function is pure (NumPy arrays in, a frozen dataclass out, SI units) so that a validation table can be
filled from any record. The modules, by what they measure:

* :mod:`~aca_warp.analysis.measures.peaks` — one spectral peak and the spectrum around it: :func:`first_peak`
  ("the first peak of each velocity spectrum", §3.1), :func:`peak_width` ("the peaks of HF₂ and HF₄ ... are
  narrower"), :func:`peak_to_floor` ("significantly more pronounced than the other output quantities"),
  :func:`plateau_excess` ("broad-band plateaus"), :func:`tonality` ("from stochastic ... to periodic", §3.2),
  :func:`averaged_spectrum` (a Welch-averaged amplitude spectrum whose peaks stand out of the scatter);
* :mod:`~aca_warp.analysis.measures.comparison` — spectra of one record compared: :func:`spectral_overlap` ("μ and
  torque ... nearly completely overlapping", Fig. 8), :func:`shared_peaks` and :func:`shared_peak_fraction`
  ("similar characteristic peaks of the global friction coefficient, friction torque, and effective friction
  radius", §3.1);
* :mod:`~aca_warp.analysis.measures.spatial` — the patches' motion in space: :func:`phase_correlation_length`
  (synchronised "islands", Figs. 4/6) and :func:`neighbour_coherence` ("local clustering", §3.3);
* :mod:`~aca_warp.analysis.measures.lines` — spectral lines over time: :func:`stft_peak` (Fig. 10: "about 0.004
  ... around 69.1 kHz"), :func:`peak_track` and :func:`line_trend` ("decreasing frequencies of the characteristic
  peaks", §3.2);
* :mod:`~aca_warp.analysis.measures.prevalence` — S(f) at equal Φ: :func:`sync_by_prevalence` and
  :func:`equal_prevalence_difference` (S depends on Φ: a few random phases already give a high S), and
  :func:`spectral_agreement` ("agreement between the Synchronization Index results and the friction frequency
  spectrum", §3.1);
* :mod:`~aca_warp.analysis.measures.ensemble` — :func:`ensemble_interval`, mean and 95 % intervals over seeds, for
  every validation row.

Every name is importable from this package (``from aca_warp.analysis.measures import first_peak``).
"""

from __future__ import annotations

from .comparison import (
    SharedFraction,
    SharedPeak,
    SpectralOverlap,
    shared_peak_fraction,
    shared_peaks,
    spectral_overlap,
)
from .ensemble import EnsembleInterval, ensemble_interval
from .lines import STFT_WINDOWS, LineTrend, StftPeak, line_trend, peak_track, stft_peak, stft_peaks
from .peaks import (
    PeakContrast,
    PeakWidth,
    PlateauExcess,
    Tonality,
    averaged_spectrum,
    first_peak,
    peak_to_floor,
    peak_width,
    plateau_excess,
    tonality,
)
from .prevalence import (
    EqualPrevalence,
    PrevalenceTable,
    equal_prevalence_difference,
    prevalence_classes,
    spectral_agreement,
    sync_by_prevalence,
)
from .spatial import CorrelationLength, neighbour_coherence, phase_correlation_length

__all__ = [
    "STFT_WINDOWS", "CorrelationLength", "EnsembleInterval", "EqualPrevalence", "LineTrend", "PeakContrast",
    "PeakWidth", "PlateauExcess", "PrevalenceTable", "SharedFraction", "SharedPeak", "SpectralOverlap", "StftPeak",
    "Tonality", "averaged_spectrum", "ensemble_interval", "equal_prevalence_difference", "first_peak", "line_trend",
    "neighbour_coherence", "peak_to_floor", "peak_track", "peak_width", "phase_correlation_length",
    "plateau_excess", "prevalence_classes", "shared_peak_fraction", "shared_peaks", "spectral_agreement",
    "spectral_overlap", "stft_peak", "stft_peaks", "sync_by_prevalence", "tonality",
]  # fmt: skip
