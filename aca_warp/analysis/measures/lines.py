"""Spectral lines over time (paper §3.2, Figs. 10/11): the largest mean-normalised STFT amplitude, the frequency of
the largest bin per window, and the trend of a line with its confidence interval.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.stats

from ..spectra import DEFAULT_FLOOR_HZ
from ..timefreq import stft
from .ensemble import t_quantile
from .peaks import _refine


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
    q = t_quantile(0.5 + level / 2.0, t.size - 2)
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
