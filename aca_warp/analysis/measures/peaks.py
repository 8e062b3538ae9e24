"""Measures of one spectral peak and of a spectrum's shape around it (paper §3.1, Fig. 8; §3.2): the first peak,
its width and height, its contrast over the floor around it, the plateau above it, and how tonal a spectrum is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.signal

from ..spectra import peak


@dataclass(frozen=True)
class PeakWidth:
    """Width and height of one spectral peak.

    Attributes:
        frequency: Peak frequency, Gaussian-interpolated (``spectra.peak``) [Hz].
        height: Peak amplitude at that frequency (units of the spectrum).
        width: Full width at ``rel_height``·height, between linearly interpolated crossings [Hz]; NaN if a
            side does not fall below that level inside the spectrum (or the search stops at a deeper peak).
        f_low: Lower crossing [Hz] (NaN if none).
        f_high: Upper crossing [Hz] (NaN if none).
        rel_height: Fraction of the height at which the width is measured.
        prominence: Height of the peak bin above the higher of its two bases (``scipy.signal.peak_prominences``).
        relative_prominence: prominence / peak-bin amplitude, in [0, 1].
    """

    frequency: float
    height: float
    width: float
    f_low: float
    f_high: float
    rel_height: float
    prominence: float
    relative_prominence: float


def _crossing(freq: np.ndarray, amp: np.ndarray, i: int, level: float, step: int) -> float:
    """Frequency where amp falls below ``level`` walking from bin i in direction ``step`` (linear interpolation)."""
    j = i
    while 0 <= j + step < amp.size:
        k = j + step
        if amp[k] < level:
            frac = (amp[j] - level) / (amp[j] - amp[k])
            return float(freq[j] + frac * (freq[k] - freq[j]))
        j = k
    return float("nan")


def peak_width(
    freq: np.ndarray, amp: np.ndarray, f0: float, *, search: float | None = None, rel_height: float = 0.5
) -> PeakWidth:
    """Full width of the spectral peak nearest ``f0`` at ``rel_height`` of its height.

    The peak is the largest bin within ``f0 ± search``; its frequency and height are Gaussian-interpolated
    (``spectra.peak``). From the peak bin the spectrum is followed down on each side to the first bin below
    ``rel_height``·height, and the crossing is interpolated linearly between that bin and the one before.
    ``rel_height = 0.5`` is the full width at half maximum of the *amplitude* spectrum (a Hann-windowed
    sinusoid on a bin: exactly 2 bins); ``rel_height = 1/√2`` is the half-power bandwidth (2γ of a Lorentzian
    resonance, f/Q).

    Args:
        freq: Uniformly spaced frequencies [Hz], shape (F,).
        amp: Amplitude spectrum, shape (F,), non-negative (linear units, not dB).
        f0: Frequency near which the peak lies [Hz].
        search: Half-width of the band searched for the peak [Hz]; default 3 bins.
        rel_height: Fraction of the height where the width is measured, in (0, 1).

    Returns:
        A :class:`PeakWidth`.
    """
    freq = np.asarray(freq, dtype=np.float64)
    amp = np.asarray(amp, dtype=np.float64)
    if freq.shape != amp.shape or freq.ndim != 1 or freq.size < 3:
        raise ValueError(f"freq and amp must be 1-D of equal length >= 3, got {freq.shape} and {amp.shape}")
    if not 0.0 < rel_height < 1.0:
        raise ValueError(f"rel_height must lie in (0, 1), got {rel_height}")
    df = freq[1] - freq[0]
    search = 3.0 * df if search is None else search
    f_peak, height = peak(freq, amp, fmin=f0 - search, fmax=f0 + search)
    band = np.flatnonzero((freq >= f0 - search) & (freq <= f0 + search))
    i = int(band[np.argmax(amp[band])])
    level = rel_height * height
    lo, hi = _crossing(freq, amp, i, level, -1), _crossing(freq, amp, i, level, +1)
    prom = float(scipy.signal.peak_prominences(amp, [i])[0][0]) if 0 < i < amp.size - 1 else 0.0
    return PeakWidth(
        frequency=f_peak,
        height=height,
        width=hi - lo,
        f_low=lo,
        f_high=hi,
        rel_height=rel_height,
        prominence=prom,
        relative_prominence=prom / amp[i] if amp[i] > 0 else 0.0,
    )


def _refine(freq: np.ndarray, amp: np.ndarray, i: int) -> tuple[float, float]:
    """Gaussian interpolation of the peak at bin i (``spectra.peak`` restricted to bins i-1..i+1)."""
    lo, hi = max(i - 1, 0), min(i + 2, freq.size)
    f, a = peak(freq[lo:hi], amp[lo:hi])
    return f, a


def _band_bins(freq: np.ndarray, lo: float, hi: float, what: str) -> np.ndarray:
    """Indices of the bins with lo <= f <= hi; ValueError naming ``what`` when there is none."""
    idx = np.flatnonzero((freq >= lo) & (freq <= hi))
    if idx.size == 0:
        raise ValueError(f"no frequency bin in the {what} band [{lo:g}, {hi:g}] Hz")
    return idx


def first_peak(
    freq: np.ndarray, amp: np.ndarray, *, fraction: float = 0.5, fmin: float = -np.inf, fmax: float = np.inf
) -> tuple[float, float]:
    """The first peak of a spectrum: the lowest-frequency local maximum that reaches ``fraction`` of the largest
    amplitude in ``[fmin, fmax]``.

    From the first bin at or above ``fraction``·max the spectrum is followed uphill to its local maximum, which is
    Gaussian-interpolated as in ``spectra.peak``. In the saturated HF state the patch velocities fill a band
    (each patch near its own natural frequency, coupling spreading it upward) whose lower edge is a sharp peak
    followed by a plateau; the largest bin may lie anywhere in the plateau, the first peak does not.

    Args:
        freq: Uniformly spaced frequencies [Hz], shape (F,).
        amp: Amplitude spectrum, shape (F,), non-negative.
        fraction: Share of the band's maximum the first peak must reach, in (0, 1].
        fmin: Lower band edge [Hz].
        fmax: Upper band edge [Hz].

    Returns:
        ``(f_peak [Hz], a_peak)``.
    """
    freq, amp = np.asarray(freq, dtype=np.float64), np.asarray(amp, dtype=np.float64)
    if not 0.0 < fraction <= 1.0:
        raise ValueError(f"fraction must lie in (0, 1], got {fraction}")
    band = _band_bins(freq, fmin, fmax, "search")
    sub = amp[band]
    i = int(np.flatnonzero(sub >= fraction * sub.max())[0])
    while i + 1 < sub.size and sub[i + 1] > sub[i]:
        i += 1
    return _refine(freq[band], sub, i)


@dataclass(frozen=True)
class PeakContrast:
    """Height of a spectral peak over the typical level around it.

    Attributes:
        frequency: Frequency of the largest bin within the search band [Hz].
        height: Its amplitude (units of the spectrum).
        floor: Median amplitude over the floor band (units of the spectrum).
        ratio: height / floor (dimensionless; independent of how the spectrum is normalised).
        floor_band: (fmin, fmax) of the floor band [Hz].
    """

    frequency: float
    height: float
    floor: float
    ratio: float
    floor_band: tuple[float, float]


def peak_to_floor(
    freq: np.ndarray,
    amp: np.ndarray,
    f0: float,
    *,
    search: float | None = None,
    floor_band: tuple[float, float] = (0.5, 2.0),
) -> PeakContrast:
    """How pronounced the peak near ``f0`` is: its height over the median amplitude of the band around it.

    The height is the largest bin within ``f0 ± search`` (no interpolation, so that spectra of one grid are
    compared bin for bin); the floor is the median over ``[floor_band[0]·f0, floor_band[1]·f0]`` (an octave on
    either side by default), which a single peak hardly moves. The ratio does not depend on a spectrum's
    normalisation, so spectra of different quantities (μ, torque, Σu̇) can be compared.

    Args:
        freq: Uniformly spaced frequencies [Hz], shape (F,).
        amp: Amplitude spectrum, shape (F,), non-negative.
        f0: Peak frequency [Hz], e.g. the first velocity-spectrum peak.
        search: Half-width of the search band [Hz]; default 2 bins.
        floor_band: Floor band as multiples of f0.

    Returns:
        A :class:`PeakContrast`.
    """
    freq, amp = np.asarray(freq, dtype=np.float64), np.asarray(amp, dtype=np.float64)
    if freq.shape != amp.shape or freq.ndim != 1 or freq.size < 3:
        raise ValueError(f"freq and amp must be 1-D of equal length >= 3, got {freq.shape} and {amp.shape}")
    search = 2.0 * (freq[1] - freq[0]) if search is None else search
    near = _band_bins(freq, f0 - search, f0 + search, "search")
    i = int(near[np.argmax(amp[near])])
    band = (floor_band[0] * f0, floor_band[1] * f0)
    floor = float(np.median(amp[_band_bins(freq, *band, "floor")]))
    ratio = float(amp[i] / floor) if floor > 0 else float("inf")
    return PeakContrast(float(freq[i]), float(amp[i]), floor, ratio, band)


@dataclass(frozen=True)
class PlateauExcess:
    """Level of a spectrum just above a peak against its level further up (natural-log units).

    Attributes:
        excess: ln(near_level) − ln(far_level): 0 for a flat spectrum, ln 2 for a near band twice as high.
        near_level: Median amplitude over the near band.
        far_level: Median amplitude over the far band.
        near_band: (fmin, fmax) [Hz].
        far_band: (fmin, fmax) [Hz].
    """

    excess: float
    near_level: float
    far_level: float
    near_band: tuple[float, float]
    far_band: tuple[float, float]


def plateau_excess(
    freq: np.ndarray,
    amp: np.ndarray,
    f0: float,
    *,
    near: tuple[float, float] = (1.1, 2.0),
    far: tuple[float, float] = (2.5, 4.0),
) -> PlateauExcess:
    """How much a spectrum stays raised above a peak at ``f0``: a broad-band plateau after the peak (§3.1).

    excess = ln median(amp over near·f0) − ln median(amp over far·f0). A plateau that follows the peak (the
    near band, clear of the peak's own lobe) raises the excess above that of a spectrum that falls off evenly;
    a comparison between spectra of one record (velocity against μ, torque, friction radius) tells which of them
    carries the plateau. Medians make both levels insensitive to single peaks.

    Args:
        freq: Frequencies [Hz], shape (F,).
        amp: Amplitude spectrum, shape (F,), positive in both bands.
        f0: Peak frequency [Hz].
        near: Near band as multiples of f0.
        far: Far band as multiples of f0.

    Returns:
        A :class:`PlateauExcess`.
    """
    freq, amp = np.asarray(freq, dtype=np.float64), np.asarray(amp, dtype=np.float64)
    if freq.shape != amp.shape or freq.ndim != 1:
        raise ValueError(f"freq and amp must be 1-D of equal length, got {freq.shape} and {amp.shape}")
    nb, fb = (near[0] * f0, near[1] * f0), (far[0] * f0, far[1] * f0)
    a = float(np.median(amp[_band_bins(freq, *nb, "near")]))
    b = float(np.median(amp[_band_bins(freq, *fb, "far")]))
    if not (a > 0 and b > 0):
        raise ValueError("plateau_excess needs positive median amplitudes in both bands")
    return PlateauExcess(float(np.log(a) - np.log(b)), a, b, nb, fb)


@dataclass(frozen=True)
class Tonality:
    """How periodic (a few dominant lines) or stochastic (broad band) a spectrum is over a band.

    Attributes:
        peak_to_median: ln(largest amplitude / median amplitude) over the band: 0 for a flat spectrum, large for
            one dominant line above a low floor.
        flatness: Spectral flatness of the power a²: geometric mean over arithmetic mean, in (0, 1]; 1 for a flat
            (white) spectrum, near 0 for a few lines.
        peak_frequency: Frequency of the largest amplitude [Hz].
        band: (fmin, fmax) [Hz].
        bins: Bins in the band.
    """

    peak_to_median: float
    flatness: float
    peak_frequency: float
    band: tuple[float, float]
    bins: int


def tonality(freq: np.ndarray, amp: np.ndarray, *, band: tuple[float, float]) -> Tonality:
    """Peak-to-median ratio and spectral flatness of an amplitude spectrum over ``band`` (paper §3.2: "from
    stochastic (low-amplitude oscillations over a wide frequency range) to periodic (one or multiple dominant
    frequencies)").

    Both are independent of the spectrum's scale. Zero amplitudes are left out of the flatness (its logarithm).

    Args:
        freq: Frequencies [Hz], shape (F,).
        amp: Amplitude spectrum, shape (F,), non-negative.
        band: (fmin, fmax) [Hz].

    Returns:
        A :class:`Tonality`.
    """
    freq, amp = np.asarray(freq, dtype=np.float64), np.asarray(amp, dtype=np.float64)
    if freq.shape != amp.shape or freq.ndim != 1:
        raise ValueError(f"freq and amp must be 1-D of equal length, got {freq.shape} and {amp.shape}")
    idx = _band_bins(freq, band[0], band[1], "tonality")
    a = amp[idx]
    med = float(np.median(a))
    if not (med > 0 and np.all(a >= 0)):
        raise ValueError("tonality needs a non-negative spectrum with a positive median over the band")
    p = a[a > 0] ** 2
    flat = float(np.exp(np.mean(np.log(p))) / np.mean(p))
    i = int(np.argmax(a))
    return Tonality(float(np.log(a[i] / med)), flat, float(freq[idx[i]]), (float(band[0]), float(band[1])), idx.size)


def averaged_spectrum(x: np.ndarray, dt: float, *, segments: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Welch-averaged one-sided amplitude spectrum of a real signal: Hann segments of N // ``segments`` samples
    overlapping by half, each scaled as ``spectra.amplitude_spectrum`` (a sinusoid a·sin on a bin shows a), the
    amplitudes averaged in power (√ of the mean |X|²). The average trades resolution (``segments`` times coarser)
    for a spectrum whose peaks stand out of the bin-to-bin scatter of a single periodogram of a chaotic signal.

    Args:
        x: Signal, shape (N,), N ≥ 2 ``segments``.
        dt: Sampling interval [s].
        segments: Segment length as a fraction of the record (N // segments samples; 2·segments − 1 segments).

    Returns:
        ``(freq [Hz], amplitude)`` of the segment length's grid.
    """
    from ..spectra import amplitude_spectrum

    x = np.asarray(x, dtype=np.float64)
    n = x.size // segments
    if n < 2:
        raise ValueError(f"averaged_spectrum: {x.size} samples give no segment of {segments}")
    starts = range(0, x.size - n + 1, max(1, n // 2))
    power = None
    for s in starts:
        freq, a = amplitude_spectrum(x[s : s + n] - x[s : s + n].mean(), dt, normalise=None)
        power = a**2 if power is None else power + a**2
    return freq, np.sqrt(power / len(starts))
