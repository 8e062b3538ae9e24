"""Validation of §3.1 (stand-alone HF, Table 1, Figs. 4/6, 8 and 9) from seed ensembles: the experiments of the
four presets (HF1–HF4; HF1 also from rest, for the initial-state comparison) and of the patch-area sweep, and the
rows on the first velocity peak, the A_p^(−1/4) law, the shapes of the Fig. 8 spectra and the synchronisation of
Fig. 9.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from aca_warp.studies.validation.base import (
    MM2,
    Config,
    Experiment,
    Row,
    RowValue,
    _all_of,
    _get,
    by_seed,
    ci,
    direction_verdict,
    equal_phi,
    equal_verdict,
    interval,
    paired,
    register_experiment,
    register_row,
    side,
    tables,
    threshold_verdict,
    usable,
    value_verdict,
    values,
)
from aca_warp.studies.validation.measures import FIRST_PEAK_FRACTION, SNAPSHOTS

PAPER = {
    "first_peak_hz": {"hf1": 73.0e3, "hf2": 32.8e3, "hf3": 73.0e3, "hf4": 32.8e3},
    "exponent": -0.25,
    "source": "Merlis & Ostermeyer 2019",
}

SWEEP_AREAS_MM2 = (0.125, 0.3, 0.6)  # between hf1 (0.05) and hf2 (1.25): five mean areas with the presets

for _exp in (
    Experiment("hf1", "§3.1", "HF1: 0.02–0.08 mm², M = 0.8, 487.2 N", "hf1"),
    Experiment("hf2", "§3.1", "HF2: 0.5–2 mm², M = 0.8, 12.37 kN", "hf2"),
    Experiment("hf3", "§3.1", "HF3: 0.02–0.08 mm², M = 0.4, 487.2 N", "hf3"),
    Experiment("hf4", "§3.1", "HF4: 0.5–2 mm², M = 0.4, 12.37 kN", "hf4"),
    Experiment("hf1_rest", "§3.1", "HF1 started from rest (initial-state comparison)", "hf1", initial="rest"),
    *(
        Experiment(
            f"sweep_{a:g}".replace(".", "p"),
            "§3.1",
            f"area sweep: mean {a:g} mm² (uniform 0.4–1.6 × mean), hf1 pressure, M = 0.8",
            "hf1",
            mean_area_mm2=a,
        )
        for a in SWEEP_AREAS_MM2
    ),
):
    register_experiment(_exp)
SWEEP = ("hf1", *(f"sweep_{a:g}".replace(".", "p") for a in SWEEP_AREAS_MM2), "hf2")


PRESETS = ("hf1", "hf2", "hf3", "hf4")
PEAK_TOLERANCE = 0.05  # relative: "around 73 kHz" read off Fig. 8
EXPONENT_TOLERANCE = 0.025  # absolute: 10 % of 1/4
OVERLAP_LIMIT = math.log(1.25)  # D = mean |ln μ − ln T| ≤ ln 1.25: a typical difference below 25 %
SHARED_LIMIT = 0.5  # "similar characteristic peaks": at least half of μ's peaks in torque and radius too
EQUAL_MARGIN = 0.05  # S − S_null: a difference below 0.05 counts as "not significantly affected"


def _first_peak(name: str) -> Callable[[dict[str, dict], Config], RowValue]:
    def measure(results: dict[str, dict], cfg: Config) -> RowValue:
        f = values(results.get(name), "f1")
        paper = PAPER["first_peak_hz"][name]
        sumv = values(results.get(name), "peak_frequency")
        largest = values(results.get(name), "f_largest")
        return RowValue(
            interval(f, ".1f", 1e-3, "kHz"),
            value_verdict(f, paper, PEAK_TOLERANCE * paper),
            f"first peak: the lowest peak of the mean per-patch velocity spectrum reaching {FIRST_PEAK_FRACTION:g} of "
            f"its maximum; the Σu̇ spectrum's peak there {interval(sumv, '.1f', 1e-3, 'kHz')}; the largest peak "
            f"{interval(largest, '.1f', 1e-3, 'kHz')}",
        )

    return measure


for _name in PRESETS:
    register_row(
        Row(
            "§3.1, Fig. 8",
            f"{_name.upper()}: first velocity-spectrum peak",
            f"≈ {PAPER['first_peak_hz'][_name] / 1e3:g} kHz",
            "value",
            (_name,),
            _first_peak(_name),
            f"± {100 * PEAK_TOLERANCE:g} %",
        )
    )


def exponent_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """f1 ∝ A^b per seed over the mean areas of SWEEP (at least 3 areas per seed); b against −1/4."""
    from aca_warp.studies.hf_study.base import fit_power_law

    points: dict[int, list[tuple[float, float]]] = {}
    for name in SWEEP:
        for p in usable(results.get(name)):
            f = _get(p, "f1")
            if math.isfinite(f):
                points.setdefault(int(p["seed"]), []).append((p["mean_area_m2"], f))
    b = np.array(
        [fit_power_law(*map(np.array, zip(*pts, strict=True)))["exponent"] for pts in points.values() if len(pts) >= 3]
    )
    allp = [q for pts in points.values() for q in pts]
    pooled = fit_power_law(*map(np.array, zip(*allp, strict=True))) if len(allp) >= 3 else {}
    areas = sorted({round(a / MM2, 3) for a, _ in allp})
    note = f"fit per seed over the mean areas {', '.join(f'{a:g}' for a in areas)} mm²"
    if pooled.get("stderr") is not None:
        note += (
            f"; pooled over all {pooled['n_points']} pads {pooled['exponent']:.3f} ± {pooled['stderr']:.3f} (1 s.e.)"
        )
    return RowValue(interval(b, ".3f"), value_verdict(b, PAPER["exponent"], EXPONENT_TOLERANCE), note)


register_row(
    Row(
        "§3.1",
        "f_p ∝ A_p^(−1/4): exponent of the first velocity peak against the mean patch area",
        "−1/4",
        "value",
        SWEEP,
        exponent_row,
        f"± {EXPONENT_TOLERANCE:g}",
        min_experiments=3,
    )
)


def two_area_exponent_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """b = ln(f1(HF2)/f1(HF1)) / ln(A(HF2)/A(HF1)) per seed (the two presets of the paper, paired by seed)."""

    def lnf(name: str) -> dict[int, float]:
        return by_seed(results.get(name), lambda p: math.log(_get(p, "f1")))

    def lna(name: str) -> dict[int, float]:
        return by_seed(results.get(name), lambda p: math.log(p["mean_area_m2"]))

    df, da = paired(lnf("hf2"), lnf("hf1")), paired(lna("hf2"), lna("hf1"))
    b = df / da if df.size == da.size else np.array([])
    f1 = [interval(values(results.get(n), "f1"), ".1f", 1e-3, "kHz") for n in ("hf1", "hf2")]
    return RowValue(
        interval(b, ".3f"),
        value_verdict(b, PAPER["exponent"], EXPONENT_TOLERANCE),
        f"first peaks hf1 {f1[0]}, hf2 {f1[1]}; the paper's own peaks (73 and 32.8 kHz at 0.05 and 1.25 mm²) give "
        f"{math.log(32.8 / 73.0) / math.log(25.0):.3f}",
    )


register_row(
    Row(
        "§3.1",
        "f_p ∝ A_p^(−1/4) from the two patch sizes of Table 1 (HF1, HF2)",
        "−1/4",
        "value",
        ("hf1", "hf2"),
        two_area_exponent_row,
        f"± {EXPONENT_TOLERANCE:g}",
    )
)


def _per_preset(
    results: dict[str, dict], value: Callable[[dict[str, Any]], float], verdict: Callable[[np.ndarray], Any]
) -> tuple[list[str], list[Any]]:
    """Per preset: the interval text of value(pad) and verdict(values)."""
    texts, verdicts = [], []
    for name in PRESETS:
        v = np.array(list(by_seed(results.get(name), value).values()))
        texts.append(f"{name}: {interval(v)}")
        verdicts.append(verdict(v))
    return texts, verdicts


def _combine(sides: list[int]) -> str:
    return direction_verdict(sides)


def pronounced_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """ln of the velocity spectrum's peak contrast at f1 over the largest of μ's, torque's and radius's."""

    def ratio(p: dict[str, Any]) -> float:
        others = max(_get(p, k) for k in ("contrast_mu", "contrast_torque", "contrast_radius"))
        return math.log(_get(p, "contrast_velocity") / others)

    texts, sides = _per_preset(results, ratio, side)
    mu = [f"{n}: μ {interval(values(results.get(n), 'contrast_mu'), '.2g')}" for n in PRESETS]
    return RowValue(
        "ln(contrast ratio) " + "; ".join(texts),
        _combine(sides),
        "contrast = height at f1 over the median of [f1/2, 2 f1]; velocity = |Σu̇(f)| / mean Σ|u̇|; " + "; ".join(mu),
    )


def plateau_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """Plateau excess of the velocity spectrum minus the largest of μ's, torque's and radius's."""

    def diff(p: dict[str, Any]) -> float:
        return _get(p, "plateau_velocity") - max(_get(p, k) for k in ("plateau_mu", "plateau_torque", "plateau_radius"))

    texts, sides = _per_preset(results, diff, side)
    vel = [f"{n}: {interval(values(results.get(n), 'plateau_velocity'), '.2g')}" for n in PRESETS]
    return RowValue(
        "excess difference " + "; ".join(texts),
        _combine(sides),
        "excess = ln median [1.1, 2] f1 − ln median [2.5, 4] f1; velocity's own excess " + "; ".join(vel),
    )


def overlap_row(results: dict[str, dict], cfg: Config) -> RowValue:
    texts, verdicts = _per_preset(
        results, lambda p: _get(p, "overlap_mu_torque"), lambda v: threshold_verdict(v, OVERLAP_LIMIT, True)
    )
    radius = [f"{n}: {interval(values(results.get(n), 'overlap_mu_radius'), '.2g')}" for n in PRESETS]
    return RowValue(
        "D(μ, torque) " + "; ".join(texts),
        _all_of(verdicts),
        "D = mean |ln a − ln b| over 1–200 kHz; for contrast D(μ, friction radius) " + "; ".join(radius),
    )


def shared_row(results: dict[str, dict], cfg: Config) -> RowValue:
    texts, verdicts = _per_preset(
        results, lambda p: _get(p, "shared_fraction"), lambda v: threshold_verdict(v, SHARED_LIMIT, False)
    )
    chance = [f"{n}: {interval(values(results.get(n), 'shared_chance'), '.2g')}" for n in PRESETS]
    vel = [f"{n}: {interval(values(results.get(n), 'shared_in_velocity'), '.2g')}" for n in PRESETS]
    return RowValue(
        "share of μ's peaks " + "; ".join(texts),
        _all_of(verdicts),
        "peaks ≥ 4× their surroundings, within 2 bins, 1–200 kHz; chance "
        + "; ".join(chance)
        + "; share of the shared peaks also in the velocity spectrum "
        + "; ".join(vel),
    )


for _row in (
    Row("§3.1, Fig. 8", "the first velocity peak is significantly more pronounced than in μ, torque, friction radius",
        "yes, in all four", "direction", PRESETS, pronounced_row, "ln ratio > 0 in each preset"),
    Row("§3.1, Fig. 8", "broad-band plateaus follow the first peak in the velocity spectra, not in the other outputs",
        "yes, in all four", "direction", PRESETS, plateau_row, "excess difference > 0 in each preset"),
    Row("§3.1, Fig. 8", "μ and torque spectra nearly completely overlap", "yes", "threshold", PRESETS, overlap_row,
        f"D ≤ ln 1.25 = {OVERLAP_LIMIT:.3f} in each preset"),
    Row("§3.1, Fig. 8", "similar characteristic peaks of μ, torque and friction radius", "yes", "threshold", PRESETS,
        shared_row, f"share ≥ {SHARED_LIMIT:g} in each preset"),
):  # fmt: skip
    register_row(_row)


def _sync_claim(results: dict[str, dict], a: str, b: str) -> tuple[str, str, list[int], int]:
    """S of a above S of b at equal Φ: primary (relative rule, S − S_null) and the secondary measures."""
    primary, classes = equal_phi(results, a, b)
    sec = {
        "raw S, relative": equal_phi(results, a, b, value="S")[0],
        "S − S_null, snr": equal_phi(results, a, b, rule="snr")[0],
        "median S − S_null (Φ ≥ 10), relative": paired(
            by_seed(results.get(a), lambda p: _get(p, "sync_relative.median_excess_phi10")),
            by_seed(results.get(b), lambda p: _get(p, "sync_relative.median_excess_phi10")),
        ),
    }
    notes = f"{classes}; " + "; ".join(f"{k}: {interval(v)}" for k, v in sec.items())
    return interval(primary), notes, [side(v) for v in sec.values()], side(primary)


def lower_m_row(a: str, b: str) -> Callable[[dict[str, dict], Config], RowValue]:
    def measure(results: dict[str, dict], cfg: Config) -> RowValue:
        value, notes, sec, prim = _sync_claim(results, a, b)
        return RowValue(f"Δ(S − S_null) at equal Φ {a} − {b}: {value}", direction_verdict([prim], sec), notes)

    return measure


def less_for_large_row(results: dict[str, dict], cfg: Config) -> RowValue:
    small, _ = equal_phi(results, "hf3", "hf1")
    large, _ = equal_phi(results, "hf4", "hf2")
    ds = by_seed_pairs(results, ("hf3", "hf1"), ("hf4", "hf2"))
    return RowValue(
        f"(hf3 − hf1) − (hf4 − hf2): {interval(ds)}",
        direction_verdict([side(ds)]),
        f"Δ at equal Φ (relative rule, S − S_null): small patches {interval(small)}, large patches {interval(large)}",
    )


def by_seed_pairs(results: dict[str, dict], first: tuple[str, str], second: tuple[str, str]) -> np.ndarray:
    """Per seed, the equal-Φ difference of ``first`` minus that of ``second`` (S − S_null, relative rule)."""
    from aca_warp.analysis.measures import equal_prevalence_difference

    ts = {n: tables(results.get(n), "relative") for n in (*first, *second)}
    seeds = [s for s in sorted(ts[first[0]]) if all(s in ts[n] for n in ts)]
    if not seeds:
        return np.array([])
    d1 = equal_prevalence_difference([ts[first[0]][s] for s in seeds], [ts[first[1]][s] for s in seeds]).difference
    d2 = equal_prevalence_difference([ts[second[0]][s] for s in seeds], [ts[second[1]][s] for s in seeds]).difference
    return d1 - d2


def larger_peaks_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """HF2 vs HF1 and HF4 vs HF3: ln height ratio > 0, ln width ratio < 0, frequency ratio < 1 (velocity spectrum)."""
    texts, sides = [], []
    for big, small in (("hf2", "hf1"), ("hf4", "hf3")):
        parts = {}
        for key, sign in (("peak_height", 1.0), ("peak_width", -1.0), ("f1", -1.0)):
            d = paired(
                by_seed(results.get(big), lambda p, k=key: math.log(_get(p, k))),
                by_seed(results.get(small), lambda p, k=key: math.log(_get(p, k))),
            )
            parts[key] = d
            sides.append(side(d, sign))
        texts.append(
            f"{big}/{small}: height ×{_exp_interval(parts['peak_height'])}, "
            f"width ×{_exp_interval(parts['peak_width'])}, frequency ×{_exp_interval(parts['f1'])}"
        )
    rel = [f"{n}: {interval(values(results.get(n), 'peak_relative_width'), '.2g')}" for n in PRESETS]
    return RowValue(
        "; ".join(texts),
        direction_verdict(sides),
        "peak of the velocity spectrum at f1, FWHM of the amplitude; relative width Δf/f " + "; ".join(rel),
    )


def _exp_interval(d: np.ndarray) -> str:
    m, lo, hi = ci(d)
    if not math.isfinite(m):
        return "–"
    return f"{math.exp(m):.3g} [{math.exp(lo):.3g}, {math.exp(hi):.3g}]" if math.isfinite(lo) else f"{math.exp(m):.3g}"


def spread_row(results: dict[str, dict], cfg: Config) -> RowValue:
    texts, sides, notes = [], [], []
    for key, label in (("spread", "spread"), ("prevalence", "mean Φ")):
        d = paired(*(by_seed(results.get(n), lambda p, k=key: _get(p, f"sync_relative.{k}")) for n in ("hf2", "hf1")))
        texts.append(f"Δ {label} hf2 − hf1: {interval(d)}")
        sides.append(side(d))
        snr = paired(*(by_seed(results.get(n), lambda p, k=key: _get(p, f"sync_snr.{k}")) for n in ("hf2", "hf1")))
        notes.append(f"{label} (snr rule) {interval(snr)}")
    return RowValue(
        "; ".join(texts),
        direction_verdict(sides),
        "spread = share of the bins in [f1/8, 2 f1] with S − S_null > 0.05; mean Φ over that band; " + "; ".join(notes),
    )


def patterns_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """HF2 vs HF1: the size of the co-moving groups (where C(d) of the directions of motion falls to 0: larger) and
    C among coupled neighbours (better defined); the same of the spectral phases at f1 beside them."""
    parts = []
    for key in ("corr", "corr_f1"):
        d_size = paired(*(by_seed(results.get(n), lambda p, k=key: _get(p, f"{k}_zero")) for n in ("hf2", "hf1")))
        d_near = paired(*(by_seed(results.get(n), lambda p, k=key: _get(p, f"{k}_near")) for n in ("hf2", "hf1")))
        each = "; ".join(
            f"{n}: C near {interval(values(results.get(n), f'{key}_near'))}, zero at "
            f"{interval(values(results.get(n), f'{key}_zero'), '.3g', 1e3, 'mm')}"
            for n in ("hf1", "hf2")
        )
        parts.append((d_size, d_near, each))
    (d_size, d_near, each), (f_size, f_near, f_each) = parts
    return RowValue(
        f"Δ group size hf2 − hf1: {interval(d_size, '.3g', 1e3, 'mm')}; Δ C of coupled neighbours: {interval(d_near)}",
        direction_verdict([side(d_size), side(d_near)]),
        f"C(d) = ⟨s_i s_j⟩ of the directions of motion s = sign(u̇) at {SNAPSHOTS} instants (Figs. 4/6); "
        f"{each}; spectral phases at f1 (amplitude-weighted): Δ size {interval(f_size, '.3g', 1e3, 'mm')}, "
        f"Δ C near {interval(f_near)}; {f_each}",
    )


def hf1_hf2_row(results: dict[str, dict], cfg: Config) -> RowValue:
    d, classes = equal_phi(results, "hf2", "hf1")
    snr = equal_phi(results, "hf2", "hf1", rule="snr")[0]
    return RowValue(
        f"Δ(S − S_null) at equal Φ hf2 − hf1: {interval(d)}",
        equal_verdict(d, EQUAL_MARGIN),
        f"{classes}; snr rule {interval(snr)}",
    )


def agreement_row(results: dict[str, dict], cfg: Config) -> RowValue:
    rho = {n: by_seed(results.get(n), lambda p: _get(p, "sync_relative.agreement")) for n in PRESETS}
    diffs = {n: paired(rho["hf4"], rho[n]) for n in ("hf1", "hf2", "hf3")}
    snr = {n: by_seed(results.get(n), lambda p: _get(p, "sync_snr.agreement")) for n in PRESETS}
    return RowValue(
        "; ".join(f"ρ {n}: {interval(np.array(list(rho[n].values())))}" for n in PRESETS),
        direction_verdict([side(d) for d in diffs.values()]),
        "ρ = Spearman(S·Φ, |μ(f)|/μ̄) over 20–80 kHz; paired hf4 − other: "
        + "; ".join(f"{n} {interval(d)}" for n, d in diffs.items())
        + "; snr rule ρ "
        + "; ".join(f"{n} {interval(np.array(list(snr[n].values())))}" for n in PRESETS),
    )


def combination_row(results: dict[str, dict], cfg: Config) -> RowValue:
    spread = paired(*(by_seed(results.get(n), lambda p: _get(p, "sync_relative.spread")) for n in ("hf4", "hf1")))
    high, classes = equal_phi(results, "hf4", "hf1", which="table_high")
    whole, _ = equal_phi(results, "hf4", "hf1")
    return RowValue(
        f"Δ spread hf4 − hf1: {interval(spread)}; Δ(S − S_null) at equal Φ above f1: {interval(high)}",
        direction_verdict([side(spread), side(high), side(high - whole)]),
        f'the whole band: {interval(whole)}; above f1 minus whole band ("especially at higher frequencies"): '
        f"{interval(high - whole)}; {classes}",
    )


for _row in (
    Row("§3.1, Fig. 9", "lower M raises S significantly for small patches (HF3 vs HF1)", "S(HF3) > S(HF1)",
        "direction", ("hf1", "hf3"), lower_m_row("hf3", "hf1"), "Δ > 0", uses=("sync",)),
    Row("§3.1, Fig. 9", "lower M raises S for large patches too (HF4 vs HF2)", "S(HF4) > S(HF2)", "direction",
        ("hf2", "hf4"), lower_m_row("hf4", "hf2"), "Δ > 0", uses=("sync",)),
    Row("§3.1, Fig. 9", "the rise with lower M is not as substantial for the larger patches",
        "Δ(HF3 − HF1) > Δ(HF4 − HF2)", "direction", PRESETS, less_for_large_row, "difference > 0", uses=("sync",)),
    Row("§3.1, Fig. 8", "larger patches: peaks higher, narrower, at lower frequencies (HF2 vs HF1, HF4 vs HF3)",
        "yes", "direction", PRESETS, larger_peaks_row, "height ×>1, width ×<1, frequency ×<1 in both pairs"),
    Row("§3.1, Fig. 9", "larger patches spread S over more frequencies with higher prevalence Φ (HF2 vs HF1)", "yes",
        "direction", ("hf1", "hf2"), spread_row, "both Δ > 0", uses=("sync",)),
    Row("§3.1, Figs. 4/6", "larger patches: larger, better-defined synchronisation patterns (HF2 vs HF1)", "yes",
        "direction", ("hf1", "hf2"), patterns_row, "both Δ > 0"),
    Row("§3.1, Fig. 9", "HF1 vs HF2: the size increase does not significantly affect the synchronisation quality",
        "no significant difference", "equal", ("hf1", "hf2"), hf1_hf2_row, f"margin ± {EQUAL_MARGIN:g}",
        uses=("sync",)),
    Row("§3.1, Figs. 8/9", "HF4 shows the best agreement of S with the friction spectrum", "HF4 highest", "direction",
        PRESETS, agreement_row, "ρ(hf4) − ρ(other) > 0 for all three", uses=("sync",)),
    Row("§3.1, Fig. 9", "HF4 vs HF1: S more spread out, greater, especially at higher frequencies", "yes",
        "direction", ("hf1", "hf4"), combination_row, "three Δ > 0", uses=("sync",)),
):  # fmt: skip
    register_row(_row)
