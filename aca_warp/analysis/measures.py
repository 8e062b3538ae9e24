"""Scalar measures for the paper's statements about the saturated HF state (paper §3; docs/analysis.md).

Each function is pure (NumPy arrays in, a frozen dataclass out, SI units) so that a validation table can be
filled from any record:

* :func:`peak_width` — full width at a fraction of a spectral peak's height and its prominence ("the peaks of
  HF₂ and HF₄ ... are narrower", §3.1);
* :func:`spectral_overlap` — mean |ln a − ln b| of two spectra over a band ("μ and torque ... nearly
  completely overlapping", Fig. 8);
* :func:`shared_peaks` — peaks common to several spectra ("similar characteristic peaks of the global friction
  coefficient, friction torque, and effective friction radius", §3.1);
* :func:`phase_correlation_length` — spatial decay of ⟨cos(φ_i − φ_j)⟩ with patch distance (synchronised
  "islands", Figs. 4/6, §4);
* :func:`stft_peak` — largest mean-normalised STFT amplitude and its frequency (Fig. 10: "about 0.004 ...
  around 69.1 kHz"); :func:`peak_track` — the frequency of the largest STFT bin per window;
* :func:`line_trend` — slope of a spectral line over time with a confidence interval ("decreasing
  frequencies of the characteristic peaks", §3.2);
* :func:`ensemble_interval` — mean and 95 % intervals over seeds, for every validation row;
* :func:`first_peak` — the lowest-frequency peak that reaches a fraction of a spectrum's maximum ("the first peak
  of each velocity spectrum", §3.1);
* :func:`peak_to_floor` — a peak's height over the median of its neighbourhood ("significantly more pronounced
  than the other output quantities", §3.1);
* :func:`plateau_excess` — how far a spectrum stays raised just above a peak ("broad-band plateaus", §3.1);
* :func:`shared_peak_fraction` — the share of one spectrum's peaks that every other spectrum has, beside the
  share expected by chance;
* :func:`sync_by_prevalence` and :func:`equal_prevalence_difference` — S(f) compared at equal Φ (S depends on
  Φ: a few random phases already give a high S);
* :func:`spectral_agreement` — rank correlation of S(f)·Φ(f) with a friction spectrum ("agreement between the
  Synchronization Index results and the friction frequency spectrum", §3.1);
* :func:`tonality` — peak-to-median ratio and spectral flatness of a spectrum ("from stochastic ... to periodic",
  §3.2);
* :func:`neighbour_coherence` — phase coherence of neighbouring patches per frequency bin ("local clustering",
  §3.3).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.optimize
import scipy.signal
import scipy.stats
from scipy.spatial import cKDTree

from .spectra import DEFAULT_FLOOR_HZ, peak
from .timefreq import stft

# ------------------------------------------------------------------------------------------------- spectra


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


# ---------------------------------------------------------------------------------------- spatial patterns


@dataclass(frozen=True)
class CorrelationLength:
    """Spatial phase correlation C(d) = ⟨cos(φ_i − φ_j)⟩ over patch pairs binned by distance.

    Attributes:
        length: ℓ of the least-squares fit C(d) = exp(−d/ℓ) over the bins (pair-count weights) [m]; 0 for
            uncorrelated phases, inf for phases correlated over the whole range.
        length_e: Distance where the binned C first falls below 1/e (linear interpolation) [m]; 0 if the
            first bin is already below, inf if no bin is.
        distance: Mean pair distance per bin [m], shape (B,).
        correlation: C per bin, shape (B,) (NaN for an empty bin).
        pairs: Pairs per bin, shape (B,).
        fit_rms: RMS residual of the fit over the non-empty bins.
    """

    length: float
    length_e: float
    distance: np.ndarray
    correlation: np.ndarray
    pairs: np.ndarray
    fit_rms: float


def _fit_exponential(d: np.ndarray, c: np.ndarray, w: np.ndarray, d_max: float) -> tuple[float, float]:
    """ℓ of the weighted least-squares fit of exp(−d/ℓ) to c, with ℓ in [d_max/1e4, 1e4·d_max] (0/inf at the ends)."""

    def cost(log_l: float) -> float:
        return float(np.sum(w * (c - np.exp(-d / np.exp(log_l))) ** 2))

    lo, hi = np.log(d_max * 1e-4), np.log(d_max * 1e4)
    grid = np.linspace(lo, hi, 161)
    best = int(np.argmin([cost(g) for g in grid]))
    a, b = grid[max(best - 1, 0)], grid[min(best + 1, grid.size - 1)]
    res = scipy.optimize.minimize_scalar(cost, bounds=(a, b), method="bounded", options={"xatol": 1e-6})
    ell = float(np.exp(res.x))
    rms = float(np.sqrt(cost(res.x) / w.sum()))
    if res.x <= lo + 1e-3:
        ell = 0.0
    elif res.x >= hi - 1e-3:
        ell = float("inf")
    return ell, rms


def phase_correlation_length(
    x: np.ndarray,
    y: np.ndarray,
    phase: np.ndarray,
    amplitude: np.ndarray | None = None,
    *,
    max_distance: float | None = None,
    bins: int = 20,
) -> CorrelationLength:
    """Correlation length of the phase pattern of the patches (synchronised islands, paper Figs. 4/6).

    For every pair of patches i < j closer than ``max_distance``, cos(φ_i − φ_j) (1: in phase, −1: in
    antiphase) is averaged within equal-width distance bins, over all snapshots, with weights a_i·a_j when
    amplitudes are given (so that patches barely moving count little). C(d) = exp(−d/ℓ) is then fitted with
    C(0) = 1 fixed (neighbours at zero distance move together), weighted by the pairs per bin. For a 1-D
    phase random walk C(d) is exactly exp(−d/ℓ); for other patterns ℓ is the best exponential scale and
    ``length_e``, the 1/e distance of the binned curve, is model-free.

    Args:
        x: Patch centres x [m], shape (n,).
        y: Patch centres y [m], shape (n,).
        phase: Phases [rad], shape (n,) or (m, n) for m snapshots (e.g. arg X_i(f) at a frequency bin, or
            instantaneous phases at several times).
        amplitude: Weights per patch (e.g. |X_i(f)|), shape of ``phase`` or (n,); None: equal weights.
        max_distance: Largest pair distance [m]; default half the diagonal of the patches' bounding box.
        bins: Number of distance bins on (0, max_distance].

    Returns:
        A :class:`CorrelationLength`.
    """
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    phase = np.atleast_2d(np.asarray(phase, dtype=np.float64))
    if x.shape != y.shape or x.ndim != 1 or phase.shape[1] != x.size:
        raise ValueError(f"x, y must be (n,) and phase (n,) or (m, n); got {x.shape}, {y.shape}, {phase.shape}")
    if amplitude is None:
        amp = np.ones_like(phase)
    else:
        amp = np.broadcast_to(np.asarray(amplitude, dtype=np.float64), phase.shape)
    if not (np.all(np.isfinite(phase)) and np.all(np.isfinite(amp))):
        raise ValueError("phase and amplitude must be finite")
    if max_distance is None:
        max_distance = 0.5 * float(np.hypot(np.ptp(x), np.ptp(y)))
    pairs = cKDTree(np.column_stack([x, y])).query_pairs(max_distance, output_type="ndarray")
    if len(pairs) == 0:
        raise ValueError(f"no pair of patches closer than {max_distance:g} m")
    i, j = pairs[:, 0], pairs[:, 1]
    d = np.hypot(x[i] - x[j], y[i] - y[j])
    b = np.minimum((d / max_distance * bins).astype(np.intp), bins - 1)
    w = amp[:, i] * amp[:, j]
    wc = np.sum(w * np.cos(phase[:, i] - phase[:, j]), axis=0)
    num = np.bincount(b, wc, minlength=bins)
    den = np.bincount(b, w.sum(axis=0), minlength=bins)
    count = np.bincount(b, minlength=bins)
    dist = np.bincount(b, d, minlength=bins) / np.maximum(count, 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = np.where(den > 0, num / den, np.nan)
    ok = np.isfinite(corr) & (count > 0)
    ell, rms = _fit_exponential(dist[ok], corr[ok], count[ok].astype(np.float64), max_distance)
    below = np.flatnonzero(corr[ok] < np.exp(-1.0))
    if below.size == 0:
        ell_e = float("inf")
    elif below[0] == 0:
        ell_e = 0.0
    else:
        d_ok, c_ok, k = dist[ok], corr[ok], below[0]
        ell_e = float(d_ok[k - 1] + (c_ok[k - 1] - np.exp(-1.0)) / (c_ok[k - 1] - c_ok[k]) * (d_ok[k] - d_ok[k - 1]))
    return CorrelationLength(ell, ell_e, np.where(count > 0, dist, np.nan), corr, count, rms)


# ------------------------------------------------------------------------------------------- time-frequency


@dataclass(frozen=True)
class StftPeak:
    """Largest amplitude of a mean-normalised STFT (paper Fig. 10).

    Attributes:
        amplitude: Largest |S|/mean(μ) over the map (dimensionless; a sinusoid a·sin on a bin shows a/mean).
        frequency: Its frequency, Gaussian-interpolated within the window's spectrum [Hz].
        time: Centre of the window that holds it [s].
        window: Name of the window, e.g. "periodic Hann window of 4096 samples (0.4096 ms), hop 1024 samples".
        window_samples: Window length [samples].
        hop_samples: Hop between windows [samples].
        resolution: Bin spacing 1/(window·Δt) [Hz].
        mean: The mean of μ used for the normalisation.
        normalise: "record" (mean over the record) or "window" (each window's own mean).
    """

    amplitude: float
    frequency: float
    time: float
    window: str
    window_samples: int
    hop_samples: int
    resolution: float
    mean: float
    normalise: str


STFT_WINDOWS = tuple(2**k for k in range(12, 18))
"""Window lengths [samples] scanned by :func:`stft_peaks`: 2^12 … 2^17 (the paper does not give its own)."""


def stft_peak(
    time: np.ndarray,
    mu: np.ndarray,
    window_samples: int,
    *,
    hop_samples: int | None = None,
    band: tuple[float, float] | None = None,
    normalise: Literal["record", "window"] = "record",
    detrend: Literal["constant", "linear"] | None = "linear",
) -> StftPeak:
    """Largest STFT amplitude of μ(t), divided by the mean of μ, and its frequency and time.

    The map is ``timefreq.stft``: periodic Hann window, one-sided amplitude-true scaling (a sinusoid a·sin on
    a bin shows a), only windows entirely inside the record, each window's linear trend removed (μ's mean and
    slow drift would otherwise leak into the lowest bins), f below 10 Hz dropped as in the paper. The
    amplitude is then divided by the mean of μ over the record (``normalise="record"``, the normalisation of
    the paper's spectra) or over each window (``"window"``, for a record whose mean drifts).

    Args:
        time: Sample times [s], shape (N,), uniform.
        mu: Friction coefficient μ(t), shape (N,).
        window_samples: Window length [samples] (≤ N).
        hop_samples: Hop [samples]; default a quarter window.
        band: (fmin, fmax) [Hz] searched; default (10 Hz, Nyquist).
        normalise: "record" or "window" (see above).
        detrend: Per-window trend removal passed to ``timefreq.stft``.

    Returns:
        A :class:`StftPeak`.
    """
    time, mu = np.asarray(time, dtype=np.float64), np.asarray(mu, dtype=np.float64)
    if time.shape != mu.shape or mu.ndim != 1:
        raise ValueError(f"time and mu must be 1-D of equal length, got {time.shape} and {mu.shape}")
    if not np.all(np.isfinite(mu)):
        raise ValueError("mu has non-finite values")
    dt = (time[-1] - time[0]) / (time.size - 1)
    hop = hop_samples or max(1, window_samples // 4)
    fmin = DEFAULT_FLOOR_HZ if band is None else band[0]
    fmax = np.inf if band is None else band[1]
    times, freqs, amp, info = stft(mu, dt, window_s=window_samples * dt, hop_s=hop * dt, fmin=fmin, detrend=detrend)
    keep = freqs <= fmax
    if not keep.any():
        raise ValueError(f"no STFT bin in the band {band} Hz")
    if normalise == "record":
        mean = np.full(times.size, np.mean(mu))
    elif normalise == "window":
        starts = np.rint((times - time[0]) / dt).astype(np.int64) - window_samples // 2
        c = np.concatenate([[0.0], np.cumsum(mu)])
        mean = (c[starts + window_samples] - c[starts]) / window_samples
    else:
        raise ValueError(f"normalise must be 'record' or 'window', got {normalise!r}")
    if np.any(mean == 0):
        raise ValueError("cannot normalise the STFT: the mean of mu is zero")
    norm = amp[keep] / np.abs(mean)[None, :]
    fi, ti = np.unravel_index(int(np.argmax(norm)), norm.shape)
    f_peak, a_peak = _refine(freqs[keep], norm[:, ti], fi)
    return StftPeak(
        amplitude=a_peak,
        frequency=f_peak,
        time=float(time[0] + times[ti]),
        window=info["window"],
        window_samples=int(window_samples),
        hop_samples=int(hop),
        resolution=1.0 / (window_samples * dt),
        mean=float(mean[ti]),
        normalise=normalise,
    )


def _refine(freq: np.ndarray, amp: np.ndarray, i: int) -> tuple[float, float]:
    """Gaussian interpolation of the peak at bin i (``spectra.peak`` restricted to bins i-1..i+1)."""
    lo, hi = max(i - 1, 0), min(i + 2, freq.size)
    f, a = peak(freq[lo:hi], amp[lo:hi])
    return f, a


def stft_peaks(time: np.ndarray, mu: np.ndarray, windows: tuple[int, ...] = STFT_WINDOWS, **options) -> list[StftPeak]:
    """:func:`stft_peak` for every window length in ``windows`` that fits the record (others are skipped)."""
    n = np.size(mu)
    return [stft_peak(time, mu, w, **options) for w in windows if w <= n]


def peak_track(
    times: np.ndarray, freqs: np.ndarray, amp: np.ndarray, *, band: tuple[float, float] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Frequency and amplitude of the largest bin of each column of a time-frequency map (a spectral line).

    Args:
        times: Window centres [s], shape (T,).
        freqs: Frequencies [Hz], shape (F,).
        amp: Map |S|, shape (F, T) (as from ``timefreq.stft``).
        band: (fmin, fmax) [Hz] searched; default all frequencies.

    Returns:
        ``(freq_of_peak, amp_of_peak)``, each of shape (T,), Gaussian-interpolated per column.
    """
    freqs, amp = np.asarray(freqs, dtype=np.float64), np.asarray(amp, dtype=np.float64)
    if amp.shape != (freqs.size, np.size(times)):
        raise ValueError(f"amp must have shape (freqs, times) = {(freqs.size, np.size(times))}, got {amp.shape}")
    keep = np.ones(freqs.size, bool) if band is None else (freqs >= band[0]) & (freqs <= band[1])
    f_sub, a_sub = freqs[keep], amp[keep]
    out = np.array([_refine(f_sub, a_sub[:, k], int(np.argmax(a_sub[:, k]))) for k in range(a_sub.shape[1])])
    return out[:, 0], out[:, 1]


# ------------------------------------------------------------------------------------------------ statistics


@dataclass(frozen=True)
class LineTrend:
    """Least-squares line f(t) = intercept + slope·t with a confidence interval of the slope.

    Attributes:
        slope: Slope [Hz/s] (units of y per unit of t).
        intercept: Value at t = 0 [Hz].
        slope_low: Lower end of the ``level`` confidence interval of the slope (Student t, n − 2 dof).
        slope_high: Upper end.
        stderr: Standard error of the slope.
        r2: Coefficient of determination.
        n: Points used (finite ones).
        level: Confidence level.
    """

    slope: float
    intercept: float
    slope_low: float
    slope_high: float
    stderr: float
    r2: float
    n: int
    level: float

    @property
    def falling(self) -> bool:
        """True when the whole confidence interval lies below zero."""
        return self.slope_high < 0.0


def line_trend(time: np.ndarray, freq_of_peak: np.ndarray, *, level: float = 0.95) -> LineTrend:
    """Slope of a spectral line over time (paper §3.2: "decreasing frequencies of the characteristic peaks").

    Ordinary least squares; the interval is slope ± t_{(1+level)/2, n−2}·stderr. It assumes independent
    residuals: points from overlapping STFT windows (hop < window) are correlated and make the interval too
    narrow — use every (window/hop)-th point or non-overlapping windows. Non-finite points are dropped.

    Args:
        time: Times [s], shape (n,).
        freq_of_peak: Line frequency at those times [Hz], shape (n,) (e.g. from :func:`peak_track`).
        level: Confidence level of the interval.

    Returns:
        A :class:`LineTrend`.
    """
    t, f = np.asarray(time, dtype=np.float64), np.asarray(freq_of_peak, dtype=np.float64)
    if t.shape != f.shape or t.ndim != 1:
        raise ValueError(f"time and freq_of_peak must be 1-D of equal length, got {t.shape} and {f.shape}")
    ok = np.isfinite(t) & np.isfinite(f)
    t, f = t[ok], f[ok]
    if t.size < 3 or np.ptp(t) == 0:
        raise ValueError(f"line_trend needs at least 3 finite points at distinct times, got {t.size}")
    fit = scipy.stats.linregress(t, f)
    q = scipy.stats.t.ppf(0.5 + level / 2.0, t.size - 2)
    half = q * fit.stderr
    return LineTrend(
        slope=float(fit.slope),
        intercept=float(fit.intercept),
        slope_low=float(fit.slope - half),
        slope_high=float(fit.slope + half),
        stderr=float(fit.stderr),
        r2=float(fit.rvalue**2),
        n=int(t.size),
        level=level,
    )


@dataclass(frozen=True)
class EnsembleInterval:
    """Mean and intervals of a quantity over an ensemble (seeds); arrays of shape ``values.shape[1:]``.

    Attributes:
        mean: Sample mean.
        std: Sample standard deviation (ddof = 1; NaN for n = 1).
        n: Ensemble size.
        mean_low: Lower end of the Student-t interval of the mean, mean − t_{(1+level)/2, n−1}·std/√n.
        mean_high: Upper end (both NaN for n = 1).
        low: Lower percentile (1 − level)/2 of the values (where a single run falls; linear interpolation).
        high: Upper percentile (1 + level)/2.
        median: Median of the values.
        level: Level of both intervals.
    """

    mean: np.ndarray | float
    std: np.ndarray | float
    n: int
    mean_low: np.ndarray | float
    mean_high: np.ndarray | float
    low: np.ndarray | float
    high: np.ndarray | float
    median: np.ndarray | float
    level: float


def ensemble_interval(values: np.ndarray, level: float = 0.95) -> EnsembleInterval:
    """Mean with a t-interval and the central percentile interval over an ensemble of runs (seeds).

    Two intervals answer two questions: [mean_low, mean_high] is where the ensemble mean lies (Student t,
    exact for normally distributed values, shrinking as 1/√n); [low, high] is where one run's value falls
    (empirical percentiles, needs many seeds to mean much). A validation row quotes the mean with its
    t-interval; the percentile range shows the spread between seeds.

    Args:
        values: Shape (n,) or (n, ...): one value per seed along axis 0; finite.
        level: Level of both intervals, in (0, 1).

    Returns:
        An :class:`EnsembleInterval` (floats for 1-D input).
    """
    v = np.asarray(values, dtype=np.float64)
    if v.ndim == 0 or v.shape[0] == 0:
        raise ValueError("ensemble_interval needs at least one value along axis 0")
    if not np.all(np.isfinite(v)):
        raise ValueError("ensemble values must be finite (drop failed runs first)")
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must lie in (0, 1), got {level}")
    n = v.shape[0]
    mean = v.mean(axis=0)
    if n > 1:
        std = v.std(axis=0, ddof=1)
        half = scipy.stats.t.ppf(0.5 + level / 2.0, n - 1) * std / np.sqrt(n)
    else:
        std = half = np.full(v.shape[1:], np.nan)
    low, high = np.percentile(v, [50.0 * (1.0 - level), 50.0 * (1.0 + level)], axis=0)

    def out(a: np.ndarray) -> np.ndarray | float:
        return float(a) if np.ndim(a) == 0 else a

    return EnsembleInterval(
        mean=out(mean),
        std=out(std),
        n=n,
        mean_low=out(mean - half),
        mean_high=out(mean + half),
        low=out(low),
        high=out(high),
        median=out(np.median(v, axis=0)),
        level=level,
    )


# ------------------------------------------------------------------------------------------ spectral shape


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


# ---------------------------------------------------------------------------------- synchronisation at equal Φ


@dataclass(frozen=True)
class PrevalenceTable:
    """S(f) averaged within classes of Φ (equal-prevalence comparison); every array has shape (C,).

    Attributes:
        lower: Smallest Φ of each class (inclusive).
        upper: Largest Φ of each class (exclusive).
        bins: Frequency bins in each class.
        mean_S: Mean S over the class's bins (NaN if empty).
        mean_S_null: Mean null level S_null (NaN if empty).
        mean_excess: Mean of S − S_null (NaN if empty).
    """

    lower: np.ndarray
    upper: np.ndarray
    bins: np.ndarray
    mean_S: np.ndarray
    mean_S_null: np.ndarray
    mean_excess: np.ndarray

    def value(self, name: str) -> np.ndarray:
        """``"S"``, ``"S_null"`` or ``"excess"`` per class."""
        return {"S": self.mean_S, "S_null": self.mean_S_null, "excess": self.mean_excess}[name]


def prevalence_classes(phi_max: int) -> np.ndarray:
    """Octave class edges 2, 4, 8, …, the first power of two above ``phi_max`` (Φ < 2 leaves S undefined)."""
    top = max(2, int(np.ceil(np.log2(max(phi_max, 2) + 1))))
    return 2 ** np.arange(1, top + 1)


def sync_by_prevalence(
    S: np.ndarray, S_null: np.ndarray, Phi: np.ndarray, *, edges: np.ndarray | None = None
) -> PrevalenceTable:
    """Mean S, S_null and S − S_null over the frequency bins of each class of Φ.

    S of a few patches is high by chance (its null level falls as Φ grows), so S of two records is comparable
    only at equal Φ. Bins with Φ < 2 or a non-finite S or S_null are left out.

    Args:
        S: Synchronization Index per bin, shape (F,).
        S_null: Its random-phase null level per bin, shape (F,).
        Phi: Oscillating patches per bin, shape (F,).
        edges: Increasing class edges (class k: edges[k] <= Φ < edges[k+1]); default
            :func:`prevalence_classes` of the largest Φ.

    Returns:
        A :class:`PrevalenceTable` with len(edges) − 1 classes.
    """
    S, null = np.asarray(S, dtype=np.float64), np.asarray(S_null, dtype=np.float64)
    phi = np.asarray(Phi, dtype=np.int64)
    if not S.shape == null.shape == phi.shape or S.ndim != 1:
        raise ValueError(f"S, S_null and Phi must be 1-D of equal length, got {S.shape}, {null.shape}, {phi.shape}")
    edges = prevalence_classes(int(phi.max()) if phi.size else 2) if edges is None else np.asarray(edges)
    ok = (phi >= 2) & np.isfinite(S) & np.isfinite(null)
    cls = np.searchsorted(edges, phi[ok], side="right") - 1
    inside = (cls >= 0) & (cls < edges.size - 1)
    cls, s, sn = cls[inside], S[ok][inside], null[ok][inside]
    c = edges.size - 1
    count = np.bincount(cls, minlength=c)

    def mean(v: np.ndarray) -> np.ndarray:
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(count > 0, np.bincount(cls, v, minlength=c) / count, np.nan)

    return PrevalenceTable(edges[:-1].copy(), edges[1:].copy(), count, mean(s), mean(sn), mean(s - sn))


@dataclass(frozen=True)
class EqualPrevalence:
    """Differences of S between paired records at equal Φ.

    Attributes:
        difference: Per pair, the mean over the common classes of (value of a − value of b), shape (n,); NaN
            when no class is common.
        classes: Boolean mask of the classes used (populated by ``min_bins`` bins in every record), shape (C,).
        lower: Smallest Φ of each class, shape (C,).
        upper: Largest Φ (exclusive), shape (C,).
        value: Which per-class value was compared ("S", "S_null" or "excess").
    """

    difference: np.ndarray
    classes: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    value: str


def equal_prevalence_difference(
    a: list[PrevalenceTable], b: list[PrevalenceTable], *, value: str = "excess", min_bins: int = 10
) -> EqualPrevalence:
    """Paired differences a_k − b_k of S at equal Φ, over the Φ classes every record populates.

    A class counts when each of the records a_1…a_n, b_1…b_n has at least ``min_bins`` bins in it, so every
    pair is compared over the same classes; each class weighs the same (an average over Φ, not over bins).

    Args:
        a: Tables of the first ensemble (one per seed), all with the same class edges.
        b: Tables of the second ensemble, paired with ``a`` by position.
        value: "excess" (S − S_null, default), "S" or "S_null".
        min_bins: Fewest bins a class needs in every record.

    Returns:
        An :class:`EqualPrevalence`.
    """
    if len(a) != len(b) or not a:
        raise ValueError(f"need two non-empty ensembles of equal size, got {len(a)} and {len(b)}")
    edges = a[0].lower
    if any(t.lower.shape != edges.shape or np.any(t.lower != edges) for t in (*a, *b)):
        raise ValueError("every table must have the same class edges")
    mask = np.logical_and.reduce([t.bins >= min_bins for t in (*a, *b)])
    pairs = zip(a, b, strict=True)
    diff = np.array([np.mean(x.value(value)[mask] - y.value(value)[mask]) if mask.any() else np.nan for x, y in pairs])
    return EqualPrevalence(diff, mask, edges.copy(), a[0].upper.copy(), value)


def spectral_agreement(
    freq: np.ndarray, S: np.ndarray, Phi: np.ndarray, amp: np.ndarray, *, band: tuple[float, float] = (20e3, 80e3)
) -> float:
    """Spearman rank correlation of S(f)·Φ(f) with an amplitude spectrum over ``band`` (paper §3.1, §4).

    High where the bins with synchronised, prevalent patch motion are the bins where the friction spectrum is
    high. Bins where S is undefined count as S·Φ = 0 (no synchronised patches). The paper's 20–80 kHz is
    where it finds its friction and synchronisation behaviour to agree with measurements (§4).

    Args:
        freq: Frequencies [Hz], shape (F,).
        S: Synchronization Index, shape (F,) (NaN where undefined).
        Phi: Oscillating patches per bin, shape (F,).
        amp: Amplitude spectrum on the same bins (e.g. |μ(f)|/μ̄), shape (F,).
        band: (fmin, fmax) [Hz].

    Returns:
        ρ in [−1, 1] (NaN when either series is constant over the band).
    """
    freq = np.asarray(freq, dtype=np.float64)
    S, phi, amp = (np.asarray(v, dtype=np.float64) for v in (S, Phi, amp))
    if not freq.shape == S.shape == phi.shape == amp.shape or freq.ndim != 1:
        raise ValueError("freq, S, Phi and amp must be 1-D of equal length")
    idx = _band_bins(freq, band[0], band[1], "agreement")
    weight = np.where(np.isfinite(S[idx]), S[idx], 0.0) * phi[idx]
    if np.ptp(weight) == 0 or np.ptp(amp[idx]) == 0:
        return float("nan")
    return float(scipy.stats.spearmanr(weight, amp[idx]).statistic)


# ---------------------------------------------------------------------------------- tonality and local clustering


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


def neighbour_coherence(x: np.ndarray, y: np.ndarray, spectra: np.ndarray, radius: float) -> np.ndarray:
    """Phase coherence of neighbouring patches per frequency bin (local clustering of synchronised motion).

    C(f) = Σ_pairs Re(X_i X_j*) / Σ_pairs |X_i||X_j| over the pairs of patches closer than ``radius``: the
    amplitude-weighted mean cos(φ_i − φ_j) of neighbours at f, as :func:`phase_correlation_length` over the
    first distance bin but for every bin at once. 1: neighbours oscillate in phase at f (a synchronised island),
    0: unrelated phases, negative: neighbours in antiphase.

    Args:
        x: Patch centres x [m], shape (n,).
        y: Patch centres y [m], shape (n,).
        spectra: Complex per-patch spectra X_i(f), shape (F, n).
        radius: Largest pair distance [m] (e.g. the coupling radius).

    Returns:
        C per bin, shape (F,); NaN where no pair has amplitude.
    """
    import scipy.sparse as sp

    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    X = np.asarray(spectra)
    if x.shape != y.shape or x.ndim != 1 or X.ndim != 2 or X.shape[1] != x.size:
        raise ValueError(f"x, y must be (n,) and spectra (F, n); got {x.shape}, {y.shape}, {X.shape}")
    pairs = cKDTree(np.column_stack([x, y])).query_pairs(radius, output_type="ndarray")
    if len(pairs) == 0:
        raise ValueError(f"no pair of patches closer than {radius:g} m")
    n = x.size
    adj = sp.csr_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    num = np.real(np.sum(np.conj(X) * (adj @ X.T).T, axis=1))
    a = np.abs(X)
    den = np.sum(a * (adj @ a.T).T, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / den, np.nan)
