"""§3.1 rows on the spectra of Fig. 8: the first velocity peak (read from the velocity sum Σu̇, as which Fig. 8's
velocity spectrum is read; :mod:`~aca_warp.studies.validation.measures`), the A_p^(−1/4) law in the spectra and in
S(f), the shapes of the spectra (pronounced first peak, plateaus, overlapping μ and torque, shared peaks), the first
peak and plateau against S, μ's high-frequency peaks without an S counterpart, and the larger patches' higher,
narrower, lower peaks.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from aca_warp.studies.validation.base import (
    CHANCE_MARGIN,
    MM2,
    Config,
    Row,
    RowValue,
    _get,
    by_seed,
    each,
    interval,
    paired,
    ratio_interval,
    register_row,
    usable,
    values,
)
from aca_warp.studies.validation.hf_experiments import PRESETS, SWEEP
from aca_warp.studies.validation.measures import PATCH_FRACTIONS, patch_key
from aca_warp.studies.validation.verdicts import (
    NOT_COMPARABLE,
    all_of,
    direction_verdict,
    effect,
    effect_text,
    equivalence_verdict,
    rules_verdict,
    threshold_verdict,
    value_verdict,
)

PAPER_PEAK_HZ = {"hf1": 73.0e3, "hf2": 32.8e3, "hf3": 73.0e3, "hf4": 32.8e3}
PAPER_EXPONENT = -0.25
PEAK_TOLERANCE = 0.05  # relative: "around 73 kHz" read off Fig. 8
EXPONENT_TOLERANCE = 0.025  # absolute: 10 % of 1/4
OVERLAP_LIMIT = math.log(1.25)  # D = mean |ln μ − ln T| ≤ ln 1.25: a typical difference below 25 %
SHARED_LIMIT = 0.5  # "similar characteristic peaks" / "most of which": at least half
PRONOUNCED_MARGIN = math.log(2.0)  # "significantly more pronounced": at least twice the contrast
PLATEAU_MARGIN = math.log(1.5)  # a plateau raised at least 1.5 × above the other outputs' level there
RATIO_MARGIN = math.log(1.25)  # larger patches: heights, widths, frequencies differing by at least 25 %
FEATURE_MARGIN = 0.02  # S − S_null higher at the first peak and plateau by at least 0.02
UNMATCHED_LIMIT = 0.5  # "many peaks ... that do not correspond to any S": at least half of μ's peaks above 2 f1
SINGLE_MARGIN = math.log(2.0)  # Φ at those peaks at most half the band's median: "individual ... patches"
RESOLVED_BINS = 3.0  # a peak narrower than 3 bins is the window's own width (a Hann window's peak: 2 bins)


# ------------------------------------------------------------------------------------------------ the first peak


# the other readings of the first peak the paper leaves open: (label, per-pad measure key)
F1_CANDIDATES: tuple[tuple[str, str], ...] = (
    ("Σu̇ first peak ≥ ½ its largest", "f1_first_half"),
    ("Σu̇ single periodogram", "f1_periodogram"),
    *((f"per-patch mean spectrum at {x:g}", f"f1_patch.{patch_key(x)}") for x in PATCH_FRACTIONS),
    ("Σ|u̇| largest peak", "f1_abs"),
    ("Σ|u̇| first peak ≥ ½ its largest", "f1_abs_first_half"),
)
PRIMARY_F1 = (
    "primary: the largest peak of the Welch-averaged spectrum of the velocity sum Σu̇ (Fig. 8's velocity spectrum read "
    "as Σu̇'s, the sum Figs. 5/7 show; the paper calls its first peak significantly more pronounced than the other "
    "outputs', read here as the spectrum's largest)"
)


def held(pads: list[dict[str, Any]], key: str) -> bool:
    """Whether any of ``pads`` holds the measure ``key`` (a results file made before a reading was added holds
    none: its notes leave that reading out rather than show it empty)."""
    return any(math.isfinite(_get(p, key)) for p in pads)


def held_in(results: dict[str, dict], names: tuple[str, ...], key: str) -> bool:
    """:func:`held` over the usable pads of the experiments ``names``."""
    return held([p for n in names for p in usable(results.get(n))], key)


def _candidates(res: dict[str, Any] | None) -> str:
    """The other readings of the first peak the paper leaves open, and how often the largest peak is the first."""
    pads = usable(res)
    parts = [
        f"{label} {interval(values(res, key), '.1f', 1e-3, 'kHz')}" for label, key in F1_CANDIDATES if held(pads, key)
    ]
    first = sum(bool(p["measures"].get("f1_is_first")) for p in pads)
    return "; ".join([*parts, f"the largest Σu̇ peak is its first reaching ½ of it in {first} of {len(pads)} pads"])


def first_peak_row(name: str) -> Callable[[dict[str, dict], Config], RowValue]:
    def measure(results: dict[str, dict], cfg: Config) -> RowValue:
        res = results.get(name)
        f = values(res, "f1")
        paper = PAPER_PEAK_HZ[name]
        return RowValue(
            interval(f, ".1f", 1e-3, "kHz"),
            value_verdict(f, paper, PEAK_TOLERANCE * paper),
            PRIMARY_F1 + "; beside it: " + _candidates(res),
        )

    return measure


def _fit_per_seed(points: dict[int, list[tuple[float, float]]]) -> tuple[np.ndarray, dict[str, Any]]:
    from aca_warp.studies.hf_study.base import fit_power_law

    b = np.array(
        [fit_power_law(*map(np.array, zip(*pts, strict=True)))["exponent"] for pts in points.values() if len(pts) >= 3]
    )
    allp = [q for pts in points.values() for q in pts]
    pooled = fit_power_law(*map(np.array, zip(*allp, strict=True))) if len(allp) >= 3 else {}
    return b, pooled


def _exponent_verdict(b: np.ndarray) -> str:
    """An exponent's interval and the verdict it would give, for the candidates' notes."""
    return f"{interval(b, '.3f')} ({value_verdict(b, PAPER_EXPONENT, EXPONENT_TOLERANCE)})"


def _candidate_exponents(exponent: Callable[[str], np.ndarray]) -> str:
    """The exponent of each other reading of the first peak (``exponent(key)``), with the verdict it would give:
    the convention decides these rows where the readings' verdicts differ (a reading no seed gives is left out)."""
    got = ((label, exponent(key)) for label, key in F1_CANDIDATES)
    return "with the other readings of f1: " + "; ".join(
        f"{label} {_exponent_verdict(b)}" for label, b in got if np.isfinite(b).any()
    )


def sweep_exponents(results: dict[str, dict], key: str = "f1") -> tuple[np.ndarray, dict[str, Any], list[float]]:
    """f ∝ A^b per seed over the mean areas of SWEEP (at least 3 areas per seed) with f the per-pad measure ``key``:
    (b per seed, the pooled fit, the mean areas [mm²])."""
    points: dict[int, list[tuple[float, float]]] = {}
    for name in SWEEP:
        for p in usable(results.get(name)):
            f = _get(p, key)
            if math.isfinite(f):
                points.setdefault(int(p["seed"]), []).append((p["mean_area_m2"], f))
    b, pooled = _fit_per_seed(points)
    return b, pooled, sorted({round(a / MM2, 2) for pts in points.values() for a, _ in pts})


def exponent_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """f1 ∝ A^b per seed over the mean areas of SWEEP; b against −1/4, the other readings of f1 beside it."""
    b, pooled, areas = sweep_exponents(results)
    note = f"f1 from Σu̇ (its largest peak); fit per seed over the mean areas {', '.join(f'{a:g}' for a in areas)} mm²"
    if pooled.get("stderr") is not None:
        note += (
            f"; pooled over all {pooled['n_points']} pads {pooled['exponent']:.3f} ± {pooled['stderr']:.3f} (1 s.e.)"
        )
    note += "; " + _candidate_exponents(lambda key: sweep_exponents(results, key)[0])
    return RowValue(interval(b, ".3f"), value_verdict(b, PAPER_EXPONENT, EXPONENT_TOLERANCE), note)


def two_area_exponent(results: dict[str, dict], key: str, pairs: tuple[tuple[str, str], ...]) -> np.ndarray:
    """b = ln(f(big)/f(small)) / ln(A(big)/A(small)) per seed, the pairs of presets pooled by seed (mean)."""
    per: dict[int, list[float]] = {}
    for big, small in pairs:
        fb, fs = (by_seed(results.get(n), lambda p: math.log(_get(p, key))) for n in (big, small))
        ab, as_ = (by_seed(results.get(n), lambda p: math.log(p["mean_area_m2"])) for n in (big, small))
        for s in sorted(set(fb) & set(fs) & set(ab) & set(as_)):
            per.setdefault(s, []).append((fb[s] - fs[s]) / (ab[s] - as_[s]))
    return np.array([np.mean(v) for v in per.values()])


def two_area_row(results: dict[str, dict], cfg: Config) -> RowValue:
    b = two_area_exponent(results, "f1", (("hf2", "hf1"),))
    return RowValue(
        interval(b, ".3f"),
        value_verdict(b, PAPER_EXPONENT, EXPONENT_TOLERANCE),
        f"first peaks (Σu̇, its largest) {each(results, ('hf1', 'hf2'), 'f1', '.1f', 1e-3, 'kHz')}; the paper's own "
        f"peaks (73 and 32.8 kHz at 0.05 and 1.25 mm²) give {math.log(32.8 / 73.0) / math.log(25.0):.3f}; HF3/HF4 "
        f"{interval(two_area_exponent(results, 'f1', (('hf4', 'hf3'),)), '.3f')}; "
        + _candidate_exponents(lambda key: two_area_exponent(results, key, (("hf2", "hf1"),))),
    )


def sync_exponent_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """The same exponent from S's first feature f_S (relative rule; snr beside), both pairs pooled by seed."""
    pairs = (("hf2", "hf1"), ("hf4", "hf3"))
    b = two_area_exponent(results, "sync_relative.f_sync", pairs)
    snr = two_area_exponent(results, "sync_snr.f_sync", pairs)
    return RowValue(
        interval(b, ".3f"),
        value_verdict(b, PAPER_EXPONENT, EXPONENT_TOLERANCE),
        "f_S: the first peak (≥ ¼ of the largest) of max(S − S_null, 0)·Φ smoothed over 5 bins, relative rule; "
        f"per preset {each(results, PRESETS, 'sync_relative.f_sync', '.1f', 1e-3, 'kHz')}; snr rule "
        f"{interval(snr, '.3f')}",
    )


FIRST_PEAK_ROWS = tuple(
    Row("§3.1, Fig. 8", f"{n.upper()}: first velocity-spectrum peak", f"≈ {PAPER_PEAK_HZ[n] / 1e3:g} kHz", "value",
        (n,), first_peak_row(n), f"± {100 * PEAK_TOLERANCE:g} %")
    for n in PRESETS
)  # fmt: skip
LAW_ROWS = (
    Row("§3.1", "f_p ∝ A_p^(−1/4): exponent of the first velocity peak against the mean patch area", "−1/4", "value",
        SWEEP, exponent_row, f"± {EXPONENT_TOLERANCE:g}", min_experiments=3),
    Row("§3.1", "f_p ∝ A_p^(−1/4) from the two patch sizes of Table 1 (HF1, HF2)", "−1/4", "value", ("hf1", "hf2"),
        two_area_row, f"± {EXPONENT_TOLERANCE:g}"),
    Row("§3.1, Fig. 9", "the A_p^(−1/4) shift is also seen in the Synchronization Indices (HF1→HF2, HF3→HF4)",
        "−1/4", "value", PRESETS, sync_exponent_row, f"± {EXPONENT_TOLERANCE:g}", uses=("sync",)),
)  # fmt: skip


# ------------------------------------------------------------------------------------------------ the shapes


def per_preset(
    results: dict[str, dict], value: Callable[[dict[str, Any]], float]
) -> tuple[list[str], dict[str, np.ndarray]]:
    """Per preset: "name: interval" of value(pad), and the values."""
    vals = {n: np.array(list(by_seed(results.get(n), value).values())) for n in PRESETS}
    return [f"{n}: {interval(v)}" for n, v in vals.items()], vals


def _shape_per_preset(
    results: dict[str, dict], measure: str, combine: Callable[[float, float], float], margin: float, suffix: str
) -> tuple[list[str], str]:
    """Per preset "name: interval" of ``combine(velocity's, the largest of μ's, torque's and radius's)`` of the
    shape ``measure`` ("contrast" or "plateau") with the keys' ``suffix``, and the direction verdict at ``margin``."""

    def value(p: dict[str, Any]) -> float:
        others = max(_get(p, f"{measure}_{k}{suffix}") for k in ("mu", "torque", "radius"))
        return combine(_get(p, f"{measure}_velocity{suffix}"), others)

    texts, vals = per_preset(results, value)
    return texts, direction_verdict([effect(v, margin) for v in vals.values()])


def _abs_reading(
    results: dict[str, dict], measure: str, combine: Callable[[float, float], float], margin: float
) -> str:
    """The same row read on Σ|u̇|'s spectrum at its own largest peak (the other reading of Fig. 8's velocity
    spectrum, :data:`F1_CANDIDATES`), for the notes; empty where the results hold no Σ|u̇| reading."""
    if not held_in(results, PRESETS, f"{measure}_velocity_abs"):
        return ""
    texts, verdict = _shape_per_preset(results, measure, combine, margin, "_abs")
    where = "read on Σ|u̇|'s spectrum at its own largest peak (μ's, torque's, radius's there)"
    return f"; {where}: {'; '.join(texts)} ({verdict})"


def _log_ratio(a: float, b: float) -> float:
    return math.log(a / b)


def _difference(a: float, b: float) -> float:
    return a - b


def pronounced_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """ln of the velocity spectrum's peak contrast at f1 over the largest of μ's, torque's and radius's."""
    texts, verdict = _shape_per_preset(results, "contrast", _log_ratio, PRONOUNCED_MARGIN, "")
    return RowValue(
        "ln(contrast ratio) " + "; ".join(texts),
        verdict,
        "contrast = height at f1 over the median of [f1/2, 2 f1]; velocity = |Σu̇(f)| / mean Σ|u̇|; μ's contrast "
        + each(results, PRESETS, "contrast_mu", ".2g")
        + _abs_reading(results, "contrast", _log_ratio, PRONOUNCED_MARGIN),
    )


def plateau_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """Plateau excess of the velocity spectrum minus the largest of μ's, torque's and radius's."""
    texts, verdict = _shape_per_preset(results, "plateau", _difference, PLATEAU_MARGIN, "")
    return RowValue(
        "excess difference " + "; ".join(texts),
        verdict,
        "excess = ln median [1.1, 2] f1 − ln median [2.5, 4] f1; velocity's own excess "
        + each(results, PRESETS, "plateau_velocity", ".2g")
        + _abs_reading(results, "plateau", _difference, PLATEAU_MARGIN),
    )


def _limit_row(
    results: dict[str, dict], key: str, label: str, limit: float, above: bool, note: str, contrast: str
) -> RowValue:
    """``label`` and the value of ``key`` per preset, each against ``limit`` (:func:`threshold_verdict`, ``above``);
    ``note`` and the value of ``contrast`` per preset."""
    texts, vals = per_preset(results, lambda p: _get(p, key))
    return RowValue(
        f"{label} " + "; ".join(texts),
        all_of([threshold_verdict(v, limit, above) for v in vals.values()]),
        f"{note} " + each(results, PRESETS, contrast, ".2g"),
    )


def overlap_row(results: dict[str, dict], cfg: Config) -> RowValue:
    note = "D = mean |ln a − ln b| over 1–200 kHz; for contrast D(μ, friction radius)"
    return _limit_row(results, "overlap_mu_torque", "D(μ, torque)", OVERLAP_LIMIT, True, note, "overlap_mu_radius")


def shared_row(results: dict[str, dict], cfg: Config) -> RowValue:
    note = "peaks ≥ 4× their surroundings, within 2 bins, 1–200 kHz; chance"
    return _limit_row(results, "shared_fraction", "share of μ's peaks", SHARED_LIMIT, False, note, "shared_chance")


def shared_velocity_row(results: dict[str, dict], cfg: Config) -> RowValue:
    label = "share of the peaks shared by μ, torque and radius also in the velocity spectrum"
    note = "within 2 bins, 1–200 kHz; chance of a μ peak meeting a velocity peak"
    return _limit_row(results, "shared_in_velocity", label, SHARED_LIMIT, False, note, "shared_in_velocity_chance")


def _rules(results: dict[str, dict], key: str) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    rel = {n: values(results.get(n), f"sync_relative.{key}") for n in PRESETS}
    snr = {n: values(results.get(n), f"sync_snr.{key}") for n in PRESETS}
    return rel, snr


def features_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """S − S_null over the first peak and its plateau against the rest of the band; Φ's share there beside."""
    rel, snr = _rules(results, "excess_peak_plateau")
    phi = {n: values(results.get(n), "sync_relative.phi_peak_plateau") for n in PRESETS}
    verdict = direction_verdict([effect(v, FEATURE_MARGIN) for v in rel.values()])
    for n in PRESETS:
        verdict = rules_verdict(verdict, rel[n], snr[n])
    return RowValue(
        "Δ(S − S_null), [0.9 f1, 2 f1] − rest of the band, relative rule: "
        + "; ".join(f"{n}: {interval(v)}" for n, v in rel.items()),
        verdict,
        "snr rule "
        + "; ".join(f"{n}: {interval(v)}" for n, v in snr.items())
        + "; Δ Φ/patches there (relative) "
        + "; ".join(f"{n}: {interval(v)}" for n, v in phi.items()),
    )


def unmatched_row(results: dict[str, dict], cfg: Config) -> RowValue:
    texts, vals = per_preset(results, lambda p: _get(p, "sync_relative.mu_hf_unmatched"))
    snr = {n: values(results.get(n), "sync_snr.mu_hf_unmatched") for n in PRESETS}
    return RowValue(
        "share of μ's peaks above 2 f1 with no synchronised bin (S − S_null > 0.05) within 2 bins, relative rule: "
        + "; ".join(texts),
        all_of([threshold_verdict(v, UNMATCHED_LIMIT, False) for v in vals.values()]),
        "peaks ≥ 4× their surroundings; their number "
        + each(results, PRESETS, "sync_relative.mu_hf_peaks", ".3g")
        + "; snr rule "
        + "; ".join(f"{n}: {interval(v)}" for n, v in snr.items())
        + _unmatched_against_chance(results),
    )


def _unmatched_against_chance(results: dict[str, dict]) -> str:
    """The other reading of "do not correspond": the share against chance (less the share of the bins above 2 f1
    with no synchronised bin within 2 bins, what a peak placed there at random would give) per preset, with the
    verdict it would give (:data:`CHANCE_MARGIN`); empty where the results hold no chance share."""
    if not held_in(results, PRESETS, "sync_relative.mu_hf_unmatched_chance"):
        return ""
    texts, vals = per_preset(
        results, lambda p: _get(p, "sync_relative.mu_hf_unmatched") - _get(p, "sync_relative.mu_hf_unmatched_chance")
    )
    verdict = all_of([threshold_verdict(v, -CHANCE_MARGIN, False) for v in vals.values()])
    return (
        "; against chance (the share − that of the bins above 2 f1 with no synchronised bin within 2 bins) "
        + "; ".join(texts)
        + f" ({verdict}: ≥ −{CHANCE_MARGIN:g} in each preset, at S at most that much more often than at random)"
    )


def single_patch_row(results: dict[str, dict], cfg: Config) -> RowValue:
    texts, vals = per_preset(results, lambda p: -math.log(_get(p, "sync_relative.mu_hf_phi_ratio")))
    return RowValue(
        "−ln(Φ at those peaks / median Φ above 2 f1) " + "; ".join(texts),
        direction_verdict([effect(v, SINGLE_MARGIN) for v in vals.values()]),
        "few patches oscillating at a μ peak without S: individual patches; the ratio "
        + each(results, PRESETS, "sync_relative.mu_hf_phi_ratio", ".2g"),
    )


SHAPE_ROWS = (
    Row("§3.1, Fig. 8", "the first velocity peak is significantly more pronounced than in μ, torque, friction radius",
        "yes, in all four", "direction", PRESETS, pronounced_row, "ln ratio > 0 in each preset, margin ln 2"),
    Row("§3.1, Fig. 8", "broad-band plateaus follow the first peak in the velocity spectra, not in the other outputs",
        "yes, in all four", "direction", PRESETS, plateau_row, "excess difference > 0 in each preset, margin ln 1.5"),
    Row("§3.1, Fig. 8", "μ and torque spectra nearly completely overlap", "yes", "threshold", PRESETS, overlap_row,
        f"D ≤ ln 1.25 = {OVERLAP_LIMIT:.3f} in each preset"),
    Row("§3.1, Fig. 8", "similar characteristic peaks of μ, torque and friction radius", "yes", "threshold", PRESETS,
        shared_row, f"share ≥ {SHARED_LIMIT:g} in each preset"),
    Row("§3.1, Fig. 8", "most of those shared peaks are also present in the velocity spectra", "most", "threshold",
        PRESETS, shared_velocity_row, f"share ≥ {SHARED_LIMIT:g} in each preset"),
    Row("§3.1, Figs. 8/9", "the first peaks and plateaus correspond well to the Synchronization Index results",
        "S high there", "direction", PRESETS, features_row, f"Δ > 0 in each preset, margin {FEATURE_MARGIN:g}",
        uses=("sync",)),
    Row("§3.1, Figs. 8/9", "many μ peaks at higher frequencies do not correspond to any Synchronization Index result",
        "many", "threshold", PRESETS, unmatched_row, f"share ≥ {UNMATCHED_LIMIT:g} in each preset", uses=("sync",)),
    Row("§3.1, Fig. 8", "those peaks are caused by individual, highly influential patches (few oscillate there)",
        "likely", "direction", PRESETS, single_patch_row, "−ln ratio > 0 in each preset, margin ln 2", uses=("sync",)),
)  # fmt: skip


# ------------------------------------------------------------------------------------------------ larger patches


PAIRS = (("hf2", "hf1"), ("hf4", "hf3"))


def _log_pairs(results: dict[str, dict], key: str, pairs: tuple[tuple[str, str], ...] = PAIRS) -> list[np.ndarray]:
    """ln(measure ``key`` of a / of b) per seed, for each preset pair (a, b) of ``pairs`` (the pads of one seed)."""
    return [paired(*(by_seed(results.get(n), lambda p: math.log(_get(p, key))) for n in (a, b))) for a, b in pairs]


def larger_height_row(results: dict[str, dict], cfg: Config) -> RowValue:
    d = _log_pairs(results, "peak_height")
    return RowValue(
        "; ".join(f"{b}/{s}: height {ratio_interval(x)}" for (b, s), x in zip(PAIRS, d, strict=True)),
        direction_verdict([effect(x, RATIO_MARGIN) for x in d]),
        "height of the velocity spectrum's peak at f1 (|Σu̇(f)| / mean Σ|u̇|); "
        + "; ".join(effect_text(x, RATIO_MARGIN) for x in d),
    )


def larger_width_row(results: dict[str, dict], cfg: Config) -> RowValue:
    d = _log_pairs(results, "peak_relative_width")
    hz = _log_pairs(results, "peak_width")
    bins = {n: values(results.get(n), "peak_width_bins") for n in PRESETS}
    verdict = direction_verdict([effect(x, RATIO_MARGIN, -1.0) for x in d])
    unresolved = [n for n, v in bins.items() if v.size and np.median(v) < RESOLVED_BINS]
    if unresolved:
        verdict = NOT_COMPARABLE
    return RowValue(
        "; ".join(f"{b}/{s}: relative width Δf/f {ratio_interval(x)}" for (b, s), x in zip(PAIRS, d, strict=True)),
        verdict,
        "FWHM of the amplitude of the velocity spectrum's peak at f1 over its own saturated span; in Hz "
        + "; ".join(f"{b}/{s} {ratio_interval(x)}" for (b, s), x in zip(PAIRS, hz, strict=True))
        + "; width in bins " + "; ".join(f"{n}: {interval(v)}" for n, v in bins.items())
        + (f"; not comparable: the peaks of {', '.join(unresolved)} are narrower than {RESOLVED_BINS:g} bins (the "
           "window's own width); the paper's record length is not stated" if unresolved else ""),
    )  # fmt: skip


def larger_frequency_row(results: dict[str, dict], cfg: Config) -> RowValue:
    d = _log_pairs(results, "f1")
    return RowValue(
        "; ".join(f"{b}/{s}: f1 {ratio_interval(x)}" for (b, s), x in zip(PAIRS, d, strict=True)),
        direction_verdict([effect(x, RATIO_MARGIN, -1.0) for x in d]),
        "first peaks from Σu̇; " + "; ".join(effect_text(x, RATIO_MARGIN, -1.0) for x in d),
    )


M_PAIRS = (("hf3", "hf1"), ("hf4", "hf2"))  # M = 0.4 against M = 0.8, each patch size (one seed: the same patches)


def m_independent_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """§3.1 gives one first peak per patch size for both friction levels ("around 73 kHz for HF1 and HF3, and
    around 32.8 kHz for HF2 and HF4"): the peak does not move with M, within the ± 5 % the values are read to."""
    d = _log_pairs(results, "f1", M_PAIRS)
    margin = math.log1p(PEAK_TOLERANCE)

    def reading(key: str) -> str:
        parts = _log_pairs(results, key, M_PAIRS)
        return (
            ", ".join(f"{a}/{b} {ratio_interval(x)}" for (a, b), x in zip(M_PAIRS, parts, strict=True))
            + f" ({all_of([equivalence_verdict(x, margin) for x in parts])})"
        )

    return RowValue(
        "; ".join(f"{a}/{b}: f1 {ratio_interval(x)}" for (a, b), x in zip(M_PAIRS, d, strict=True)),
        all_of([equivalence_verdict(x, margin) for x in d]),
        "first peaks from Σu̇, paired by seed (one seed's HF1 and HF3 pads, and its HF2 and HF4 pads, have the same "
        "patches); the other readings of the first peak: "
        + "; ".join(f"{label}: {reading(key)}" for label, key in F1_CANDIDATES if held_in(results, PRESETS, key)),
    )


SIZE_ROWS = (
    Row("§3.1, Fig. 8", "the first velocity peak does not depend on M (HF3 as HF1, HF4 as HF2)",
        "≈ 73 kHz for HF1 and HF3, ≈ 32.8 kHz for HF2 and HF4", "equivalence", PRESETS, m_independent_row,
        "ln ratio within ± ln 1.05 in both pairs, the tolerance each paper value is read to"),
    Row("§3.1, Fig. 8", "larger patches (HF2, HF4): the peaks have increased amplitudes", "higher", "direction",
        PRESETS, larger_height_row, "ln ratio > 0 in both pairs, margin ln 1.25"),
    Row("§3.1, Fig. 8", "larger patches (HF2, HF4): the peaks are narrower", "narrower", "direction", PRESETS,
        larger_width_row, "ln ratio < 0 in both pairs, margin ln 1.25"),
    Row("§3.1, Fig. 8", "larger patches (HF2, HF4): the peaks occur at lower frequencies", "lower", "direction",
        PRESETS, larger_frequency_row, "ln ratio < 0 in both pairs, margin ln 1.25"),
)  # fmt: skip


def register() -> None:
    """Register the §3.1 rows on the spectra of Fig. 8."""
    for row in (*FIRST_PEAK_ROWS, *LAW_ROWS, *SHAPE_ROWS, *SIZE_ROWS):
        register_row(row)
