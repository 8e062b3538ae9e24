"""Validation of §3.2 (stand-alone HF with varying patch area, Eq. 10, Figs. 10–11) from seed ensembles: the
experiments and the measures of a growing pad (the rows are in :mod:`~aca_warp.studies.validation.area_rows`).

The ``varying_area`` preset — HF1-size patches under the HF2 load, areas growing by Eq. 10 until HF2 size — runs
as a batch of pads that differ in their seed (layout, areas, heights, initial perturbation), like the §3.1
experiments. ``va_full`` runs the **paper's growth rate** over its 0.36 s (uncompressed; the areas grown in events
every 5 µs of the ``growth`` stepping, each adding its spacing's growth: docs/model.md §2.10), from equilibrium +
the seeded perturbation, and ``va_full_rest`` the same from rest, in one batch; the rows read ``va_full``, with the
from-rest pads beside. ``va`` runs the same area path **compressed** (the increment of Eq. 10 × s and the run ÷ s,
s = ``Config.growth_speedup``: 10 on the GPU, 20 in the quick variant) with its variants ``va_equal`` (every height
3 µm) and ``va_rest`` (from rest). Only the global outputs are recorded (every ``sample_dt``); every measure comes
from μ(t) and Σu̇(t) of each pad (:func:`growth_measures`) over the record after its first saturation:

* **rise of μ**: the least-squares slope of μ(t) times the analysed length (Δμ over the growth), the mean μ and the
  standard deviation of its HF part (μ less its 1 ms moving mean) beside it;
* **the falling line**: STFTs in non-overlapping windows; per window the frequency of the lowest peak of Σu̇'s
  reaching a quarter of its largest (the **first line**: the primary, since the dominant line of μ hops between
  harmonics) and of the largest bin of μ's above 5 kHz (the dominant line); ``line_trend`` of ln f against the
  record's fraction t/T: Δ ln f over the record, beside the isolated-patch prediction −½ ln(√A(T)/√A(t_s));
* **the largest STFT peak**: ``stft_peaks`` of μ over windows of 2^12 … 2^17 samples (those that fit), above
  10 Hz × the growth compression (the paper truncates at 10 Hz; μ's slow rise is compressed with the growth),
  divided by the record's mean μ, one-sided (Fig. 10's normalisation), with the mean kept so that the other
  conventions follow;
* **stochastic → periodic**: the amplitude spectrum of μ over the first and the last third of the analysed
  record, its ``tonality`` over 5–150 kHz: ln(peak / median) and the spectral flatness, late − early;
* **the CWT of μ** (Fig. 11): the complex Morlet transform of μ (linear trend removed) on
  :data:`CWT_FREQUENCIES`, its amplitude averaged over the line tracks' windows; per window the frequency of each
  line of :data:`CWT_LINES` (the primary the **ridge**, the largest value of the energy-normalised CWT, whose noise
  floor is as flat as a spectrum's, within §4's characteristic band of 20–80 kHz: the counterpart of μ's largest STFT
  bin there; beside it the largest value and the first line over the whole band, energy-normalised and
  amplitude-true) with its trend of ln f over t/T and the trend's R², and
  ln(peak / median) of the energy-normalised amplitude averaged over each third of the record
  (:func:`cwt_measures`, read by :func:`cwt_lines` and :func:`cwt_peak_to_median`);
* **the load on the patches**: the contact solved for the areas of Eq. 10 at the end of the run (the share of the
  load the matrix carries, the patches in contact, the mean area) beside the start's, and the matrix's share at
  :data:`CONTACT_INSTANTS` instants evenly over the run (:func:`growth_contact`).

The first saturation is found by ``saturation`` on Σ|u̇| over the first part of the record (four times the
predicted settling time at the starting areas, at least a fifth of the record); a pad released from rest counts
once Σ|u̇| has settled, without a growth phase (its patches start near their saturated amplitude); a pad without it
is listed and not used.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aca_warp.studies.validation.base import (
    CHARACTERISTIC_BAND,
    EXPERIMENTS,
    Config,
    Experiment,
    register_experiment,
)

PRIMARY_WINDOW = 2**12  # samples: the STFT window of the rows (4.1 ms at 1 µs; fits every variant's record)
HF_SMOOTH_S = 1.0e-3  # s: μ less its moving mean over this is μ's HF part (above ~1 kHz)
LINE_BAND = (5.0e3, 200.0e3)  # Hz: the vibration lines, above μ's slow drift
TONALITY_BAND = (5.0e3, 150.0e3)  # Hz
FIRST_LINE_FRACTION = 0.25  # the first line: the lowest STFT peak reaching a quarter of the window's largest
CWT_FREQUENCIES = np.geomspace(LINE_BAND[0], LINE_BAND[1], 48)  # Hz: the CWT's analysis frequencies, 8 % apart
CWT_STRIDE_S = 8.0e-6  # s: the CWT's output spacing (its envelope at 200 kHz varies over σ_t ≈ 4 µs)
# the lines read off μ's CWT, block by block (the convention is open: Fig. 11 names neither normalisation nor line):
# name -> (normalisation, fraction of the block's largest the line's peak must reach, the lowest such peak; the band
# searched [Hz]). "L2" is
# the energy-normalised CWT, |W| / √f, flat for white noise as an amplitude spectrum is (a line's maximum sits ≈ 1.3 %
# below its frequency there, a constant factor that leaves Δ ln f alone); "L1" the amplitude-true |W|, which white
# noise makes rise as √f.
CWT_LINES = {
    # the primary: the ridge within §4's characteristic band (20–80 kHz), on a noise floor as flat as the STFT's;
    # over the whole band the ridges leave the lines: the energy-normalised one hops down to μ's slow fluctuations
    # (below 12 kHz) in part of the windows, the amplitude-true one lies in the broadband top (120–170 kHz)
    "band": ("L2", 1.0, CHARACTERISTIC_BAND),
    "largest": ("L2", 1.0, LINE_BAND),
    "first": ("L2", 0.25, LINE_BAND),  # the rule of Σu̇'s STFT line (μ's slow fluctuations reach it early on)
    "largest_l1": ("L1", 1.0, LINE_BAND),
    "first_l1": ("L1", 0.25, LINE_BAND),
}
CONTACT_INSTANTS = 37  # the matrix share's instants over a run (every 10 ms of the paper's 0.36 s)


# ------------------------------------------------------------------------------------------------ measures


def line_window(samples: int) -> int:
    """STFT window of the line tracks: the largest power of two ≤ 2^12 that gives at least 8 windows, ≥ 2^8."""
    w = PRIMARY_WINDOW
    while w > 256 and samples // w < 8:
        w //= 2
    return w


def line_tracks(t: np.ndarray, mu: np.ndarray, velocity: np.ndarray, dt: float) -> dict[str, Any]:
    """The dominant line of μ's STFT and the first lines of Σu̇'s and of μ's, in non-overlapping windows, and their
    trends of ln f over t/T.

    The dominant line: the largest bin of μ's STFT within :data:`LINE_BAND` per window. The first line: the
    lowest peak of the STFT of Σu̇ (the patches' summed velocity, whose first peak stands out, Fig. 8) reaching
    :data:`FIRST_LINE_FRACTION` of the window's largest in the band; ``mu_first`` the same rule on μ's STFT (the
    counterpart of the CWT's first line); ``mu_band`` μ's largest bin within §4's band (20–80 kHz, the CWT
    ridge's counterpart). Returns the window (samples), the window centres [s], the four tracks [Hz], and per
    track the fitted slope of ln f against the fraction of the record (Δ ln f over it) with its 95 % interval and
    the fit's R² (``line_trend``).
    """
    from aca_warp.analysis.measures import first_peak, line_trend, peak_track
    from aca_warp.analysis.timefreq import stft

    w = line_window(mu.size)
    times, freqs, amp, _ = stft(mu, dt, window_s=w * dt, hop_s=w * dt, detrend="linear")
    dominant, _ = peak_track(times, freqs, amp, band=LINE_BAND)
    in_band, _ = peak_track(times, freqs, amp, band=CHARACTERISTIC_BAND)
    _, _, vamp, _ = stft(velocity, dt, window_s=w * dt, hop_s=w * dt, detrend="linear")
    band = (freqs >= LINE_BAND[0]) & (freqs <= LINE_BAND[1])
    first = np.array(
        [first_peak(freqs[band], vamp[band, k], fraction=FIRST_LINE_FRACTION)[0] for k in range(times.size)]
    )
    mu_first = np.array(
        [first_peak(freqs[band], amp[band, k], fraction=FIRST_LINE_FRACTION)[0] for k in range(times.size)]
    )
    span = float(t[-1] - t[0]) if t.size > 1 else 1.0
    frac = times / span
    out: dict[str, Any] = {"window_samples": w, "times": (t[0] + times).tolist()}
    for name, track in (("dominant", dominant), ("first", first), ("mu_first", mu_first), ("mu_band", in_band)):
        out[f"{name}_hz"] = track.tolist()
        if times.size >= 3:
            lt = line_trend(frac, np.log(track))
            out[f"{name}_dlnf"] = lt.slope
            out[f"{name}_dlnf_ci"] = [lt.slope_low, lt.slope_high]
            out[f"{name}_r2"] = lt.r2
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


def cwt_measures(mu: np.ndarray, dt: float, window: int, t0: float = 0.0) -> dict[str, Any]:
    """The CWT of μ (Fig. 11): complex Morlet ``cmor1.5-1.0`` (``cwt_morlet``, amplitude-true) of μ less its linear
    trend on :data:`CWT_FREQUENCIES`, output every :data:`CWT_STRIDE_S`, averaged over consecutive blocks of
    ``window`` samples (the line tracks' STFT windows) and over each third of the record.

    Returns the record's first and last instants (``record_s``, ``t0`` [s] the first), the block centres [s], the
    frequencies [Hz], and the amplitude-true means (``amplitude``, shape (F, blocks), and ``thirds``, (F, 3); four
    significant digits) that :func:`cwt_lines` and :func:`cwt_peak_to_median` read. The record's ends lie within
    the wavelets' reach (≈ 0.35 ms at 5 kHz): zero-padded there.
    """
    import scipy.signal

    from aca_warp.analysis.timefreq import cwt_morlet

    stride = max(1, int(round(CWT_STRIDE_S / dt)))
    x = scipy.signal.detrend(np.asarray(mu, dtype=np.float64), type="linear")
    _, freqs, amp, _ = cwt_morlet(x, dt, CWT_FREQUENCIES, stride=stride)
    per = max(1, window // stride)
    blocks = amp.shape[1] // per
    if blocks < 3:
        raise ValueError(f"cwt_measures: {amp.shape[1]} outputs give {blocks} blocks of {per}, at least 3 needed")
    mean = amp[:, : blocks * per].reshape(freqs.size, blocks, per).mean(axis=2)
    thirds = np.stack([part.mean(axis=1) for part in np.array_split(amp, 3, axis=1)], axis=1)
    return {
        "record_s": [t0, t0 + float(x.size - 1) * dt],
        "times": (t0 + (np.arange(blocks) + 0.5) * per * stride * dt).tolist(),
        "freqs_hz": freqs.tolist(),
        "amplitude": _digits(mean),
        "thirds": _digits(thirds),
    }


def _digits(a: np.ndarray) -> list[list[float]]:
    return [[float(f"{v:.4g}") for v in row] for row in a]


def l2_weight(freqs: np.ndarray) -> np.ndarray:
    """(f₀/f)^½: the amplitude-true CWT times this is the energy-normalised one (flat for white noise), (F,)."""
    return (freqs[0] / freqs) ** 0.5


def _weighted(cwt: dict[str, Any], key: str, norm: str) -> tuple[np.ndarray, np.ndarray]:
    freqs, a = np.asarray(cwt["freqs_hz"]), np.asarray(cwt[key], dtype=np.float64)
    return freqs, a * l2_weight(freqs)[:, None] if norm == "L2" else a


def cwt_lines(cwt: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Every line of :data:`CWT_LINES` read off a pad's stored CWT (:func:`cwt_measures`): per block its frequency
    (:func:`_line_peak`) [Hz], and its trend of ln f over the record's fraction (``line_trend``: Δ ln f over the
    record, its 95 % interval, R²)."""
    from aca_warp.analysis.measures import line_trend

    t0, t1 = cwt["record_s"]
    frac = (np.asarray(cwt["times"]) - t0) / (t1 - t0)
    out = {}
    for name, (norm, fraction, band) in CWT_LINES.items():
        freqs, a = _weighted(cwt, "amplitude", norm)
        keep = (freqs >= band[0]) & (freqs <= band[1])
        track = _line_peaks(freqs[keep], a[keep], fraction)
        lt = line_trend(frac, np.log(track))
        out[name] = {"hz": track, "dlnf": lt.slope, "dlnf_ci": [lt.slope_low, lt.slope_high], "r2": lt.r2}
    return out


def cwt_peak_to_median(cwt: dict[str, Any], norm: str = "L2") -> list[float]:
    """Per third of the record, ln(peak / median) of the CWT's mean amplitude within :data:`TONALITY_BAND` (as
    ``tonality`` gives it for a spectrum), energy-normalised ("L2", flat for white noise as a spectrum is) or
    amplitude-true ("L1")."""
    freqs, a = _weighted(cwt, "thirds", norm)
    band = (freqs >= TONALITY_BAND[0]) & (freqs <= TONALITY_BAND[1])
    return [float(np.log(a[band, k].max() / np.median(a[band, k]))) for k in range(a.shape[1])]


def _line_peaks(freqs: np.ndarray, a: np.ndarray, fraction: float) -> np.ndarray:
    """The line of every block (column of ``a``, shape (F, K)) over log-spaced ``freqs`` [Hz], shape (K,): the
    lowest interior local maximum reaching ``fraction`` of the block's largest value (a band edge is where the band
    is cut, not a peak), or the largest value when none does (``fraction`` 1: always); Gaussian-interpolated in
    ln f through its neighbours where the three values are positive and the parabola opens downwards."""
    cols = np.arange(a.shape[1])
    lo = a >= fraction * a.max(axis=0)
    interior = (a[1:-1] >= a[:-2]) & (a[1:-1] >= a[2:]) & lo[1:-1]
    k = np.argmax(a, axis=0)
    if fraction < 1.0 and interior.size:  # (fewer than three frequencies: no interior, the largest value)
        k = np.where(interior.any(axis=0), np.argmax(interior, axis=0) + 1, k)
    x = np.log(freqs)
    inside = (k > 0) & (k < a.shape[0] - 1)
    km, kp = np.clip(k - 1, 0, None), np.clip(k + 1, None, a.shape[0] - 1)
    am, ak, ap = a[km, cols], a[k, cols], a[kp, cols]
    fit = inside & (am > 0) & (ak > 0) & (ap > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        la, lb, lc = np.log(am), np.log(ak), np.log(ap)
        den = la - 2.0 * lb + lc
        fit &= den < 0
        peak = np.exp(x[k] + 0.5 * (la - lc) / den * (x[kp] - x[k]))
    return np.where(fit, peak, freqs[k])


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
    k = max(1, int(round(HF_SMOOTH_S / dt)))
    hf = m - np.convolve(m, np.ones(k) / k, mode="same")
    out: dict[str, Any] = {
        "analysed_s": span,
        "mu_rise": float(fit.slope * span),
        "mu_thirds": [float(np.mean(x)) for x in np.array_split(m, 3)],
        "mu_mean": float(np.mean(m)),
        "mu_hf_std": float(np.std(hf[k:-k])) if hf.size > 2 * k else float(np.std(hf)),
    }
    out["line"] = line_tracks(t, m, velocity[keep], dt)
    out["line"]["predicted_dlnf"] = predicted_line_change(scene, float(t[0]), float(t[-1]))
    floor = stft_floor(scene)
    out["stft_floor_hz"] = floor
    out["stft"] = [
        {"window": p.window, "samples": p.window_samples, "amplitude": p.amplitude, "frequency": p.frequency,
         "time": p.time, "mean": p.mean}
        for p in stft_peaks(t, m, band=(floor, np.inf))
    ]  # fmt: skip
    out["tonality"] = thirds_tonality(m, dt)
    out["cwt"] = cwt_measures(m, dt, out["line"]["window_samples"], float(t[0]))
    return out


def first_saturation(
    time: np.ndarray, sum_abs_velocity: np.ndarray, settle: float, from_rest: bool = False
) -> dict[str, Any]:
    """The first saturation of a growing pad: ``saturation`` of Σ|u̇| over the first max(4·settle, T/5) of the
    record (window means). ``status`` "saturated" (a growth phase, then settled; a pad ``from_rest`` without one)
    or the detector's reason."""
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
    elif rs.growth_rate is None and not from_rest:
        out.update(status="no growth phase", t_start=None)
    else:
        out.update(status="saturated", t_start=rs.t_s)
    return out


def grown_area(scene: Any, t: float) -> np.ndarray:
    """The patch areas of Eq. 10 at ``t`` [s] of a growing scene (√A grows by increment/2 per event) [m²], (n,)."""
    g = scene.growth
    return (np.sqrt(scene.patches.area) + 0.5 * g.increment * np.floor(t / g.interval + 1e-9)) ** 2


def contact_at(scene: Any, t: float) -> dict[str, Any]:
    """The contact of a growing pad with the areas of Eq. 10 at ``t`` [s] (:func:`grown_area`; the matrix cells as
    they are, as the run re-solves it): the matrix's share of the load (``matrix_share``), the share of the patches
    in contact (``in_contact``), and the mean and extreme areas [m²] (``mean_area_m2``, ``area_range_m2``)."""
    from aca_warp.hf.contact import solve_scene_contact

    area = grown_area(scene, t)
    c = solve_scene_contact(scene, area=area)
    return {
        "matrix_share": float(c.matrix_force.sum() / scene.normal_force),
        "in_contact": float(np.mean(c.patch_force > 0)),
        "mean_area_m2": float(area.mean()),
        "area_range_m2": [float(area.min()), float(area.max())],
    }


def growth_contact(scene: Any, duration: float, instants: int = CONTACT_INSTANTS) -> dict[str, Any]:
    """The contact of a growing pad over [0, ``duration``] [s], solved once at each of ``instants`` times evenly
    over it (:func:`contact_at`): its end as ``end_matrix_share``, ``end_in_contact``, ``end_mean_area_m2`` and
    ``end_area_range_m2``, and ``contact_track``, the matrix's share at every instant (``times_s``,
    ``matrix_share``)."""
    if instants < 2:
        raise ValueError(f"the contact track needs at least 2 instants (its start and its end), got {instants}")
    times = np.linspace(0.0, duration, instants)
    at = [contact_at(scene, t) for t in times]
    track = {"times_s": times.tolist(), "matrix_share": [a["matrix_share"] for a in at]}
    return {**{f"end_{k}": v for k, v in at[-1].items()}, "contact_track": track}


def analyse_growth(
    scenes: list[Any], time: np.ndarray, glob: np.ndarray, plan: Any, cfg: Config
) -> tuple[list[dict[str, Any]], dict[str, np.ndarray], dict[str, Any]]:
    """Per pad of a growing batch: first saturation and :func:`growth_measures` (pads, arrays, segment)."""
    pads: list[dict[str, Any]] = []
    for p, s in enumerate(scenes):
        entry: dict[str, Any] = {"seed": s.initial.seed, "patches": s.patches.count}
        entry.update(first_saturation(time, glob[:, p, 4], plan.settle, s.initial.state == "rest"))
        entry.update(growth_contact(s, plan.duration))
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


VA = "va_full"
VA_EXPERIMENTS = (
    Experiment(VA, "§3.2", va_description("at the paper's clock (0.36 s)"), "varying_area", kind="growth",
               growth_speedup=1.0, batch="va_full", stepping="growth"),
    Experiment("va_full_rest", "§3.2", va_description("at the paper's clock, from rest"), "varying_area",
               kind="growth", initial="rest", growth_speedup=1.0, batch="va_full", stepping="growth"),
    Experiment("va", "§3.2", va_description("compressed × the configured speedup (growth-clock variant)"),
               "varying_area", kind="growth", batch="va", stepping="growth"),
    Experiment("va_equal", "§3.2", "as va with every height 3 µm (preset varying_area_equal; height-spread variant)",
               "varying_area_equal", kind="growth", quick=False, batch="va", stepping="growth"),
    Experiment("va_rest", "§3.2", "as va started from rest", "varying_area", kind="growth", initial="rest",
               quick=False, batch="va", stepping="growth"),
)  # fmt: skip


def register() -> None:
    """Register the §3.2 experiments of the rows (``va_full``, ``va_full_rest``; once)."""
    if VA in EXPERIMENTS:
        return
    for exp in VA_EXPERIMENTS[:2]:
        register_experiment(exp)


def register_variants() -> None:
    """Register the compressed §3.2 variants (growth clock, height spread, initial state)."""
    for exp in VA_EXPERIMENTS[2:]:
        register_experiment(exp)


# ------------------------------------------------------------------------------------------------ page


def growth_table(results: dict[str, dict]) -> tuple[list[str], list[list[str]]]:
    """One line per growth experiment: growth compression, analysed length, μ by thirds, the line trends, the STFT
    maximum (2^12 samples) and the tonality and spread of μ in the first and the last third (means over pads)."""
    header = ["experiment", "run", "mean μ by thirds",
              "Δ ln f: first line / dominant / CWT ridge in 20–80 kHz / isolated patch", "STFT max (2^12): μ/μ̄ at f",
              "ln(peak/median) first → last third",
              "std μ first → last third", "matrix share of the load: start → end"]  # fmt: skip
    rows = []
    for name, exp in EXPERIMENTS.items():
        res = results.get(name)
        if exp.kind != "growth" or not res or "plan" not in res:
            continue
        pads = [p for p in res.get("pads", []) if "measures" in p]
        if not pads:
            rows.append([name, res.get("status", "–"), *["–"] * 6])
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
                " / ".join(f"{mean(lambda m, k=k: m['line'].get(k)):.3f}" for k in ("first_dlnf", "dominant_dlnf"))
                + f" / {mean(lambda m: cwt_lines(m['cwt'])['band']['dlnf'] if 'cwt' in m else None):.3f}"
                + f" / {mean(lambda m: m['line'].get('predicted_dlnf')):.3f}",
                f"{mean(lambda m: stft(m, 'amplitude')):.3g} at {mean(lambda m: stft(m, 'frequency')) / 1e3:.1f} kHz",
                f"{tn('peak_to_median', 0):.2f} → {tn('peak_to_median', 2):.2f}",
                f"{tn('std', 0):.3g} → {tn('std', 2):.3g}",
                f"{np.mean([p['matrix_share'] for p in pads]):.3f} → "
                f"{np.mean([p['end_matrix_share'] for p in pads]):.3f}",
            ]
        )
    return header, rows
