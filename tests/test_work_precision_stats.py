"""``aca_warp.studies.work_precision_stats`` (``scripts/work_precision_stats.py``) with its rule and report modules:
the error/σ bookkeeping on ensembles whose answer is known, the rule's choice, the grid syntax (a new integrator
name enters without a change), the per-pad measures, the page from a synthetic result, and one tiny run on the
CPU end to end."""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import scipy.stats

from aca_warp.studies import work_precision_stats as wps
from aca_warp.studies import work_precision_stats_report as wps_report
from aca_warp.studies import work_precision_stats_rule as rule

REPO = Path(__file__).resolve().parent.parent


def test_compare_known_ensemble():
    """A setting whose every seed is the reference's + 0.3: error 0.3 with no noise (bound = low = 0.3), σ the
    reference's sample std, the 95 % half-width t·σ/√n; seed-by-seed noise of zero mean leaves no error but a bound
    of t·sd/√n; a vector measure gives the rms over its components; a seed missing in either ensemble is left out."""
    rng = np.random.default_rng(4)
    ref = rng.normal(5.0, 2.0, 40)
    t = scipy.stats.t.ppf(0.975, 39)
    c = rule.compare(ref, ref + 0.3)
    sd = ref.std(ddof=1)
    assert c.n == 40
    assert c.error == pytest.approx(0.3, rel=1e-12) and c.bound == pytest.approx(0.3) and c.low == pytest.approx(0.3)
    assert c.sigma == pytest.approx(sd, rel=1e-12)
    assert c.ratio == pytest.approx(0.3 / sd, rel=1e-12)
    assert c.half_width == pytest.approx(t * sd / math.sqrt(40), rel=1e-9)
    assert c.paired_se == pytest.approx(0.0, abs=1e-12)
    assert c.reference_mean == pytest.approx(ref.mean(), rel=1e-12)
    noise = np.tile([0.5, -0.5], 20)
    d = rule.compare(ref, ref + noise)
    se = 0.5 * math.sqrt(40 / 39) / math.sqrt(40)
    assert d.error == pytest.approx(0.0, abs=1e-12) and d.paired_se == pytest.approx(se, rel=1e-12)
    assert d.bound == pytest.approx(t * se, rel=1e-9) and d.low == 0.0
    vec = np.stack([ref, 2 * ref], axis=1)
    v = rule.compare(vec, vec + [0.3, 0.4])
    assert v.error == pytest.approx(math.sqrt((0.09 + 0.16) / 2), rel=1e-12)
    assert v.sigma == pytest.approx(math.sqrt((sd**2 + 4 * sd**2) / 2), rel=1e-12)
    assert v.reference_mean == pytest.approx(1.5 * ref.mean(), rel=1e-12)
    bad = ref + 0.3
    bad[0] = np.nan
    e = rule.compare(ref, bad)
    assert e.n == 39 and e.sigma == pytest.approx(ref[1:].std(ddof=1), rel=1e-12)
    assert math.isnan(rule.compare(ref[:1], ref[:1]).ratio)


def _setting(label: str, role: str, wall: float, values: dict, complete: bool = True) -> dict:
    """A row of a result file as the study writes it."""
    (setting,) = wps.parse_setting(label)
    return {"label": label, "role": role, **dataclasses.asdict(setting), "wall_s": wall, "complete": complete,
            "values": values if complete else None, "steps": 1, "kernels": "0123456789ab"}  # fmt: skip


T29 = scipy.stats.t.ppf(0.975, 29)


def synthetic_regime(seeds: int = 30) -> dict:
    """A regime with μ std (σ ≈ 1) and Φ (σ ≈ 2) over ``seeds`` pads. A setting's values are the reference's +
    bias·σ + c·σ·z (z of mean 0 and standard deviation 1 over the seeds), so its bound/σ is bias + c·t/√n. Settings
    (wall; μ std bias, c; Φ bias): cheap (1; 0.5, 0; 0) moves μ std, noisy (1.5; 0, 1; 0) leaves it undecided
    (bound 0.37), mid (2; 0.1, 0.2; 0) keeps it (bound 0.17), dear (3; 0, 0; 0.3) moves Φ, fast (0.5) did not
    complete."""
    rng = np.random.default_rng(7)
    a = rng.normal(0.0, 1.0, seeds)
    b = rng.normal(10.0, 2.0, seeds)
    z = rng.normal(0.0, 1.0, seeds)
    z = (z - z.mean()) / z.std(ddof=1)
    sa, sb = a.std(ddof=1), b.std(ddof=1)

    def vals(bias: float, c: float, bias_b: float) -> dict:
        return {"mu_std": (a + bias * sa + c * sa * z).tolist(), "phi": (b + bias_b * sb).tolist()}

    return {
        "name": "syn", "description": "synthetic", "kind": "saturated", "measures": ["mu_std", "phi"],
        "pads": [{"seed": s + 1, "member": None, "patches": 10} for s in range(seeds)],
        "config": {"perturbation": 0.01}, "duration_s": 0.03, "window_start_s": 0.02,
        "settings": [
            _setting("strang@fp64:dt=1e-08", "reference", 10.0, vals(0, 0, 0)),
            _setting("strang@fp32:dt=5e-07", "grid", 1.0, vals(0.5, 0, 0)),
            _setting("adaptive@fp64:tol=0.001", "grid", 1.5, vals(0, 1, 0)),
            _setting("strang@fp32:dt=1e-07", "grid", 2.0, vals(0.1, 0.2, 0)),
            _setting("strang@fp32:dt=2e-08", "grid", 3.0, vals(0, 0, 0.3)),
            _setting("implicit-friction@fp32:dt=5e-07", "grid", 0.5, {}, complete=False),
        ],
    }  # fmt: skip


def test_verdicts_are_an_equivalence_test():
    """keeps: the 95 % interval of the bias within ± rule·σ; moves: wholly beyond; between them the strict
    criterion leaves the measure undecided, the resolution criterion keeps it within resolution when the estimate
    is within ± rule·σ (noisy: bias 0, sd(d) = σ); an incomplete run keeps nothing."""
    reg = synthetic_regime()
    cheap, noisy, mid, dear, fast = reg["settings"][1:]
    c = rule.compare_setting(reg, mid, "mu_std")
    assert c.ratio == pytest.approx(0.1) and c.bound_ratio == pytest.approx(0.1 + 0.2 * T29 / math.sqrt(30))
    assert c.bound90 / c.sigma == pytest.approx(0.1 + 0.2 * scipy.stats.t.ppf(0.95, 29) / math.sqrt(30))
    assert rule.compare_setting(reg, noisy, "mu_std").sd_ratio == pytest.approx(1.0)
    settings = (cheap, noisy, mid, dear, fast)
    assert [rule.verdict(reg, s, "mu_std", 0.25, "strict") for s in settings] == [
        "moves", "undecided", "keeps", "keeps", "no run"]  # fmt: skip
    assert [rule.verdict(reg, s, "mu_std", 0.25) for s in settings] == [
        "moves", "within resolution", "keeps", "keeps", "no run"]  # fmt: skip
    assert rule.verdict(reg, dear, "phi", 0.25) == "moves" and rule.verdict(reg, dear, "phi", 0.31) == "keeps"
    assert rule.verdict(reg, noisy, "mu_std", 0.4, "strict") == "keeps"  # bound 0.373
    assert rule.verdict(reg, reg["settings"][0], "phi", 0.0) == "keeps"
    with pytest.raises(KeyError):
        rule.verdict(reg, noisy, "mu_std", 0.25, "loose")


def _orthogonal(rng: np.random.Generator, seeds: int, against: list[np.ndarray]) -> np.ndarray:
    """Values of mean 0 and sample standard deviation 1, uncorrelated with every array of ``against``."""
    z = rng.normal(0.0, 1.0, seeds)
    z -= z.mean()
    for a in against:
        a0 = a - a.mean()
        z -= (z @ a0) / (a0 @ a0) * a0
    return z / z.std(ddof=1)


def parted_regime(seeds: int = 32) -> dict:
    """The saturated state's case: one measure (S − S_null) whose runs part from the reference's. Reference r (mean
    0, σ 1); ``twin`` (strang fp32 at the reference's step: as exact, its runs parted) and ``cheap`` have values
    uncorrelated with r of equal spread and the same mean, so d has mean 0 and sd √2 σ exactly; ``wide`` scatters
    twice as far (sd(d) = √5 σ); ``biased`` is as ``cheap`` + 0.3 σ."""
    rng = np.random.default_rng(11)
    r = _orthogonal(rng, seeds, [])
    x = _orthogonal(rng, seeds, [r])
    y = _orthogonal(rng, seeds, [r, x])

    def vals(v: np.ndarray) -> dict:
        return {"sync_excess": v.tolist()}

    return {
        "name": "parted", "description": "synthetic", "kind": "saturated", "measures": ["sync_excess"],
        "pads": [{"seed": s + 1, "member": None, "patches": 10} for s in range(seeds)],
        "config": {"perturbation": 0.01}, "duration_s": 0.03, "window_start_s": 0.02,
        "settings": [
            _setting("strang@fp64:dt=1e-08", "reference", 30.0, vals(r)),
            _setting("strang@fp32:dt=5e-07", "grid", 1.0, vals(x + 0.3)),
            _setting("implicit-friction@fp32:dt=5e-07", "grid", 1.5, vals(2 * y)),
            _setting("strang@fp32:dt=8e-08", "grid", 8.0, vals(x)),
            _setting("strang@fp32:dt=1e-08", "grid", 13.0, vals(y)),
        ],
    }  # fmt: skip


def test_an_exact_twin_keeps_within_resolution():
    """Runs that have parted give sd(d) = √2 σ: at 32 seeds the 95 % bound of even an exact setting is
    t √2/√32 = 0.51 σ, so the strict criterion keeps nothing and picks the reference; the resolution criterion
    (the default) keeps the exact settings within resolution and picks the cheapest of them; a setting that
    scatters wider than the floor or whose estimate lies beyond ¼ σ stays undecided."""
    doc = {"regimes": {"parted": parted_regime()}}
    reg = doc["regimes"]["parted"]
    biased, wide, cheap, twin = reg["settings"][1:]
    c = rule.compare_setting(reg, twin, "sync_excess")
    floor = scipy.stats.t.ppf(0.975, 31) * math.sqrt(2 / 32)
    assert c.sd_ratio == pytest.approx(math.sqrt(2)) and c.bound_ratio == pytest.approx(floor)
    assert rule.resolution_floor(32) == pytest.approx(floor) and floor > 0.5
    assert rule.settings_for(doc, "parted").setting == "strang@fp32:dt=8e-08"  # the old rule: the reference
    assert rule.settings_for(doc, "parted", criterion="strict").setting == "strang@fp64:dt=1e-08"
    assert rule.settings_for(doc, "parted", criterion="tost").setting == "strang@fp64:dt=1e-08"
    assert [rule.verdict(reg, s, "sync_excess", 0.25) for s in (biased, wide, cheap, twin)] == [
        "undecided", "undecided", "within resolution", "within resolution"]  # fmt: skip
    assert rule.compare_setting(reg, wide, "sync_excess").sd_ratio == pytest.approx(math.sqrt(5))
    ch = rule.settings_for(doc, "parted")
    assert ch.verdicts == {"sync_excess": "within resolution"} and ch.passing[:2] == [
        "strang@fp32:dt=8e-08", "strang@fp32:dt=1e-08"]  # fmt: skip
    assert ch.fails == {"strang@fp32:dt=5e-07": ["sync_excess"], "implicit-friction@fp32:dt=5e-07": ["sync_excess"]}
    assert ch.binding == ["sync_excess"]


def test_twin_criterion_takes_the_floor_from_the_twin():
    """The twin is the grid setting that differs from the reference in precision only. A twin that keeps its
    pairing (sd(d) = 0.3 σ) sets a floor the parted setting (sd(d) = √2 σ) exceeds: undecided under "twin", within
    resolution under "resolution"; without a twin run the "twin" criterion keeps only what "strict" keeps."""
    doc = {"regimes": {"parted": parted_regime()}}
    reg = doc["regimes"]["parted"]
    twin = reg["settings"][-1]
    r = np.array(reg["settings"][0]["values"]["sync_excess"])
    twin["values"]["sync_excess"] = (r + 0.3 * np.array(twin["values"]["sync_excess"])).tolist()
    assert rule.twin_of(reg) is twin
    assert rule.compare_setting(reg, twin, "sync_excess").sd_ratio == pytest.approx(0.3)
    cheap = reg["settings"][3]
    assert rule.verdict(reg, cheap, "sync_excess", 0.25, "twin") == "undecided"
    assert rule.verdict(reg, cheap, "sync_excess", 0.25, "resolution") == "within resolution"
    assert rule.settings_for(doc, "parted", criterion="twin").setting == "strang@fp32:dt=1e-08"
    twin["precision"] = "fp64"  # no twin left
    assert rule.twin_of(reg) is None
    assert rule.verdict(reg, cheap, "sync_excess", 0.25, "twin") == "undecided"


def test_resolution_figures():
    """The floor factor is the one-sided 95 % variance ratio of two ensembles; seeds_needed is the least n whose
    95 % half-width t·sd(d)/√n reaches the rule (≈ 126 for sd(d) = √2 σ, the number the strict rule needs for a
    parted measure); keep_chance is the normal probability of an estimate within ± rule σ."""
    assert rule.floor_factor(32) == pytest.approx(math.sqrt(scipy.stats.f.ppf(0.95, 31, 31)))
    for ratio in (0.1, 1.0, math.sqrt(2)):
        n = rule.seeds_needed(ratio)
        assert scipy.stats.t.ppf(0.975, n - 1) * ratio / math.sqrt(n) <= 0.25
        assert n == 2 or scipy.stats.t.ppf(0.975, n - 2) * ratio / math.sqrt(n - 1) > 0.25
    assert rule.seeds_needed(math.sqrt(2)) == 126 and rule.seeds_needed(0.0) == 2
    assert rule.seeds_needed(math.nan) is None and rule.seeds_needed(1e4, limit=1000) is None
    assert rule.keep_chance(32, 0.0) == pytest.approx(scipy.stats.norm.cdf(1) - scipy.stats.norm.cdf(-1))
    assert rule.keep_chance(32, 0.25) == pytest.approx(scipy.stats.norm.cdf(0) - scipy.stats.norm.cdf(-2))


def test_rule_picks_the_cheapest_setting_that_keeps_every_measure():
    """Strictly, mid is the cheapest setting that keeps both (cheap moves μ std, noisy leaves it undecided); μ std
    binds it; a tighter rule leaves the reference, a looser one takes the cheaper settings; one measure alone its
    cheapest; an incomplete run is never chosen. Within resolution noisy keeps μ std too and is picked."""
    doc = {"regimes": {"syn": synthetic_regime()}}
    ch = rule.settings_for(doc, "syn", criterion="strict")
    assert ch.setting == "strang@fp32:dt=1e-07" and ch.wall_s == 2.0 and ch.speedup == pytest.approx(5.0)
    assert ch.passing == ["strang@fp32:dt=1e-07", "strang@fp64:dt=1e-08"]
    assert ch.cheapest == {"mu_std": "strang@fp32:dt=1e-07", "phi": "strang@fp32:dt=5e-07"}
    assert ch.binding == ["mu_std"] and ch.verdicts == {"mu_std": "keeps", "phi": "keeps"}
    assert rule.settings_for(doc, "syn", rule=0.1, criterion="strict").setting == "strang@fp64:dt=1e-08"
    assert rule.settings_for(doc, "syn", rule=0.4, criterion="strict").setting == "adaptive@fp64:tol=0.001"
    assert rule.settings_for(doc, "syn", rule=0.6, criterion="strict").setting == "strang@fp32:dt=5e-07"
    assert rule.settings_for(doc, "syn", ["phi"]).setting == "strang@fp32:dt=5e-07"
    res = rule.settings_for(doc, "syn")
    assert res.setting == "adaptive@fp64:tol=0.001" and res.verdicts["mu_std"] == "within resolution"
    with pytest.raises(KeyError):
        rule.settings_for(doc, "syn", ["f1"])
    with pytest.raises(KeyError):
        rule.settings_for(doc, "other")
    with pytest.raises(KeyError):
        rule.settings_for(doc, "syn", criterion="loose")


def test_an_amplitude_that_few_pads_dominate_is_judged_in_log_too():
    """The STFT maximum of 64 pads about 1.7e-3 (a fixed draw), a few turning tonal at five times that, different
    pads in the two runs: the arithmetic mean's paired differences scatter beyond the floor (undecided), while the
    same comparison on the logarithms, a geometric mean over the pads, keeps it within resolution; a setting that
    moves every pad by 30 % moves in log too, and a measure every setting keeps gets no sentence."""
    from aca_warp.studies import work_precision_stats_report as report

    rng = np.random.default_rng(3)
    base = 1.7e-3 * np.exp(0.1 * rng.standard_normal(64))
    ref, same, moved = base.copy(), base * np.exp(0.02 * rng.standard_normal(64)), base * 1.3
    ref[[5]] *= 5.0  # tonal in the reference
    same[[20, 41]] *= 5.0  # others tonal in the setting
    moved[[20, 41]] *= 5.0
    same[7] = 0.0  # a pad without a maximum: it drops out of the log comparison (NaN), not the arithmetic one
    row = {"mu_mean": [0.4] * 64}
    reg = {"measures": ["stft_amplitude", "mu_mean"], "pads": [{"seed": s} for s in range(64)], "settings": [
        _setting("strang@fp32:dt=1e-08", "reference", 10.0, {**row, "stft_amplitude": ref.tolist()}),
        _setting("strang@fp64:dt=1e-08", "grid", 12.0, {**row, "stft_amplitude": ref.tolist()}),  # keeps it
        _setting("strang@fp32:dt=1e-07", "grid", 2.0, {**row, "stft_amplitude": same.tolist()}),
        _setting("strang@fp32:dt=5e-07", "grid", 1.0, {**row, "stft_amplitude": moved.tolist()}),
        _setting("strang@fp32:dt=1e-06", "grid", 0.5, {}, complete=False),  # no run
    ]}  # fmt: skip
    assert rule.verdict(reg, reg["settings"][2], "stft_amplitude", 0.25) == "undecided"
    view = report.logged(reg, "stft_amplitude")
    assert rule.verdict(view, view["settings"][2], "stft_amplitude", 0.25) == "within resolution"
    assert view["settings"][2]["values"]["mu_mean"] == [0.4] * 64  # only the named measure is taken in log
    assert math.isnan(view["settings"][2]["values"]["stft_amplitude"][7])
    log = rule.compare_setting(view, view["settings"][2], "stft_amplitude")
    assert log.n == 63 and rule.compare_setting(reg, reg["settings"][2], "stft_amplitude").n == 64
    (text,) = report.log_candidates(reg, 0.25, "resolution")
    assert text.startswith("STFT max averaged in log over the pads")
    assert f"`strang@fp32:dt=1e-07` within resolution (error {report._small(log.ratio)} σ, sd(d) " in text
    assert f"sd(d) {log.sd_ratio:.2g} σ)" in text and "`strang@fp32:dt=5e-07` moves" in text
    assert "fp64" not in text and "1e-06" not in text  # a setting that keeps it, a row that did not run: not named
    assert report.log_candidates(reg, 0.25, "resolution", ["mu_mean"]) == []  # not asked for
    reg["measures"] = ["mu_mean"]
    assert report.log_candidates(reg, 0.25, "resolution") == []


def test_one_seed_that_decides_a_verdict_is_named(monkeypatch):
    """64 pads whose STFT maximum agrees closely between two runs, but for seed 7, tonal (×6) in the setting's run
    only: the setting is undecided, its pick the reference, and the report names seed 7, without which it keeps every
    measure; a seed that is no outlier (×1.2) is not named, nor a setting that moves a measure, and without the seed
    the pads (and every setting's values) are one fewer."""
    from aca_warp.studies import work_precision_stats_report as report

    rng = np.random.default_rng(11)
    base = 1.7e-3 * np.exp(0.1 * rng.standard_normal(64))
    near = base * np.exp(0.01 * rng.standard_normal(64))
    tonal, mild, moved = near.copy(), near.copy(), near * 1.3
    tonal[6] *= 6.0  # seed 7
    mild[6] *= 1.2
    row = {"mu_mean": (0.4 + 0.01 * rng.standard_normal(64)).tolist()}  # the same in every run: kept

    def regime(values: np.ndarray) -> dict:
        return {"measures": ["stft_amplitude", "mu_mean"], "pads": [{"seed": s + 1} for s in range(64)], "settings": [
            _setting("strang@fp32:dt=1e-08", "reference", 10.0, {**row, "stft_amplitude": base.tolist()}),
            _setting("strang@fp32:dt=5e-07", "grid", 1.0, {**row, "stft_amplitude": moved.tolist()}),
            _setting("strang@fp32:dt=1e-07", "grid", 2.0, {**row, "stft_amplitude": values.tolist()}),
        ]}  # fmt: skip

    reg = regime(tonal)
    doc = {"regimes": {"syn": reg}}
    ch = rule.settings_for(doc, "syn")
    assert ch.setting == "strang@fp32:dt=1e-08"
    assert rule.verdict(reg, reg["settings"][2], "stft_amplitude", 0.25) == "undecided"
    assert report.seed_differences(reg, reg["settings"][2], "stft_amplitude")[7] > report.outlier_bound(64)
    (text,) = report.one_seed_notes(reg, ch, 0.25, "resolution")
    assert text.startswith("Kept without one seed") and "`strang@fp32:dt=1e-07` without seed 7 (" in text
    assert "5e-07" not in text  # it moves the measure: no seed decides that
    view = report.without_seeds(reg, {7})
    assert len(view["pads"]) == 63 and all(len(s["values"]["stft_amplitude"]) == 63 for s in view["settings"])
    assert rule.kept(rule.verdict(view, view["settings"][2], "stft_amplitude", 0.25))
    assert 4.9 < report.outlier_bound(128) < 5.1 and report.outlier_bound(32) < report.outlier_bound(128)
    calm = regime(mild)  # a seed within what two parted runs give: nothing named
    assert report.one_seed_notes(calm, rule.settings_for({"regimes": {"syn": calm}}, "syn"), 0.25, "resolution") == []
    monkeypatch.setattr(report, "outlier_bound", lambda n: 100.0)  # seed 7's pad no outlier: not named either
    assert report.one_seed_notes(reg, ch, 0.25, "resolution") == []
    monkeypatch.undo()
    # two members (LF states) per seed, 32 seeds: the tonal pad (pad 38, seed 7) in member b, whose values (and σ)
    # are 100 times member a's: each pad in units of its own member's reference σ, the bound over all 64 pads
    tonal_b = near.copy()
    tonal_b[38] *= 6.0
    two = regime(tonal_b)
    two["pads"] = [{"seed": k % 32 + 1, "member": "ab"[k // 32]} for k in range(64)]
    wide = np.where(np.arange(64) < 32, 1.0, 100.0)
    for s in two["settings"]:
        s["values"]["stft_amplitude"] = (np.array(s["values"]["stft_amplitude"]) * wide).tolist()
    b = slice(32, 64)
    sigma_b = float(np.std(base[b] * 100.0, ddof=1))
    got = report.seed_differences(two, two["settings"][2], "stft_amplitude")
    assert got[7] == pytest.approx(abs(tonal_b[38] - base[38]) * 100.0 / sigma_b)
    assert max(got.values()) == got[7] > 10.0
    counted = []
    monkeypatch.setattr(report, "outlier_bound", lambda n: counted.append(n) or 5.0)
    (note,) = report.one_seed_notes(two, rule.settings_for({"regimes": {"syn": two}}, "syn"), 0.25, "resolution")
    assert counted == [64] and "without seed 7 (" in note


def test_members_take_the_worst():
    """A regime with two members (LF states): the regime's figure is the member with the larger bound/σ."""
    reg = synthetic_regime(20)
    for i, p in enumerate(reg["pads"]):
        p["member"] = "s1" if i < 10 else "s2"
    mid = reg["settings"][3]
    mid["values"]["mu_std"] = [x + (2.0 if i >= 10 else 0.0) for i, x in enumerate(mid["values"]["mu_std"])]
    c = rule.compare_setting(reg, mid, "mu_std")
    ref_a = np.array(reg["settings"][0]["values"]["mu_std"][10:])
    assert c.member == "s2" and c.n == 10
    assert c.sigma == pytest.approx(ref_a.std(ddof=1), rel=1e-12)
    assert c.error == pytest.approx(np.mean(mid["values"]["mu_std"][10:]) - ref_a.mean(), rel=1e-9)
    noisy = reg["settings"][2]  # within resolution in each member; one member moved makes the regime's verdict move
    assert rule.verdict(reg, noisy, "mu_std", 0.25) == "within resolution"
    noisy["values"]["mu_std"] = [x + (5.0 if i >= 10 else 0.0) for i, x in enumerate(noisy["values"]["mu_std"])]
    assert rule.verdict(reg, noisy, "mu_std", 0.25) == "moves"


def test_grid_syntax_and_new_integrators(monkeypatch):
    """Specs expand to products and labels parse back; bad specs are refused with the reason; a name added to
    INTEGRATORS enters the default grid at its defaults and is accepted in a spec."""
    s = wps.parse_setting("strang@fp32,fp64:dt=1e-8,5e-7")
    assert [x.label for x in s] == ["strang@fp32:dt=1e-08", "strang@fp32:dt=5e-07", "strang@fp64:dt=1e-08",
                                    "strang@fp64:dt=5e-07"]  # fmt: skip
    for x in s:
        assert wps.parse_setting(x.label) == [x]
    a = wps.parse_setting("adaptive@fp64:tol=1e-4:dt=1e-9")
    assert a == [wps.Setting("adaptive", "fp64", 1e-9, 1e-4)]
    assert math.isinf(a[0].cost(1e-3)) and s[0].cost(1e-3) == pytest.approx(1e5)
    m = wps.parse_setting("strang@fp32:dt=2.5e-7:mean")
    assert m == [wps.Setting("strang", "fp32", 2.5e-7, crossing="mean")] and m[0].label == "strang@fp32:dt=2.5e-07:mean"
    assert wps.parse_setting(m[0].label) == m
    for bad in ("rk4@fp32", "strang@fp16", "strang@fp32:h=1e-8", "strang@fp32:dt=-1", "strang@fp32:dt=x",
                "adaptive@fp64:tol=1e-4:mean"):  # fmt: skip
        with pytest.raises(ValueError):
            wps.parse_setting(bad)
    assert not any(spec.startswith("lstable") for spec in wps.default_grid(False))
    monkeypatch.setattr(wps, "INTEGRATORS", (*wps.INTEGRATORS, "lstable"))
    assert "lstable@fp32,fp64" in wps.default_grid(False) and "lstable@fp32,fp64" in wps.default_grid(True)
    assert [x.label for x in wps.parse_setting("lstable@fp32:tol=1e-3")] == ["lstable@fp32:tol=0.001"]
    g = wps.grid(wps.default_grid(True), ["lstable", "adaptive"], ["fp64"])
    assert {x.integrator for x in g} == {"lstable", "adaptive"} and {x.precision for x in g} == {"fp64"}


def test_pad_measures_read_from_the_validation_pad():
    """Band spectra are log10 of band means (NaN above the record's Nyquist), the velocity-sum peak is the largest
    peak above 5 kHz, the STFT and tonality measures read their entries, a pad without measures is NaN."""
    freq = np.arange(0, 100_001, 250.0)
    amp = np.full(freq.size, 10.0)
    amp[(freq > 40e3) & (freq < 60e3)] = 0.1
    velocity = np.exp(-0.5 * ((freq - 51e3) / 1e3) ** 2) + 2.0 * (freq < 4e3)  # the largest bins below 5 kHz
    bands = rule.band_log10(freq, amp)
    assert bands[0] == pytest.approx(1.0) and bands[8] == pytest.approx(-1.0)  # 5–10 kHz and 45–50 kHz
    assert np.isnan(bands[-1]) and np.isfinite(bands[18])  # 145–150 kHz beyond 100 kHz; 95–100 kHz in
    pad = {
        "growth_rate": 812.0,
        "measures": {
            "mu_std": 0.02, "sync_relative": {"median_excess_phi10": 0.07},
            "stft": [{"samples": 2048, "amplitude": 9.0}, {"samples": 4096, "amplitude": 0.004, "frequency": 7e4}],
            "tonality": {"peak_to_median": [2.0, 3.0, 2.0 * math.e]},
        },
    }  # fmt: skip
    spectra = {"freq": freq, "mu": amp, "velocity": velocity}
    names = ["mu_std", "vsum_peak", "mu_spectrum", "sync_excess", "growth_rate", "stft_amplitude", "tonality", "f1"]
    vals = rule.pad_values([pad, {"seed": 2}], [spectra, None], names)
    assert vals["mu_std"][0] == 0.02
    assert vals["vsum_peak"][0] == pytest.approx(51e3, abs=10)
    assert vals["mu_spectrum"][0][0] == pytest.approx(1.0)
    assert vals["sync_excess"][0] == 0.07 and vals["growth_rate"][0] == 812.0
    assert vals["stft_amplitude"][0] == 0.004 and vals["tonality"][0] == pytest.approx(1.0)
    assert math.isnan(vals["f1"][0])
    assert all(math.isnan(vals[k][1]) for k in names)


def test_report_page_from_a_synthetic_result(tmp_path):
    """The page names the machine, the floor and the choice with the other criteria's beside it, gives every
    setting's error/σ with its bound and verdict (≈: within resolution), sd(d)/σ with the seeds the strict rule
    would need, and the cheapest setting per measure; the figure is written; a regime named in two files is
    refused."""
    doc = {
        "machine": {"device": "cpu", "device_name": "CPU", "host": "Test CPU, 2 cores"},
        "tag": "cpu_quick", "quick": True, "commands": ["python3 scripts/work_precision_stats.py --quick"],
        "regimes": {"syn": synthetic_regime()},
    }  # fmt: skip
    path = tmp_path / "wps_cpu_quick_syn.json"
    path.write_text(json.dumps(doc))
    page, figs = tmp_path / "docs" / "page.md", tmp_path / "docs" / "fig"
    page.parent.mkdir()
    wps_report.report([path], page, figs, 0.25, None, "resolution")
    text = page.read_text()
    assert "Test CPU, 2 cores" in text and "(the quick CPU variant)" in text
    assert "With 30 seeds the resolution floor t₀.₉₇₅ √2 σ/√n is 0.53 σ" in text
    assert (
        "| syn | 30 × 10 | 30.0 ms | `strang@fp64:dt=1e-08` (10 s) | `adaptive@fp64:tol=0.001` | 1.5 | 6.7 | μ std | "
        "μ std |" in text
    )
    assert "| syn | 30 × 10 | `adaptive@fp64:tol=0.001` (6.7×) | `strang@fp32:dt=1e-07` (5×) |" in text
    assert "`strang@fp32:dt=5e-07` (μ std 0.5 σ)" in text and "the strict criterion would need 64 seeds" in text
    assert "| `strang@fp32:dt=5e-07` | 1 | 10 | **0.5 (0.5)** | 0 (0) ✓ | no |" in text
    assert "| `adaptive@fp64:tol=0.001` | 1.5 | 6.7 | < 0.001 (0.37) ≈ | 0 (0) ✓ | yes |" in text
    assert "| `strang@fp32:dt=1e-07` | 2 | 5 | 0.1 (0.17) ✓ | 0 (0) ✓ | yes |" in text
    assert "| `implicit-friction@fp32:dt=5e-07` | 0.5 | 20 | – | – | no (incomplete) |" in text
    assert (
        "| μ std | 1 | -0.4141 | 0.836 | 0.312 | 30 | – | 0–1 | – | 2–64 | `adaptive@fp64:tol=0.001` (1.5 s) |" in text
    )
    assert "`strang@fp32:dt=5e-07` (1 s) |" in text  # Φ: the cheapest setting keeping it
    wps_report.report([path], page, figs, 0.25, None, "strict")
    assert "`strang@fp32:dt=1e-07` | 2 | 5 | μ std | – |" in page.read_text()
    assert (figs / "wps_cpu_quick.png").stat().st_size > 10_000
    with pytest.raises(ValueError, match="both"):
        wps_report.report([path, path], page, figs, 0.25, None, "resolution")


def test_bad_input_exits_2(capsys):
    """A bad grid spec, reference or size: argparse's exit code 2 with the reason, nothing run."""
    for argv in (["--grid", "rk4@fp32"], ["--reference", "strang@fp32,fp64"], ["--seeds", "1"]):
        with pytest.raises(SystemExit) as e:
            wps.main(argv)
        assert e.value.code == 2
    assert "rk4" in capsys.readouterr().err
    assert wps.main(["--report", "missing.json"]) == 2


def _tiny_argv(out, patches: int, duration: float) -> list[str]:
    """The arguments of a tiny quick hf1 run: two sectors of ``patches`` patches over ``duration`` [s], the window
    its second half, results into ``out``."""
    return ["--quick", "--regimes", "hf1", "--seeds", "2", "--patches", str(patches), "--duration", f"{duration:g}",
            "--window", f"{duration / 2:g}", "--out", str(out)]  # fmt: skip


def test_tiny_run_end_to_end(tmp_path, capsys):
    """Two 10-patch hf1 sectors for 1 ms (linear growth: not chaotic yet): strang at 1e-8 s stays within 1e-3 σ of
    the 2e-8 s reference, at 5e-7 s forced it moves the measures by more than 0.1 σ; the file holds every pad's
    value. A second call with another grid continues the file (the reference kept, not rerun), also when the file
    was made on another host with the same kind of device (each run records its host; the file keeps the machine
    and tag it was begun on); a call with other pads or on another device is refused."""
    out = tmp_path / "wps"
    argv = _tiny_argv(out, 10, 1e-3)
    assert wps.main([*argv, "--grid", "strang@fp64:dt=5e-7,1e-8"]) == 0
    path = out / "wps_cpu_quick_hf1.json"
    first = json.loads(path.read_text())
    reg = first["regimes"]["hf1"]
    assert [s["label"] for s in reg["settings"]] == ["strang@fp64:dt=2e-08", "strang@fp64:dt=5e-07",
                                                     "strang@fp64:dt=1e-08"]  # fmt: skip
    assert all(s["complete"] for s in reg["settings"])
    assert len(reg["settings"][0]["values"]["mu_mean"]) == 2 and reg["settings"][0]["role"] == "reference"
    fine = [rule.compare_setting(reg, reg["settings"][2], m).ratio for m in ("mu_mean", "mu_std", "f1", "phi")]
    assert max(fine) < 1e-3, fine
    coarse = [rule.compare_setting(reg, reg["settings"][1], m).ratio for m in ("mu_std", "f1", "phi", "top_excess")]
    assert max(coarse) > 0.1, coarse
    moved = json.loads(path.read_text())  # the file made on another host with the same device: continued
    moved["machine"]["host"], moved["tag"] = "Other host", "cpu3_quick"
    path.write_text(json.dumps(moved))
    assert wps.main([*argv, "--grid", "implicit-friction@fp64:dt=2.5e-7"]) == 0
    assert "it keeps that tag, cpu3_quick" in "".join(capsys.readouterr())
    doc = json.loads(path.read_text())
    assert doc["tag"] == "cpu3_quick"  # the tag it was begun with, as its machine
    assert doc["machine"]["host"] == "Other host" and doc["regimes"]["hf1"]["settings"][-1]["host"] != "Other host"
    again = doc["regimes"]["hf1"]["settings"]
    assert [s["label"] for s in again] == [*(s["label"] for s in reg["settings"]), "implicit-friction@fp64:dt=2.5e-07"]
    assert again[0] == reg["settings"][0] and len(doc["commands"]) == 2
    assert doc["regime_wall_s"] > first["regime_wall_s"] + again[-1]["wall_s"]
    capsys.readouterr()
    assert wps.main([*argv[:4], "3", *argv[5:], "--grid", "strang@fp64:dt=5e-7"]) == 2
    assert "choose another --out" in capsys.readouterr().err
    doc["machine"]["device_name"] = "Other device"
    path.write_text(json.dumps(doc))
    assert wps.main([*argv, "--grid", "strang@fp64:dt=5e-7"]) == 2
    assert "choose another --out" in capsys.readouterr().err


def test_the_default_reference_is_capped_and_a_named_one_runs_as_given():
    """The default reference's strang step is capped at REFERENCE_MARGIN × the regime's friction step; a reference
    named with ``--reference`` (e.g. the fp64 side of a precision pair) runs at its step, with a line saying it is
    past the margin, and none when it is not."""
    from aca_warp.hf.solver import friction_step, stable_step
    from aca_warp.studies.friction_stats import sector_scenes
    from aca_warp.studies.runs import batch_at_start

    model, _ = batch_at_start(sector_scenes(1, 20), "cpu", "fp64")
    bound = wps.REFERENCE_MARGIN * friction_step(stable_step(model))
    spec = f"strang@fp64:dt={3 * bound:.3g}"
    assert wps.reference_setting(spec, model).dt == pytest.approx(bound, rel=1e-2)
    lines: list[str] = []
    named = wps.reference_setting(spec, model, capped=False, log=lines.append)
    assert named.dt == pytest.approx(3 * bound, rel=1e-2)
    assert len(lines) == 1 and "run as given" in lines[0]
    assert wps.reference_setting(f"strang@fp64:dt={bound / 2:.3g}", model, capped=False, log=lines.append).dt < bound
    assert len(lines) == 1


def test_a_named_reference_runs_as_given_through_the_command(tmp_path, capsys):
    """``--reference`` past the margin (hf1: 0.9 × its friction step ≈ 8.7e-8 s) is the file's reference as given,
    and the call says so."""
    out = tmp_path / "wps"
    argv = [*_tiny_argv(out, 10, 2e-4), "--reference", "strang@fp64:dt=3e-7", "--grid", "strang@fp64:dt=5e-7"]
    assert wps.main(argv) == 0
    reg = json.loads((out / "wps_cpu_quick_hf1.json").read_text())["regimes"]["hf1"]
    assert reg["reference"] == "strang@fp64:dt=3e-07"
    assert reg["settings"][0]["dt_used"] > 2e-7  # run near 3e-7 s (fitted whole into the sample), not capped
    assert "run as given" in capsys.readouterr().out


def test_again_runs_the_grid_again_and_rows_name_their_kernels(tmp_path):
    """Each row records the digest of the kernels it ran on; ``--again`` runs the grid's settings of a continued
    file again and replaces their rows, keeping the reference's (also where the grid names its setting) and every
    other row, and only rows made on other kernels; a call cut short by --max-wall keeps the earlier rows, and the
    same call again finishes it. The report marks an fp32 row without a digest
    (run on the kernels whose fp32 friction sub-step dropped the damping), and only such a row."""
    out = tmp_path / "wps"
    argv = _tiny_argv(out, 6, 2e-4)
    assert wps.main([*argv, "--grid", "strang@fp32:dt=5e-7,1e-7"]) == 0
    path = out / "wps_cpu_quick_hf1.json"
    doc = json.loads(path.read_text())
    rows = doc["regimes"]["hf1"]["settings"]
    from aca_warp.common.files import kernels_digest

    digest = kernels_digest()
    assert re.fullmatch(r"[0-9a-f]{12}", digest) and all(r["kernels"] == digest for r in rows)
    assert "kernels" not in doc  # a file's rows may come from several calls: the digest is per row
    for r in rows:
        r["kernels"] = None if r["precision"] == "fp32" else r["kernels"]
        r["wall_s"] = 1e3 if r["label"] == "strang@fp32:dt=1e-07" else r["wall_s"]  # marks the rows kept
    path.write_text(json.dumps(doc))
    marked = [wps_report.earlier_fp32(r) for r in rows]
    assert marked == [False, True, True], marked  # the fp64 reference is not marked
    table = wps_report.setting_table(doc["regimes"]["hf1"], 0.25, ["mu_mean"], "resolution")
    assert [line.split(" |")[0] for line in table[2:]] == [
        "| `strang@fp64:dt=2e-08` (reference)",
        "| `strang@fp32:dt=5e-07` †",
        "| `strang@fp32:dt=1e-07` †",
    ]
    grid = ["--grid", "strang@fp32:dt=5e-7", "strang@fp64:dt=2e-8", "--again"]  # the second: the reference's
    assert wps.main([*argv, *grid, "--max-wall", "0"]) == 0  # cut before its first run: every earlier row kept
    assert json.loads(path.read_text())["regimes"]["hf1"]["settings"] == rows
    assert wps.main([*argv, *grid]) == 0
    after = json.loads(path.read_text())["regimes"]["hf1"]["settings"]
    assert [r["label"] for r in after] == [rows[0]["label"], rows[2]["label"], rows[1]["label"]]
    assert after[0] == rows[0] and after[1] == rows[2]  # the reference and the other grid row kept as they were
    assert after[2]["kernels"] == digest and not wps_report.earlier_fp32(after[2])
    (mixed,) = wps_report.versions_text(after)  # wall times of two kernel versions side by side: said
    assert f"kernels of 2 versions (1 from before the rows recorded their kernels; 2 on kernels `{digest}`)" in mixed
    assert wps_report.versions_text([after[0], after[2]]) == []
    assert wps.main([*argv, "--grid", "strang@fp32:dt=5e-7"]) == 0  # without --again: nothing run again
    assert json.loads(path.read_text())["regimes"]["hf1"]["settings"] == after
    assert wps.main([*argv, *grid]) == 0  # --again again: its rows are on these kernels now, nothing run again
    assert json.loads(path.read_text())["regimes"]["hf1"]["settings"] == after


def test_kernels_digest_follows_the_sources(tmp_path):
    """The kernels' digest changes with a file's content and name, not with the folder's place or the files'
    order on disk; every run's versions carry it."""
    from aca_warp.common.files import kernels_digest, version_changes, versions

    a, b = tmp_path / "a", tmp_path / "b"
    for folder, names in ((a, ("x.py", "y.py")), (b, ("y.py", "x.py"))):
        folder.mkdir()
        for n in names:
            (folder / n).write_text(f"# {n}\nK = 1\n")
    assert kernels_digest(a) == kernels_digest(b) != kernels_digest()
    (b / "y.py").write_text("# y.py\nK = 2\n")
    assert kernels_digest(b) != kernels_digest(a)
    (b / "y.py").rename(b / "z.py")
    (b / "z.py").write_text("# y.py\nK = 1\n")
    assert kernels_digest(b) != kernels_digest(a)
    assert versions()["kernels"] == kernels_digest()  # a rerun names a kernel edit as it names a package's
    assert version_changes({"kernels": "000000000000"}) == [f"kernels 000000000000 -> {kernels_digest()}"]


def test_merged_rows_of_two_kernel_versions():
    """A merged row whose parts ran on different kernels (one before rows recorded them) holds both; the report
    counts it under each version, marks it as earlier in fp32, and never marks a row that did not run."""
    from aca_warp.studies.work_precision_stats_merge import _merged_row

    values = {"mu_mean": [0.5]}
    new = _setting("strang@fp32:dt=1e-7", "grid", 1.0, values) | {"kernels": "0123456789ab"}
    old = {k: v for k, v in new.items() if k != "kernels"}
    row = _merged_row(new["label"], "grid", [new, old], [(0, 0), (1, 0)], ["mu_mean"])
    assert row["kernels"] == ["0123456789ab", None] and wps_report.kernel_versions(row) == {"0123456789ab", None}
    assert wps_report.earlier_fp32(row) and not wps_report.earlier_fp32(new)
    assert "kernels" not in _merged_row(old["label"], "grid", [old, old], [(0, 0), (1, 0)], ["mu_mean"])
    ref = _setting("strang@fp64:dt=1e-8", "reference", 2.0, values) | {"kernels": "0123456789ab"}
    (text,) = wps_report.versions_text([ref, row])
    assert "kernels of 2 versions (1 from before the rows recorded their kernels; 2 on kernels `0123456789ab`)" in text
    assert "None" not in text
    cut = {**old, "complete": False, "fault": "not run: --max-wall", "wall_s": None, "values": None}
    del cut["steps"], cut["values"]
    assert not wps_report.earlier_fp32(cut)
    half = _merged_row(old["label"], "grid", [cut, old], [(1, 0)], ["mu_mean"])  # ran in one part, cut in the other
    assert "complete in 1 of 2 parts" in half["fault"] and wps_report.earlier_fp32(half)
    half = _merged_row(new["label"], "grid", [cut, new], [(1, 0)], ["mu_mean"])
    assert half["kernels"] == "0123456789ab" and not wps_report.earlier_fp32(half)
    with pytest.raises(KeyError, match="no setting"):
        wps_report.row_of({"name": "hf1", "settings": [ref]}, "strang@fp32:dt=1e-07")


def test_again_only_with_a_measuring_call(capsys):
    """``--again`` with --report, --merge, --by-part or --steps is refused (exit 2, nothing written)."""
    for extra in (["--report", "x.json"], ["--merge", "a.json", "b.json"], ["--by-part", "x.json"],
                  ["--steps", "x.json"]):  # fmt: skip
        with pytest.raises(SystemExit) as e:
            wps.main([*extra, "--again"])
        assert e.value.code == 2 and "--again goes with a call that measures" in capsys.readouterr().err


ABSENT_TEXT = "not in this part"  # the merge's fault text of a setting a part did not ask for


def test_committed_page_is_what_the_report_writes():
    """The generated section of docs/work_precision_statistics.md is what ``--report`` writes from the committed
    result files (every number on the page traceable to them)."""
    from pathlib import Path

    repo = Path(__file__).resolve().parent.parent
    page = repo / "docs" / "work_precision_statistics.md"
    folder = repo / "docs" / "figures" / "work_precision_statistics"
    text = page.read_text()
    names = [n for n in re.findall(r"`(docs/figures/work_precision_statistics/wps_[^`]+\.json)`", text)]
    assert names, "the page names no result file"
    docs = [rule.load_results(repo / n) for n in names]
    tags = list(dict.fromkeys(d["tag"] for d in docs))
    body = wps_report.render(docs, names, [folder / f"wps_{t}.png" for t in tags], page, 0.25, None, "resolution")
    begin, end = wps_report.generated_markers(wps_report.MARKER)
    assert text.split(begin, 1)[1].split(end, 1)[0] == "\n" + "\n".join(body) + "\n"
    for t in tags:
        assert (folder / f"wps_{t}.png").is_file()


def test_a_result_file_continues_across_a_change_of_the_validation_stepping():
    """The regime's config is compared without the validation's stepping table (the grid sets the steps)."""
    from aca_warp.studies.validation.base import without_stepping

    key = {"seeds": 32, "window": 0.01, "stepping": {"hf": "strang, dt = 1e-07 s, fp32"}}
    assert without_stepping(key) == {"seeds": 32, "window": 0.01} == without_stepping({**key, "stepping": {}})
    assert without_stepping({**key, "dt": None, "growth_dt": None}) == without_stepping(key)  # overrides too


def test_committed_parts_continue_under_the_current_settings():
    """The config a run of the study writes now, for the arguments of a committed part's command, is the one that
    part holds (as the continuation compares them): a part can be continued with more settings, and parts made
    before and after a change of the validation's run key merge."""
    import shlex
    from pathlib import Path

    from aca_warp.studies.validation.base import without_stepping

    root = Path(__file__).resolve().parent.parent / "docs" / "figures" / "work_precision_statistics"
    parts = sorted((root / "growth_events").glob("*_parts/s*/wps_*.json"))
    assert len(parts) == 7
    for path in parts:
        doc = json.loads(path.read_text())
        args = wps.build_parser().parse_args(shlex.split(doc["commands"][-1])[2:])
        (reg,) = doc["regimes"].values()
        assert without_stepping(wps.regime_config(args).run_key()) == without_stepping(reg["config"]), path


def _parts_of(reg: dict, seeds: list[range], tags: list[str]) -> list[dict]:
    """``reg`` split into result documents by seed (part k: the pads of every member with a seed in ``seeds[k]``),
    each as one part's file."""
    import copy

    docs = []
    for k, span in enumerate(seeds):
        idx = [i for i, p in enumerate(reg["pads"]) if p["seed"] in span]
        part = copy.deepcopy(reg)
        part["pads"] = [reg["pads"][i] for i in idx]
        part["duration_s"] = 0.03 + 0.001 * k  # each part's own plan
        part["config"] = {**reg["config"], "seeds": len(span), "first_seed": span[0]}
        for s in part["settings"]:
            s["values"] = {m: [v[i] for i in idx] for m, v in s["values"].items()} if s["values"] else None
            s["wall_s"] = s["wall_s"] / (k + 1)
        docs.append({"machine": {"device": f"cuda:{tags[k][-1]}", "device_name": "GPU X", "host": "Test host"},
                     "tag": tags[k], "quick": False, "rule": 0.25, "versions": {"warp": "1"},
                     "commands": [f"part {k}"], "regimes": {"syn": part}, "regime_wall_s": 100.0})  # fmt: skip
    return docs


def test_setting_table_says_run_in_some_parts_only_where_every_part_that_asked_for_it_ran_it(tmp_path):
    """A merged setting one part did not ask for and another cut reads as the merge's fault in the setting table and
    as cut by a time limit in the words, not as run in the parts that asked for it."""
    from aca_warp.studies.work_precision_stats_merge import merge

    whole = synthetic_regime(6)
    parts = _parts_of(whole, [range(1, 3), range(3, 5), range(5, 7)], ["cuda0", "cuda1", "cuda2"])
    label = parts[0]["regimes"]["syn"]["settings"][1]["label"]
    del parts[0]["regimes"]["syn"]["settings"][1]  # not asked for
    parts[1]["regimes"]["syn"]["settings"][1].update(complete=False, fault="not run: --max-wall")
    paths = [tmp_path / f"p{k}.json" for k in range(3)]
    for path, part in zip(paths, parts, strict=True):
        path.write_text(json.dumps(part))
    reg = merge(paths)["regimes"]["syn"]
    fault = next(s["fault"] for s in reg["settings"] if s["label"] == label)
    assert fault == "not run: complete in 1 of 3 parts (not run: not in this part; not run: --max-wall)"
    row = next(r for r in wps_report.setting_table(reg, 0.25, ["mu_std"], "resolution") if f"`{label}`" in r)
    assert row.endswith(f"| no ({fault}) |") and "run in 1 of 3 parts only" not in row
    words = wps_report.regime_results({"regimes": {"syn": reg}}, "syn", 0.25, None, "resolution")
    assert f"cut by the call's time limit: `{label}`" in words and "some parts only" not in words


def test_merging_parts_gives_the_whole_regime(tmp_path, capsys):
    """A regime measured in parts over disjoint seeds and merged gives every comparison of the whole regime (pads
    ordered by member, then seed, whatever order the parts come in); a setting's wall time is the sum of its
    parts', each part's kept; a setting incomplete in one part is not run in the merge, and the report names one
    that a part did not ask for as run in some parts only, not as cut by a time limit; parts that overlap in
    seeds, hold another regime or another device are refused; the CLI writes OUT/wps_<tag>_<regime>.json and never
    over an existing file; the page gives each part's run length."""
    from aca_warp.studies.work_precision_stats_merge import merge, merged_tag

    whole = synthetic_regime(20)
    for i, p in enumerate(whole["pads"]):
        p["member"], p["seed"] = ("s1", i + 1) if i < 10 else ("s2", i - 9)
    spans = [range(1, 4), range(4, 6), range(6, 9), range(9, 11)]
    parts = _parts_of(whole, spans, ["cuda0", "cuda1", "cuda2", "cuda3"])
    paths = []
    for k in (2, 0, 3, 1):  # any order
        paths.append(tmp_path / f"p{k}.json")
        paths[-1].write_text(json.dumps(parts[k]))
    doc = merge(paths)
    reg = doc["regimes"]["syn"]
    assert doc["tag"] == "cuda0123" and doc["regime_wall_s"] == 400.0 and len(doc["commands"]) == 4
    assert [(p["member"], p["seed"]) for p in reg["pads"]] == [(p["member"], p["seed"]) for p in whole["pads"]]
    assert reg["config"]["seeds"] == 10 and reg["config"]["first_seed"] == 1
    assert [p["seeds"] for p in reg["parts"]] == [[1, 2, 3], [4, 5], [6, 7, 8], [9, 10]]  # by seed, any order given
    assert [p["duration_s"] for p in reg["parts"]] == [0.03, 0.031, 0.032, 0.033] and reg["duration_s"] == 0.033
    for s, w in zip(reg["settings"], whole["settings"], strict=True):
        if not w["complete"]:
            assert not s["complete"] and s["wall_s"] is None and s["fault"].startswith("incomplete: complete in 0")
            continue
        assert s["wall_s"] == pytest.approx(w["wall_s"] * (1 / 3 + 1 + 1 / 4 + 1 / 2))
        assert len(s["part_wall_s"]) == 4
        for m in whole["measures"]:
            assert s["values"][m] == w["values"][m]
            a, b = rule.compare_setting(reg, s, m), rule.compare_setting(whole, w, m)
            assert (a.error, a.bound, a.member) == (b.error, b.bound, b.member)
    short = json.loads(paths[1].read_text())
    short["regimes"]["syn"]["settings"][1].update(complete=False, fault="not run: --max-wall")
    paths[1].write_text(json.dumps(short))
    cut = merge(paths)["regimes"]["syn"]["settings"][1]
    assert not cut["complete"] and cut["fault"] == "not run: complete in 3 of 4 parts (not run: --max-wall)"
    words = wps_report.regime_results(merge(paths), "syn", 0.25, None, "resolution")
    assert f"cut by the call's time limit: `{cut['label']}`" in words and "some parts only" not in words
    lacking = json.loads(json.dumps(short))
    del lacking["regimes"]["syn"]["settings"][1]  # a setting this part did not ask for
    paths[1].write_text(json.dumps(lacking))
    doc = merge(paths)
    absent = next(s for s in doc["regimes"]["syn"]["settings"] if s["label"] == cut["label"])
    assert absent["fault"] == "not run: complete in 3 of 4 parts (not run: not in this part)"
    words = wps_report.regime_results(doc, "syn", 0.25, None, "resolution")
    assert f"left out of the rule: `{cut['label']}` (complete in 3 of 4 parts))." in words
    assert "time limit" not in words
    table = "\n".join(wps_report.setting_table(doc["regimes"]["syn"], 0.25, ["mu_std"], "resolution"))
    assert f"`{cut['label']}` |" in table and "no (run in 3 of 4 parts only) |" in table and ABSENT_TEXT not in table
    short["regimes"]["syn"]["settings"][1]["fault"] = "refused: too tight"
    paths[1].write_text(json.dumps(short))
    assert merge(paths)["regimes"]["syn"]["settings"][1]["fault"].startswith("incomplete: complete in 3 of 4")
    with pytest.raises(ValueError, match="gap"):
        merge([paths[1], paths[0]])  # seeds 1–3 and 6–8
    paths[1].write_text(json.dumps(parts[0]))
    twice = [paths[1], tmp_path / "again.json"]
    twice[1].write_text(json.dumps(parts[0]))
    with pytest.raises(ValueError, match="in both"):
        merge(twice)
    other = json.loads(json.dumps(parts[3]))
    other["machine"]["device_name"] = "GPU Y"
    (tmp_path / "other.json").write_text(json.dumps(other))
    with pytest.raises(ValueError, match="GPU Y"):
        merge([paths[1], tmp_path / "other.json"])
    assert merged_tag(["cuda3", "cuda1"]) == "cuda13" and merged_tag(["cuda0_quick", "cuda1_quick"]) == "cuda01_quick"
    assert merged_tag(["cpu", "cuda0"]) == "cpu_cuda0" and merged_tag(["cuda0", "cuda0"]) == "cuda0"
    paths[1].write_text(json.dumps(parts[0]))
    out = tmp_path / "merged"
    assert wps.main(["--merge", *map(str, paths), "--out", str(out)]) == 0
    written = out / "wps_cuda0123_syn.json"
    assert json.loads(written.read_text())["regimes"]["syn"]["pads"] == reg["pads"]
    with pytest.raises(ValueError, match="itself merged"):
        merge([written, paths[0]])
    assert wps.main(["--merge", *map(str, paths), "--out", str(out)]) == 2
    assert "exists" in capsys.readouterr().err
    assert wps.main(["--merge", str(paths[0]), "--out", str(out)]) == 2
    page = tmp_path / "docs" / "page.md"
    page.parent.mkdir()
    wps_report.report([written], page, page.parent / "fig", 0.25, None, "resolution")
    text = page.read_text()
    assert "| syn | 20 × 10 | 30.0–33.0 ms |" in text
    assert "measured in 4 parts (seeds 1…3; 4…5; 6…8; 9…10; on cuda:0, cuda:1, cuda:2, cuda:3)" in text
    assert "33.0 ms (from 20.0 ms) (a setting's wall time: the sum of its parts'), perturbation" in text


def test_max_wall_estimate_counts_what_a_run_spends_besides_stepping():
    """A run's estimate for --max-wall: its steps at the reference's time per step plus the mean of the earlier runs'
    set-up and analysis time (a call that counted the stepping alone started a run it had no time left to finish)."""
    assert wps.run_estimate(4e5, 7.4e-5, []) == pytest.approx(29.6)
    assert wps.run_estimate(4e5, 7.4e-5, [60.0, 40.0]) == pytest.approx(79.6)
    assert wps.run_estimate(math.inf, 7.4e-5, [50.0]) == 50.0  # a step chosen by error control: the overhead only
    assert wps.run_estimate(4e5, math.nan, []) == 0.0  # nothing known


def test_max_wall_reckons_a_new_file_s_reference_by_the_cost_model(tmp_path, monkeypatch):
    """Before a regime's reference has run, ``--max-wall`` reckons it by the validation's cost model
    (``model_step``), so a new file's first run whose modelled time cannot end in time is not started (before, the
    estimate was 0 and any reference started); the model gives the CPU's throughput here, and no time for a step
    chosen by error control."""
    from aca_warp.studies.validation.cost import CPU_PATCH_STEPS

    out = tmp_path / "wps"
    argv = _tiny_argv(out, 10, 1e-3)
    seen: list[float] = []
    real = wps.model_step

    def model(scenes, setting, kind, cfg):
        seen.append(real(scenes, setting, kind, cfg))
        return 1.0  # s per step: 5e4 steps of the reference cannot fit in 60 s

    monkeypatch.setattr(wps, "model_step", model)
    assert wps.main([*argv, "--grid", "strang@fp64:dt=5e-7", "--max-wall", "60"]) == 0
    rows = json.loads((out / "wps_cpu_quick_hf1.json").read_text())["regimes"]["hf1"]["settings"]
    assert [(r["role"], r["fault"]) for r in rows] == [("reference", "not run: --max-wall"),
                                                       ("grid", "not run: --max-wall")]  # fmt: skip
    assert seen == [pytest.approx(2 * 10 / CPU_PATCH_STEPS)]  # two 10-patch pads on the CPU
    adaptive = wps.parse_setting("adaptive@fp64:tol=1e-6")[0]
    assert math.isnan(real([], adaptive, "window", None))


def test_errors_by_part_split_a_merged_regime_by_seed(tmp_path, capsys):
    """``--by-part``: each setting's error in units of σ (the reference's spread over every seed) over all pads and
    over each part's pads alone, signed for a scalar measure: a shift of +0.6 σ in the first part's seeds and
    −0.2 σ in the second's reads +0.6, −0.2 and their seed-weighted mean; a file that is not merged, and a measure
    the regime lacks, are refused (exit 2)."""
    from aca_warp.studies.work_precision_stats_merge import errors_by_part, merge

    whole = synthetic_regime(20)
    ref = np.array(whole["settings"][0]["values"]["phi"])
    sigma = ref.std(ddof=1)
    shift = np.where(np.arange(20) < 8, 0.6, -0.2) * sigma  # seeds 1–8, then 9–20
    whole["settings"][4]["values"]["phi"] = (ref + shift).tolist()
    paths = []
    for k, part in enumerate(_parts_of(whole, [range(1, 9), range(9, 21)], ["cuda0", "cuda1"])):
        paths.append(tmp_path / f"p{k}.json")
        paths[-1].write_text(json.dumps(part))
    doc = merge(paths)
    table = errors_by_part(doc, ["phi"])
    row = next(line for line in table.splitlines() if "`strang@fp32:dt=2e-08`" in line)
    assert row.split("|")[4:7] == [" +0.12 ", " +0.60 ", " -0.20 "]  # all: (8 × 0.6 − 12 × 0.2) / 20
    assert "| measure | member | setting | all 20 seeds | seeds 1–8 | seeds 9–20 |" in table
    assert len([line for line in table.splitlines() if line.startswith("| Φ |")]) == 4  # complete grid settings
    with pytest.raises(ValueError, match="merged"):
        errors_by_part(json.loads(paths[0].read_text()))
    with pytest.raises(ValueError, match="no measure f1"):
        errors_by_part(doc, ["f1"])
    merged = tmp_path / "m"
    assert wps.main(["--merge", *map(str, paths), "--out", str(merged)]) == 0
    capsys.readouterr()
    assert wps.main(["--by-part", str(merged / "wps_cuda01_syn.json"), "--measures", "phi"]) == 0
    assert "| Φ | – | `strang@fp32:dt=2e-08` |" in capsys.readouterr().out
    assert wps.main(["--by-part", str(paths[0])]) == 2
    assert "merged" in capsys.readouterr().err


def _page_blocks(kind: str, head: str) -> list[tuple[str, ...]]:
    """Every ``<!-- kind HEAD -->`` … ``<!-- END kind -->`` block of the docs pages: the groups of the regex ``head``
    (the block's header fields), then the block's text."""
    blocks = []
    for page in sorted((REPO / "docs").rglob("*.md")):
        blocks += re.findall(rf"<!-- {kind} {head} -->\n(.*?)<!-- END {kind} -->", page.read_text(), flags=re.S)
    return blocks


def test_the_pages_part_by_part_tables_are_the_scripts_output():
    """Every ``BY PART`` table of the docs is what ``--by-part FILE --measures …`` prints from the committed merged
    result file it names."""
    from aca_warp.studies.work_precision_stats_merge import errors_by_part

    blocks = _page_blocks("BY PART", r"(\S+) ([^>]+?)")
    assert len(blocks) >= 3
    for path, measures, table in blocks:
        printed = errors_by_part(rule.load_results(REPO / path), measures.split())
        assert printed.split("\n\n", 1)[1] == table, path


@pytest.mark.parametrize("regime", ["hf1", "ms_fast"])
def test_first_part_regenerates_in_the_later_parts_code(regime):
    """The first part of hf1 and of ms_fast (seeds 1–32) was measured with earlier code than the later parts; seeds
    1 and 2 rerun with the later parts' code (``<regime>_parts/check_s1-2``; ms_fast's on another H200 host, its LF
    runs made again) gave the first part's reference values bit for bit, so merging the parts mixes no two versions
    of the model."""
    from pathlib import Path

    wps = Path(__file__).resolve().parent.parent / "docs" / "figures" / "work_precision_statistics" / f"{regime}_parts"
    first = rule.load_results(wps / "s1" / f"wps_cuda0_{regime}.json")["regimes"][regime]
    check = rule.load_results(wps / "check_s1-2" / f"wps_cuda0_{regime}.json")["regimes"][regime]
    assert [int(p["seed"]) for p in check["pads"]] == [1, 2] == [int(p["seed"]) for p in first["pads"][:2]]
    ref_first, ref_check = rule.reference_of(first), rule.reference_of(check)
    assert ref_first["label"] == ref_check["label"] == "strang@fp64:dt=1e-08"
    for m in first["measures"]:
        a = np.asarray(ref_first["values"][m][:2], dtype=float)
        b = np.asarray(ref_check["values"][m], dtype=float)
        assert np.array_equal(a, b, equal_nan=True), m


MERGED = [("hf1", "cuda0"), ("hf2", "cuda0"), ("hf3", "cuda0"), ("va", "cuda0"), ("ms_fast", "cuda0"),
          ("ms_short", "cuda01"), ("ms_mid", "cuda01"), ("ms_app3", "cuda0123")]  # fmt: skip
"""(regime, tag of its merged file) of the main page's regimes measured in parts."""


@pytest.mark.parametrize(("regime", "tag"), MERGED)
def test_main_pages_merged_files_are_the_merge_of_their_parts(regime, tag, monkeypatch):
    """The main page's merged result files are the ``--merge`` of the parts committed beside them (hf1–hf3's and
    ms_app3's parts continued with the fp32 grid run again on the fixed kernels, ms_short's first part with fp64 at
    5e-8 s; va's four parts and ms_mid's two run anew); a part keeps the tag of the device it was begun on."""
    from pathlib import Path

    from aca_warp.studies.report import clean
    from aca_warp.studies.work_precision_stats_merge import merge

    repo = Path(__file__).resolve().parent.parent
    monkeypatch.chdir(repo)  # the parts named as the merge names them
    folder = repo / "docs" / "figures" / "work_precision_statistics"
    parts = sorted((p.relative_to(repo) for p in (folder / f"{regime}_parts").glob(f"s*/wps_cuda*_{regime}.json")),
                   key=lambda p: int(p.parent.name[1:]))  # fmt: skip
    assert len(parts) >= 2
    assert all(p.name == f"wps_{rule.load_results(repo / p)['tag']}_{regime}.json" for p in parts)
    assert json.loads(json.dumps(clean(merge(parts)))) == rule.load_results(folder / f"wps_{tag}_{regime}.json")


def test_ms_short_precision_pairs_are_the_merge_of_their_parts(monkeypatch):
    """The fp32/fp64 folder's fresh LF seeds of ms_short (65–128): the merged file is the ``--merge`` of its two
    parts, its reference is the fp64 setting of the pair at 5e-8 s, run as given past the friction-step margin, and
    every setting of the pair ran on all 128 pads."""
    from pathlib import Path

    from aca_warp.studies.report import clean
    from aca_warp.studies.work_precision_stats_merge import merge

    repo = Path(__file__).resolve().parent.parent
    monkeypatch.chdir(repo)
    folder = repo / "docs" / "figures" / "work_precision_statistics" / "fp32_fp64" / "ms_short_pairs"
    parts = [p.relative_to(repo) for p in (folder / "s65" / "wps_cuda0_ms_short.json",
                                           folder / "s97" / "wps_cuda1_ms_short.json")]  # fmt: skip
    merged = rule.load_results(folder / "wps_cuda01_ms_short.json")
    assert json.loads(json.dumps(clean(merge(parts)))) == merged
    reg = merged["regimes"]["ms_short"]
    assert reg["reference"] == "strang@fp64:dt=5e-08" and {p["seed"] for p in reg["pads"]} == set(range(65, 129))
    full = {s["label"] for s in reg["settings"] if len(s.get("values", {}).get("mu_mean", [])) == len(reg["pads"])}
    assert {"strang@fp64:dt=5e-08", "strang@fp32:dt=5e-08", "strang@fp32:dt=1e-07", "strang@fp64:dt=1e-07"} <= full


def test_growth_events_page_is_what_merge_and_report_write(monkeypatch):
    """The growth-events page (docs/figures/work_precision_statistics/growth_events/): its merged files are the
    ``--merge`` of its parts and its generated section is what ``--report`` writes from them."""
    from pathlib import Path

    from aca_warp.studies.report import clean
    from aca_warp.studies.work_precision_stats_merge import merge

    repo = Path(__file__).resolve().parent.parent
    monkeypatch.chdir(repo)  # the parts named as the page's command names them
    folder = repo / "docs" / "figures" / "work_precision_statistics" / "growth_events"
    docs, names = [], []
    for regime, tag, count in (("va", "cuda0", 3), ("va_full", "cuda01", 4)):
        merged = rule.load_results(folder / f"wps_{tag}_{regime}.json")
        parts = sorted(p.relative_to(repo) for p in (folder / f"{regime}_parts").glob(f"*/wps_cuda*_{regime}.json"))
        assert len(parts) == count
        assert json.loads(json.dumps(clean(merge(parts)))) == merged
        docs.append(merged)
        names.append(f"growth_events/wps_{tag}_{regime}.json")
    page = folder / "README.md"
    text = page.read_text()
    figures = [folder / "wps_cuda0.png", folder / "wps_cuda01.png"]  # one per device tag: va's, va_full's
    body = wps_report.render(docs, names, figures, page, 0.25, None, "resolution")
    begin, end = wps_report.generated_markers(wps_report.MARKER)
    assert text.split(begin, 1)[1].split(end, 1)[0] == "\n" + "\n".join(body) + "\n"
    assert len(docs[0]["regimes"]["va"]["pads"]) == 96 and len(docs[1]["regimes"]["va_full"]["pads"]) == 96
    for doc, regime in zip(docs, ("va", "va_full"), strict=True):
        assert rule.settings_for(doc, regime).setting == "strang@fp32:dt=1e-07:growth_dt=5e-06"


def test_equal_heights_page_is_what_merge_and_report_write(monkeypatch):
    """The equal-height presets' page (docs/figures/work_precision_statistics/equal_heights/): its three merged files
    are the ``--merge`` of their parts, its generated section is what ``--report`` writes from its five files, every
    fp32 row names the kernels it ran on (made since the fp32 fix), and the rule keeps 1e-7 s for the four HF
    presets."""
    from pathlib import Path

    from aca_warp.studies.report import clean
    from aca_warp.studies.work_precision_stats_merge import merge

    repo = Path(__file__).resolve().parent.parent
    monkeypatch.chdir(repo)  # the parts named as the page's command names them
    folder = repo / "docs" / "figures" / "work_precision_statistics" / "equal_heights"
    files = ["wps_cuda01_hf1_equal.json", "wps_cuda1_hf2_equal.json", "wps_cuda0_hf3_equal.json",
             "wps_cuda1_hf4_equal.json", "wps_cuda0_va_equal.json"]  # fmt: skip
    docs = [rule.load_results(folder / f) for f in files]
    for doc in docs:
        (regime,) = doc["regimes"]
        parts = sorted(p.relative_to(repo) for p in (folder / f"{regime}_parts").glob(f"s*/wps_*_{regime}.json"))
        if parts:
            assert len(parts) == 2 and json.loads(json.dumps(clean(merge(parts)))) == doc
        grid = [s for s in doc["regimes"][regime]["settings"] if s["role"] == "grid"]
        assert grid and all(s.get("kernels") for s in grid), regime
    page = folder / "README.md"
    figures = [folder / f"wps_{t}.png" for t in ("cuda01", "cuda1", "cuda0")]
    body = wps_report.render(docs, [f"equal_heights/{f}" for f in files], figures, page, 0.25, None, "resolution")
    begin, end = wps_report.generated_markers(wps_report.MARKER)
    assert page.read_text().split(begin, 1)[1].split(end, 1)[0] == "\n" + "\n".join(body) + "\n"
    for doc in docs[:4]:
        (regime,) = doc["regimes"]
        assert rule.settings_for(doc, regime).setting == "strang@fp32:dt=1e-07", regime
    va = docs[4]["regimes"]["va_equal"]  # made anew on the fixed kernels, its reference too: one seed decides it
    assert all(s.get("kernels") for s in va["settings"])
    ch = rule.settings_for(docs[4], "va_equal")
    assert ch.setting == "strang@fp32:dt=1e-08"
    (note,) = wps_report.one_seed_notes(va, ch, 0.25, "resolution")
    assert "`strang@fp32:dt=1e-07:growth_dt=5e-06` without seed 3 (" in note and note in page.read_text()


def test_fast_math_page_is_what_merge_and_report_write(monkeypatch):
    """The fast-math page (docs/figures/work_precision_statistics/fast_math/): each merged file is the ``--merge`` of
    its parts, which are the study's own part files with fast-math rows added (every other row as in the study's
    file), every row was made on kernels that record their digest or in fp64, and its generated section is what
    ``--report`` writes from its eight files."""
    from pathlib import Path

    from aca_warp.studies.report import clean
    from aca_warp.studies.work_precision_stats_merge import merge

    repo = Path(__file__).resolve().parent.parent
    monkeypatch.chdir(repo)
    study = repo / "docs" / "figures" / "work_precision_statistics"
    folder = study / "fast_math"
    files = [f"wps_cuda0_{r}.json" for r in ("hf1", "hf2", "hf3", "hf4", "va", "ms_fast")]
    files += [f"wps_cuda01_{r}.json" for r in ("ms_short", "ms_mid")]
    docs = [rule.load_results(folder / f) for f in files]
    for doc in docs:
        (regime,) = doc["regimes"]
        parts = sorted(p.relative_to(repo) for p in (folder / f"{regime}_parts").glob(f"s*/wps_*_{regime}.json"))
        own = sorted(p.relative_to(repo) for p in (study / f"{regime}_parts").glob(f"s*/wps_*_{regime}.json"))
        if regime == "hf4":
            parts, own = [], [(study / "wps_cuda0_hf4.json").relative_to(repo)]
        else:
            assert len(parts) >= 2 and json.loads(json.dumps(clean(merge(parts)))) == doc
        for mine, theirs in zip(parts or [(folder / "wps_cuda0_hf4.json").relative_to(repo)], own, strict=True):
            rows = rule.load_results(mine)["regimes"][regime]["settings"]
            study_rows = rule.load_results(theirs)["regimes"][regime]["settings"]
            by_label = {s["label"]: s for s in study_rows}  # the study's file may have gained rows since
            assert [s for s in rows if not s.get("fast_math")] == [by_label[s["label"]] for s in rows
                                                                   if not s.get("fast_math")], mine  # fmt: skip
            fast = [s for s in rows if s.get("fast_math")]
            assert fast and all(s.get("kernels") and s.get("complete") for s in fast), mine
    page = folder / "README.md"
    figures = [folder / f"wps_{t}.png" for t in ("cuda0", "cuda01")]
    body = wps_report.render(docs, [f"fast_math/{f}" for f in files], figures, page, 0.25, None, "resolution")
    begin, end = wps_report.generated_markers(wps_report.MARKER)
    assert page.read_text().split(begin, 1)[1].split(end, 1)[0] == "\n" + "\n".join(body) + "\n"
    picks = {next(iter(d["regimes"])): rule.settings_for(d, next(iter(d["regimes"]))).setting for d in docs}
    assert picks["ms_short"] == picks["ms_fast"] == "strang@fp32:dt=5e-08:fast"


class _Clock:
    """A stand-in for the ``time`` module of work_precision_stats: ``perf_counter`` advances ``step`` [s] a call."""

    def __init__(self, step: float) -> None:
        self.now, self.step = 0.0, step

    def perf_counter(self) -> float:
        self.now += self.step
        return self.now


def test_progress_stops_a_run_whose_projected_end_is_past_the_deadline(monkeypatch):
    """With a deadline, the sink projects the run's end from its rate since the first chunk once that rate spans
    PROBE_S, and stops the run (PastBudget) when the end lies past the deadline; without one it never stops, and a
    run whose end fits goes on."""
    from types import SimpleNamespace

    class Log(list):
        def __call__(self, message: str) -> None:
            self.append(message)

        def elapsed(self) -> float:
            return 100.0  # the call's wall time [s]

    monkeypatch.setattr(wps, "time", _Clock(5.0))  # 5 s of wall time between the sink's clock readings
    chunks = [SimpleNamespace(time=np.array([k * 1e-3])) for k in range(1, 6)]  # 1 ms of 10 per chunk

    def feed(deadline):
        sink = wps.Progress(lambda c: None, "x", 10e-3, Log(), deadline)
        for c in chunks:
            sink(c)

    feed(None)  # no deadline: never stops
    feed(140.0)  # the end projected at the third chunk, 100 + 5e3 s/s × 7 ms = 135 s, fits
    with pytest.raises(wps.PastBudget) as e:
        feed(120.0)  # the second chunk's 5 s are short of PROBE_S (10 s); the third's 10 s project 135 s
    assert e.value.done == pytest.approx(0.3) and e.value.rate == pytest.approx(5e3)
    assert e.value.end == pytest.approx(135.0)


def test_a_run_stopped_past_max_wall_is_written_as_not_run_and_run_by_a_later_call(tmp_path, monkeypatch, capsys):
    """A run whose projected end lies past ``--max-wall`` is stopped, written as not run (with the rate it ran
    at), and the next call without the limit runs it."""
    out = tmp_path / "wps"
    argv = [*_tiny_argv(out, 10, 2e-4), "--grid", "strang@fp64:dt=1e-7"]

    class Projecting(wps.Progress):  # a run of one chunk, projected as a sink of several would project it
        def __call__(self, chunk):
            super().__call__(chunk)
            if self.deadline is not None:
                raise wps.PastBudget(0.25, self.deadline + 50.0, 2e5)

    monkeypatch.setattr(wps, "Progress", Projecting)
    assert wps.main([*argv, "--max-wall", "100"]) == 0
    reg = json.loads((out / "wps_cpu_quick_hf1.json").read_text())["regimes"]["hf1"]
    stopped = [s for s in reg["settings"] if str(s["fault"]).startswith("not run: --max-wall (stopped at")]
    assert stopped and all(s["rate"] > 0 and s["wall_s"] is None for s in stopped)
    assert "past --max-wall: not run" in capsys.readouterr().out
    monkeypatch.undo()
    assert wps.main(argv) == 0
    reg = json.loads((out / "wps_cpu_quick_hf1.json").read_text())["regimes"]["hf1"]
    assert [s["complete"] for s in reg["settings"]] == [True, True]


def test_pads_far_from_the_median_are_listed_by_setting(tmp_path, capsys):
    """32 pads whose STFT maximum sits near 1.7e-3 but for seed 5, tonal (×6) in the reference only, and seed 9,
    tonal (×4) in the setting's run only: each listed where it is far from its setting's median, with its value in
    units of the median and its difference from the reference's value of the same pad in units of σ; a signed measure
    is left out with a line; two members each take their own σ; bad input is refused."""
    from aca_warp.studies.work_precision_stats_pads import pads_far_from_median

    rng = np.random.default_rng(3)
    base = 1.7e-3 * np.exp(0.05 * rng.standard_normal(32))
    ref, run = base.copy(), base.copy()
    ref[4] *= 6.0  # seed 5
    run[8] *= 4.0  # seed 9
    signed = (-0.6 + 0.05 * rng.standard_normal(32)).tolist()
    reg = {"name": "syn", "measures": ["stft_amplitude", "line_first"], "pads": [{"seed": s + 1} for s in range(32)],
           "settings": [_setting("strang@fp32:dt=1e-08", "reference", 10.0,
                                 {"stft_amplitude": ref.tolist(), "line_first": signed}),
                        _setting("strang@fp32:dt=1e-07", "grid", 1.0,
                                 {"stft_amplitude": run.tolist(), "line_first": signed}),
                        _setting("strang@fp32:dt=5e-07", "grid", 1.0, {}, complete=False)]}  # fmt: skip
    text = pads_far_from_median({"regimes": {"syn": reg}})
    sigma = float(np.std(ref, ddof=1))
    rows = [line for line in text.splitlines() if line.startswith("| STFT max |")]
    assert len(rows) == 2  # the reference and the completed setting; the run that did not complete is not listed
    assert "(reference)" in rows[0] and f"| 5: {ref[4] / np.median(ref):.1f}×, +0.0 σ |" in rows[0]
    d9 = (run[8] - ref[8]) / sigma
    assert rows[1].endswith(f"| {np.median(run):.4g} | 9: {run[8] / np.median(run):.1f}×, {d9:+.1f} σ |")
    assert "first line Δln f: left out" in text
    assert "| 9:" not in pads_far_from_median({"regimes": {"syn": reg}}, ["stft_amplitude"], factor=5.0)
    edge = json.loads(json.dumps(reg))  # a pad at exactly the factor × the median counts (above the median already)
    k = int(np.flatnonzero(run > np.median(run))[0])
    vals = run.copy()
    vals[k] = 3.0 * float(np.median(run))
    assert float(np.median(vals)) == float(np.median(run))
    edge["settings"][1]["values"]["stft_amplitude"] = vals.tolist()
    listed = pads_far_from_median({"regimes": {"syn": edge}}, ["stft_amplitude"]).replace("; ", "| ")
    assert f"| {k + 1}: 3.0×" in listed
    # two members per seed: member b's values 100 times a's, each pad in units of its own member's σ
    two = json.loads(json.dumps(reg))
    two["pads"] = [{"seed": k % 16 + 1, "member": "ab"[k // 16]} for k in range(32)]
    wide = np.where(np.arange(32) < 16, 1.0, 100.0)
    for s in two["settings"][:2]:
        s["values"]["stft_amplitude"] = (np.array(s["values"]["stft_amplitude"]) * wide).tolist()
    text = pads_far_from_median({"regimes": {"syn": two}}, ["stft_amplitude"], factor=2.0)
    b_rows = [line for line in text.splitlines() if line.startswith("| STFT max | b |")]
    assert len(b_rows) == 2 and all(line.endswith("| none |") for line in b_rows)  # b's pads: no tonal one
    (a_ref,) = [line for line in text.splitlines() if line.startswith("| STFT max | a | `strang@fp32:dt=1e-08`")]
    assert "| 5: " in a_ref and "| 5: " not in text.split(a_ref)[1]  # seed 5 is pad 4, in member a
    a_sigma = float(np.std(ref[:16], ddof=1))
    assert f"9: {run[8] / np.median(run[:16]):.1f}×, {(run[8] - ref[8]) / a_sigma:+.1f} σ" in text
    with pytest.raises(ValueError, match="exceed 1"):
        pads_far_from_median({"regimes": {"syn": reg}}, factor=1.0)
    with pytest.raises(ValueError, match="one regime"):
        pads_far_from_median({"regimes": {"a": reg, "b": reg}})
    with pytest.raises(ValueError, match="has no measure"):
        pads_far_from_median({"regimes": {"syn": reg}}, ["phi"])
    path = tmp_path / "wps_cpu_syn.json"
    path.write_text(json.dumps({"regimes": {"syn": reg}}))
    assert wps.main(["--by-pad", str(path), "--measures", "stft_amplitude"]) == 0
    assert "| 5: " in capsys.readouterr().out
    assert wps.main(["--by-pad", str(path), "--factor", "0.5"]) == 2
    assert "exceed 1" in capsys.readouterr().err
    for argv in (["--factor", "3"], ["--by-pad", str(path), "--report", str(path)], ["--by-pad", str(path), "--again"]):
        with pytest.raises(SystemExit):  # the default factor without --by-pad too: refused before anything runs
            wps.main(argv)
    assert "--by-pad" in capsys.readouterr().err


def test_the_pages_pad_tables_are_the_scripts_output():
    """Every ``BY PAD`` table of the docs is what ``--by-pad FILE --factor F --measures …`` prints from the committed
    result file it names."""
    from aca_warp.studies.work_precision_stats_pads import pads_far_from_median

    blocks = _page_blocks("BY PAD", r"(\S+) (\S+) ([^>]+?)")
    assert len(blocks) >= 3
    for path, factor, measures, table in blocks:
        printed = pads_far_from_median(rule.load_results(REPO / path), measures.split(), float(factor))
        assert printed.split("\n\n", 1)[1] == table, path
