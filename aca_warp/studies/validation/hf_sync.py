"""§3.1 rows on the Synchronization Index of Fig. 9 (and the §5 conclusion on S and μ's peaks).

S depends on Φ (a few random phases already give a high S), so S of two experiments is compared **at equal Φ**
(``sync_by_prevalence``, ``equal_prevalence_difference``: mean S − S_null within octave classes of Φ, over the
classes every pad of both populates with ≥ 10 bins, paired by seed) and over **common absolute bands** (the whole
S band 1–150 kHz; 20–80 kHz beside), under both Φ rules: the ``relative`` rule (η = 0.1, primary) and the ``snr``
rule (κ = 5). The paper does not state its Φ threshold, so a measure that is significant in opposite directions
under the two rules is *undetermined*. A difference of S − S_null below 0.05 counts as negligible (the margin of the
"not significantly different" row and of every directional S row). The paper does not say what "significantly"
measures either, and 0.05 exceeds the mean excess of the small patches; each S row's notes therefore give the
relative reading beside it (``equal_phi_ratio``: ln of the ratio of the two excesses at equal Φ, against ln 1.25,
the margin of the other ratio rows) with the verdict it would give.
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import math
from typing import Any

import numpy as np

from aca_warp.studies.validation.base import (
    Config,
    Row,
    RowValue,
    _get,
    by_seed,
    equal_phi,
    equal_phi_ratio,
    interval,
    paired,
    register_row,
    seed_map,
    tables,
)
from aca_warp.studies.validation.hf_experiments import PRESETS
from aca_warp.studies.validation.verdicts import (
    FAILED,
    NEGLIGIBLE,
    NOT_COMPARABLE,
    NOT_MEASURED,
    NOT_REPRODUCED,
    PARTLY,
    REPRODUCED,
    UNDETERMINED,
    direction_verdict,
    effect,
    effect_text,
    equivalence_verdict,
    raised,
    rules_verdict,
    spread_text,
)

S_MARGIN = 0.05  # S − S_null: a difference below 0.05 is negligible (equivalence margin and direction margin)
SPREAD_MARGIN = 0.05  # the share of synchronised bins: at least 5 % of the band more
PREVALENCE_MARGIN = 0.02  # Φ as a share of the patches: at least 2 % of the patches more
RHO_MARGIN = 0.1  # a rank correlation of at least 0.1
RELATIVE_MARGIN = math.log(1.25)  # the relative reading: excesses at equal Φ differing by at least 25 %
RATIO_TEXT = "ln(S − S_null at equal Φ, {a} / {b})"


def _ratios(
    results: dict[str, dict], a: str, b: str, which: str = "table", only: set[int] | None = None
) -> tuple[dict, dict]:
    """Seed -> ln(a / b) of S − S_null at equal Φ under the relative and the snr rule of Φ (``only``: these seeds)."""
    return equal_phi_ratio(results, a, b, "relative", which, only), equal_phi_ratio(results, a, b, "snr", which, only)


def _values(m: dict[int, float]) -> np.ndarray:
    return np.array(list(m.values()), dtype=np.float64)


_RELATIVE = contextvars.ContextVar("relative_s", default=False)


def relative_s() -> contextlib.AbstractContextManager[None]:
    """Inside it the S rows that compare two presets take the verdict of their relative reading (the ratio of the
    two excesses at equal Φ against ln 1.25) instead of the absolute margin 0.05, and so does the combination row
    through its M part: for the page's line on what that reading would move."""
    return raised(_RELATIVE)


def _read(value: RowValue, relative_verdict: str) -> RowValue:
    """``value``, with the verdict of its relative reading inside :func:`relative_s`."""
    return dataclasses.replace(value, verdict=relative_verdict) if _RELATIVE.get() else value


def relative_direction(
    what: str, rel: np.ndarray, snr: np.ndarray, sign: float = 1.0, extra: tuple[str, ...] = ()
) -> tuple[str, str]:
    """The relative reading of a directional S row: its verdict (``what``, a ln ratio per seed, against ln 1.25 with
    the further parts ``extra`` (:func:`effect` outcomes) of the row; undetermined where the Φ rules disagree) and
    its text (the ratio under both rules, how its mean compares with ln 1.25, the verdict)."""
    verdict = rules_verdict(direction_verdict([effect(rel, RELATIVE_MARGIN, sign), *extra]), rel, snr, sign)
    text = (f"relative reading {what}: {interval(rel)}, snr rule {interval(snr)}; "
            f"{effect_text(rel, RELATIVE_MARGIN, sign)}: {verdict}")  # fmt: skip
    return verdict, text


def _share(results: dict[str, dict], name: str, key: str) -> dict[int, float]:
    """Seed -> a Φ measure as a share of the pad's patches."""
    return by_seed(results.get(name), lambda p: _get(p, key) / p["patches"])


def _diff(results: dict[str, dict], a: str, b: str, key: str) -> np.ndarray:
    return paired(seed_map(results.get(a), key), seed_map(results.get(b), key))


def _ruled(results: dict[str, dict], a: str, b: str, key: str) -> tuple[np.ndarray, np.ndarray]:
    """a − b of ``sync_<rule>.key`` under the relative and the snr rule."""
    return _diff(results, a, b, f"sync_relative.{key}"), _diff(results, a, b, f"sync_snr.{key}")


def spread_row_for(a: str, b: str):  # noqa: ANN201
    def measure(results: dict[str, dict], cfg: Config) -> RowValue:
        rel, snr = _ruled(results, a, b, "spread_all")
        own = _diff(results, a, b, "sync_relative.spread")
        band = _diff(results, a, b, "sync_relative.spread_band")
        return RowValue.direction(
            f"Δ spread {a} − {b} over 1–150 kHz (relative rule)",
            rel,
            SPREAD_MARGIN,
            "spread = share of the bins with S − S_null > 0.05",
            f"snr rule {interval(snr)}; over each pad's [f1/8, 2 f1] {interval(own)}; over 20–80 kHz {interval(band)}",
            snr=snr,
        )

    return measure


def prevalence_row(results: dict[str, dict], cfg: Config) -> RowValue:
    rel = paired(*(_share(results, n, "sync_relative.prevalence_all") for n in ("hf2", "hf1")))
    snr = paired(*(_share(results, n, "sync_snr.prevalence_all") for n in ("hf2", "hf1")))
    own = paired(*(_share(results, n, "sync_relative.prevalence") for n in ("hf2", "hf1")))
    return RowValue.direction(
        "Δ mean Φ/patches hf2 − hf1 over 1–150 kHz (relative rule)",
        rel,
        PREVALENCE_MARGIN,
        after=f"snr rule {interval(snr)}; over each pad's [f1/8, 2 f1] {interval(own)}",
        snr=snr,
    )


def _equal(results: dict[str, dict], a: str, b: str) -> tuple[np.ndarray, np.ndarray, str, str]:
    """a − b of S − S_null at equal Φ (relative, snr; whole band) with the classes and the 20–80 kHz beside."""
    rel, classes = equal_phi(results, a, b)
    snr = equal_phi(results, a, b, rule="snr")[0]
    band = equal_phi(results, a, b, which="table_band")[0]
    raw = equal_phi(results, a, b, value="S")[0]
    return rel, snr, classes, f"snr rule {interval(snr)}; over 20–80 kHz {interval(band)}; raw S {interval(raw)}"


def lower_m_row(a: str, b: str):  # noqa: ANN201
    def measure(results: dict[str, dict], cfg: Config) -> RowValue:
        rel, snr, classes, notes = _equal(results, a, b)
        verdict, ratio = relative_direction(RATIO_TEXT.format(a=a, b=b), *map(_values, _ratios(results, a, b)))
        value = RowValue.direction(
            f"Δ(S − S_null) at equal Φ {a} − {b}", rel, S_MARGIN, after=f"{notes}; {ratio}; {classes}", snr=snr
        )
        return _read(value, verdict)

    return measure


def ordering_text(results: dict[str, dict], size: np.ndarray) -> str:
    """The size effect ``size`` (hf2 − hf1 per seed) beside the M effect the paper's next sentence calls significant
    (hf3 − hf1), which the paper's two sentences order: M's effect significant, size's not."""
    lower_m = equal_phi(results, "hf3", "hf1")[0]
    text = f"the M effect of the paper's next sentence (hf3 − hf1) {interval(lower_m)}"
    if size.size and size.size == lower_m.size:
        text += f"; size effect − M effect {interval(size - lower_m)} (the paper orders them M > size)"
    return text


def hf1_hf2_row(results: dict[str, dict], cfg: Config) -> RowValue:
    rel, snr, classes, notes = _equal(results, "hf2", "hf1")
    r_rel, r_snr = map(_values, _ratios(results, "hf2", "hf1"))
    relative = equivalence_verdict(r_rel, RELATIVE_MARGIN)
    ratio = (f"relative reading {RATIO_TEXT.format(a='hf2', b='hf1')}: {interval(r_rel)}, snr rule "
             f"{interval(r_snr)}: {relative} within ± ln 1.25 "
             f"(snr rule alone: {equivalence_verdict(r_snr, RELATIVE_MARGIN)})")  # fmt: skip
    value = RowValue(
        f"Δ(S − S_null) at equal Φ hf2 − hf1: {interval(rel)}",
        equivalence_verdict(rel, S_MARGIN),
        f"{notes}; snr rule alone: {equivalence_verdict(snr, S_MARGIN)}; {ratio}; {ordering_text(results, rel)}; "
        f"{classes}",
    )
    return _read(value, relative)


def _every_preset(ts: dict[str, dict[int, Any]]) -> list[int]:
    """The seeds every preset's tables have (seed -> table per preset), in order."""
    return [s for s in sorted(ts["hf1"]) if all(s in ts[n] for n in PRESETS)]


def interaction(results: dict[str, dict], which: str = "table", rule: str = "relative") -> np.ndarray:
    """Per seed (hf4 − hf2) − (hf3 − hf1) of S − S_null at equal Φ: what lower M adds for large patches beyond what
    it adds for small ones (0 when the effects of size and M add)."""
    from aca_warp.analysis.measures import equal_prevalence_difference

    ts = {n: tables(results.get(n), rule, which) for n in PRESETS}
    seeds = _every_preset(ts)
    if not seeds:
        return np.array([])
    large = equal_prevalence_difference([ts["hf4"][s] for s in seeds], [ts["hf2"][s] for s in seeds]).difference
    small = equal_prevalence_difference([ts["hf3"][s] for s in seeds], [ts["hf1"][s] for s in seeds]).difference
    return large - small


def less_for_large_row(results: dict[str, dict], cfg: Config) -> RowValue:
    rel, snr = -interaction(results), -interaction(results, rule="snr")
    every = set(_every_preset({n: tables(results.get(n), "relative") for n in PRESETS}))  # as interaction pairs
    small, large = _ratios(results, "hf3", "hf1", only=every), _ratios(results, "hf4", "hf2", only=every)
    verdict, ratio = relative_direction("ln(hf3 / hf1) − ln(hf4 / hf2) of S − S_null at equal Φ",
                                        *(paired(s, g) for s, g in zip(small, large, strict=True)))  # fmt: skip
    value = RowValue.direction(
        "(hf3 − hf1) − (hf4 − hf2) at equal Φ",
        rel,
        S_MARGIN,
        after=f"snr rule {interval(snr)}; small patches {interval(equal_phi(results, 'hf3', 'hf1')[0])}, large "
        f"{interval(equal_phi(results, 'hf4', 'hf2')[0])}; {ratio}",
        snr=snr,
    )
    return _read(value, verdict)


def agreement_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """HF4's agreement of S·Φ with |μ(f)| against the others': not comparable (the Φ threshold decides it)."""
    texts, cands = [], {}
    for rule in ("relative", "snr"):
        rho = {n: seed_map(results.get(n), f"sync_{rule}.agreement") for n in PRESETS}
        best = [n for n in ("hf1", "hf2", "hf3") if rho[n]]
        diffs = {n: paired(rho["hf4"], rho[n]) for n in best}
        texts.append(f"{rule} rule: ρ " + "; ".join(f"{n} {interval(np.array(list(rho[n].values())))}" for n in PRESETS)
                     + "; hf4 − other " + "; ".join(f"{n} {interval(d)}" for n, d in diffs.items()))  # fmt: skip
        for n, d in diffs.items():
            cands[f"hf4 − {n}, {rule}"] = float(np.mean(d)) if d.size else float("nan")
    return RowValue(
        "; ".join(texts),
        NOT_COMPARABLE,
        "ρ = Spearman(S·Φ, |μ(f)|/μ̄) over 20–80 kHz. Unstated: the threshold that counts a patch in Φ (the paper "
        "names no rule or level), and S·Φ depends on it; the candidates' hf4 − other differences: "
        + spread_text(cands)
        + " (signs differ between the rules where the spread crosses 0)",
    )


def combination_high_row(results: dict[str, dict], cfg: Config) -> RowValue:
    high, classes = equal_phi(results, "hf4", "hf1", which="table_high")
    whole = equal_phi(results, "hf4", "hf1")[0]
    snr_high = equal_phi(results, "hf4", "hf1", rule="snr", which="table_high")[0]
    extra = high - whole if high.size == whole.size else np.array([])
    verdict = direction_verdict([effect(high, S_MARGIN), effect(extra, 0.0)])
    what = f"above f1, {RATIO_TEXT.format(a='hf4', b='hf1')}"
    h_rel, h_snr = _ratios(results, "hf4", "hf1", "table_high")
    rise = paired(h_rel, equal_phi_ratio(results, "hf4", "hf1"))  # the ratio above f1 over the whole band's
    relative, ratio = relative_direction(what, _values(h_rel), _values(h_snr), extra=(effect(rise, 0.0),))
    ratio += f" (with the ratio above f1 less the whole band's {interval(rise)})"
    value = RowValue(
        f"Δ(S − S_null) at equal Φ above f1, hf4 − hf1: {interval(high)}; above f1 minus the whole band: "
        f"{interval(extra)}",
        rules_verdict(verdict, high, snr_high),
        f"{effect_text(high, S_MARGIN)}; the whole band {interval(whole)}; snr rule above f1 {interval(snr_high)}; "
        f"{ratio}; {classes}",
    )
    return _read(value, relative)


def both_verdict(a: str, b: str) -> str:
    """The verdict of a statement that two changes are both present, from the verdicts of the two, as
    :func:`~aca_warp.studies.validation.verdicts.direction_verdict` combines parts: reproduced when both are;
    significant but negligible when both are; partly when one is reproduced, partly or negligible; undetermined when
    neither is and one is undetermined; else not reproduced. A part not measured (or failed, or not comparable)
    leaves the statement so."""
    pair = (a, b)
    for v in pair:
        if v in (NOT_MEASURED, FAILED, NOT_COMPARABLE):
            return v
    if all(v == REPRODUCED for v in pair):
        return REPRODUCED
    if all(v == NEGLIGIBLE for v in pair):
        return NEGLIGIBLE
    if any(v in (REPRODUCED, PARTLY, NEGLIGIBLE) for v in pair):
        return PARTLY
    return UNDETERMINED if UNDETERMINED in pair else NOT_REPRODUCED


def combination_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """HF4 as the combination of HF2's and HF3's changes, read as the paper's example reads it (§3.1: HF4's S "more
    spread out than HF1 (influence of increased patch size), and greater in value, especially at higher frequencies
    (influence of decreased friction coefficient)"): both changes present in HF4 against HF1, each as its own row
    tests it (:func:`both_verdict`). The additive reading, an interaction of size and M within ± the margin, is
    shown beside it: the paper's sentences before say the rise with lower M is smaller for the larger patches, an
    interaction, so it is not the primary."""
    size = spread_row_for("hf4", "hf1")(results, cfg)
    lower_m = combination_high_row(results, cfg)
    d, d_snr = interaction(results), interaction(results, rule="snr")
    spread = {n: seed_map(results.get(n), "sync_relative.spread_all") for n in PRESETS}
    seeds = [s for s in spread["hf1"] if all(s in spread[n] for n in PRESETS)]
    sp = np.array([spread["hf4"][s] - spread["hf2"][s] - spread["hf3"][s] + spread["hf1"][s] for s in seeds])
    return RowValue(
        f"size: {size.value} ({size.verdict}); M: {lower_m.value} ({lower_m.verdict})",
        both_verdict(size.verdict, lower_m.verdict),
        f"the additive reading: interaction (hf4 − hf2) − (hf3 − hf1) of S − S_null at equal Φ {interval(d)} "
        f"({equivalence_verdict(d, S_MARGIN)} within ± {S_MARGIN:g}); snr rule {interval(d_snr)}; the same of the "
        f"spread over 1–150 kHz {interval(sp)}",
    )


def mu_relation_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """§5: both the value (S − S_null) and the prevalence (Φ) of S relate to μ's spectrum over 20–80 kHz."""
    parts, notes, verdicts = [], [], []
    for key, label in (("rho_excess_mu", "S − S_null"), ("rho_phi_mu", "Φ")):
        per = {}
        for rule in ("relative", "snr"):
            maps = [seed_map(results.get(n), f"sync_{rule}.{key}") for n in PRESETS]
            seeds = sorted(set.intersection(*(set(m) for m in maps))) if all(maps) else []
            per[rule] = np.array([np.mean([m[s] for m in maps]) for s in seeds])
        parts.append(effect(per["relative"], RHO_MARGIN))
        verdicts.append((per["relative"], per["snr"]))
        notes.append(f"ρ({label}, |μ(f)|): relative {interval(per['relative'])}, snr {interval(per['snr'])}")
    verdict = direction_verdict(parts)
    for rel, snr in verdicts:
        verdict = rules_verdict(verdict, rel, snr)
    return RowValue("; ".join(notes), verdict, "Spearman over 20–80 kHz per pad, mean over the four presets per seed")


SYNC_ROWS = (
    Row("§3.1, Fig. 9", "larger patches: Synchronization Index results more spread out (HF2 vs HF1)", "yes",
        "direction", ("hf1", "hf2"), spread_row_for("hf2", "hf1"), f"Δ > 0, margin {SPREAD_MARGIN:g}", uses=("sync",)),
    Row("§3.1, Fig. 9", "larger patches: generally increased prevalence Φ (HF2 vs HF1)", "yes", "direction",
        ("hf1", "hf2"), prevalence_row, f"Δ > 0, margin {PREVALENCE_MARGIN:g} of the patches", uses=("sync",)),
    Row("§3.1, Fig. 9", "HF1 vs HF2: the size increase does not significantly affect the synchronisation quality",
        "no significant difference", "equivalence", ("hf1", "hf2"), hf1_hf2_row, f"margin ± {S_MARGIN:g}",
        uses=("sync",)),
    Row("§3.1, Fig. 9", "lower M raises S significantly for small patches (HF3 vs HF1)", "S(HF3) > S(HF1)",
        "direction", ("hf1", "hf3"), lower_m_row("hf3", "hf1"), f"Δ > 0, margin {S_MARGIN:g}", uses=("sync",)),
    Row("§3.1, Fig. 9", "lower friction coefficients yield higher S for large patches too (HF4 vs HF2)",
        "S(HF4) > S(HF2)", "direction", ("hf2", "hf4"), lower_m_row("hf4", "hf2"), f"Δ > 0, margin {S_MARGIN:g}",
        uses=("sync",)),
    Row("§3.1, Fig. 9", "the rise with lower M is not as substantial for the larger patches",
        "Δ(HF3 − HF1) > Δ(HF4 − HF2)", "direction", PRESETS, less_for_large_row, f"difference > 0, margin {S_MARGIN:g}",
        uses=("sync",)),
    Row("§3.1, Figs. 8/9", "HF4 shows the best agreement of S with the friction spectrum", "HF4 highest",
        "not comparable", PRESETS, agreement_row, "the Φ threshold is not stated", uses=("sync",)),
    Row("§3.1, Fig. 9", "HF4 vs HF1: S more spread out (the influence of the patch size)", "yes", "direction",
        ("hf1", "hf4"), spread_row_for("hf4", "hf1"), f"Δ > 0, margin {SPREAD_MARGIN:g}", uses=("sync",)),
    Row("§3.1, Fig. 9", "HF4 vs HF1: S greater, especially at higher frequencies (the influence of M)", "yes",
        "direction", ("hf1", "hf4"), combination_high_row, f"Δ above f1 > 0 (margin {S_MARGIN:g}) and above the whole "
        "band's", uses=("sync",)),
    Row("§3.1", "HF4 can be interpreted as the combination of the changes of HF2 and HF3",
        "both changes in HF4 vs HF1", "direction", ("hf1", "hf4"), combination_row,
        "both: S more spread out (size) and greater above f1 (M), each as its row tests it", uses=("sync",)),
)  # fmt: skip


def register() -> None:
    """Register the §3.1 rows on the Synchronization Index (Fig. 9)."""
    for row in SYNC_ROWS:
        register_row(row)


def register_conclusions() -> None:
    """Register the §5 row on S and μ's peaks (after §4, in the paper's order)."""
    register_row(
        Row("§5", "both the value and the prevalence of S are related to peaks in the spectrum of μ", "related",
            "direction", PRESETS, mu_relation_row, f"ρ > 0 for both, margin {RHO_MARGIN:g}", uses=("sync",))
    )  # fmt: skip
