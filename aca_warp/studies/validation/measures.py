"""The measures of one pad (stage 5 of :mod:`aca_warp.studies.validation`): from its global outputs over its own
saturated span (the quantities of Fig. 8: the spectra of μ, torque, friction radius and the velocity sum Σu̇, and
μ's STFT of Fig. 10) and from its per-patch velocities over the experiment's common window (S(f) of Fig. 9 and the
spatial patterns of Figs. 4/6, :mod:`~aca_warp.studies.validation.sync_measures`).

**The first velocity peak** (§3.1: "the first peak of each velocity spectrum ... around 73 kHz for HF₁ and HF₃,
and around 32.8 kHz for HF₂ and HF₄"). Fig. 8's velocity spectrum is read as that of the *velocity sum* Σu̇ (the
paper does not name its signal; for Figs. 5/7 "an impression of the patches' motions is given through the sum of all
patch velocities", and a sum of absolute values would put a patch's line at twice its frequency), so the primary f1
is read there: the largest
peak of Σu̇'s Welch-averaged amplitude spectrum (:func:`~aca_warp.analysis.measures.averaged_spectrum`, segments of
a quarter of the span) above 3 bins — the first peak of Fig. 8 is its most pronounced one, and the average lets it
stand out of a single chaotic periodogram's scatter. Beside it (the candidates the paper leaves open): the first
peak of the same spectrum reaching half its largest, the largest peak of the single Hann periodogram, the first
peak of the mean *per-patch* velocity spectrum at thresholds of 0.02 … 0.25 of its maximum, and the same two
readings of the averaged spectrum of the *sum of the absolute velocities* Σ|u̇| (the other reading of §3.1's "the
total of all absolute velocities in reference to the stationary brake pad", whose mean, unlike Σu̇'s, is the DC
offset Fig. 8 normalises by): its largest peak and its first peak reaching half of it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aca_warp.studies.validation.base import CHARACTERISTIC_BAND, Config

PATCH_FRACTIONS = (0.02, 0.05, 0.1, 0.25)  # the per-patch first peak: lowest peak reaching this share of the maximum
SUM_SEGMENTS = 4  # Welch segments of a quarter of the span for Σu̇'s spectrum
COHERENCE_SEGMENTS = 8  # segments of Σu̇–μ coherence


def global_spectra(seg: np.ndarray, sample_dt: float) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Hann amplitude spectra of one pad's global outputs over a segment (N, ≥ 5), all dimensionless.

    μ, torque, friction radius and Σ|u̇| divided by their mean (paper Fig. 8); the "velocity" spectrum is Σu̇ (the
    patches' velocities in the pad frame) divided by the mean of Σ|u̇|, since Σu̇ itself has zero mean.
    """
    from aca_warp.analysis.spectra import amplitude_spectrum

    freq, amp = amplitude_spectrum(seg[:, [0, 1, 2, 4]], sample_dt, normalise="mean", axis=0)
    _, v = amplitude_spectrum(seg[:, 3], sample_dt, normalise=None)
    out = {"mu": amp[:, 0], "torque": amp[:, 1], "friction_radius": amp[:, 2], "abs_velocity": amp[:, 3]}
    out["velocity"] = v / abs(float(np.mean(seg[:, 4])))
    return freq, out


def _averaged_peaks(x: np.ndarray, sample_dt: float, fmin: float) -> tuple[float, float, float, float]:
    """(largest peak [Hz], its amplitude, first peak reaching half of it [Hz], resolution [Hz]) of the averaged
    amplitude spectrum of ``x`` (N,) above ``fmin`` [Hz] and 3 of its bins."""
    from aca_warp.analysis.measures import averaged_spectrum, first_peak
    from aca_warp.analysis.spectra import peak

    freq, amp = averaged_spectrum(x, sample_dt, segments=SUM_SEGMENTS)
    df = float(freq[1] - freq[0])
    lo = max(fmin, 3.0 * df)
    f, a = peak(freq, amp, fmin=lo)
    half, _ = first_peak(freq, amp, fraction=0.5, fmin=lo)
    return f, a, half, df


def velocity_sum_peaks(seg: np.ndarray, sample_dt: float, fmin: float) -> dict[str, Any]:
    """The first velocity peak (module docstring) from Σu̇: ``f1`` (the primary: largest peak of the averaged
    spectrum above ``fmin`` [Hz] and 3 of its bins), ``f1_first_half`` (its first peak reaching half the largest),
    ``f1_periodogram`` (largest peak of one Hann periodogram), ``f1_is_first`` (the largest is the first peak
    reaching half of it) and the averaged spectrum's resolution [Hz]; from Σ|u̇|: ``f1_abs`` and
    ``f1_abs_first_half`` (the same two readings of its averaged spectrum)."""
    from aca_warp.analysis.spectra import amplitude_spectrum, peak

    f1, a1, half, df = _averaged_peaks(seg[:, 3], sample_dt, fmin)
    fp, ap = amplitude_spectrum(seg[:, 3], sample_dt, normalise=None)
    f_one, _ = peak(fp, ap, fmin=max(fmin, 3.0 * df))
    f_abs, _, abs_half, _ = _averaged_peaks(seg[:, 4], sample_dt, fmin)
    return {
        "f1": f1,
        "f1_amplitude": a1 / abs(float(np.mean(seg[:, 4]))),
        "f1_first_half": half,
        "f1_periodogram": f_one,
        "f1_is_first": bool(abs(half - f1) <= 1.5 * df),
        "sum_resolution_hz": df,
        "f1_abs": f_abs,
        "f1_abs_first_half": abs_half,
    }


PLATEAU_FAR = (2.5, 4.0)  # the plateau's far band, multiples of f1


def shape_at(
    freq: np.ndarray, spectra: dict[str, np.ndarray], f: float, velocity: str = "velocity", suffix: str = ""
) -> dict[str, float | None]:
    """``contrast_{velocity,mu,torque,radius}{suffix}``: peak_to_floor at ``f`` [Hz] (±2 bins over the median of
    [f/2, 2 f]) of the spectrum ``spectra[velocity]`` and of μ's, torque's and radius's; ``plateau_…{suffix}``:
    their plateau_excess (median over [1.1, 2] f against [2.5, 4] f), None where the far band starts beyond the
    spectrum's last bin (f above a 2.5th of it: no level to compare with)."""
    from aca_warp.analysis.measures import peak_to_floor, plateau_excess

    out: dict[str, float | None] = {}
    names = {"velocity": velocity, "mu": "mu", "torque": "torque", "radius": "friction_radius"}
    far_inside = PLATEAU_FAR[0] * f < float(freq[-1])
    for short, key in names.items():
        out[f"contrast_{short}{suffix}"] = peak_to_floor(freq, spectra[key], f).ratio
        out[f"plateau_{short}{suffix}"] = (
            plateau_excess(freq, spectra[key], f, far=PLATEAU_FAR).excess if far_inside else None
        )
    return out


def fig8_measures(freq: np.ndarray, spectra: dict[str, np.ndarray], f1: float) -> dict[str, Any]:
    """The Fig. 8 shape measures of one pad at its first velocity peak f1 (global spectra of one segment).

    * ``contrast_*``, ``plateau_*``: :func:`shape_at` f1 of the velocity spectrum (Σu̇'s) and μ's, torque's, radius's;
    * ``overlap_mu_torque`` / ``overlap_mu_radius``: spectral_overlap D over 1–200 kHz;
    * ``shared_*``: shared_peak_fraction of μ's peaks in μ, torque and radius (1–200 kHz), with chance, and the
      share of those shared peaks also in the velocity spectrum (``shared_in_velocity``) with its chance;
    * ``peak_*``: peak_width (FWHM) of the velocity spectrum's peak at f1: frequency, height, width, width/f, and
      the width in bins (a Hann window's own peak is 2 bins wide: a width near it is the resolution's).
    """
    import warnings

    from aca_warp.analysis.measures import (
        peak_width,
        shared_peak_fraction,
        shared_peaks,
        spectral_overlap,
    )

    out: dict[str, Any] = {**shape_at(freq, spectra, f1)}
    band = (1.0e3, min(200.0e3, float(freq[-1])))
    out["overlap_mu_torque"] = spectral_overlap(freq, spectra["mu"], spectra["torque"], band=band).mean_abs_log
    out["overlap_mu_radius"] = spectral_overlap(freq, spectra["mu"], spectra["friction_radius"], band=band).mean_abs_log
    trio = {k: spectra[k] for k in ("mu", "torque", "friction_radius")}
    sf = shared_peak_fraction(freq, trio, "mu", band=band)
    out.update(
        shared_fraction=sf.fraction, shared_count=sf.shared, shared_chance=sf.chance, mu_peaks=sf.reference_peaks
    )
    four = shared_peaks(freq, {**trio, "velocity": spectra["velocity"]}, band=band)
    out["shared_in_velocity"] = len(four) / sf.shared if sf.shared else None
    with_v = shared_peak_fraction(freq, {"mu": spectra["mu"], "velocity": spectra["velocity"]}, "mu", band=band)
    out["shared_in_velocity_chance"] = with_v.chance
    df = freq[1] - freq[0]
    with warnings.catch_warnings():  # the prominence of a largest bin that is no local maximum is 0: said, not warned
        warnings.filterwarnings("ignore", message="some peaks have a prominence of 0")
        w = peak_width(freq, spectra["velocity"], f1, search=max(2.0 * df, 0.01 * f1))
    out.update(
        peak_frequency=w.frequency, peak_height=w.height, peak_width=w.width, peak_relative_width=w.width / w.frequency,
        peak_width_bins=w.width / df, spectrum_resolution_hz=float(df),
    )  # fmt: skip
    return out


def coherence_measures(seg: np.ndarray, sample_dt: float, f1: float) -> dict[str, Any]:
    """Magnitude-squared coherence of Σu̇ (the co-moving patches' net motion) with μ (Welch, segments of an eighth of
    the span): at the first peak f1 (the largest within ±2 of its bins) and its mean over 20–80 kHz (§3.1: "these
    synchronized islands exhibit periodic behaviors that correspond well to the global friction dynamics")."""
    import scipy.signal

    n = max(16, seg.shape[0] // COHERENCE_SEGMENTS)
    f, c = scipy.signal.coherence(seg[:, 3], seg[:, 0], fs=1.0 / sample_dt, nperseg=n)
    i = int(np.argmin(np.abs(f - f1)))
    near = c[max(i - 2, 0) : i + 3]
    band = (f >= CHARACTERISTIC_BAND[0]) & (f <= CHARACTERISTIC_BAND[1])
    return {
        "coherence_f1": float(near.max()),
        "coherence_band": float(c[band].mean()) if band.any() else None,
        "coherence_resolution_hz": float(f[1] - f[0]),
    }


def stft_measures(mu: np.ndarray, sample_dt: float) -> list[dict[str, Any]]:
    """Largest STFT amplitude of μ over the saturated part divided by its mean (Fig. 10's normalisation), for every
    window of 2^12 … 2^17 samples that fits, with the window named and μ's mean (the other conventions follow)."""
    from aca_warp.analysis.measures import stft_peaks

    t = np.arange(mu.size) * sample_dt
    return [
        {"window": p.window, "samples": p.window_samples, "amplitude": p.amplitude, "frequency": p.frequency,
         "mean": p.mean}
        for p in stft_peaks(t, mu)
    ]  # fmt: skip


def mu_measures(freq: np.ndarray, spectra: dict[str, np.ndarray], mu: np.ndarray) -> dict[str, Any]:
    """μ's oscillation: mean, standard deviation (the amplitude of §3.3) and the largest peak of |μ(f)|/μ̄ at or
    above 5 kHz (frequency and height)."""
    from aca_warp.analysis.spectra import peak

    f, a = peak(freq, spectra["mu"], fmin=5.0e3)
    return {"mu_mean": float(np.mean(mu)), "mu_std": float(np.std(mu)), "mu_peak_hz": f, "mu_peak_amplitude": a}


def patch_first_peaks(freq: np.ndarray, mean_amp: np.ndarray, fmin: float) -> dict[str, float]:
    """The first peak of the mean per-patch velocity spectrum at every threshold of :data:`PATCH_FRACTIONS`
    (keys :func:`patch_key`)."""
    from aca_warp.analysis.measures import first_peak

    return {patch_key(x): first_peak(freq, mean_amp, fraction=x, fmin=fmin)[0] for x in PATCH_FRACTIONS}


def patch_key(fraction: float) -> str:
    """The key of the per-patch first peak at ``fraction`` ("0p1" for 0.1: a dotted key reads measures' levels)."""
    return f"{fraction:g}".replace(".", "p")


def global_measures(gsat: np.ndarray, cfg: Config) -> dict[str, Any]:
    """Every measure of one pad from its global outputs over its own saturated span ``gsat`` (N, ≥ 5)."""
    out = velocity_sum_peaks(gsat, cfg.sample_dt, cfg.sync_band[0])
    f1 = out["f1"]
    fg, spectra = global_spectra(gsat, cfg.sample_dt)
    out.update(fig8_measures(fg, spectra, f1))
    out.update(shape_at(fg, spectra, out["f1_abs"], velocity="abs_velocity", suffix="_abs"))
    out.update(mu_measures(fg, spectra, gsat[:, 0]))
    out.update(coherence_measures(gsat, cfg.sample_dt, f1))
    out["global_span_s"] = gsat.shape[0] * cfg.sample_dt
    out["stft"] = stft_measures(gsat[:, 0], cfg.sample_dt)
    return out
