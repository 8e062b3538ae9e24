"""Hann-windowed one-sided spectra of recorded signals (paper §3.1, Fig. 8).

Scaling convention (shared by every function here): the signal is multiplied by a periodic Hann
window w of its own length N and transformed with a real FFT; the result is divided by the
window sum Σw = N/2 (coherent-gain correction) and the bins 0 < f < f_Nyquist are doubled. A sinusoid
a·sin(2πft) whose frequency falls on a bin then shows |X(f)| = a, and a constant c shows
X(0) = c. Phases are referenced to the first sample of the record.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import scipy.fft
from scipy.signal.windows import hann

DEFAULT_FLOOR_HZ = 10.0
"""Frequencies below this are dropped from plots (paper Fig. 10: "truncated below 10 Hz")."""


def _windowed_rfft(x: np.ndarray, axis: int, workers: int | None, bins: slice = slice(None)) -> np.ndarray:
    """Coherent-gain-corrected one-sided FFT of ``x`` along ``axis`` (see module docstring).

    Only the rfft bins ``bins`` are scaled and returned (a view into the full transform).
    """
    n = x.shape[axis]
    if n < 2:
        raise ValueError(f"need at least 2 samples along axis {axis}, got {n}")
    real = np.float32 if x.dtype == np.float32 else np.float64
    w = hann(n, sym=False).astype(real)
    shape = [1] * x.ndim
    shape[axis] = n
    spec = scipy.fft.rfft(x * w.reshape(shape), axis=axis, workers=workers)
    index = np.arange(n // 2 + 1)[bins]
    gain = np.where((index == 0) | (2 * index == n), 1.0, 2.0) / w.sum(dtype=np.float64)
    shape[axis] = index.size
    sel = [slice(None)] * x.ndim
    sel[axis] = bins
    spec = spec[tuple(sel)]
    spec *= gain.astype(real).reshape(shape)
    return spec


def amplitude_spectrum(
    x: np.ndarray,
    dt: float,
    *,
    normalise: Literal["mean"] | None = "mean",
    axis: int = -1,
) -> tuple[np.ndarray, np.ndarray]:
    """One-sided Hann-windowed amplitude spectrum.

    Args:
        x: Real signal(s); 1-D of shape (N,) or N-D with the N samples along ``axis``
            (e.g. (N, n_patches) with ``axis=0``).
        dt: Sampling interval [s].
        normalise: ``"mean"`` divides every spectrum by the absolute mean of its raw signal
            (paper Fig. 8, "normalized to the mean value of the raw data"; dimensionless);
            ``None`` keeps the physical amplitude (units of ``x``).
        axis: Sample axis of ``x``.

    Returns:
        ``(freq, amp)``: ``freq`` of shape (N//2 + 1,) [Hz]; ``amp`` of the shape of ``x`` with
        ``axis`` replaced by the frequency axis. A sinusoid a·sin(2πft) on a bin gives a peak
        of a (a/|mean| when normalised); bin 0 holds the mean.

    Raises:
        ValueError: If ``normalise="mean"`` and a signal has zero mean, or ``normalise`` is
            not one of the accepted values.
    """
    if normalise not in ("mean", None):
        raise ValueError(f"normalise must be 'mean' or None, got {normalise!r}")
    x = np.asarray(x)
    axis = axis % x.ndim
    amp = np.abs(_windowed_rfft(x, axis, workers=None))
    if normalise == "mean":
        mean = np.abs(np.mean(x, axis=axis, keepdims=True, dtype=np.float64))
        if np.any(mean == 0.0):
            raise ValueError("cannot normalise to the mean: a signal has zero mean (use normalise=None)")
        amp = amp / mean.astype(amp.dtype)
    return scipy.fft.rfftfreq(x.shape[axis], dt), amp


def complex_spectrum(
    x: np.ndarray,
    dt: float,
    axis: int = 0,
    *,
    freq_range: tuple[float, float] | None = None,
    workers: int | None = -1,
) -> tuple[np.ndarray, np.ndarray]:
    """One-sided Hann-windowed complex spectra, e.g. of per-patch velocities.

    Each column is transformed independently, so a (N, n_patches) record can be processed in
    column chunks with identical results.

    Args:
        x: Real signal(s), N samples along ``axis``; typically (N, n_patches) with ``axis=0``.
            float32 input gives complex64 output, anything else complex128.
        dt: Sampling interval [s].
        axis: Sample axis of ``x``.
        freq_range: Optional inclusive band ``(fmin, fmax)`` [Hz]; only bins inside it are
            returned (a contiguous copy, so the full-length FFT is freed).
        workers: Threads for ``scipy.fft`` (-1: all CPUs).

    Returns:
        ``(freq, X)``: ``freq`` of shape (F,) [Hz] and ``X`` of the shape of ``x`` with
        ``axis`` replaced by the F frequencies, scaled so that |X| is the amplitude of a
        sinusoid on a bin (units of ``x``) and arg X its phase (cosine phase at t = 0).
    """
    x = np.asarray(x)
    if x.dtype != np.float32:
        x = x.astype(np.float64, copy=False)
    axis = axis % x.ndim
    freq = scipy.fft.rfftfreq(x.shape[axis], dt)
    if freq_range is None:
        return freq, _windowed_rfft(x, axis, workers)
    keep = np.flatnonzero((freq >= freq_range[0]) & (freq <= freq_range[1]))
    if keep.size == 0:
        raise ValueError(f"no frequency bin inside freq_range={freq_range} Hz")
    bins = slice(keep[0], keep[-1] + 1)
    return freq[bins], _windowed_rfft(x, axis, workers, bins).copy()


def drop_low_frequencies(
    freq: np.ndarray, values: np.ndarray, *, fmin: float = DEFAULT_FLOOR_HZ, axis: int = -1
) -> tuple[np.ndarray, np.ndarray]:
    """Remove the bins below ``fmin`` (for plotting; the paper omits f < 10 Hz).

    Args:
        freq: Frequencies of shape (F,) [Hz].
        values: Array with F entries along ``axis``.
        fmin: Lowest frequency kept [Hz].
        axis: Frequency axis of ``values``.

    Returns:
        ``(freq[keep], values[..., keep, ...])`` with keep = ``freq >= fmin``.
    """
    keep = np.asarray(freq) >= fmin
    return np.asarray(freq)[keep], np.compress(keep, values, axis=axis)


def peak(freq: np.ndarray, amp: np.ndarray, *, fmin: float = -np.inf, fmax: float = np.inf) -> tuple[float, float]:
    """Largest peak of an amplitude spectrum in a band, with sub-bin accuracy.

    The largest bin in ``[fmin, fmax]`` is refined by fitting a parabola through the log
    amplitudes of it and its two neighbours (Gaussian interpolation); if it is not a strict
    interior local maximum of positive values, the bin itself is returned. On the Hann spectra
    of this module a sinusoid between bins is located to within 0.02 bin and its amplitude
    over-estimated by at most 4 % (exact on a bin).

    Args:
        freq: Uniformly spaced frequencies of shape (F,) [Hz].
        amp: Amplitudes of shape (F,) (any units, non-negative).
        fmin: Lower band edge [Hz], inclusive.
        fmax: Upper band edge [Hz], inclusive.

    Returns:
        ``(f_peak [Hz], a_peak)``.
    """
    freq = np.asarray(freq, dtype=np.float64)
    amp = np.asarray(amp, dtype=np.float64)
    band = np.flatnonzero((freq >= fmin) & (freq <= fmax))
    if band.size == 0:
        raise ValueError(f"no frequency bin in [{fmin}, {fmax}] Hz")
    i = int(band[np.argmax(amp[band])])
    if i == 0 or i == amp.size - 1:
        return float(freq[i]), float(amp[i])
    lo, mid, hi = amp[i - 1 : i + 2]
    if min(lo, hi) <= 0.0 or max(lo, hi) >= mid:
        return float(freq[i]), float(amp[i])
    lo, mid, hi = np.log([lo, mid, hi])
    delta = 0.5 * (lo - hi) / (lo - 2.0 * mid + hi)
    return float(freq[i] + delta * (freq[1] - freq[0])), float(np.exp(mid - 0.25 * (lo - hi) * delta))
