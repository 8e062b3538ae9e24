"""The measures of one pad from its per-patch velocities over the experiment's common window: S(f) under the
``relative`` and the ``snr`` rule of Φ with the random-phase null level and its summaries (Fig. 9, §3.1–§3.3, §5),
the spatial patterns of the directions of motion (Figs. 4/6, Fig. 13), the radial imbalance of the motion against
the friction radius and torque (§3.1), and the permutation test of §5 (S does not see the spatial arrangement).

Bands: the S summaries are taken over the pad's own band [f1/8, 2 f1] (four octaves around its first peak) and over
common **absolute** bands (the whole S band and §4's 20–80 kHz), so that two experiments with different first peaks
are also compared over the same frequencies.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aca_warp.studies.validation.base import CHARACTERISTIC_BAND, SYNC_EXCESS, Config

COUPLING_RADIUS = 5.0e-3  # m: the default coupling radius (docs/model.md §2.5)
SNAPSHOTS = 64  # instants of the direction-of-motion pattern (Figs. 4/6) per pad
PEAK_PROMINENCE = 4.0  # a μ peak stands a factor 4 above its surroundings (as shared_peaks)
PEAK_TOLERANCE_BINS = 2


_NULL_TABLES: dict[int, np.ndarray] = {}


def null_table(n_max: int) -> np.ndarray:
    """S_null for Φ = 0 … n_max (``sync_null_level`` with its defaults, so equal to what ``sync_index`` stores)."""
    from aca_warp.analysis.sync import sync_null_level

    if n_max not in _NULL_TABLES:
        _NULL_TABLES[n_max] = sync_null_level(np.arange(n_max + 1))
    return _NULL_TABLES[n_max]


def _table_dict(t: Any) -> dict[str, list]:
    return {
        k: np.asarray(getattr(t, k)).tolist()
        for k in ("lower", "upper", "bins", "mean_S", "mean_S_null", "mean_excess")
    }


def _mean(x: np.ndarray) -> float | None:
    return float(np.mean(x)) if x.size else None


def _spearman(a: np.ndarray, b: np.ndarray) -> float | None:
    import scipy.stats

    if a.size < 3 or np.ptp(a) == 0 or np.ptp(b) == 0:
        return None
    return float(scipy.stats.spearmanr(a, b).statistic)


def band_summaries(freq: np.ndarray, S: np.ndarray, null: np.ndarray, phi: np.ndarray, f1: float) -> dict[str, Any]:
    """Spread (share of the defined bins with S − S_null > 0.05) and prevalence (mean Φ) over the pad's band
    [f1/8, 2 f1] and over the absolute bands (the whole S band, 20–80 kHz), with the mean S − S_null there."""
    ok = np.isfinite(S) & np.isfinite(null)
    bands = {"": (f1 / 8, 2 * f1), "_all": (freq[0], freq[-1]), "_band": CHARACTERISTIC_BAND}
    out: dict[str, Any] = {}
    for suffix, (lo, hi) in bands.items():
        sel = ok & (freq >= lo) & (freq <= hi)
        ex = (S - null)[sel]
        out[f"spread{suffix}"] = float(np.mean(ex > SYNC_EXCESS)) if sel.any() else None
        out[f"prevalence{suffix}"] = _mean(phi[sel].astype(np.float64))
        out[f"excess{suffix}"] = _mean(ex)
    return out


def peak_features(
    freq: np.ndarray, S: np.ndarray, null: np.ndarray, phi: np.ndarray, mu_amp: np.ndarray, f1: float
) -> dict[str, Any]:
    """S around the first peak and at μ's peaks (§3.1, §3.3):

    * ``excess_peak_plateau``: mean S − S_null over [0.9 f1, 2 f1] (the first peak and its plateau) minus the mean
      over the other defined bins; ``phi_peak_plateau``: the same of Φ over the patches (the share oscillating);
    * ``f_sync``: the first peak (reaching a quarter of the largest) of max(S − S_null, 0)·Φ smoothed over 5 bins —
      where S's first feature lies, for the A^(−1/4) shift "in the Synchronization Indices";
    * μ's peaks (≥ 4× their surroundings) above 2 f1: ``mu_hf_peaks``, the share with no synchronised bin
      (S − S_null > 0.05) within 2 bins (``mu_hf_unmatched``), the share of the bins above 2 f1 with none, what a
      peak placed there at random would show (``mu_hf_unmatched_chance``), and Φ at those peaks over the median Φ of
      the band above 2 f1 (``mu_hf_phi_ratio``: few patches oscillate there when the peaks are single patches');
    * μ's peaks over the whole band: the share at a synchronised bin (``mu_peaks_synced``) and the share of the
      band's bins within 2 bins of a synchronised one (``mu_peaks_synced_chance``).
    """
    from aca_warp.analysis.measures import first_peak
    from aca_warp.analysis.measures.comparison import _find_peaks

    ok = np.isfinite(S) & np.isfinite(null)
    ex = np.where(ok, S - null, np.nan)
    near = (freq >= 0.9 * f1) & (freq <= 2 * f1)
    n = max(int(phi.max()), 1)
    out: dict[str, Any] = {
        "excess_peak_plateau": None if not (ok & near).any() or not (ok & ~near).any() else float(
            np.nanmean(ex[near & ok]) - np.nanmean(ex[~near & ok])),
        "phi_peak_plateau": float(phi[near].mean() / n - phi[~near].mean() / n)
        if near.any() and (~near).any() else None,
    }  # fmt: skip
    w = np.convolve(np.where(ok, np.maximum(ex, 0.0), 0.0) * phi, np.ones(5) / 5, mode="same")
    out["f_sync"] = first_peak(freq, w, fraction=0.25)[0] if np.any(w > 0) else None
    synced = np.convolve((ok & (ex > SYNC_EXCESS)).astype(float), np.ones(2 * PEAK_TOLERANCE_BINS + 1), "same") > 0
    peaks = _find_peaks(freq, mu_amp, (freq[0], freq[-1]), PEAK_PROMINENCE)
    hf = peaks[freq[peaks] > 2 * f1]
    above = freq > 2 * f1
    out["mu_hf_peaks"] = int(hf.size)
    out["mu_hf_unmatched"] = float(np.mean(~synced[hf])) if hf.size else None
    out["mu_hf_unmatched_chance"] = float(np.mean(~synced[above])) if above.any() else None
    med = float(np.median(phi[above])) if above.any() else 0.0
    lone = hf[~synced[hf]]
    out["mu_hf_phi_ratio"] = float(np.median(phi[lone]) / med) if lone.size and med > 0 else None
    out["mu_peaks"] = int(peaks.size)
    out["mu_peaks_synced"] = float(np.mean(synced[peaks])) if peaks.size else None
    out["mu_peaks_synced_chance"] = float(np.mean(synced))
    return out


def sync_measures(
    freq: np.ndarray, X: np.ndarray, f1: float, mu_amp: np.ndarray, rule: str, coherence: np.ndarray | None = None
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """S(f) of one pad's per-patch spectra X (F, n) under ``rule``, with S_null, and its summaries (scalars, arrays):
    the equal-Φ tables (octave classes of Φ, ``sync_by_prevalence``) over the whole band, above f1 and over 20–80 kHz
    (``table``, ``table_high``, ``table_band``), the median S − S_null over bins with Φ ≥ 10, the share of defined
    bins with S > S_null, :func:`band_summaries`, S and Φ at f1, :func:`peak_features`, the agreement with the μ
    spectrum over 20–80 kHz (``agreement``: Spearman ρ of S·Φ with |μ(f)|; ``rho_excess_mu``, ``rho_phi_mu``: of
    S − S_null and of Φ alone) and the §3.3 summaries (:func:`local_sync_measures`)."""
    from aca_warp.analysis.measures import prevalence_classes, spectral_agreement, sync_by_prevalence
    from aca_warp.analysis.sync import sync_index

    res = sync_index(X, freq=freq, rule=rule, null_trials=0)
    S, phi = res.S, res.Phi
    null = null_table(X.shape[1])[phi]
    edges = prevalence_classes(X.shape[1])
    tabs = {}
    for key, sel in (("table", np.ones(freq.size, bool)), ("table_high", freq > f1),
                     ("table_band", (freq >= CHARACTERISTIC_BAND[0]) & (freq <= CHARACTERISTIC_BAND[1]))):  # fmt: skip
        tabs[key] = _table_dict(sync_by_prevalence(S[sel], null[sel], phi[sel], edges=edges))
    ok = np.isfinite(S) & np.isfinite(null)
    i1 = int(np.argmin(np.abs(freq - f1)))
    prevalent = ok & (phi >= 10)
    in_band = (freq >= CHARACTERISTIC_BAND[0]) & (freq <= CHARACTERISTIC_BAND[1])
    both = in_band & ok
    scalars = {
        **tabs,
        "median_excess_phi10": float(np.median(S[prevalent] - null[prevalent])) if prevalent.any() else None,
        "fraction_above_null": float(np.mean(S[ok] > null[ok])) if ok.any() else None,
        **band_summaries(freq, S, null, phi, f1),
        "S_at_f1": float(S[i1]),
        "Phi_at_f1": int(phi[i1]),
        **peak_features(freq, S, null, phi, mu_amp, f1),
        "agreement": spectral_agreement(freq, S, phi, mu_amp, band=CHARACTERISTIC_BAND) if in_band.sum() > 2 else None,
        "rho_excess_mu": _spearman((S - null)[both], mu_amp[both]),
        "rho_phi_mu": _spearman(phi[in_band].astype(float), mu_amp[in_band]),
        "params": res.params,
    }
    scalars.update(local_sync_measures(S, null, phi, X.shape[1], coherence))
    return scalars, {"S": S.astype(np.float32), "Phi": phi.astype(np.int32), "S_null": null.astype(np.float32)}


def local_sync_measures(
    S: np.ndarray, null: np.ndarray, phi: np.ndarray, patches: int, coherence: np.ndarray | None
) -> dict[str, Any]:
    """The §3.3 summaries of S(f) (:func:`sync_measures`): top-1 % excess, Φ of the synchronised bins, and the
    rank correlation of the neighbours' coherence C(f) with Φ(f)."""
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
        out["cluster_phi_rho"] = _spearman(coherence[use], phi[use].astype(float))
    return out


def _zero_crossing(d: np.ndarray, c: np.ndarray, reach: float) -> float:
    """First distance where c falls to 0 (linear interpolation); 0 if c[0] <= 0, ``reach`` if it never does."""
    below = np.flatnonzero(c <= 0)
    if below.size == 0:
        return reach
    k = int(below[0])
    if k == 0:
        return 0.0
    return float(d[k - 1] + c[k - 1] / (c[k - 1] - c[k]) * (d[k] - d[k - 1]))


def patch_spacing(x: np.ndarray, y: np.ndarray) -> float:
    """Median distance of a patch to its nearest neighbour [m]."""
    from scipy.spatial import cKDTree

    d, _ = cKDTree(np.column_stack([x, y])).query(np.column_stack([x, y]), k=2)
    return float(np.median(d[:, 1]))


def correlation_measures(x: np.ndarray, y: np.ndarray, v: np.ndarray, X: np.ndarray, i1: int) -> dict[str, Any]:
    """Spatial correlation C(d) of the patch motion over pairs closer than 20 mm (or half the patches' extent)
    (``phase_correlation_length``, 20 distance bins), summarised by

    * ``*_near``: C over the pairs within the coupling radius 5 mm (pair-weighted): > 0 when coupled neighbours move
      together (co-moving groups), < 0 when they move against each other;
    * ``*_zero``: where C first falls to 0 (linear interpolation; 0 when it starts at or below 0, the reach when it
      stays positive): the size of the co-moving groups, against ``patch_spacing`` (a group smaller than the
      distance between neighbours is no group);

    for ``corr``: the direction-of-motion pattern of Figs. 4/6 — sign(u̇_i) at ``SNAPSHOTS`` instants evenly spread
    over the segment (phase 0 with the disc, π against it, so cos(φ_i − φ_j) = s_i s_j), unweighted; and for
    ``corr_f1``: the phases of the patch spectra at the first peak, bins f1 ± 2, weighted by the amplitudes.
    """
    from aca_warp.analysis.measures import phase_correlation_length

    reach = min(20.0e-3, 0.5 * float(np.hypot(np.ptp(x), np.ptp(y))))
    rows = np.linspace(0, v.shape[0] - 1, min(SNAPSHOTS, v.shape[0])).round().astype(int)
    sign = np.where(v[rows] < 0, np.pi, 0.0)
    spec = X[max(i1 - 2, 0) : i1 + 3]
    out: dict[str, Any] = {"corr_reach": reach, "patch_spacing": patch_spacing(x, y)}
    for key, c in (
        ("corr", phase_correlation_length(x, y, sign, max_distance=reach)),
        ("corr_f1", phase_correlation_length(x, y, np.angle(spec), np.abs(spec), max_distance=reach)),
    ):
        ok = np.isfinite(c.correlation) & (c.pairs > 0)
        d, cc, n = c.distance[ok], c.correlation[ok], c.pairs[ok]
        near = d <= COUPLING_RADIUS
        out[f"{key}_near"] = float(np.average(cc[near], weights=n[near])) if near.any() else None
        out[f"{key}_zero"] = _zero_crossing(d, cc, reach)
    return out


def radial_measures(gseg: np.ndarray, v: np.ndarray, r: np.ndarray, decimation: int) -> dict[str, Any]:
    """Radial imbalance of the patches' motion against the friction radius and the torque (§3.1: "radially
    imbalanced synchronization patterns ... should also be reflected through the effective friction radius").

    B(t) = Σ_i u̇_i (r_i − r̄) / Σ_i |u̇_i| (> 0 when the outer patches move with the disc more than the inner ones,
    which lowers their sliding speed and, on the falling friction law, raises their friction force: the friction
    radius then moves out). Pearson ρ of B with the friction radius, with the torque and, for contrast, with μ
    (the torque follows an imbalance beyond μ when ρ(B, T) > ρ(B, μ)), over the per-patch samples."""
    g = gseg[: v.shape[0] * decimation : decimation]
    b = (v * (r - r.mean())[None, :]).sum(axis=1) / np.maximum(np.abs(v).sum(axis=1), 1e-30)

    def rho(y: np.ndarray) -> float | None:
        return float(np.corrcoef(b, y)[0, 1]) if np.std(b) > 0 and np.std(y) > 0 else None

    return {"radial_rho_radius": rho(g[:, 2]), "radial_rho_torque": rho(g[:, 1]), "radial_rho_mu": rho(g[:, 0])}


def permutation_measures(
    X: np.ndarray, freq: np.ndarray, x: np.ndarray, y: np.ndarray, coherence: np.ndarray | None, seed: int = 0
) -> dict[str, Any]:
    """§5 ("The Synchronization Index is not sensitive ... to the spatial distribution of these bodies"): the
    patches' spatial arrangement permuted at random. S(f) of the permuted spectra (the largest |ΔS| over the bins)
    against the neighbours' coherence C(f) over 20–80 kHz before and after (the spatial measure that does change)."""
    from aca_warp.analysis.measures import neighbour_coherence
    from aca_warp.analysis.sync import sync_index

    perm = np.random.default_rng(seed).permutation(X.shape[1])
    S = sync_index(X, rule="relative", null_trials=0).S
    S2 = sync_index(X[:, perm], rule="relative", null_trials=0).S
    both = np.isfinite(S) & np.isfinite(S2)
    out: dict[str, Any] = {"perm_max_dS": float(np.max(np.abs(S[both] - S2[both]))) if both.any() else None}
    if coherence is not None:
        band = (freq >= CHARACTERISTIC_BAND[0]) & (freq <= CHARACTERISTIC_BAND[1])
        c2 = neighbour_coherence(x[perm], y[perm], X, COUPLING_RADIUS)
        out["perm_coherence"] = float(np.nanmean(coherence[band]))
        out["perm_coherence_permuted"] = float(np.nanmean(c2[band]))
    return out


def patch_measures(
    gseg: np.ndarray, vseg: np.ndarray, geometry: dict[str, np.ndarray], f1: float, cfg: Config
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Every per-patch measure of one pad over the common segment (module docstring); ``f1`` [Hz] its first
    velocity peak (from Σu̇). Returns (scalars, arrays)."""
    from aca_warp.analysis.measures import neighbour_coherence
    from aca_warp.analysis.spectra import complex_spectrum
    from aca_warp.studies.validation.measures import global_spectra, patch_first_peaks

    dtp = cfg.sample_dt * cfg.decimation
    fg, spectra = global_spectra(gseg, cfg.sample_dt)
    top = min(cfg.sync_band[1], 0.9 / (2.0 * dtp))
    fp, X = complex_spectrum(vseg, dtp, axis=0, freq_range=(cfg.sync_band[0], top))
    mean_amp = np.abs(X).mean(axis=1)
    df = fp[1] - fp[0]
    fmin = max(cfg.sync_band[0], 3.0 * df)
    lo = int(round(fp[0] / (fg[1] - fg[0])))
    mu_on_p = spectra["mu"][lo : lo + fp.size]
    x, y = geometry["x"], geometry["y"]
    out: dict[str, Any] = {"f1_patch": patch_first_peaks(fp, mean_amp, fmin), "resolution_hz": df}
    out["segment_s"] = vseg.shape[0] * dtp
    arrays: dict[str, np.ndarray] = {"patch_mean_amplitude": mean_amp.astype(np.float32)}
    try:
        coherence = neighbour_coherence(x, y, X, COUPLING_RADIUS)
        arrays["neighbour_coherence"] = coherence.astype(np.float32)
    except ValueError:  # no two patches within the coupling radius: no local clustering to measure
        coherence = None
    for rule in ("relative", "snr"):
        scalars, arr = sync_measures(fp, X, f1, mu_on_p, rule, coherence)
        out[f"sync_{rule}"] = scalars
        arrays.update({f"{k}_{rule}": v for k, v in arr.items()})
    i1 = int(np.argmin(np.abs(fp - f1)))
    out.update(correlation_measures(x, y, vseg, X, i1))
    out.update(radial_measures(gseg, vseg, geometry["r"], cfg.decimation))
    out.update(permutation_measures(X, fp, x, y, coherence))
    arrays.update({f"spectrum_{k}": v.astype(np.float32) for k, v in spectra.items()})
    return out, arrays


def track_measures(
    gwin: np.ndarray, vwin: np.ndarray, geometry: dict[str, np.ndarray], cfg: Config
) -> dict[str, Any]:  # fmt: skip
    """The compact measures of one track window (a per-patch window of a long run, ``Experiment.tracks``): the
    first velocity peak (Σu̇, and the per-patch one at 0.1), the correlation of the directions of motion of coupled
    neighbours and the size of the co-moving groups, S − S_null (median over Φ ≥ 10, both rules) and the spread, μ's
    standard deviation and mean Σ|u̇|."""
    from aca_warp.analysis.spectra import complex_spectrum
    from aca_warp.studies.validation.measures import patch_first_peaks, velocity_sum_peaks

    dtp = cfg.sample_dt * cfg.decimation
    vs = velocity_sum_peaks(gwin, cfg.sample_dt, cfg.sync_band[0])
    top = min(cfg.sync_band[1], 0.9 / (2.0 * dtp))
    fp, X = complex_spectrum(vwin, dtp, axis=0, freq_range=(cfg.sync_band[0], top))
    fmin = max(cfg.sync_band[0], 3.0 * (fp[1] - fp[0]))
    f1 = vs["f1"]
    out: dict[str, Any] = {
        "f1": f1,
        "f1_patch": patch_first_peaks(fp, np.abs(X).mean(axis=1), fmin)["0p1"],
        "mu_std": float(np.std(gwin[:, 0])),
        "sum_abs_velocity": float(np.mean(gwin[:, 4])),
    }
    corr = correlation_measures(geometry["x"], geometry["y"], vwin, X, int(np.argmin(np.abs(fp - f1))))
    out.update({k: corr[k] for k in ("corr_near", "corr_zero", "corr_f1_near")})
    from aca_warp.analysis.sync import sync_index

    for rule in ("relative", "snr"):
        res = sync_index(X, freq=fp, rule=rule, null_trials=0)
        null = null_table(X.shape[1])[res.Phi]
        ok = np.isfinite(res.S) & (res.Phi >= 10)
        out[f"excess_{rule}"] = float(np.median(res.S[ok] - null[ok])) if ok.any() else None
        if rule == "relative":
            out["spread"] = band_summaries(fp, res.S, null, res.Phi, f1)["spread"]
    return out
