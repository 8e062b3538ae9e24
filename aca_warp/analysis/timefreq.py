"""Time-frequency maps of a recorded signal such as μ(t): STFT and complex-Morlet CWT (paper Figs. 10-11).

Both maps are amplitude-true: a stationary sinusoid a·sin(2πft) shows a value ≈ a at f (the STFT
exactly when f lies on a bin). Each function also returns a dict of strings describing its
scaling, for figure captions and file attributes.
"""

from __future__ import annotations

import inspect
import math
from typing import Literal

import numpy as np
from scipy.signal import ShortTimeFFT
from scipy.signal.windows import hann

from .spectra import DEFAULT_FLOOR_HZ

MIN_STFT_SAMPLES = 4
"""Fewest samples of an STFT window: fewer resolve no frequency between 0 Hz and the Nyquist frequency."""

MIN_STFT_WINDOWS = 2
"""Fewest windows of an STFT map (``aca-warp analyze``, the figure): one window is a spectrum, with no time axis to
draw. :func:`stft` itself accepts one window (a measure such as ``stft_peak`` may use one as long as the record)."""


def default_window_samples(n: int, at_least: float = 0.0) -> int:
    """The default STFT window of a record of ``n`` samples, in samples, a power of two: 2^round(log2(N/64)), at
    least 16; the smallest power of two of ``at_least`` samples or more where that is longer (rounded up: 40 give
    64); at most the largest power of two ≤ N/2 (at least :data:`MIN_STFT_SAMPLES`), so that the map has several
    windows."""
    samples = max(16, 2 ** round(math.log2(max(n / 64, 1.0))))
    if samples < at_least * (1 - 1e-9):
        samples = 2 ** math.ceil(math.log2(at_least) - 1e-9)
    return min(samples, max(MIN_STFT_SAMPLES, 2 ** math.floor(math.log2(max(n / 2, 1.0)))))


def stft_window_count(nperseg: int, hop: int, n: int) -> int:
    """Number of STFT windows of ``nperseg`` samples, ``hop`` apart, that lie wholly inside a record of ``n``
    samples (0 when the window is longer than the record). Window p spans samples p·hop - nperseg//2 up to
    p·hop - nperseg//2 + nperseg - 1 (the grid of ``scipy.signal.ShortTimeFFT``)."""
    mid = nperseg // 2
    return max(0, (n - nperseg + mid) // hop + 1 - -(-mid // hop))


def check_stft_window(
    nperseg: int,
    hop: int,
    n: int,
    dt: float,
    name: str = "window",
    seconds: float | None = None,
    windows: int = MIN_STFT_WINDOWS,
) -> None:
    """Refuse an STFT window of ``nperseg`` samples (hop ``hop``) on ``n`` samples at ``dt`` [s] that is shorter than
    :data:`MIN_STFT_SAMPLES` or leaves fewer than ``windows`` windows inside the record (ValueError, in seconds and
    samples; ``name`` names the window, ``seconds`` its length as given [s], in the message)."""
    seconds = nperseg * dt if seconds is None else seconds
    given = f"{name} {seconds:.4g} s is {nperseg} sample{'s' if nperseg != 1 else ''} at dt = {dt:.4g} s"
    if nperseg < MIN_STFT_SAMPLES:
        raise ValueError(f"{given}; at least {MIN_STFT_SAMPLES} samples ({MIN_STFT_SAMPLES * dt:.4g} s) needed")
    count = stft_window_count(nperseg, hop, n)
    if count < windows:
        quarter = hop == max(1, nperseg // 4)  # the default hop follows the window
        longest = next(
            (w for w in range(min(nperseg, n), MIN_STFT_SAMPLES - 1, -1)
             if stft_window_count(w, max(1, w // 4) if quarter else hop, n) >= windows),
            0,
        )  # fmt: skip
        record = f"{n} samples, {n * dt:.4g} s"
        fit = (
            f"longer than the record ({record})"
            if nperseg > n
            else f"the record ({record}) holds {count} window{'s' if count != 1 else ''} of it"
        )
        if longest:  # windows sit on a grid centred at multiples of the hop: not every shorter length fits
            fix = f"a window of {longest * dt:.4g} s ({longest} samples) fits"
        elif n < MIN_STFT_SAMPLES * windows or hop <= 1:
            fix = f"the record is too short for an STFT map of {MIN_STFT_SAMPLES}-sample windows"
        else:
            fix = f"no window length does at a hop of {hop * dt:.4g} s ({hop} samples): shorten the hop"
        need = f"the map needs {windows} windows" if windows > 1 else "a whole window is needed"
        raise ValueError(f"{given}; {fit}, and {need}: {fix}")


def stft(
    x: np.ndarray,
    dt: float,
    *,
    window_s: float | None = None,
    hop_s: float | None = None,
    fmin: float = DEFAULT_FLOOR_HZ,
    detrend: Literal["constant", "linear"] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, str]]:
    """Short-time Fourier transform amplitude with ``scipy.signal.ShortTimeFFT``.

    Periodic Hann window, ``scale_to("magnitude")`` (window normalised to unit sum) and the
    bins 0 < f < f_Nyquist doubled, so |S| is a one-sided amplitude. Only windows lying
    entirely inside the record are kept: none starts before sample 0 or reaches past the last one,
    so a per-window trend is fitted to recorded samples only.

    Args:
        x: Real signal of shape (N,).
        dt: Sampling interval [s].
        window_s: Window length [s], at least 4 samples and at most the record (one window may be all);
            default 2^round(log2(N/64)) samples, at least 16 and at most the largest power of two ≤ N/2
            (at least 4).
        hop_s: Hop between windows [s]; default a quarter of the window.
        fmin: Bins below this frequency are dropped [Hz] (paper: 10 Hz).
        detrend: Subtract each segment's mean (``"constant"``) or linear trend (``"linear"``)
            before windowing. Without it a large mean such as μ ≈ 0.4 leaks into the first
            bin above 0 Hz with its full value and may dominate ``info["peak"]``.

    Returns:
        ``(times, freqs, amp, info)``: window centres of shape (T,) [s], frequencies of shape
        (F,) [Hz], |S| of shape (F, T) in units of ``x``, and a caption dict.

    Raises:
        ValueError: A window of fewer than :data:`MIN_STFT_SAMPLES` samples or longer than the record (no
            whole window inside it); a hop below one sample.
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.size
    if window_s is None:
        nperseg = default_window_samples(n)
    else:
        nperseg = round(window_s / dt)
    hop = max(1, nperseg // 4) if hop_s is None else round(hop_s / dt)
    if hop < 1:
        raise ValueError(f"hop of {hop_s:.4g} s is {hop} samples at dt = {dt:.4g} s; at least 1 sample needed")
    check_stft_window(nperseg, hop, n, dt, seconds=window_s, windows=1)
    # ShortTimeFFT centres window p on sample p·hop (its first sample at p·hop - nperseg//2). Its own border
    # (lower_border_end) also keeps a window whose first sample lies before the record where the periodic Hann
    # window is 0, but a per-window detrend still fits that zero-padded sample: keep only p with
    # 0 <= p·hop - nperseg//2 and p·hop - nperseg//2 + nperseg <= N.
    sft = ShortTimeFFT(hann(nperseg, sym=False), hop, fs=1.0 / dt, fft_mode="onesided", scale_to="magnitude")
    p0 = -(-(nperseg // 2) // hop)
    p1 = p0 + stft_window_count(nperseg, hop, n)
    amp = np.abs(sft.stft_detrend(x, detrend, p0=p0, p1=p1))
    amp[1:] *= 2.0
    if nperseg % 2 == 0:
        amp[-1] /= 2.0
    keep = sft.f >= fmin
    freqs, amp = sft.f[keep], amp[keep]
    window = f"periodic Hann window of {nperseg} samples ({nperseg * dt:.4g} s), hop {hop} samples ({hop * dt:.4g} s)"
    info = {
        "quantity": "one-sided STFT amplitude |S| in units of the signal; a sinusoid a·sin(2πft) on a bin shows a",
        "window": window,
        "resolution": f"Δf = {1.0 / (nperseg * dt):.4g} Hz, Δt = {hop * dt:.4g} s",
        "scaling": 'scipy ShortTimeFFT scale_to("magnitude") (window sum 1), ×2 for 0 < f < f_Nyquist',
        "fmin": f"f < {fmin:g} Hz omitted",
        "detrend": f"{detrend} trend removed per segment" if detrend else "none",
        "peak": f"{amp.max(initial=0.0):.4g} (largest |S| shown)",
        "caption": f"STFT amplitude, {window}; amplitude-true (a sinusoid of amplitude a shows a); "
        f"f < {fmin:g} Hz omitted",
    }
    return sft.t(n, p0, p1), freqs, amp, info


def cwt_morlet(
    x: np.ndarray,
    dt: float,
    freqs: np.ndarray,
    *,
    bandwidth: float = 1.5,
    center: float = 1.0,
    complex_output: bool = False,
    stride: int = 1,
    chunk: int = 8,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, str]]:
    """Continuous wavelet transform with the PyWavelets complex Morlet ``cmor{B}-{C}``.

    Amplitude-true (L1) normalisation: PyWavelets' coefficients (L2-type, ∝ √scale) are
    multiplied by 2/√scale, so a stationary sinusoid a·sin(2πft) gives |W| ≈ a at f (the 2
    restores the half of a real sinusoid that lies at negative frequencies). Scales are
    s = C/(f·dt). Frequencies are transformed a few at a time (``method="fft"``), with the
    PyWavelets ``precision`` raised for large scales so that the sampled wavelet has no
    staircase; memory stays near the output size plus a few copies of the signal.

    Args:
        x: Real signal of shape (N,); float32 gives float32/complex64 output.
        dt: Sampling interval [s].
        freqs: Analysis frequencies of shape (F,) [Hz], 0 < f < 1/(2·dt).
        bandwidth: B of ``cmorB-C`` (ψ(t) = (πB)^(-1/2)·exp(-t²/B)·exp(2πiCt)).
        center: C of ``cmorB-C``.
        complex_output: Return complex W instead of |W|.
        stride: Keep every ``stride``-th time sample of the output.
        chunk: Frequencies transformed per PyWavelets call.

    Returns:
        ``(times, freqs, W, info)``: output times of shape (T,) [s] with T = ceil(N/stride),
        the frequencies [Hz], |W| (or W) of shape (F, T) in units of ``x``, and a caption dict.
    """
    import pywt  # here, not above: the STFT and the spectra, which most measures use, do without it

    x = np.asarray(x)
    if x.dtype != np.float32:
        x = x.astype(np.float64, copy=False)
    freqs = np.asarray(freqs, dtype=np.float64)
    if np.any(freqs <= 0) or np.any(freqs >= 0.5 / dt):
        raise ValueError("cwt_morlet: frequencies must lie in (0, 1/(2 dt))")
    has_precision = "precision" in inspect.signature(pywt.cwt).parameters
    wavelet = pywt.ContinuousWavelet(f"cmor{bandwidth}-{center}")
    support = wavelet.upper_bound - wavelet.lower_bound
    scales = center / (freqs * dt)
    dtype = np.result_type(x.dtype, np.complex64) if complex_output else x.dtype
    out = np.empty((freqs.size, -(-x.size // stride)), dtype=dtype)
    order = np.argsort(scales)
    for start in range(0, freqs.size, chunk):
        idx = order[start : start + chunk]
        precision = int(np.clip(np.ceil(np.log2(support * scales[idx].max())), 12, 24))
        kw = {"precision": precision} if has_precision else {}  # PyWavelets < 1.8 samples at 2^12 points
        coef, _ = pywt.cwt(x, scales[idx], wavelet, method="fft", **kw)
        coef = coef[:, ::stride] * (2.0 / np.sqrt(scales[idx]))[:, None].astype(x.dtype)
        out[idx] = coef if complex_output else np.abs(coef)
    sigma_f = 1.0 / (np.pi * center * np.sqrt(2.0 * bandwidth))
    sigma_t = np.sqrt(bandwidth / 2.0) * center
    name = f"cmor{bandwidth}-{center}"
    info = {
        "quantity": "CWT amplitude |W| in units of the signal; a sinusoid a·sin(2πft) gives a at f",
        "wavelet": f"PyWavelets {name}: complex Morlet, bandwidth B = {bandwidth}, centre frequency C = {center}",
        "normalisation": "L1 (amplitude-true): PyWavelets coefficients × 2/√scale, scale = C/(f·dt)",
        "resolution": f"Gaussian responses with σ_f = {sigma_f:.3g}·f and σ_t = {sigma_t:.3g}/f",
        "edges": f"zero-padded record: values within about {2 * sigma_t:.3g}/f of either end are attenuated",
        "caption": f"CWT amplitude, complex Morlet {name}, amplitude-true (L1) normalisation",
    }
    return np.arange(0, x.size, stride) * dt, freqs, out, info
