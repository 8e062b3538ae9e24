"""The measures of one pad over its analysis segment (stage 5 of :mod:`aca_warp.studies.validation`): spectra
of the global outputs and of the patch velocities, the first velocity-spectrum peak, the Fig. 8 shape measures,
S(f) under the ``relative`` and the ``snr`` rule with the random-phase null level and its summaries, the spatial
correlation of the directions of motion (Figs. 4/6) and of the spectral phases at the first peak, μ's oscillation
and its STFT maxima.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aca_warp.studies.validation.base import Config

FIRST_PEAK_FRACTION = 0.1  # the first peak: the lowest peak of the mean per-patch spectrum reaching 1/10 of its maximum


def global_spectra(seg: np.ndarray, sample_dt: float) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Hann amplitude spectra of one pad's global outputs over a segment (N, 5), all dimensionless.

    μ, torque, friction radius and Σ|u̇| divided by their mean (paper Fig. 8); the "velocity" spectrum is Σu̇ (the
    patches' velocities in the pad frame) divided by the mean of Σ|u̇|, since Σu̇ itself has zero mean.
    """
    from aca_warp.analysis.spectra import amplitude_spectrum

    freq, amp = amplitude_spectrum(seg[:, [0, 1, 2, 4]], sample_dt, normalise="mean", axis=0)
    _, v = amplitude_spectrum(seg[:, 3], sample_dt, normalise=None)
    out = {"mu": amp[:, 0], "torque": amp[:, 1], "friction_radius": amp[:, 2], "abs_velocity": amp[:, 3]}
    out["velocity"] = v / abs(float(np.mean(seg[:, 4])))
    return freq, out


_NULL_TABLES: dict[int, np.ndarray] = {}


def null_table(n_max: int) -> np.ndarray:
    """S_null for Φ = 0 … n_max (``sync_null_level`` with its defaults, so equal to what ``sync_index`` stores)."""
    from aca_warp.analysis.sync import sync_null_level

    if n_max not in _NULL_TABLES:
        _NULL_TABLES[n_max] = sync_null_level(np.arange(n_max + 1))
    return _NULL_TABLES[n_max]


def sync_measures(
    freq: np.ndarray, X: np.ndarray, f1: float, mu_amp: np.ndarray, rule: str, coherence: np.ndarray | None = None
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """S(f) of one pad's per-patch spectra X (F, n) under ``rule``, with S_null, and its summaries (scalars, arrays).

    Summaries: the equal-Φ tables over the whole band and above f1 (octave classes of Φ, ``sync_by_prevalence``),
    the median S − S_null over bins with Φ ≥ 10, the share of defined bins with S > S_null, the *spread* (share of
    the bins in [f1/8, 2 f1] with S − S_null > 0.05) and *prevalence* (mean Φ over the bins of that band with S
    defined), S and Φ at f1, and the agreement with the μ spectrum (``spectral_agreement``, 20–80 kHz); for §3.3:
    ``top_excess`` (mean of the top 1 % of S − S_null over the defined bins: "individual high-valued S"),
    ``phi_sync`` and ``phi_sync_share`` (mean Φ, and Φ over the patches, of the bins with S − S_null > 0.05) and,
    with the neighbours' phase coherence C(f) (``neighbour_coherence``), ``cluster_phi_rho``: Spearman ρ of C
    against Φ over the bins with Φ ≥ 2.
    """
    from aca_warp.analysis.measures import prevalence_classes, spectral_agreement, sync_by_prevalence
    from aca_warp.analysis.sync import sync_index

    res = sync_index(X, freq=freq, rule=rule, null_trials=0)
    S, phi = res.S, res.Phi
    null = null_table(X.shape[1])[phi]
    edges = prevalence_classes(X.shape[1])
    table = sync_by_prevalence(S, null, phi, edges=edges)
    high = freq > f1
    table_high = sync_by_prevalence(S[high], null[high], phi[high], edges=edges)
    ok = np.isfinite(S) & np.isfinite(null)
    rel = ok & (freq >= f1 / 8) & (freq <= 2 * f1)
    i1 = int(np.argmin(np.abs(freq - f1)))
    prevalent = ok & (phi >= 10)
    band = (20e3, 80e3)
    in_band = (freq >= band[0]) & (freq <= band[1])
    scalars = {
        "table": _table_dict(table),
        "table_high": _table_dict(table_high),
        "median_excess_phi10": float(np.median(S[prevalent] - null[prevalent])) if prevalent.any() else None,
        "fraction_above_null": float(np.mean(S[ok] > null[ok])) if ok.any() else None,
        "spread": float(np.mean(S[rel] - null[rel] > 0.05)) if rel.any() else None,
        "prevalence": float(np.mean(phi[rel])) if rel.any() else None,
        "S_at_f1": float(S[i1]),
        "Phi_at_f1": int(phi[i1]),
        "agreement": spectral_agreement(freq, S, phi, mu_amp, band=band) if in_band.sum() > 2 else None,
        "params": res.params,
    }
    scalars.update(local_sync_measures(S, null, phi, X.shape[1], coherence))
    return scalars, {"S": S.astype(np.float32), "Phi": phi.astype(np.int32), "S_null": null.astype(np.float32)}


def local_sync_measures(
    S: np.ndarray, null: np.ndarray, phi: np.ndarray, patches: int, coherence: np.ndarray | None
) -> dict[str, Any]:
    """The §3.3 summaries of S(f) (:func:`sync_measures`): top-1 % excess, Φ of the synchronised bins, and the
    rank correlation of the neighbours' coherence C(f) with Φ(f)."""
    import scipy.stats

    ok = np.isfinite(S) & np.isfinite(null)
    ex = np.sort((S - null)[ok])[::-1]
    sync = ok & (S - null > SYNC_EXCESS)
    out: dict[str, Any] = {
        "top_excess": float(np.mean(ex[: max(1, ex.size // 100)])) if ex.size else None,
        "phi_sync": float(np.mean(phi[sync])) if sync.any() else None,
        "phi_sync_share": float(np.mean(phi[sync]) / patches) if sync.any() else None,
        "sync_bins": int(sync.sum()),
        "cluster_phi_rho": None,
    }
    if coherence is not None:
        use = (phi >= 2) & np.isfinite(coherence)
        if use.sum() > 2 and np.ptp(coherence[use]) > 0 and np.ptp(phi[use]) > 0:
            out["cluster_phi_rho"] = float(scipy.stats.spearmanr(coherence[use], phi[use]).statistic)
    return out


SYNC_EXCESS = 0.05  # S − S_null above which a bin counts as synchronised (the spread of §3.1, Φ of §3.3)


def _table_dict(t: Any) -> dict[str, list]:
    return {
        k: np.asarray(getattr(t, k)).tolist()
        for k in ("lower", "upper", "bins", "mean_S", "mean_S_null", "mean_excess")
    }


def fig8_measures(freq: np.ndarray, spectra: dict[str, np.ndarray], f1: float) -> dict[str, Any]:
    """The Fig. 8 shape measures of one pad at its first velocity peak f1 (global spectra of one segment).

    * ``contrast_*``: peak_to_floor at f1 (±2 bins over the median of [f1/2, 2 f1]) of velocity, μ, torque, radius;
    * ``plateau_*``: plateau_excess (median over [1.1, 2] f1 against [2.5, 4] f1) of the same four;
    * ``overlap_mu_torque`` / ``overlap_mu_radius``: spectral_overlap D over 1–200 kHz;
    * ``shared_*``: shared_peak_fraction of μ's peaks in μ, torque and radius (1–200 kHz), with chance, and the
      share of those shared peaks also in the velocity spectrum;
    * ``peak_*``: peak_width (FWHM) of the velocity spectrum's peak at f1: frequency, height, width, width/f.
    """
    import warnings

    from aca_warp.analysis.measures import (
        peak_to_floor,
        peak_width,
        plateau_excess,
        shared_peak_fraction,
        shared_peaks,
        spectral_overlap,
    )

    out: dict[str, Any] = {}
    names = {"velocity": "velocity", "mu": "mu", "torque": "torque", "radius": "friction_radius"}
    for short, key in names.items():
        out[f"contrast_{short}"] = peak_to_floor(freq, spectra[key], f1).ratio
        out[f"plateau_{short}"] = plateau_excess(freq, spectra[key], f1).excess
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
    with warnings.catch_warnings():  # the prominence of a largest bin that is no local maximum is 0: said, not warned
        warnings.filterwarnings("ignore", message="some peaks have a prominence of 0")
        w = peak_width(freq, spectra["velocity"], f1, search=max(2.0 * (freq[1] - freq[0]), 0.01 * f1))
    out.update(
        peak_frequency=w.frequency, peak_height=w.height, peak_width=w.width, peak_relative_width=w.width / w.frequency
    )
    return out


SNAPSHOTS = 64  # instants of the direction-of-motion pattern (Figs. 4/6) per pad


def correlation_measures(x: np.ndarray, y: np.ndarray, v: np.ndarray, X: np.ndarray, i1: int) -> dict[str, Any]:
    """Spatial correlation C(d) of the patch motion over pairs closer than 20 mm (or half the patches' extent)
    (``phase_correlation_length``, 20 distance bins), summarised by

    * ``*_near``: C over the pairs within the coupling radius 5 mm (pair-weighted): > 0 when coupled neighbours move
      together (synchronised islands), < 0 when they move against each other;
    * ``*_zero``: where C first falls to 0 (linear interpolation; 0 when it starts at or below 0, the reach when it
      stays positive): the size of the co-moving groups;

    for ``corr``: the direction-of-motion pattern of Figs. 4/6 — sign(u̇_i) at ``SNAPSHOTS`` instants evenly spread
    over the segment (phase 0 with the disc, π against it, so cos(φ_i − φ_j) = s_i s_j), unweighted; and for
    ``corr_f1``: the phases of the patch spectra at the first peak, bins f1 ± 2, weighted by the amplitudes.
    """
    from aca_warp.analysis.measures import phase_correlation_length

    reach = min(20.0e-3, 0.5 * float(np.hypot(np.ptp(x), np.ptp(y))))
    rows = np.linspace(0, v.shape[0] - 1, min(SNAPSHOTS, v.shape[0])).round().astype(int)
    sign = np.where(v[rows] < 0, np.pi, 0.0)
    spec = X[max(i1 - 2, 0) : i1 + 3]
    out: dict[str, Any] = {"corr_reach": reach}
    for key, c in (
        ("corr", phase_correlation_length(x, y, sign, max_distance=reach)),
        ("corr_f1", phase_correlation_length(x, y, np.angle(spec), np.abs(spec), max_distance=reach)),
    ):
        ok = np.isfinite(c.correlation) & (c.pairs > 0)
        d, cc, n = c.distance[ok], c.correlation[ok], c.pairs[ok]
        near = d <= COUPLING_RADIUS
        out[f"{key}_near"] = float(np.average(cc[near], weights=n[near])) if near.any() else None
        out[f"{key}_zero"] = _zero_crossing(d, cc, reach)
        out[f"{key}_curve"] = {"distance": d.tolist(), "C": cc.tolist()}
    return out


COUPLING_RADIUS = 5.0e-3  # m: the default coupling radius (docs/model.md §2.5)


def _zero_crossing(d: np.ndarray, c: np.ndarray, reach: float) -> float:
    """First distance where c falls to 0 (linear interpolation); 0 if c[0] <= 0, ``reach`` if it never does."""
    below = np.flatnonzero(c <= 0)
    if below.size == 0:
        return reach
    k = int(below[0])
    if k == 0:
        return 0.0
    return float(d[k - 1] + c[k - 1] / (c[k - 1] - c[k]) * (d[k] - d[k - 1]))


def stft_measures(mu: np.ndarray, sample_dt: float) -> list[dict[str, Any]]:
    """Largest STFT amplitude of μ over the saturated part divided by its mean (Fig. 10's normalisation), for every
    window of 2^12 … 2^17 samples that fits, with the window named."""
    from aca_warp.analysis.measures import stft_peaks

    t = np.arange(mu.size) * sample_dt
    return [
        {"window": p.window, "samples": p.window_samples, "amplitude": p.amplitude, "frequency": p.frequency}
        for p in stft_peaks(t, mu)
    ]


def mu_measures(freq: np.ndarray, spectra: dict[str, np.ndarray], mu: np.ndarray) -> dict[str, Any]:
    """μ's oscillation over the segment: mean, standard deviation (the amplitude of §3.3) and the largest peak
    of |μ(f)|/μ̄ at or above 5 kHz (frequency and height)."""
    from aca_warp.analysis.spectra import peak

    f, a = peak(freq, spectra["mu"], fmin=5.0e3)
    return {"mu_mean": float(np.mean(mu)), "mu_std": float(np.std(mu)), "mu_peak_hz": f, "mu_peak_amplitude": a}


def pad_measures(
    gseg: np.ndarray, vseg: np.ndarray, xy: tuple[np.ndarray, np.ndarray], cfg: Config
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Every measure of one saturated pad over its analysis segment.

    Args:
        gseg: Global outputs over the segment, shape (decimation·M, 5), sampled every ``cfg.sample_dt``.
        vseg: Patch velocities over the same span, shape (M, n) float32, every ``cfg.sample_dt·decimation``.
        xy: Patch centres (x, y) [m], each (n,).
        cfg: Settings.

    Returns:
        (scalars, arrays): JSON-ready numbers, and the spectra and S(f) for the arrays file.
    """
    from aca_warp.analysis.measures import first_peak, neighbour_coherence
    from aca_warp.analysis.spectra import complex_spectrum, peak

    dtp = cfg.sample_dt * cfg.decimation
    fg, spectra = global_spectra(gseg, cfg.sample_dt)
    top = min(cfg.sync_band[1], 0.9 / (2.0 * dtp))
    fp, X = complex_spectrum(vseg, dtp, axis=0, freq_range=(cfg.sync_band[0], top))
    mean_amp = np.abs(X).mean(axis=1)
    df = fp[1] - fp[0]
    fmin = max(cfg.sync_band[0], 3.0 * df)
    f1, a1 = first_peak(fp, mean_amp, fraction=FIRST_PEAK_FRACTION, fmin=fmin)
    f_max, a_max = peak(fp, mean_amp, fmin=fmin)
    i1 = int(np.argmin(np.abs(fp - f1)))
    lo = int(round(fp[0] / (fg[1] - fg[0])))
    mu_on_p = spectra["mu"][lo : lo + fp.size]
    out: dict[str, Any] = {"f1": f1, "f1_amplitude": a1, "f_largest": f_max, "largest_amplitude": a_max}
    out.update(resolution_hz=df, segment_s=vseg.shape[0] * dtp)
    out.update(fig8_measures(fg, spectra, f1))
    out.update(mu_measures(fg, spectra, gseg[:, 0]))
    arrays: dict[str, np.ndarray] = {"patch_mean_amplitude": mean_amp.astype(np.float32)}
    try:
        coherence = neighbour_coherence(xy[0], xy[1], X, COUPLING_RADIUS)
        arrays["neighbour_coherence"] = coherence.astype(np.float32)
    except ValueError:  # no two patches within the coupling radius: no local clustering to measure
        coherence = None
    for rule in ("relative", "snr"):
        scalars, arr = sync_measures(fp, X, f1, mu_on_p, rule, coherence)
        out[f"sync_{rule}"] = scalars
        arrays.update({f"{k}_{rule}": v for k, v in arr.items()})
    out.update(correlation_measures(xy[0], xy[1], vseg, X, i1))
    out["stft"] = stft_measures(gseg[:, 0], cfg.sample_dt)
    arrays.update({f"spectrum_{k}": v.astype(np.float32) for k, v in spectra.items()})
    return out, arrays
