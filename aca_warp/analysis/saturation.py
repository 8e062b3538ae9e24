"""Saturation of the HF friction instability: where a record's linear growth ends, and the linear growth rate.

The falling friction law (paper Eq. 4) gives every patch negative damping at its sliding speed ω r_i, so a run
started from rest grows roughly exponentially and then saturates (patches reach sticking, the amplitude is
limited). The paper's findings (§3) refer to the saturated state; :func:`saturation` finds where it starts in
a recorded series such as Σ|u̇| or μ, and :func:`predicted_growth_rate` gives the growth rate of the
linearised patch equation that the fitted growth rate is compared with.

Envelope and criterion of :func:`saturation` (all thresholds are its parameters; docs/analysis.md gives the
reasoning behind each default):

1. The record is cut into K consecutive windows of W samples (trailing W − 1 samples at most are dropped).
   Per window the envelope e_k is the ``statistic``: ``"std"`` (RMS about the window mean: the oscillation
   amplitude of μ, torque, Σu̇), ``"mean"`` (window mean: the level of a rectified signal such as Σ|u̇|) or
   ``"rms"``. In the linear phase about an equilibrium of zero velocity every one is proportional to the
   oscillation amplitude, so ln e_k grows at the growth rate σ.
2. L_k = ln e_k; its local slope s_k [1/s] is the least-squares slope over ``smooth`` windows centred on k
   (the span truncated at the record's ends); L̄_k is the moving average over the same span.
3. Growth phase: the windows a ≤ b that maximise the rise L̄_b − L̄_a (largest-sum run of increments). It
   counts when the rise is at least ``min_rise`` e-folds. The growth rate is the least-squares slope of L_k
   over the windows of that run whose L̄_k lies ``fit_margin[0]`` e-folds above L̄_a and ``fit_margin[1]``
   e-folds below L̄_b (away from the initial transient or noise floor and from the nonlinear approach to the
   saturated level; the whole run if fewer than 3 windows remain), with its R². A fit below ``min_r2`` is no
   exponential growth (e.g. a release transient faster than a few windows, then a slow drift): no growth phase.
4. A window is *settled* when |s_k|·T_w ≤ ``rel_change`` (the envelope changes by less than that fraction per
   window of duration T_w), when exp(L̄_k) lies within a factor 1 + ``band`` of the final level exp(L_f)
   (L_f the mean of L over the last ``min_saturated`` windows; the settling time of control engineering) and,
   if a growth phase was found, when s_k ≤ ``growth_fraction``·σ. The saturated part starts at the first
   window k_s after which every window is settled; it must span ``min_saturated`` windows, otherwise the
   record is reported as not saturated.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from aca_warp.scene import Friction, Material

if TYPE_CHECKING:
    from aca_warp.scene import Scene

Statistic = Literal["std", "mean", "rms"]
STATISTICS = ("std", "mean", "rms")
DEFAULT_WINDOWS = 64
"""The default window is shortened so that a record gives at least this many windows."""


@dataclass(frozen=True)
class SaturationResult:
    """Saturation analysis of one recorded series (one column of the input).

    Attributes:
        t_s: Start of the saturated part [s] (start of window k_s), or None when the record does not saturate.
        start_index: First sample of the saturated part (``signal[start_index:]``), or None.
        verdict: One human-readable sentence with the figures below.
        envelope_time: Window centres [s], shape (K,).
        envelope: Envelope e_k per window (units of the signal), shape (K,).
        log_slope: Local slope s_k of ln e_k [1/s], shape (K,).
        window: Samples per window W.
        window_duration: T_w = W·Δt [s].
        statistic: Envelope statistic ("std", "mean" or "rms").
        growth_rate: Fitted exponential growth rate σ of the growth phase [1/s], or None without one.
        growth_window: (start, end) of the fit window [s], or None.
        growth_r2: R² of the linear fit of ln e over the fit window (also of a fit rejected by ``min_r2``), or None.
        growth_rise: Rise of the smoothed ln e over the growth phase [e-folds] (also when below min_rise).
        level: Mean envelope over the saturated part (units of the signal), or None.
        level_spread: Standard deviation of the envelope over the saturated part, or None.
        final_log_slope: s at the last window [1/s] (how fast the envelope still changes at the end).
    """

    t_s: float | None
    start_index: int | None
    verdict: str
    envelope_time: np.ndarray
    envelope: np.ndarray
    log_slope: np.ndarray
    window: int
    window_duration: float
    statistic: str
    growth_rate: float | None
    growth_window: tuple[float, float] | None
    growth_r2: float | None
    growth_rise: float
    level: float | None
    level_spread: float | None
    final_log_slope: float

    @property
    def saturated(self) -> bool:
        """True when a saturated part was found."""
        return self.t_s is not None


_BLOCK_COLUMNS = 64
"""Columns converted to float64 at a time: bounds the temporaries of a per-patch record to 64 columns."""

_FREQUENCY_COLUMNS = 32
"""At most this many evenly spaced columns are transformed to find a batch's dominant frequency."""


def _check_record(time: np.ndarray, signal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Validate shapes and time; return (time (N,), signal (N, P)) without copying a floating-point signal."""
    time = np.asarray(time, dtype=np.float64)
    signal = np.asarray(signal)
    if not np.issubdtype(signal.dtype, np.floating):
        signal = signal.astype(np.float64)
    if time.ndim != 1 or signal.ndim not in (1, 2) or signal.shape[0] != time.size:
        raise ValueError(f"time must be (N,) and signal (N,) or (N, pads); got {time.shape} and {signal.shape}")
    if not np.all(np.isfinite(time)) or np.any(np.diff(time) <= 0):
        raise ValueError("time must be finite and strictly increasing")
    return time, signal.reshape(time.size, -1)


def _finite_block(x: np.ndarray, columns: np.ndarray, one: bool) -> np.ndarray:
    """``x`` as float64, or ValueError naming the first non-finite sample (``columns``: the input's column numbers)."""
    x = np.asarray(x, dtype=np.float64)
    bad = ~np.isfinite(x)
    if bad.any():
        row, col = np.unravel_index(int(np.flatnonzero(bad.ravel())[0]), x.shape)
        where = f"sample {row}" + ("" if one else f", column {columns[col]}")
        raise ValueError(f"signal has a non-finite value at {where}; saturation needs a finite record")
    return x


def dominant_frequency(time: np.ndarray, signal: np.ndarray) -> float:
    """Frequency of the largest Hann-spectrum bin of the sample-to-sample differences of ``signal`` [Hz].

    Differencing suppresses a growing or drifting mean (its spectrum sits in the lowest bins) by the factor
    2 sin(πfΔt) relative to the oscillation, so the oscillation of a growing record is found. For a batch
    (N, P) the median over at most 32 evenly spaced columns is returned. Bins below 3 are ignored.
    """
    import scipy.fft  # here, not at the top: every HF run writes scene_growth_rate, which needs no FFT (≈ 0.4 s CPU)

    time, x = _check_record(time, signal)
    if time.size < 9:
        raise ValueError(f"need at least 9 samples to find a dominant frequency, got {time.size}")
    cols = np.unique(np.linspace(0, x.shape[1] - 1, min(x.shape[1], _FREQUENCY_COLUMNS)).round().astype(int))
    dt = (time[-1] - time[0]) / (time.size - 1)
    d = np.diff(_finite_block(x[:, cols], cols, np.ndim(signal) == 1), axis=0)
    w = np.hanning(d.shape[0])[:, None]
    amp = np.abs(scipy.fft.rfft(d * w, axis=0))
    freq = scipy.fft.rfftfreq(d.shape[0], dt)
    return float(np.median(freq[3 + np.argmax(amp[3:], axis=0)]))


def _envelope(x: np.ndarray, window: int, statistic: str, one: bool) -> np.ndarray:
    """Per-window statistic of x (N, P) -> (K, P), float64, computed 64 columns at a time."""
    k = x.shape[0] // window
    out = np.empty((k, x.shape[1]))
    for c0 in range(0, x.shape[1], _BLOCK_COLUMNS):
        xb = _finite_block(x[:, c0 : c0 + _BLOCK_COLUMNS], np.arange(c0, x.shape[1]), one)
        xw = xb[: k * window].reshape(k, window, xb.shape[1])
        if statistic == "std":
            e = xw.std(axis=1)
        elif statistic == "mean":
            e = np.abs(xw.mean(axis=1))
        else:
            e = np.sqrt(np.mean(xw * xw, axis=1))
        out[:, c0 : c0 + xb.shape[1]] = e
    return out


def _local_fit(y: np.ndarray, t: np.ndarray, span: int) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares slope and mean of y (K, P) over ``span`` points centred on each k (truncated at the ends)."""
    k = y.shape[0]
    h = span // 2
    lo = np.clip(np.arange(k) - h, 0, None)
    hi = np.clip(np.arange(k) + h + 1, None, k)

    def window_sum(v: np.ndarray) -> np.ndarray:
        c = np.concatenate([np.zeros((1,) + v.shape[1:]), np.cumsum(v, axis=0)])
        return c[hi] - c[lo]

    tc = t - t.mean()  # centred: better conditioned sums
    n = (hi - lo).astype(np.float64)[:, None]
    st, stt = window_sum(tc)[:, None], window_sum(tc * tc)[:, None]
    sy, sty = window_sum(y), window_sum(tc[:, None] * y)
    den = n * stt - st * st
    slope = np.where(den > 0, (n * sty - st * sy) / np.where(den > 0, den, 1.0), 0.0)
    return slope, sy / n


def _max_rise(levels: np.ndarray) -> tuple[int, int]:
    """Indices a ≤ b maximising levels[b] − levels[a] (the largest-sum run of increments)."""
    low = np.minimum.accumulate(levels)
    b = int(np.argmax(levels - low))
    a = int(np.argmin(levels[: b + 1]))
    return a, b


def _linear_fit(t: np.ndarray, y: np.ndarray) -> tuple[float, float, float]:
    """Slope, intercept and R² of y(t)."""
    tm, ym = t.mean(), y.mean()
    sxx = np.sum((t - tm) ** 2)
    slope = float(np.sum((t - tm) * (y - ym)) / sxx)
    resid = y - ym - slope * (t - tm)
    syy = np.sum((y - ym) ** 2)
    r2 = float(1.0 - np.sum(resid**2) / syy) if syy > 0 else 1.0
    return slope, float(ym - slope * tm), r2


@dataclass(frozen=True)
class _Options:
    smooth: int
    min_rise: float
    min_r2: float
    fit_margin: tuple[float, float]
    growth_fraction: float
    rel_change: float
    band: float
    min_saturated: int
    fit_window: tuple[float, float] | None


def _growth_fit(
    L: np.ndarray, Lbar: np.ndarray, te: np.ndarray, t0: np.ndarray, tw: float, opt: _Options
) -> tuple[tuple[float, float, float, float, float] | None, float]:
    """Growth fit (σ, fit start, fit end, R², rise) or None, and the rise of the growth phase [e-folds]."""
    a, b = _max_rise(Lbar)
    rise = float(Lbar[b] - Lbar[a])
    if opt.fit_window is not None:
        sel = np.flatnonzero((t0 >= opt.fit_window[0]) & (t0 + tw <= opt.fit_window[1] * (1 + 1e-12)))
        if sel.size < 3:
            raise ValueError(f"fit_window {opt.fit_window} s holds {sel.size} whole windows; need at least 3")
    elif rise >= opt.min_rise:
        lo, hi = Lbar[a] + opt.fit_margin[0], Lbar[b] - opt.fit_margin[1]
        sel = np.arange(a, b + 1)
        inside = sel[(Lbar[sel] >= lo) & (Lbar[sel] <= hi)]
        if inside.size >= 3:
            sel = np.arange(inside[0], inside[-1] + 1)
    else:
        return None, rise
    sigma, _, r2 = _linear_fit(te[sel], L[sel])
    if sigma <= 0 and opt.fit_window is None:
        return None, rise
    return (sigma, float(t0[sel[0]]), float(t0[sel[-1]] + tw), r2, rise), rise


def _analyse_column(
    e: np.ndarray, te: np.ndarray, s: np.ndarray, Lbar: np.ndarray, t0: np.ndarray, opt: _Options
) -> tuple[int | None, tuple[float, float, float, float, float] | None, float, str, float | None]:
    """Decide one column: (k_s or None, growth fit (σ, t_a, t_b, R², rise) or None, rise, reason if none, R² of a
    fit rejected by ``min_r2`` or None)."""
    L = np.log(e)
    tw = t0[1] - t0[0]
    fit, rise = _growth_fit(L, Lbar, te, t0, tw, opt)
    rejected = None
    if fit is not None and opt.fit_window is None and opt.min_r2 > 0 and fit[3] < opt.min_r2:
        fit, rejected = None, fit[3]
    final = L[-opt.min_saturated :].mean()
    settled = (np.abs(s) * tw <= opt.rel_change) & (np.abs(Lbar - final) <= np.log1p(opt.band))
    if fit is not None and fit[0] > 0:
        settled &= s <= opt.growth_fraction * fit[0]
    tail = np.flip(np.logical_and.accumulate(np.flip(settled)))
    if not tail[-1]:
        return None, fit, rise, "unsettled_end", rejected
    k_s = int(np.argmax(tail))
    if L.size - k_s < opt.min_saturated:
        return None, fit, rise, "short_tail", rejected
    return k_s, fit, rise, "", rejected


def _verdict(res: dict, opt: _Options, reason: str, unit: str) -> str:
    """One sentence describing a column's result."""
    u = f" {unit}" if unit else ""
    g = ""
    if res["growth_rate"] is not None:
        ga, gb = res["growth_window"]
        g = (
            f"; growth phase fitted over {ga * 1e3:.4g}-{gb * 1e3:.4g} ms at σ = {res['growth_rate']:.4g} s^-1 "
            f"(R² = {res['growth_r2']:.3f}, rise {res['growth_rise']:.2f} e-folds)"
        )
    elif res["growth_r2"] is not None:
        g = (
            f"; no exponential growth phase (rise {res['growth_rise']:.2f} e-folds fitted with R² = "
            f"{res['growth_r2']:.3f}, {opt.min_r2:g} needed)"
        )
    else:
        g = f"; no growth phase (rise {res['growth_rise']:.2f} e-folds, {opt.min_rise:g} needed)"
    if res["t_s"] is not None:
        where = "from the start of the record" if res["start_index"] == 0 else f"from t_s = {res['t_s'] * 1e3:.4g} ms"
        return f"saturated {where}: {res['statistic']} envelope {res['level']:.4g} ± {res['level_spread']:.3g}{u}" + g
    if reason == "short_tail":
        return f"not saturated: the envelope settles only in the last < {opt.min_saturated} windows" + g
    ref = res["growth_rate"]
    frac = f" = {res['final_log_slope'] / ref:.2f} of the growth rate" if ref and ref > 0 else ""
    slope = res["final_log_slope"]
    return f"not saturated: the envelope still changes at the end (log-slope {slope:.4g} s^-1{frac})" + g


def saturation(
    time: np.ndarray,
    signal: np.ndarray,
    *,
    statistic: Statistic = "std",
    window: int | None = None,
    periods: float = 32.0,
    min_windows: int = 16,
    smooth: int = 7,
    min_rise: float = 1.0,
    min_r2: float = 0.0,
    fit_margin: tuple[float, float] = (1.0, 1.0),
    growth_fraction: float = 0.2,
    rel_change: float = 0.05,
    band: float = 0.1,
    min_saturated: int = 8,
    fit_window: tuple[float, float] | None = None,
    unit: str = "",
) -> SaturationResult | list[SaturationResult]:
    """Find the saturated part of a recorded series and fit the growth phase before it (module docstring).

    Args:
        time: Sample times [s], shape (N,), strictly increasing (uniform sampling assumed for T_w).
        signal: Recorded series, shape (N,) or (N, pads) (e.g. Σ|u̇| [m/s] of several pads); finite.
        statistic: Envelope per window: "std" (oscillation amplitude; μ, torque, Σu̇), "mean" (level of a
            non-negative signal such as Σ|u̇|; far less noisy there) or "rms".
        window: Samples per window W. Default: ``periods`` periods of the dominant frequency
            (:func:`dominant_frequency`), at least 4 samples, shortened to N // 64 if the record gives fewer
            than 64 windows (``DEFAULT_WINDOWS``).
        periods: Dominant periods per default window (32: averages the beating of many patch frequencies).
        min_windows: Fewest windows the record must give (16); fewer raises ValueError.
        smooth: Windows in the span of the local slope and the moving average (7, odd; ≥ 3).
        min_rise: Rise of the smoothed ln e [e-folds] that counts as a growth phase (1.0: ×2.7).
        min_r2: Least R² of the growth fit that counts as exponential growth (0: any); a poorer fit is no growth
            phase, and the settled windows are then not held to ``growth_fraction`` of its rate. Not applied to a
            fit over ``fit_window``, which the caller chose.
        fit_margin: (lower, upper) e-folds kept clear of the growth phase's start and end in the fit.
        growth_fraction: A settled window's log-slope stays below this fraction of the fitted growth rate (0.2).
        rel_change: A settled window's envelope changes by less than this fraction per window (0.05).
        band: A settled window's smoothed envelope lies within a factor 1 + band of the final level (0.1).
        min_saturated: Fewest windows of a saturated part (8); a shorter settled tail is "not saturated".
        fit_window: (start, end) [s]: fit the growth rate over the whole windows inside this span instead of
            the automatic growth phase (e.g. to compare records over the same span).
        unit: Unit of the signal for the verdict text (e.g. "m/s").

    Returns:
        A :class:`SaturationResult` for 1-D ``signal``; a list of them, one per column, for 2-D ``signal``.

    Raises:
        ValueError: Non-finite samples, mismatched shapes, bad options, or a record too short for
            ``min_windows`` windows of at least 4 samples.
    """
    if statistic not in STATISTICS:
        raise ValueError(f"statistic must be one of {', '.join(STATISTICS)}, got {statistic!r}")
    if smooth < 3 or smooth % 2 == 0:
        raise ValueError(f"smooth must be an odd number of windows >= 3, got {smooth}")
    one = np.ndim(signal) == 1
    time, x = _check_record(time, signal)
    n = time.size
    if n < 4 * min_windows:
        raise ValueError(f"record too short: {n} samples, need at least {4 * min_windows} ({min_windows} windows of 4)")
    dt = (time[-1] - time[0]) / (n - 1)
    if window is None:
        window = _default_window(time, signal, periods, dt)
    if not 1 <= window <= n // min_windows:
        raise ValueError(f"window of {window} samples gives fewer than {min_windows} windows in {n} samples")
    if not 0.0 <= min_r2 <= 1.0:
        raise ValueError(f"min_r2 must lie in [0, 1], got {min_r2}")
    opt = _Options(
        smooth, min_rise, min_r2, tuple(fit_margin), growth_fraction, rel_change, band, min_saturated, fit_window
    )
    e = _envelope(x, window, statistic, one)
    k = e.shape[0]
    t0 = time[: k * window : window]
    te = time[: k * window].reshape(k, window).mean(axis=1)
    positive = e > 0
    floor = np.where(positive.any(axis=0), np.min(np.where(positive, e, np.inf), axis=0), 1.0) * 1e-6
    L = np.log(np.where(positive, e, floor))
    s, Lbar = _local_fit(L, te, smooth)
    frame = _Frame(te, t0, window, dt, statistic, unit, opt)
    out = []
    for j in range(x.shape[1]):
        out.append(_column_result(frame, e[:, j], s[:, j], Lbar[:, j], positive[:, j], floor[j]))
    return out[0] if one else out


def _default_window(time: np.ndarray, signal: np.ndarray, periods: float, dt: float) -> int:
    """``periods`` periods of the dominant frequency in samples, at least 4, at most N // ``DEFAULT_WINDOWS``."""
    n = time.size
    window = int(round(periods / (dominant_frequency(time, signal) * dt)))
    return int(np.clip(window, 4, max(4, n // DEFAULT_WINDOWS)))


@dataclass(frozen=True)
class _Frame:
    """What every column of one :func:`saturation` call shares: window centres ``te`` and starts ``t0`` [s], W,
    Δt [s], the statistic, the unit of the verdict and the options."""

    te: np.ndarray
    t0: np.ndarray
    window: int
    dt: float
    statistic: str
    unit: str
    opt: _Options


def _column_result(
    fr: _Frame, e: np.ndarray, s: np.ndarray, Lbar: np.ndarray, positive: np.ndarray, floor: float
) -> SaturationResult:
    """:class:`SaturationResult` of one column: envelope ``e``, local slope ``s`` and level ``Lbar`` per window
    (K,), ``positive`` where e > 0, ``floor`` the stand-in for e = 0."""
    if not positive.any():
        k_s, fit, rise, reason, rejected = None, None, 0.0, "zero", None
    else:
        k_s, fit, rise, reason, rejected = _analyse_column(np.where(positive, e, floor), fr.te, s, Lbar, fr.t0, fr.opt)
    tail = e[k_s:] if k_s is not None else None
    res = {
        "t_s": float(fr.t0[k_s]) if k_s is not None else None,
        "start_index": k_s * fr.window if k_s is not None else None,
        "envelope_time": fr.te,
        "envelope": e,
        "log_slope": s,
        "window": fr.window,
        "window_duration": fr.window * fr.dt,
        "statistic": fr.statistic,
        "growth_rate": fit[0] if fit else None,
        "growth_window": (fit[1], fit[2]) if fit else None,
        "growth_r2": fit[3] if fit else rejected,
        "growth_rise": rise,
        "level": float(tail.mean()) if tail is not None else None,
        "level_spread": float(tail.std()) if tail is not None else None,
        "final_log_slope": float(s[-1]),
    }
    verdict = "not saturated: the signal is constant (zero envelope)" if reason == "zero" else None
    return SaturationResult(verdict=verdict or _verdict(res, fr.opt, reason, fr.unit), **res)


def common_start(results: list[SaturationResult]) -> int | None:
    """First sample from which every series of a batch is saturated (the latest start), or None if one is not."""
    starts = [r.start_index for r in results]
    return None if any(s is None for s in starts) else max(starts)


# ------------------------------------------------------------------------------------------------ a run's record


GROWTH_STATUSES = ("saturated", "not saturated", "no growth phase")
"""Status of a run's record (:func:`record_saturation`)."""


@dataclass(frozen=True)
class RecordSaturation:
    """Saturation of one pad's record from its global outputs Σ|u̇| and μ (:func:`record_saturation`).

    Attributes:
        sum_abs_velocity: :func:`saturation` of Σ|u̇| (window means, default windows).
        mu: :func:`saturation` of μ (window standard deviations, N/64 windows).
        status: "saturated" (Σ|u̇| grows, then settles), "not saturated" (Σ|u̇| has no settled part) or
            "no growth phase" (Σ|u̇| settles without having grown by ``min_rise``, or its rise fits below
            ``min_growth_r2``: not the instability's saturated state, e.g. a run started from a saturated state, a
            stable one, or a release from rest).
        t_start: Start of the saturated part [s]: the later of the two saturation times (Σ|u̇|'s alone when μ does
            not saturate); None unless ``status`` is "saturated".
    """

    sum_abs_velocity: SaturationResult
    mu: SaturationResult
    status: str
    t_start: float | None

    def figures(self) -> dict[str, Any]:
        """The figures as plain values: times [s], rates [1/s], levels [m/s], verdicts, status."""
        rs, rm = self.sum_abs_velocity, self.mu
        return {
            "t_s_sum_abs_velocity": rs.t_s,
            "t_s_mu": rm.t_s,
            "mu_saturated": rm.saturated,
            "growth_rate": rs.growth_rate,
            "growth_r2": rs.growth_r2,
            "growth_rise": rs.growth_rise,
            "growth_window": rs.growth_window,
            "level_sum_abs_velocity": rs.level,
            "mu_growth_rate": rm.growth_rate,
            "verdict_sum_abs_velocity": rs.verdict,
            "verdict_mu": rm.verdict,
            "status": self.status,
            "t_start": self.t_start,
        }


def record_saturation(
    time: np.ndarray, mu: np.ndarray, sum_abs_velocity: np.ndarray, min_growth_r2: float = 0.0
) -> RecordSaturation:
    """Saturation of one pad on Σ|u̇| (window means, default windows) and μ (standard deviation over N/64 windows).

    μ is chaotic once saturated: the default window of 32 dominant periods leaves its standard deviation too noisy
    for the ±10 % band, 64 windows over the record do not. The status follows Σ|u̇| (:class:`RecordSaturation`).

    Args:
        time: Sample times [s], shape (N,), uniform, N ≥ 64.
        mu: μ(t), shape (N,).
        sum_abs_velocity: Σ|u̇|(t) [m/s], shape (N,).
        min_growth_r2: ``min_r2`` of Σ|u̇|: the least R² of its growth fit that counts as a growth phase (μ keeps
            every fit).

    Raises:
        ValueError: As :func:`saturation` (a record shorter than 64 samples, non-finite samples).
    """
    rs = saturation(time, sum_abs_velocity, statistic="mean", unit="m/s", min_r2=min_growth_r2)
    rm = saturation(time, mu, statistic="std", window=max(4, np.size(time) // 64))
    if not rs.saturated:
        return RecordSaturation(rs, rm, "not saturated", None)
    if rs.growth_rate is None:
        return RecordSaturation(rs, rm, "no growth phase", None)
    return RecordSaturation(rs, rm, "saturated", max(rs.t_s, rm.t_s if rm.saturated else rs.t_s))


# ------------------------------------------------------------------------------------------------ linear theory


def friction_slope(v: np.ndarray | float, M: float, slope: float = 200.0, decay: float = 0.25) -> np.ndarray:
    """df/dv of the signed Eq. 4, f(v) = (M/π) atan(slope·v) (1/(decay·|v| + 1) + 1) [s/m].

    df/dv = (M/π) [slope/(1 + (slope·v)²) (g + 1) − atan(slope·v) · decay · sign(v) · g²], g = 1/(decay·|v| + 1).
    """
    v = np.asarray(v, dtype=np.float64)
    a = np.arctan(slope * v)
    g = 1.0 / (decay * np.abs(v) + 1.0)
    return M / np.pi * (slope / (1.0 + (slope * v) ** 2) * (g + 1.0) - a * decay * np.sign(v) * g * g)


def predicted_growth_rate(
    normal_force: np.ndarray,
    area: np.ndarray,
    radius: np.ndarray,
    omega: float,
    M: float,
    slope: float = Friction.slope,
    decay: float = Friction.decay,
    rho_A: float = Material.mass_per_area,
    zeta: float = Material.damping_ratio,
    k_t: np.ndarray | float | None = None,
) -> np.ndarray:
    """Growth rate of each isolated patch's linearised motion about steady sliding [1/s].

    One patch obeys m ü + c u̇ + k u = F_N f(ω r − u̇) with m = ρ_A A, c = 2ζ√(k m), k = k_T. About its
    equilibrium u* = F_N f(ω r)/k a small deviation δ obeys, to first order in δ̇,

        m δ̈ + (c + F_N f′(ω r)) δ̇ + k δ = 0,

    since F_N f(ω r − δ̇) = F_N f(ω r) − F_N f′(ω r) δ̇. Its eigenvalues are the roots of
    m λ² + c_eff λ + k = 0 with the effective damping c_eff = c + F_N f′(ω r) (negative where Eq. 4 falls).
    The returned growth rate is the larger real part of the two roots:

        σ = (−c_eff + Re √(c_eff² − 4 m k)) / (2 m),

    which for an underdamped pair (c_eff² < 4mk, the case of every preset) is exactly

        σ = (F_N·(−f′(ω r)) − c) / (2 m) = p·|f′(ω r)|/(2 ρ_A) − ζ ω_0,   p = F_N/A, ω_0 = √(k/m)

    (the last form for falling f). Coupling: with the symmetric coupling stiffness of paper Eq. 3 and the
    diagonal mass and effective damping, every underdamped eigenvalue λ of the coupled pad, with eigenvector x,
    satisfies λ² xᴴMx + λ xᴴC_eff x + xᴴKx = 0 with real coefficients, so Re λ = −xᴴC_eff x/(2 xᴴMx), a
    weighted mean of the patches' −c_eff,i/(2 m_i): coupling moves a mode's rate between the smallest and the
    largest isolated σ_i, never beyond (:func:`coupled_growth_rates` computes them). The bound fails for a
    non-symmetric stiffness (follower forces, mode coupling) or a friction force that depends on a
    neighbour's motion, neither of which the model has.

    Args:
        normal_force: F_N,i [N], shape (n,).
        area: A_i [m²], shape (n,).
        radius: Friction radius r_i [m], shape (n,).
        omega: Disc angular velocity ω [rad/s].
        M: Multiplicative factor of Eq. 4.
        slope: Regularisation slope of Eq. 4 [s/m].
        decay: Decay constant of Eq. 4 [s/m].
        rho_A: Mass per area [kg/m²].
        zeta: Damping ratio ζ.
        k_t: Tangential stiffness k_T,i [N/m], shape (n,) or scalar; default K_T √A_i (paper Eq. 2).

    Returns:
        σ_i [1/s], shape (n,) (negative: the patch's oscillation decays).
    """
    fn, a, r = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (normal_force, area, radius)))
    m = rho_A * a
    k = Material.K_T * np.sqrt(a) if k_t is None else np.broadcast_to(np.asarray(k_t, dtype=np.float64), a.shape)
    c_eff = 2.0 * zeta * np.sqrt(k * m) + fn * friction_slope(omega * r, M, slope, decay)
    disc = (c_eff * c_eff - 4.0 * m * k).astype(np.complex128)
    return (-c_eff + np.sqrt(disc).real) / (2.0 * m)


def scene_growth_rate(scene: Scene, normal_force: np.ndarray) -> np.ndarray:
    """:func:`predicted_growth_rate` of every patch of ``scene`` under the contact forces ``normal_force`` [N],
    shape (patches,): the scene's friction law, material and disc speed, k_T,i = K_T √A_i (paper Eq. 2) [1/s]."""
    f, m, a = scene.friction, scene.material, scene.patches.area
    return predicted_growth_rate(
        normal_force, a, scene.patches.friction_radius, scene.angular_velocity, f.M, f.slope, f.decay,
        m.mass_per_area, m.damping_ratio, m.K_T * np.sqrt(a),
    )  # fmt: skip


def coupled_growth_rates(
    mass: np.ndarray, effective_damping: np.ndarray, stiffness: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Growth rates and frequencies of the linearised coupled pad M δ̈ + C_eff δ̇ + K δ = 0 (dense; small pads).

    Args:
        mass: m_i [kg], shape (n,).
        effective_damping: c_i + F_N,i f′(ω r_i) [N s/m], shape (n,).
        stiffness: K [N/m], shape (n, n) (dense or SciPy sparse): k_T,i + Σ_j k_ij on the diagonal, −k_ij off it.

    Returns:
        ``(rates, freqs)``: Re λ [1/s] and |Im λ|/2π [Hz] of the 2n eigenvalues, sorted by rate, largest first.
    """
    mass = np.asarray(mass, dtype=np.float64)
    kmat = stiffness.toarray() if hasattr(stiffness, "toarray") else np.asarray(stiffness, dtype=np.float64)
    n = mass.size
    a = np.zeros((2 * n, 2 * n))
    a[:n, n:] = np.eye(n)
    a[n:, :n] = -kmat / mass[:, None]
    a[n:, n:] = -np.diag(np.asarray(effective_damping, dtype=np.float64) / mass)
    lam = np.linalg.eigvals(a)
    order = np.argsort(-lam.real)
    return lam.real[order], np.abs(lam.imag[order]) / (2.0 * np.pi)


def growth_rate_summary(sigma: np.ndarray, pad: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Minimum, median and maximum of per-patch growth rates, per pad.

    Args:
        sigma: σ_i [1/s], shape (n,).
        pad: Pad index of each patch, shape (n,) (integers 0..P−1); None: one pad.

    Returns:
        ``{"min", "median", "max"}``, each of shape (P,) [1/s] (NaN for a pad without patches).
    """
    sigma = np.asarray(sigma, dtype=np.float64)
    pad = np.zeros(sigma.size, dtype=np.int64) if pad is None else np.asarray(pad, dtype=np.int64)
    count = int(pad.max()) + 1 if pad.size else 0
    out = {key: np.full(count, np.nan) for key in ("min", "median", "max")}
    for p in range(count):
        s = sigma[pad == p]
        if s.size:
            out["min"][p], out["median"][p], out["max"][p] = s.min(), np.median(s), s.max()
    return out
