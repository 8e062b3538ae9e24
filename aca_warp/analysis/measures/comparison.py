"""Measures that compare spectra of one record (paper Fig. 8): how nearly two spectra overlap, and which peaks
several spectra share (with the share expected by chance).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.signal

from ..spectra import DEFAULT_FLOOR_HZ


@dataclass(frozen=True)
class SpectralOverlap:
    """Distance between two spectra on a logarithmic amplitude scale, over the bins of a band.

    Attributes:
        mean_abs_log: D = mean |ln a − ln b| (0 for identical spectra; exp(D) − 1 is the typical relative
            difference, e.g. D = 0.095 for a 10 % difference).
        median_abs_log: Median of |ln a − ln b|.
        max_abs_log: Largest |ln a − ln b|.
        mean_log_ratio: Mean of ln a − ln b (a systematic offset: a ≈ b·exp(mean_log_ratio)).
        bins: Bins used (both amplitudes > 0 inside the band).
        band: (fmin, fmax) [Hz].
    """

    mean_abs_log: float
    median_abs_log: float
    max_abs_log: float
    mean_log_ratio: float
    bins: int
    band: tuple[float, float]


def spectral_overlap(
    freq: np.ndarray, a: np.ndarray, b: np.ndarray, *, band: tuple[float, float] | None = None
) -> SpectralOverlap:
    """How nearly two amplitude spectra overlap on the log axes of paper Fig. 8.

    D = mean over the bins f in ``band`` with a(f) > 0 and b(f) > 0 of |ln a(f) − ln b(f)|. On log-log axes
    the vertical distance between the curves is what the eye compares, so D weights every bin alike, from
    the peaks to the floor between them. Use spectra with the same normalisation (both mean-normalised, as
    μ and torque in ``/analysis/spectra``) and the same frequency grid.

    Args:
        freq: Frequencies [Hz], shape (F,).
        a: First amplitude spectrum, shape (F,).
        b: Second amplitude spectrum, shape (F,).
        band: (fmin, fmax) [Hz]; default (10 Hz, highest frequency), the paper's plotted range.

    Returns:
        A :class:`SpectralOverlap`.
    """
    freq, a, b = (np.asarray(v, dtype=np.float64) for v in (freq, a, b))
    if not freq.shape == a.shape == b.shape or freq.ndim != 1:
        raise ValueError(f"freq, a and b must be 1-D of equal length, got {freq.shape}, {a.shape}, {b.shape}")
    band = (DEFAULT_FLOOR_HZ, float(freq[-1])) if band is None else (float(band[0]), float(band[1]))
    keep = (freq >= band[0]) & (freq <= band[1]) & (a > 0) & (b > 0)
    if not keep.any():
        raise ValueError(f"no bin in {band} Hz where both spectra are positive")
    d = np.log(a[keep]) - np.log(b[keep])
    return SpectralOverlap(
        mean_abs_log=float(np.mean(np.abs(d))),
        median_abs_log=float(np.median(np.abs(d))),
        max_abs_log=float(np.max(np.abs(d))),
        mean_log_ratio=float(np.mean(d)),
        bins=int(keep.sum()),
        band=band,
    )


@dataclass(frozen=True)
class SharedPeak:
    """A spectral peak found in several spectra.

    Attributes:
        frequency: Mean of the members' peak frequencies [Hz].
        members: Spectrum name -> (peak frequency [Hz], amplitude), for every spectrum that has the peak.
    """

    frequency: float
    members: dict[str, tuple[float, float]]


def _find_peaks(freq: np.ndarray, amp: np.ndarray, band: tuple[float, float], prominence: float) -> np.ndarray:
    """Indices of peaks inside ``band`` whose prominence in ln amplitude is at least ln(prominence)."""
    la = np.log(np.maximum(amp, np.finfo(np.float64).tiny))
    idx, _ = scipy.signal.find_peaks(la, prominence=np.log(prominence))
    return idx[(freq[idx] >= band[0]) & (freq[idx] <= band[1])]


def shared_peaks(
    freq: np.ndarray,
    spectra: dict[str, np.ndarray],
    *,
    band: tuple[float, float] | None = None,
    prominence: float = 4.0,
    tolerance: float | None = None,
    min_count: int | None = None,
) -> list[SharedPeak]:
    """Peaks that several spectra have in common, e.g. μ, torque and friction radius (paper Fig. 8).

    Peaks of each spectrum are the local maxima (``scipy.signal.find_peaks``) that stand at least a factor
    ``prominence`` above the higher of their two surrounding minima (prominence measured in ln amplitude, so
    independent of normalisation). All peaks are sorted by frequency and grouped greedily: a group starts at
    the lowest unassigned peak and takes every later peak within ``tolerance`` of it, the largest one per
    spectrum. Groups with peaks from at least ``min_count`` spectra are returned.

    Args:
        freq: Uniformly spaced frequencies [Hz], shape (F,).
        spectra: Name -> amplitude spectrum, each of shape (F,).
        band: (fmin, fmax) [Hz] in which peaks count; default (10 Hz, highest frequency).
        prominence: Factor by which a peak must exceed its surroundings (4: 12 dB). The single-record Hann
            spectrum of a chaotic saturated signal fluctuates from bin to bin; a factor 2 there finds a peak
            every few bins.
        tolerance: Largest frequency difference within a group [Hz]; default 2 bins.
        min_count: Spectra a shared peak must appear in; default all of them.

    Returns:
        The shared peaks, sorted by frequency.
    """
    freq = np.asarray(freq, dtype=np.float64)
    if len(spectra) < 2:
        raise ValueError("shared_peaks needs at least two spectra")
    band = (DEFAULT_FLOOR_HZ, float(freq[-1])) if band is None else band
    tolerance = 2.0 * (freq[1] - freq[0]) if tolerance is None else tolerance
    need = len(spectra) if min_count is None else min_count
    found = []
    for name, amp in spectra.items():
        amp = np.asarray(amp, dtype=np.float64)
        if amp.shape != freq.shape:
            raise ValueError(f"spectrum {name!r} has shape {amp.shape}, freq {freq.shape}")
        found += [(float(freq[i]), float(amp[i]), name) for i in _find_peaks(freq, amp, band, prominence)]
    found.sort()
    out: list[SharedPeak] = []
    i = 0
    while i < len(found):
        j = i
        while j + 1 < len(found) and found[j + 1][0] - found[i][0] <= tolerance * (1 + 1e-9):
            j += 1
        members: dict[str, tuple[float, float]] = {}
        for f, a, name in found[i : j + 1]:
            if name not in members or a > members[name][1]:
                members[name] = (f, a)
        if len(members) >= need:
            out.append(SharedPeak(float(np.mean([m[0] for m in members.values()])), members))
        i = j + 1
    return out


@dataclass(frozen=True)
class SharedFraction:
    """Share of a reference spectrum's peaks that every other spectrum has too.

    Attributes:
        fraction: shared / reference_peaks (NaN without reference peaks).
        shared: Reference peaks found in every spectrum (:func:`shared_peaks` groups).
        reference_peaks: Peaks of the reference spectrum in the band.
        chance: Fraction expected if the other spectra's peaks lay at random: Π_x min(1, n_x (2t + 1)/B),
            n_x the peaks of spectrum x, t the tolerance in bins, B the bins of the band.
    """

    fraction: float
    shared: int
    reference_peaks: int
    chance: float


def shared_peak_fraction(
    freq: np.ndarray,
    spectra: dict[str, np.ndarray],
    reference: str,
    *,
    band: tuple[float, float] | None = None,
    prominence: float = 4.0,
    tolerance: float | None = None,
) -> SharedFraction:
    """Share of the peaks of ``spectra[reference]`` that all spectra have (:func:`shared_peaks`), and chance.

    Args:
        freq: Uniformly spaced frequencies [Hz], shape (F,).
        spectra: Name -> amplitude spectrum, each (F,); at least two, ``reference`` among them.
        reference: Name of the spectrum whose peaks are counted (e.g. "mu").
        band: (fmin, fmax) [Hz]; default (10 Hz, highest frequency).
        prominence: As in :func:`shared_peaks`.
        tolerance: As in :func:`shared_peaks` [Hz]; default 2 bins.

    Returns:
        A :class:`SharedFraction`.
    """
    freq = np.asarray(freq, dtype=np.float64)
    if reference not in spectra:
        raise ValueError(f"reference spectrum {reference!r} is not among {sorted(spectra)}")
    band = (DEFAULT_FLOOR_HZ, float(freq[-1])) if band is None else (float(band[0]), float(band[1]))
    df = freq[1] - freq[0]
    tolerance = 2.0 * df if tolerance is None else tolerance
    common = shared_peaks(freq, spectra, band=band, prominence=prominence, tolerance=tolerance)
    counts = {k: _find_peaks(freq, np.asarray(a, dtype=np.float64), band, prominence).size for k, a in spectra.items()}
    n_band = int(np.count_nonzero((freq >= band[0]) & (freq <= band[1])))
    width = 2.0 * np.floor(tolerance / df + 1e-9) + 1.0
    chance = float(np.prod([min(1.0, counts[k] * width / n_band) for k in spectra if k != reference]))
    n_ref = counts[reference]
    return SharedFraction(len(common) / n_ref if n_ref else float("nan"), len(common), n_ref, chance)
