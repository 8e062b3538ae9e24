"""§3.3 and §4 rows (multi-timescale study, Figs. 12–13): HF pads on the LF states of every seed
(:mod:`~aca_warp.studies.validation.multiscale`).

Every row reads the states of this project's LF automaton, whose rules and parameters (patch birth, growth and
destruction, the debris, the thermal model) the paper does not give, and whose application levels are this project's
choice within §3.3's order: the rows comparing μ's amplitudes between states say so first in their notes, beside the
spread over the states (:data:`ON_THIS_LF`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from aca_warp.studies.validation.base import (
    CHANCE_MARGIN,
    CHARACTERISTIC_BAND,
    Config,
    Row,
    RowValue,
    _get,
    by_seed,
    interval,
    member_result,
    paired,
    register_row,
    values,
)
from aca_warp.studies.validation.multiscale import MAIN, STATES
from aca_warp.studies.validation.verdicts import (
    NOT_MEASURED,
    NOT_REPRODUCED,
    PARTLY,
    REPRODUCED,
    all_of,
    direction_verdict,
    effect,
    rules_verdict,
    spread_text,
    threshold_verdict,
)

LOG_MARGIN = 0.1  # ln ratios of μ's amplitudes: at least 10 %
S_MARGIN = 0.05
RHO_MARGIN = 0.1
PHI_MARGIN = math.log(1.25)
MATCH_LIMIT = 0.8  # "a patch coverage state similar to the one present at the end of Application 2"
CAP_TOLERANCE = 0.02  # a first peak within 2 % of the LF cap frequency sits at it
# every §3.3 row reads the states of this project's LF automaton, whose rules and parameters the paper does not state
# (docs/lf_model.md); μ's amplitudes across the applications follow from those states most directly
ON_THIS_LF = (
    "on this project's LF automaton (the paper states neither its rules nor its parameters; the application levels, "
    "10/30/5/15 bar, are this project's choice within §3.3's order, turned into forces with the 370 N/bar of §3.1)"
)
AMPLITUDE_CRITERION = f"ln ratio > 0, margin {LOG_MARGIN:g}, on this LF automaton"


def state_values(results: dict[str, dict], names: tuple[str, ...], state: str, key: str) -> dict[int, float]:
    """Seed -> a pad measure (dotted key) of ``state`` over the experiments ``names``."""
    return by_seed(member_result(results, names, state), lambda p: _get(p, key))


def per_state(results: dict[str, dict], key: str, names: tuple[str, ...] = MAIN) -> dict[str, dict[int, float]]:
    return {s: state_values(results, names, s, key) for s in STATES}


def state_line(per: dict[str, dict[int, float]], spec: str = ".3g", scale: float = 1.0, unit: str = "") -> str:
    return "; ".join(f"{s} {interval(np.array(list(v.values())), spec, scale, unit)}" for s, v in per.items() if v)


def _ratio_to_others(per: dict[str, dict[int, float]], state: str, others: tuple[str, ...]) -> np.ndarray:
    """Per seed ln(value at ``state`` / the largest value of ``others``)."""
    out = []
    for seed, v in per[state].items():
        o = [per[s][seed] for s in others if seed in per[s]]
        if len(o) >= 1 and v > 0 and max(o) > 0:
            out.append(math.log(v / max(o)))
    return np.array(out)


def _largest(per: dict[str, dict[int, float]]) -> str:
    top: dict[str, int] = {}
    for seed in sorted({s for v in per.values() for s in v}):
        vals = {s: v[seed] for s, v in per.items() if seed in v}
        best = max(vals.items(), key=lambda kv: kv[1])[0]
        top[best] = top.get(best, 0) + 1
    return ", ".join(f"{k} ×{v}" for k, v in sorted(top.items(), key=lambda kv: -kv[1]))


def _amplitude_verdict(d: list[np.ndarray]) -> str:
    """The verdict of the ln ratios ``d`` (one part each) against :data:`LOG_MARGIN`."""
    return direction_verdict([effect(x, LOG_MARGIN) for x in d])


def _amplitude(value: str, d: list[np.ndarray], per: dict[str, dict[int, float]], extra: str = "") -> RowValue:
    """An amplitude row: every ln ratio of ``d`` against :data:`LOG_MARGIN`, read on this LF automaton; the spread of
    std μ over the states and the state with the largest per seed in the notes."""
    means = {s: float(np.mean(list(v.values()))) for s, v in per.items() if v}
    return RowValue(
        value,
        _amplitude_verdict(d),
        f"{ON_THIS_LF}: std μ over the states spans {spread_text(means)}; the largest per seed: {_largest(per)}"
        + (f"; {extra}" if extra else ""),
    )


# the states Fig. 13 shows (its rows: the start and end of applications 2 and 3, the start of application 4); the
# paper ran HF analyses at the start and end of every application, the primary reading of the amplitude rows
FIG13_STATES = ("app2_start", "app2_end", "app3_start", "app3_end", "app4_start")


def _fig13_reading(d: list[np.ndarray]) -> str:
    """The same ln ratios over Fig. 13's five states only, with the verdict they would give."""
    return f"over Fig. 13's five states only: {'; '.join(interval(x) for x in d)} ({_amplitude_verdict(d)})"


def greatest_row(results: dict[str, dict], cfg: Config) -> RowValue:
    per = per_state(results, "mu_std")
    d = _ratio_to_others(per, "app3_start", tuple(s for s in STATES if s != "app3_start"))
    fig = _ratio_to_others(per, "app3_start", tuple(s for s in FIG13_STATES if s != "app3_start"))
    return _amplitude(
        f"ln(std μ at app3_start / largest of the other states): {interval(d)}", [d], per, _fig13_reading([fig])
    )


def during_row(results: dict[str, dict], cfg: Config) -> RowValue:
    per = per_state(results, "mu_std")
    others = tuple(s for s in STATES if not s.startswith("app3"))
    d = [_ratio_to_others(per, s, others) for s in ("app3_start", "app3_end")]
    fig_others = tuple(s for s in FIG13_STATES if not s.startswith("app3"))
    fig = [_ratio_to_others(per, s, fig_others) for s in ("app3_start", "app3_end")]
    return _amplitude(
        f"ln(std μ / largest of the other applications' states): app3_start {interval(d[0])}; app3_end "
        f"{interval(d[1])}", d, per, _fig13_reading(fig),
    )  # fmt: skip


def start_end_row(results: dict[str, dict], cfg: Config) -> RowValue:
    per = per_state(results, "mu_std")
    d = paired(
        {s: math.log(v) for s, v in per["app3_start"].items()}, {s: math.log(v) for s, v in per["app3_end"].items()}
    )
    return _amplitude(f"ln(std μ app3_start / app3_end): {interval(d)}", [d], per)


def low_pressure_row(results: dict[str, dict], cfg: Config) -> RowValue:
    per = per_state(results, "mu_std")

    def mean_ln(states: tuple[str, ...]) -> dict[int, float]:
        seeds = set.intersection(*(set(per[s]) for s in states)) if all(per[s] for s in states) else set()
        return {k: float(np.mean([math.log(per[s][k]) for s in states])) for k in seeds}

    d = paired(mean_ln(("app3_start", "app3_end")), mean_ln(("app2_start", "app2_end")))
    return _amplitude(f"ln(std μ at 5 bar (app3) / at 30 bar (app2)), both states: {interval(d)}", [d], per)


def history_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """ln std μ at app3_start (5 bar after 30 bar) minus at the 5-bar start after 10 bar (ms_order), by seed."""
    high = state_values(results, ("ms_app3",), "app3_start", "mu_std")
    low = state_values(results, ("ms_order",), "app2_start", "mu_std")
    d = paired({s: math.log(v) for s, v in high.items()}, {s: math.log(v) for s, v in low.items()})
    return _amplitude(
        f"ln(std μ after 30 bar / after 10 bar) at the 5-bar application's start: {interval(d)}", [d],
        {"after 30 bar": high, "after 10 bar": low},
    )  # fmt: skip


def clustering_every_row(results: dict[str, dict], cfg: Config) -> RowValue:
    per = per_state(results, "corr_near")
    verdicts = [threshold_verdict(np.array(list(v.values())), 0.0, False) for v in per.values() if v]
    good = verdicts.count(REPRODUCED)
    return RowValue(
        f"states whose C of coupled neighbours' directions lies above 0: {good} of {len(verdicts)}",
        all_of(verdicts) if verdicts else NOT_MEASURED,
        f"C per state: {state_line(per)}; group size {state_line(per_state(results, 'corr_zero'), '.3g', 1e3, 'mm')}",
    )


def less_defined_row(results: dict[str, dict], cfg: Config) -> RowValue:
    per = per_state(results, "corr_near")
    seeds = sorted({s for v in per.values() for s in v})
    ms = {k: float(np.mean([v[k] for v in per.values() if k in v])) for k in seeds}
    hf = {}
    for name in ("hf1", "hf2"):
        for k, v in by_seed(results.get(name), lambda p: _get(p, "corr_near")).items():
            hf.setdefault(k, []).append(v)
    return RowValue.direction(
        "C of coupled neighbours, HF1/HF2 mean − the LF states' mean",
        paired({k: float(np.mean(v)) for k, v in hf.items()}, ms),
        S_MARGIN,
        after=f"hf1 {interval(values(results.get('hf1'), 'corr_near'))}, hf2 "
        f"{interval(values(results.get('hf2'), 'corr_near'))}",
    )


def clustering_row(results: dict[str, dict], cfg: Config) -> RowValue:
    per = per_state(results, "sync_relative.cluster_phi_rho")
    rho = np.array(list(per["app3_end"].values()))
    snr = np.array(list(per_state(results, "sync_snr.cluster_phi_rho")["app3_end"].values()))
    return RowValue(
        f"ρ(C_neighbours(f), Φ(f)) at app3_end: {interval(rho)}",
        rules_verdict(direction_verdict([effect(rho, RHO_MARGIN)]), rho, snr),
        f"C(f) = amplitude-weighted cos(φ_i − φ_j) of patches within 5 mm, Spearman over the bins with Φ ≥ 2; snr "
        f"rule {interval(snr)}; per state: {state_line(per)}",
    )


def coverage_row(results: dict[str, dict], cfg: Config) -> RowValue:
    lf = results.get("lf_states")
    m = values(lf, "match_app2_end")
    back = values(lf, "match_back_app2_end")
    return RowValue(
        f"share of app3_start's patch area on app2_end's patches: {interval(m)}",
        threshold_verdict(m, MATCH_LIMIT, False) if m.size else NOT_MEASURED,
        f"centres within 0.5 mm; back (app2_end on app3_start) {interval(back)}; for contrast app3_start on app3_end "
        f"{interval(values(lf, 'match_app3_end'))}, on app2_start {interval(values(lf, 'match_app2_start'))}",
    )


def high_sync_row(results: dict[str, dict], cfg: Config) -> RowValue:
    out = {}
    for rule in ("relative", "snr"):
        per = per_state(results, f"sync_{rule}.top_excess")
        d = []
        for seed, v in per["app3_start"].items():
            others = [per[s][seed] for s in STATES if s != "app3_start" and seed in per[s]]
            if len(others) >= 2:
                d.append(v - float(np.mean(others)))
        out[rule] = (np.array(d), per)
    d, per = out["relative"]
    snr = out["snr"][0]
    return RowValue.direction(
        "top-1 % S − S_null at app3_start − mean of the other states",
        d,
        S_MARGIN,
        after=f"snr rule {interval(snr)}; per state (relative): {state_line(per)}",
        snr=snr,
    )


def prevalence_row(results: dict[str, dict], cfg: Config) -> RowValue:
    d = {}
    for rule in ("relative", "snr"):
        per = per_state(results, f"sync_{rule}.phi_sync")
        d[rule] = paired(*({s: math.log(v) for s, v in per[k].items() if v > 0} for k in ("app3_end", "app3_start")))
    share = per_state(results, "sync_relative.phi_sync_share")
    ds = paired(share["app3_end"], share["app3_start"])
    return RowValue(
        f"ln(mean Φ of the synchronised bins, app3_end / app3_start): {interval(d['relative'])}",
        rules_verdict(direction_verdict([effect(d["relative"], PHI_MARGIN)]), d["relative"], d["snr"]),
        f"synchronised: S − S_null > 0.05; snr rule {interval(d['snr'])}; Φ as a share of the state's patches "
        f"{interval(ds)}; mean Φ per state: {state_line(per_state(results, 'sync_relative.phi_sync'))}",
    )


def peaks_synced_row(results: dict[str, dict], cfg: Config) -> RowValue:
    d = {}
    for rule in ("relative", "snr"):
        res = member_result(results, MAIN, "app3_end")
        d[rule] = np.array(list(by_seed(res, lambda p, r=rule: _get(p, f"sync_{r}.mu_peaks_synced")
                                        - _get(p, f"sync_{r}.mu_peaks_synced_chance")).values()))  # fmt: skip
    return RowValue(
        f"share of μ's peaks at a synchronised bin − chance, app3_end: {interval(d['relative'])}",
        rules_verdict(direction_verdict([effect(d["relative"], S_MARGIN)]), d["relative"], d["snr"]),
        f"within 2 bins; snr rule {interval(d['snr'])}",
    )


def _mean_over_states(results: dict[str, dict], key: str | Callable[[dict[str, Any]], float]) -> np.ndarray:
    """Per seed the mean over the states of a pad measure: a dotted key, or a function of the pad (a value that
    combines several measures of the same pad, so that each state pairs its own)."""
    value = key if callable(key) else (lambda p, k=key: _get(p, k))
    per = {s: by_seed(member_result(results, MAIN, s), value) for s in STATES}
    seeds = sorted({s for v in per.values() for s in v})
    return np.array([np.mean([v[s] for v in per.values() if s in v]) for s in seeds])


def agreement_row(results: dict[str, dict], cfg: Config) -> RowValue:
    rel, snr = (_mean_over_states(results, f"sync_{r}.agreement") for r in ("relative", "snr"))
    return RowValue(
        f"ρ = Spearman(S·Φ, |μ(f)|/μ̄) over 20–80 kHz, mean over the states: {interval(rel)}",
        rules_verdict(direction_verdict([effect(rel, RHO_MARGIN)]), rel, snr),
        f"snr rule {interval(snr)}; per state (relative): {state_line(per_state(results, 'sync_relative.agreement'))}",
    )


def unmatched_row(results: dict[str, dict], cfg: Config) -> RowValue:
    rel, snr = (1.0 - _mean_over_states(results, f"sync_{r}.mu_peaks_synced") for r in ("relative", "snr"))
    chance = _mean_over_states(
        results, lambda p: _get(p, "sync_relative.mu_peaks_synced_chance") - _get(p, "sync_relative.mu_peaks_synced")
    )  # the share without a synchronised bin less chance's, 1 − synced − (1 − synced by chance), per state
    return RowValue(
        f"share of μ's peaks without a synchronised bin, mean over the states: {interval(rel)}",
        rules_verdict(direction_verdict([effect(rel, RHO_MARGIN)]), rel, snr),
        f"peaks ≥ 4× their surroundings, 1–150 kHz, within 2 bins; snr rule {interval(snr)}; against chance (the "
        f"share − that of the band's bins with no synchronised bin within 2 bins) {interval(chance)} "
        f"({threshold_verdict(chance, -CHANCE_MARGIN, False)}: ≥ −{CHANCE_MARGIN:g}, at S at most that much more "
        "often than at random)",
    )


def early_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """|ln f1(k_start / k_end)| − |ln f1(k_start / (k−1)_end)| per seed, mean over applications 2–4."""
    per = per_state(results, "f1")
    seeds = sorted({s for v in per.values() for s in v})
    d = []
    for seed in seeds:
        diffs = []
        for k in (2, 3, 4):
            a, own, prev = (per[s].get(seed) for s in (f"app{k}_start", f"app{k}_end", f"app{k - 1}_end"))
            if a and own and prev:
                diffs.append(abs(math.log(a / own)) - abs(math.log(a / prev)))
        if diffs:
            d.append(float(np.mean(diffs)))
    return RowValue.direction(
        "|ln f1(start/own end)| − |ln f1(start/previous end)|, applications 2–4",
        np.array(d),
        S_MARGIN,
        "> 0: an application's first velocity peak lies nearer the previous coverage's than its own end's",
        f"first peaks per state: {state_line(per, '.1f', 1e-3, 'kHz')}",
    )


def in_band(v: np.ndarray) -> str:
    """Threshold verdict of a state's values ``v`` [Hz] against both edges of §4's band
    (:data:`CHARACTERISTIC_BAND`): reproduced when the whole 95 % interval of the mean lies inside, not reproduced when
    the mean lies outside, partly otherwise."""
    edges = (threshold_verdict(v, CHARACTERISTIC_BAND[0], False), threshold_verdict(v, CHARACTERISTIC_BAND[1], True))
    if NOT_REPRODUCED in edges or NOT_MEASURED in edges:
        return NOT_REPRODUCED if NOT_REPRODUCED in edges else NOT_MEASURED
    return REPRODUCED if edges == (REPRODUCED, REPRODUCED) else PARTLY


def band_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """Every state's first velocity peak and μ's largest peak within 20–80 kHz, each state and measure a part of the
    threshold (:func:`in_band`), the parts combined as every row's (:func:`all_of`); the states at the LF cap
    flagged."""
    f1, mu = per_state(results, "f1"), per_state(results, "mu_peak_hz")
    cap = (results.get("lf_states") or {}).get("cap_frequency_hz")
    parts = {
        name: [in_band(np.array(list(v.values()))) for v in per.values() if v] for name, per in (("f1", f1), ("mu", mu))
    }
    (a, n), (b, m) = ((p.count(REPRODUCED), len(p)) for p in parts.values())
    at_cap = [s for s, v in f1.items() if v and cap and abs(np.mean(list(v.values())) / cap - 1) <= CAP_TOLERANCE]
    verdict = all_of(parts["f1"] + parts["mu"]) if n else NOT_MEASURED
    cap_text = f"{cap / 1e3:.1f} kHz" if cap else "–"
    return RowValue(
        f"states with the first velocity peak inside 20–80 kHz: {a} of {n}; with μ's largest peak inside: {b} of {m}",
        verdict,
        f"first peak (Σu̇): {state_line(f1, '.1f', 1e-3, 'kHz')}; μ's largest peak (≥ 5 kHz): "
        f"{state_line(mu, '.1f', 1e-3, 'kHz')}; the isolated frequency of the LF automaton's largest patch (its area "
        f"cap) {cap_text}: states there {', '.join(at_cap) or 'none'}",
    )


MS_ROWS = (
    Row("§3.3, Fig. 13", "a degree of local clustering can be observed in the states' patterns", "in every state",
        "threshold", MAIN, clustering_every_row, "C of coupled neighbours > 0 in every state"),
    Row("§3.3, Fig. 13", "these patterns are not as clearly defined as those of HF1/HF2", "less defined",
        "direction", ("hf1", "hf2", *MAIN), less_defined_row, f"Δ C > 0, margin {S_MARGIN:g}"),
    Row("§3.3, Fig. 13", "end of application 3: local clustering correlates with the number of patches in S",
        "ρ > 0", "direction", MAIN, clustering_row, f"ρ > 0, margin {RHO_MARGIN:g}", uses=("sync",)),
    Row("§3.3, Fig. 13", "μ oscillates with the greatest amplitudes during application 3 (low pressure)",
        "app3 largest", "direction", MAIN, during_row, AMPLITUDE_CRITERION),
    Row("§3.3, Fig. 13", "the maximum amplitudes occur at the beginning of application 3", "app3_start largest",
        "direction", MAIN, greatest_row, AMPLITUDE_CRITERION),
    Row("§3.3", "μ's amplitudes at the start of application 3 exceed those at its end", "start > end",
        "direction", MAIN, start_end_row, AMPLITUDE_CRITERION),
    Row("§3.3", "application 3 starts on a coverage similar to the end of application 2", "similar", "threshold",
        ("ms_app3",), coverage_row, f"≥ {MATCH_LIMIT:g} of the area at the same places",
        construction="this LF automaton changes no patch in a pause (docs/lf_model.md), so app3_start carries "
        "app2_end's coverage but for what the load's ramp into application 3 does"),
    Row("§3.3, Fig. 13", "individual high-valued S at the start of application 3", "high S at app3_start",
        "direction", MAIN, high_sync_row, f"Δ > 0, margin {S_MARGIN:g}", uses=("sync",)),
    Row("§3.3, Fig. 13", "at the end of application 3: medium to high S with increased prevalence",
        "Φ(app3_end) > Φ(app3_start)", "direction", MAIN, prevalence_row, "ln ratio > 0, margin ln 1.25",
        uses=("sync",)),
    Row("§3.3, Fig. 13", "end of application 3: some synchronisation points are associated with μ's amplitude peaks",
        "some", "direction", MAIN, peaks_synced_row, f"share − chance > 0, margin {S_MARGIN:g}", uses=("sync",)),
    Row("§3.3", "μ-spectrum peaks at the frequencies of high and prevalent S", "agreement > 0", "direction", MAIN,
        agreement_row, f"ρ > 0, margin {RHO_MARGIN:g}", uses=("sync",)),
    Row("§3.3", "some μ-spectrum peaks do not correspond to the S results", "some", "direction", MAIN, unmatched_row,
        f"share > 0, margin {RHO_MARGIN:g}", uses=("sync",)),
    Row("§3.3, §4", "a low-load application right after a high-load one oscillates more (load history)",
        "after 30 bar > after 10 bar", "direction", ("ms_app3", "ms_order"), history_row,
        AMPLITUDE_CRITERION),
    Row("§4", "significant friction oscillations are associated with low normal pressures", "5 bar > 30 bar",
        "direction", MAIN, low_pressure_row, AMPLITUDE_CRITERION),
    Row("§4", "the HF behaviour at the start of an application is set by the coverage of the previous one",
        "previous coverage", "direction", MAIN, early_row, f"Δ > 0, margin {S_MARGIN:g}"),
    Row("§4", "the characteristic friction and synchronisation behaviour lies within 20–80 kHz", "20–80 kHz",
        "threshold", MAIN, band_row, "every state's first peak and μ's largest peak inside 20–80 kHz"),
)  # fmt: skip


def register() -> None:
    """Register the §3.3 and §4 rows."""
    for row in MS_ROWS:
        register_row(row)
