"""Validation of §3.2 (stand-alone HF with varying patch area, Eq. 10, Figs. 10–11) from seed ensembles.

The ``varying_area`` preset — HF1-size patches under the HF2 load, areas growing by Eq. 10 until HF2 size — runs
as a batch of pads that differ in their seed (layout, areas, heights, initial perturbation), like the §3.1
experiments. The growth is **time-compressed** by default: the increment of Eq. 10 is multiplied by the growth
speedup s (``Config.growth_speedup``: 10 on the GPU, 20 in the quick variant) and the run lasts 0.36 s / s, so the
areas follow the same path in a shorter time; ``va_full`` (opt-in, ``--full-varying-area``) runs the paper's
0.36 s. Only the global outputs are recorded (every ``sample_dt``); every measure is computed from μ(t) and Σ|u̇|(t)
of each pad (:func:`growth_measures`) over the record after its first saturation:

* **rise of μ**: the least-squares slope of μ(t) times the analysed length (Δμ over the growth);
* **the falling line**: STFTs in non-overlapping windows; per window the frequency of the largest bin of μ's
  above 5 kHz (the dominant line) and of the lowest peak of Σu̇'s reaching a quarter of its largest (the first
  line); ``line_trend`` of ln f against the record's fraction t/T: Δ ln f over the record, beside the
  isolated-patch prediction −½ ln(√A(T)/√A(t_s)) of Eq. 10's areas;
* **the largest STFT peak**: ``stft_peaks`` of μ over windows of 2^12 … 2^17 samples (those that fit), above
  10 Hz × the growth compression (the paper truncates at 10 Hz; μ's slow rise is compressed with the growth),
  divided by the record's mean μ, one-sided (Fig. 10's normalisation); the row names its window (2^12 by default,
  every other window is a variant, :mod:`~aca_warp.studies.validation.causes`);
* **stochastic → periodic**: the amplitude spectrum of μ over the first and the last third of the analysed
  record, its ``tonality`` over 5–150 kHz: ln(peak / median) and the spectral flatness, late − early.

The first saturation is found by ``saturation`` on Σ|u̇| over the first part of the record (four times the
predicted settling time at the starting areas, at least a fifth of the record); a pad without it is listed and
not used.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from aca_warp.studies.validation.base import (
    EXPERIMENTS,
    Config,
    Experiment,
    Row,
    RowValue,
    _get,
    by_seed,
    ci,
    direction_verdict,
    interval,
    register_experiment,
    register_row,
    side,
    value_verdict,
)

PAPER_PEAK_HZ = 69.1e3  # Fig. 10: the largest STFT peak "around 69.1 kHz"
PAPER_PEAK_AMPLITUDE = 0.004  # Fig. 10: "normalized to the maximum amplitude of about 0.004"
PEAK_TOLERANCE = 0.05  # relative, as the §3.1 peaks read off the figures
AMPLITUDE_TOLERANCE = math.log(1.5)  # on ln(amplitude): within a factor 1.5 of "about 0.004"
PRIMARY_WINDOW = 2**12  # samples: the STFT window of the rows (4.1 ms at 1 µs; fits every variant's record)
LINE_BAND = (5.0e3, 200.0e3)  # Hz: the vibration lines, above μ's slow drift
TONALITY_BAND = (5.0e3, 150.0e3)  # Hz
FIRST_LINE_FRACTION = 0.25  # the first line: the lowest STFT peak reaching a quarter of the window's largest


# ------------------------------------------------------------------------------------------------ measures


def line_window(samples: int) -> int:
    """STFT window of the line tracks: the largest power of two ≤ 2^12 that gives at least 8 windows, ≥ 2^8."""
    w = PRIMARY_WINDOW
    while w > 256 and samples // w < 8:
        w //= 2
    return w


def line_tracks(t: np.ndarray, mu: np.ndarray, velocity: np.ndarray, dt: float) -> dict[str, Any]:
    """The dominant line of μ's STFT and the first line of Σu̇'s, in non-overlapping windows, and their trends
    of ln f over t/T.

    The dominant line: the largest bin of μ's STFT within :data:`LINE_BAND` per window. The first line: the
    lowest peak of the STFT of Σu̇ (the patches' summed velocity, whose first peak stands out, Fig. 8) reaching
    :data:`FIRST_LINE_FRACTION` of the window's largest in the band. Returns the window (samples), the window
    centres [s], both tracks [Hz], and per track the fitted slope of ln f against the fraction of the record
    (Δ ln f over it) with its 95 % interval (``line_trend``).
    """
    from aca_warp.analysis.measures import first_peak, line_trend, peak_track
    from aca_warp.analysis.timefreq import stft

    w = line_window(mu.size)
    times, freqs, amp, _ = stft(mu, dt, window_s=w * dt, hop_s=w * dt, detrend="linear")
    dominant, _ = peak_track(times, freqs, amp, band=LINE_BAND)
    _, _, vamp, _ = stft(velocity, dt, window_s=w * dt, hop_s=w * dt, detrend="linear")
    band = (freqs >= LINE_BAND[0]) & (freqs <= LINE_BAND[1])
    first = np.array(
        [first_peak(freqs[band], vamp[band, k], fraction=FIRST_LINE_FRACTION)[0] for k in range(times.size)]
    )
    span = float(t[-1] - t[0]) if t.size > 1 else 1.0
    frac = times / span
    out: dict[str, Any] = {"window_samples": w, "times": (t[0] + times).tolist()}
    for name, track in (("dominant", dominant), ("first", first)):
        out[f"{name}_hz"] = track.tolist()
        if times.size >= 3:
            lt = line_trend(frac, np.log(track))
            out[f"{name}_dlnf"] = lt.slope
            out[f"{name}_dlnf_ci"] = [lt.slope_low, lt.slope_high]
    return out


def thirds_tonality(mu: np.ndarray, dt: float) -> dict[str, list[float]]:
    """Per third of the record: ``tonality`` of μ's amplitude spectrum (linear trend removed) over
    :data:`TONALITY_BAND`, and the standard deviation of μ about its linear trend."""
    import scipy.signal

    from aca_warp.analysis.measures import tonality
    from aca_warp.analysis.spectra import amplitude_spectrum

    out: dict[str, list[float]] = {"peak_to_median": [], "flatness": [], "peak_hz": [], "std": []}
    for part in np.array_split(mu, 3):
        x = scipy.signal.detrend(part, type="linear")
        f, a = amplitude_spectrum(x, dt, normalise=None)
        tn = tonality(f, a, band=TONALITY_BAND)
        out["peak_to_median"].append(tn.peak_to_median)
        out["flatness"].append(tn.flatness)
        out["peak_hz"].append(tn.peak_frequency)
        out["std"].append(float(np.std(x)))
    return out


def predicted_line_change(scene: Any, t0: float, t1: float) -> float:
    """Δ ln f of the isolated-patch frequency (∝ A^(−1/4), f = √(K_T √A / (ρ_A A)) / 2π) between t0 and t1 [s]
    of the scene's growth (Eq. 10: √A grows by increment/2 per interval), mean over the patches."""
    g = scene.growth
    sq0 = np.sqrt(scene.patches.area)
    rate = 0.5 * g.increment / g.interval  # d√A/dt [m/s]
    return float(np.mean(-0.5 * np.log((sq0 + rate * t1) / (sq0 + rate * t0))))


def stft_floor(scene: Any) -> float:
    """Lowest frequency of the STFT maximum [Hz]: the paper's 10 Hz (Fig. 10) on its 0.36 s record, × the
    growth compression (μ's slow rise is compressed with the growth, the vibrations are not)."""
    return 10.0 * 0.36 / float(scene.duration)


def growth_measures(
    time: np.ndarray, mu: np.ndarray, velocity: np.ndarray, scene: Any, t_start: float
) -> dict[str, Any]:
    """Every §3.2 measure of one pad from μ(t) and Σu̇(t) (global outputs, uniform ``time`` [s]) after
    ``t_start`` [s] (module docstring)."""
    import scipy.stats

    from aca_warp.analysis.measures import stft_peaks

    keep = time >= t_start
    t, m = time[keep], mu[keep]
    dt = float((t[-1] - t[0]) / (t.size - 1))
    step = max(1, t.size // 20000)
    fit = scipy.stats.linregress(t[::step], m[::step])
    span = float(t[-1] - t[0])
    out: dict[str, Any] = {
        "analysed_s": span,
        "mu_rise": float(fit.slope * span),
        "mu_thirds": [float(np.mean(x)) for x in np.array_split(m, 3)],
        "mu_mean": float(np.mean(m)),
    }
    out["line"] = line_tracks(t, m, velocity[keep], dt)
    out["line"]["predicted_dlnf"] = predicted_line_change(scene, float(t[0]), float(t[-1]))
    floor = stft_floor(scene)
    out["stft_floor_hz"] = floor
    out["stft"] = [
        {"window": p.window, "samples": p.window_samples, "amplitude": p.amplitude, "frequency": p.frequency,
         "time": p.time}
        for p in stft_peaks(t, m, band=(floor, np.inf))
    ]  # fmt: skip
    out["tonality"] = thirds_tonality(m, dt)
    return out


def first_saturation(time: np.ndarray, sum_abs_velocity: np.ndarray, settle: float) -> dict[str, Any]:
    """The first saturation of a growing pad: ``saturation`` of Σ|u̇| over the first max(4·settle, T/5) of the
    record (window means). ``status`` "saturated" (a growth phase, then settled) or the detector's reason."""
    from aca_warp.analysis.saturation import saturation

    end = max(4.0 * settle, 0.2 * float(time[-1]))
    k = max(int(np.searchsorted(time, end)), min(time.size, 256))
    rs = saturation(time[:k], sum_abs_velocity[:k], statistic="mean", unit="m/s")
    out = {
        "t_s_sum_abs_velocity": rs.t_s,
        "growth_rate": rs.growth_rate,
        "growth_r2": rs.growth_r2,
        "growth_rise": rs.growth_rise,
        "verdict_sum_abs_velocity": rs.verdict,
        "first_part_s": float(time[k - 1]),
    }
    if not rs.saturated:
        out.update(status="not saturated", t_start=None)
    elif rs.growth_rate is None:
        out.update(status="no growth phase", t_start=None)
    else:
        out.update(status="saturated", t_start=rs.t_s)
    return out


def analyse_growth(
    scenes: list[Any], time: np.ndarray, glob: np.ndarray, plan: Any, cfg: Config
) -> tuple[list[dict[str, Any]], dict[str, np.ndarray], dict[str, Any]]:
    """Per pad of a growing batch: first saturation and :func:`growth_measures` (pads, arrays, segment)."""
    pads: list[dict[str, Any]] = []
    for p, s in enumerate(scenes):
        entry: dict[str, Any] = {"seed": s.initial.seed, "patches": s.patches.count}
        entry.update(first_saturation(time, glob[:, p, 4], plan.settle))
        if entry["status"] == "saturated":
            try:
                entry["measures"] = growth_measures(time, glob[:, p, 0], glob[:, p, 3], s, entry["t_start"])
            except (ValueError, FloatingPointError, IndexError) as e:  # reported, never silently used
                entry["status"] = f"analysis failed: {type(e).__name__}: {e}"
        pads.append(entry)
    starts = [p["t_start"] for p in pads if p.get("t_start") is not None]
    segment: dict[str, Any] = {"start_s": max(starts) if starts else None, "samples": time.size}
    segment["seconds"] = float(time[-1] - (max(starts) if starts else 0.0))
    return pads, {}, segment


# ------------------------------------------------------------------------------------------------ experiments


def va_description(speed: str) -> str:
    return f"varying area (Eq. 10): hf1 patches under the HF2 load, growth {speed}"


VA = "va"
VA_EXPERIMENTS = (
    Experiment(VA, "§3.2", va_description("× the configured speedup (0.36 s ÷ speedup)"), "varying_area",
               kind="growth"),
    Experiment("va_full", "§3.2", va_description("at the paper's clock (0.36 s)"), "varying_area", kind="growth",
               growth_speedup=1.0, quick=False, opt_in=True),
    Experiment("va_clock", "§3.2", va_description("3 × faster than va (growth-clock variant)"), "varying_area",
               kind="growth", growth_clock=3.0),
    Experiment("va_equal", "§3.2", "as va with every height 3 µm (preset varying_area_equal; height-spread variant)",
               "varying_area_equal", kind="growth", quick=False),
    Experiment("va_rest", "§3.2", "as va started from rest (the preset's and the single run's start)",
               "varying_area", kind="growth", initial="rest", quick=False),
)  # fmt: skip


# ------------------------------------------------------------------------------------------------ rows


def _stft_entry(pad: dict[str, Any], samples: int) -> dict[str, Any] | None:
    """The STFT maximum of the window of ``samples`` (or of the variant's window, ``stft_window``)."""
    samples = int(pad.get("stft_window", samples))
    return next((w for w in pad["measures"].get("stft", []) if w["samples"] == samples), None)


def _stft_values(res: dict[str, Any] | None, key: str) -> tuple[np.ndarray, str]:
    vals = by_seed(res, lambda p: (_stft_entry(p, PRIMARY_WINDOW) or {})[key])
    windows = {(_stft_entry(p, PRIMARY_WINDOW) or {}).get("window") for p in (res or {}).get("pads", [])} - {None}
    return np.array(list(vals.values())), "; ".join(sorted(windows))


def rise_row(results: dict[str, dict], cfg: Config) -> RowValue:
    res = results.get(VA)
    d = np.array(list(by_seed(res, lambda p: _get(p, "mu_rise")).values()))
    thirds = np.array(list(by_seed(res, lambda p: p["measures"]["mu_thirds"][2] - p["measures"]["mu_thirds"][0])
                           .values()))  # fmt: skip
    means = [interval(np.array(list(by_seed(res, lambda p, i=i: p["measures"]["mu_thirds"][i]).values())), ".4f")
             for i in range(3)]  # fmt: skip
    return RowValue(
        f"Δμ over the analysed record (slope × length): {interval(d, '.3g')}",
        direction_verdict([side(d)], [side(thirds)]),
        f"mean μ by thirds {' → '.join(means)}; last − first third {interval(thirds)}",
    )


def line_row(results: dict[str, dict], cfg: Config) -> RowValue:
    res = results.get(VA)
    dom = np.array(list(by_seed(res, lambda p: _get(p, "line.dominant_dlnf")).values()))
    first = np.array(list(by_seed(res, lambda p: _get(p, "line.first_dlnf")).values()))
    pred = np.array(list(by_seed(res, lambda p: _get(p, "line.predicted_dlnf")).values()))
    falling = [
        sum(
            1
            for p in (res or {}).get("pads", [])
            if (p.get("measures") or {}).get("line", {}).get(f"{k}_dlnf_ci", [0, 0])[1] < 0
        )  # fmt: skip
        for k in ("dominant", "first")
    ]
    win = {p["measures"]["line"]["window_samples"] for p in (res or {}).get("pads", []) if "measures" in p}
    return RowValue(
        f"Δ ln f of the dominant line over the record: {interval(dom)}",
        direction_verdict([side(dom, -1.0)], [side(first, -1.0)]),
        f"first line (lowest peak ≥ {FIRST_LINE_FRACTION:g} of the window's largest): {interval(first)}; "
        f"isolated-patch prediction −½ ln(√A(T)/√A(t_s)): {interval(pred)}; pads whose own 95 % interval of the "
        f"slope lies below 0: dominant {falling[0]}, first {falling[1]}; STFT of "
        f"{', '.join(str(w) for w in sorted(win))} samples, no overlap, ≥ {LINE_BAND[0] / 1e3:g} kHz",
    )


def peak_frequency_row(results: dict[str, dict], cfg: Config) -> RowValue:
    res = results.get(VA)
    f, window = _stft_values(res, "frequency")
    a, _ = _stft_values(res, "amplitude")
    return RowValue(
        interval(f, ".1f", 1e-3, "kHz"),
        value_verdict(f, PAPER_PEAK_HZ, PEAK_TOLERANCE * PAPER_PEAK_HZ),
        f"{window}; its amplitude {interval(a)}; every window: {stft_summary(res)}",
    )


def peak_amplitude_row(results: dict[str, dict], cfg: Config) -> RowValue:
    res = results.get(VA)
    a, window = _stft_values(res, "amplitude")
    la = np.log(a[a > 0]) if a.size else a
    m, lo, hi = ci(la)
    ratio = "–"
    if math.isfinite(m):
        ratio = f"{math.exp(m):.3g} = exp(mean ln a), {math.exp(m) / PAPER_PEAK_AMPLITUDE:.3g} × the paper's"
    return RowValue(
        interval(a, ".3g"),
        value_verdict(la, math.log(PAPER_PEAK_AMPLITUDE), AMPLITUDE_TOLERANCE),
        f"{window}; amplitude of μ/μ̄ (μ̄ the analysed record's mean), one-sided; geometric mean {ratio}",
    )


def stft_summary(res: dict[str, Any] | None) -> str:
    """Per window that fits: the mean STFT maximum and its frequency over the pads."""
    per: dict[int, list[tuple[float, float]]] = {}
    for p in (res or {}).get("pads", []):
        for w in (p.get("measures") or {}).get("stft", []):
            per.setdefault(w["samples"], []).append((w["amplitude"], w["frequency"]))
    parts = []
    for n, v in sorted(per.items()):
        a, f = np.array(v).T
        parts.append(f"2^{int(round(math.log2(n)))}: {np.mean(a):.3g} at {np.mean(f) / 1e3:.1f} kHz")
    return ", ".join(parts) or "–"


def transition_row(results: dict[str, dict], cfg: Config) -> RowValue:
    res = results.get(VA)

    def late_minus_early(key: str, log: bool = False) -> np.ndarray:
        def d(p: dict[str, Any]) -> float:
            v = p["measures"]["tonality"][key]
            return math.log(v[2] / v[0]) if log else v[2] - v[0]

        return np.array(list(by_seed(res, d).values()))

    ptm, flat, std = late_minus_early("peak_to_median"), late_minus_early("flatness"), late_minus_early("std", True)
    return RowValue(
        f"Δ ln(peak/median) of μ's spectrum, last − first third: {interval(ptm)}",
        direction_verdict([side(ptm)], [side(flat, -1.0)]),
        f"{TONALITY_BAND[0] / 1e3:g}–{TONALITY_BAND[1] / 1e3:g} kHz; Δ spectral flatness (< 0: more periodic) "
        f"{interval(flat)}; ln(std μ last / first third) {interval(std)}",
    )


VA_ROWS = (
    Row("§3.2, Figs. 10/11", "μ rises as the load moves from the matrix to the growing patches", "rising μ",
        "direction", (VA,), rise_row, "Δμ > 0"),
    Row("§3.2, Figs. 10/11", "the frequencies of the characteristic peaks fall as the patches grow",
        "decreasing frequencies", "direction", (VA,), line_row, "Δ ln f < 0"),
    Row("§3.2, Fig. 10", "largest STFT peak of μ", "≈ 69.1 kHz", "value", (VA,), peak_frequency_row,
        f"± {100 * PEAK_TOLERANCE:g} %", uses=("stft",)),
    Row("§3.2, Fig. 10", "its amplitude, normalised to mean μ (one-sided)", "≈ 0.004", "value", (VA,),
        peak_amplitude_row, "within a factor 1.5 (on ln a)", uses=("stft",)),
    Row("§3.2", "the friction spectrum goes from stochastic (broad band) to periodic (dominant lines)",
        "stochastic → periodic", "direction", (VA,), transition_row, "Δ ln(peak/median) > 0"),
)  # fmt: skip


def register() -> None:
    """Register the §3.2 experiment ``va`` and the rows (once)."""
    if VA in EXPERIMENTS:
        return
    register_experiment(VA_EXPERIMENTS[0])
    for row in VA_ROWS:
        register_row(row)


def register_variants() -> None:
    """Register the §3.2 variant experiments (growth clock, height spread, initial state)."""
    for exp in VA_EXPERIMENTS[1:]:
        register_experiment(exp)


# ------------------------------------------------------------------------------------------------ page


def full_view(results: dict[str, dict]) -> tuple[dict[str, dict], dict[str, str]]:
    """The results the §3.2 rows read: ``va_full`` in place of ``va`` when it has two usable pads (the compressed
    ``va`` then stays as the variant ``va_compressed``), and the names to show for the experiments read."""
    from aca_warp.studies.validation.base import usable

    if len(usable(results.get("va_full"))) < 2:
        return results, {}
    view = {**results, VA: results["va_full"]}
    if VA in results:
        view["va_compressed"] = results[VA]
    return view, {VA: "va_full"}


def growth_table(results: dict[str, dict]) -> tuple[list[str], list[list[str]]]:
    """One line per growth experiment: growth compression, analysed length, μ by thirds, the line trends, the STFT
    maximum (2^12 samples) and the tonality and spread of μ in the first and the last third (means over pads)."""
    header = ["experiment", "run", "mean μ by thirds", "Δ ln f: dominant / first line / isolated patch",
              "STFT max (2^12): μ/μ̄ at f", "ln(peak/median) first → last third",
              "std μ first → last third"]  # fmt: skip
    rows = []
    for name, exp in EXPERIMENTS.items():
        res = results.get(name)
        if exp.kind != "growth" or not res or "plan" not in res:
            continue
        pads = [p for p in res.get("pads", []) if "measures" in p]
        if not pads:
            rows.append([name, res.get("status", "–"), *["–"] * 5])
            continue

        def mean(f: Any, pads: list[dict[str, Any]] = pads) -> float:
            vals = [f(p["measures"]) for p in pads]
            vals = [v for v in vals if v is not None and np.isfinite(v)]
            return float(np.mean(vals)) if vals else float("nan")

        def stft(m: dict[str, Any], key: str) -> float | None:
            w = next((w for w in m.get("stft", []) if w["samples"] == PRIMARY_WINDOW), None)
            return None if w is None else w[key]

        tn = lambda k, i: mean(lambda m: m["tonality"][k][i])  # noqa: E731
        rows.append(
            [
                name,
                f"{res['plan']['duration_s'] * 1e3:.1f} ms, analysed {mean(lambda m: m['analysed_s']) * 1e3:.1f} ms "
                f"({len(pads)} pads)",
                " → ".join(f"{mean(lambda m, i=i: m['mu_thirds'][i]):.4f}" for i in range(3)),
                " / ".join(
                    f"{mean(lambda m, k=k: m['line'].get(k)):.3f}"
                    for k in ("dominant_dlnf", "first_dlnf", "predicted_dlnf")
                ),
                f"{mean(lambda m: stft(m, 'amplitude')):.3g} at {mean(lambda m: stft(m, 'frequency')) / 1e3:.1f} kHz",
                f"{tn('peak_to_median', 0):.2f} → {tn('peak_to_median', 2):.2f}",
                f"{tn('std', 0):.3g} → {tn('std', 2):.3g}",
            ]
        )
    return header, rows
