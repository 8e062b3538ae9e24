"""The validation's verdicts and per-pad measures on inputs with known answers (``aca_warp.studies.validation``:
verdicts, measures, sync_measures, the rows' decisions), no runs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from aca_warp.studies.validation import base as VB
from aca_warp.studies.validation import measures as VM
from aca_warp.studies.validation import sync_measures as VS
from aca_warp.studies.validation import verdicts as V

# ------------------------------------------------------------------------------------------------ verdicts


def _around(mean: float, spread: float, n: int = 8, seed: int = 0) -> np.ndarray:
    x = np.random.default_rng(seed).normal(0.0, 1.0, n)
    return mean + spread * (x - x.mean()) / x.std(ddof=1)


def test_equivalence_reproduced_inside_the_margin_even_when_the_interval_excludes_zero():
    inside = _around(0.021, 0.002)  # [0.019, 0.023]: excludes 0, inside ± 0.05 (the old rule said not reproduced)
    assert V.side(inside) == 1 and V.equivalence_verdict(inside, 0.05) == V.REPRODUCED
    assert V.equivalence_verdict(_around(0.04, 0.03), 0.05) == V.PARTLY  # straddles the margin
    assert V.equivalence_verdict(_around(0.12, 0.01), 0.05) == V.NOT_REPRODUCED  # wholly beyond it
    assert V.equivalence_verdict(_around(-0.12, 0.01), 0.05) == V.NOT_REPRODUCED


def test_direction_carries_the_effect_against_the_margin():
    small, large, none = _around(0.005, 0.002), _around(0.2, 0.02), _around(0.0, 0.5)
    assert V.effect(small, 0.05) == V.SMALL and V.effect(large, 0.05) == V.AGREES
    assert V.effect(none, 0.05) == V.NONE and V.effect(-large, 0.05) == V.OPPOSITE
    assert V.effect(-large, 0.05, sign=-1.0) == V.AGREES
    assert V.direction_verdict([V.effect(small, 0.05)]) == V.NEGLIGIBLE  # significant but negligible
    assert V.direction_verdict([V.effect(large, 0.05)]) == V.REPRODUCED
    assert V.direction_verdict([V.AGREES, V.SMALL]) == V.PARTLY
    assert V.direction_verdict([V.AGREES, V.NONE]) == V.PARTLY
    assert V.direction_verdict([V.NONE]) == V.NOT_REPRODUCED
    assert (
        V.direction_verdict([V.NONE], [V.AGREES]) == V.PARTLY
        and V.direction_verdict([V.AGREES], [V.OPPOSITE]) == V.PARTLY
    )
    assert "against the margin 0.05" in V.effect_text(small, 0.05)


def test_the_strict_reading_asks_the_whole_interval_to_reach_the_margin():
    """A part whose mean reaches the margin while its interval reaches below it agrees, and under the stricter reading
    is significant but small; a part whose whole interval lies beyond the margin agrees under both; the stricter
    reading ends with its context."""
    straddles, beyond = _around(0.06, 0.03), _around(0.2, 0.02)  # [0.03, 0.09] and [0.18, 0.22] against 0.05
    assert V.effect(straddles, 0.05) == V.AGREES and V.effect(beyond, 0.05) == V.AGREES
    with V.strict_direction():
        assert V.effect(straddles, 0.05) == V.SMALL and V.effect(beyond, 0.05) == V.AGREES
        assert V.effect(-straddles, 0.05, sign=-1.0) == V.SMALL
    assert V.effect(straddles, 0.05) == V.AGREES


def test_rules_in_opposite_directions_are_undetermined():
    up, down, flat = _around(0.1, 0.01), _around(-0.1, 0.01), _around(0.0, 0.3)
    assert V.rules_verdict(V.NOT_REPRODUCED, down, up) == V.UNDETERMINED
    assert V.rules_verdict(V.REPRODUCED, up, flat) == V.REPRODUCED  # the snr rule not significant: no conflict
    assert V.rules_verdict(V.REPRODUCED, up, up) == V.REPRODUCED


def test_value_and_threshold_verdicts():
    near = 73e3 + _around(0.0, 200.0)
    assert V.value_verdict(near, 73e3, 3.65e3) == V.REPRODUCED
    assert V.value_verdict(np.array([70e3, 76.5e3]), 73e3, 3.65e3) == V.PARTLY
    assert V.value_verdict(near + 10e3, 73e3, 3.65e3) == V.NOT_REPRODUCED
    assert V.threshold_verdict(np.array([0.6, 0.7, 0.65]), 0.5, below=False) == V.REPRODUCED
    assert V.threshold_verdict(np.array([0.3, 0.35]), 0.5, below=False) == V.NOT_REPRODUCED
    assert "×2" in V.spread_text({"a": 1.0, "b": 2.0})


# ------------------------------------------------------------------------------------------------ rows


def _pad(seed: int, measures: dict, **extra) -> dict:
    return {"seed": seed, "status": "saturated", "measures": measures, "patches": 100, **extra}


def test_the_first_peak_rows_read_the_velocity_sum():
    rows = {r.statement: r for r in VB.ROWS}
    row = rows["HF2: first velocity-spectrum peak"]
    pads = [
        _pad(
            s,
            {
                "f1": 33.2e3 + 50 * s,
                "f1_first_half": 33.2e3,
                "f1_periodogram": 33.0e3,
                "f1_is_first": True,
                "f1_patch": {"0p02": 33e3, "0p05": 34e3, "0p1": 39.7e3, "0p25": 41e3},
            },
        )
        for s in range(1, 9)
    ]
    v = row.measure({"hf2": {"pads": pads}}, VB.Config())
    assert v.verdict == V.REPRODUCED and v.value.startswith("33.4")
    assert "per-patch mean spectrum at 0.1 39.7" in v.notes and "in 8 of 8 pads" in v.notes
    for p in pads:  # the per-patch reading would have failed it; the row does not read it
        p["measures"]["f1"] = 39.7e3
    assert row.measure({"hf2": {"pads": pads}}, VB.Config()).verdict == V.NOT_REPRODUCED


def test_patterns_need_co_moving_groups_in_hf2():
    """Neighbours moving against each other and groups below the patch spacing: no larger, better-defined patterns,
    however the two presets differ."""
    row = next(r for r in VB.ROWS if r.statement.startswith("larger patches: larger, better-defined"))

    def res(c: float, size: float) -> dict:
        return {"pads": [_pad(s, {"corr_near": c + 0.001 * s, "corr_zero": size + 1e-5 * s, "patch_spacing": 2.5e-3})
                         for s in range(1, 9)]}  # fmt: skip

    apart = {"hf1": res(-0.033, 0.0), "hf2": res(-0.047, 0.7e-3)}
    assert row.measure(apart, VB.Config()).verdict == V.NOT_REPRODUCED
    groups = {"hf1": res(0.05, 2e-3), "hf2": res(0.4, 8e-3)}
    assert row.measure(groups, VB.Config()).verdict == V.REPRODUCED


def test_stft_amplitude_is_not_comparable_and_shows_the_conventions():
    row = next(r for r in VB.ROWS if r.statement == "its amplitude, the STFT's maximum")
    pads = [{"seed": s, "status": "saturated", "end_mean_area_m2": 1.2e-6,
             "measures": {"stft": [{"window": "w", "samples": 4096, "amplitude": 0.003, "frequency": 6.9e4,
                                    "mean": 0.5}]}} for s in (1, 2, 3)]  # fmt: skip
    v = row.measure({"va_full": {"pads": pads}}, VB.Config())
    assert v.verdict == V.NOT_COMPARABLE
    assert "2^12 raw |FFT| ÷ μ̄: 3.07" in v.notes and "2^12 two-sided ÷ μ̄: 0.0015" in v.notes


def test_the_band_row_counts_mu_peaks_and_flags_the_area_cap():
    from aca_warp.studies.validation import multiscale as VMS

    row = next(r for r in VB.ROWS if r.statement.startswith("the characteristic friction and synchronisation"))
    groups = {}
    for g, members in VMS.GROUPS.items():
        groups[g] = {"pads": [_pad(s, {"f1": 25.1e3 + s, "mu_peak_hz": 100e3 + s}, member=m) for m in members
                              for s in range(1, 5)]}  # fmt: skip
    groups["lf_states"] = {"pads": [], "cap_frequency_hz": 25.1e3}
    v = row.measure(groups, VB.Config())
    assert v.verdict == V.PARTLY and "with μ's largest peak inside: 0 of 8" in v.value
    assert "states there app1_start" in v.notes


@pytest.mark.parametrize(
    ("f1", "mu", "verdict", "inside"),
    [
        (lambda s: 30e3 + s, lambda s: 60e3 + s, V.REPRODUCED, (8, 8)),  # every state's both peaks inside
        (lambda s: 10e3 + s, lambda s: 100e3 + s, V.NOT_REPRODUCED, (0, 0)),  # no part inside
        (lambda s: 30e3 + s, lambda s: (75e3, 90e3, 70e3, 85e3)[s - 1], V.PARTLY, (8, 0)),  # μ's means inside only
        (lambda s: 10e3 + s, lambda s: (75e3, 90e3, 70e3, 85e3)[s - 1], V.PARTLY, (0, 0)),
    ],
)
def test_the_band_row_combines_its_state_parts_as_every_statement_of_several_parts(f1, mu, verdict, inside):
    """§4's 20–80 kHz: each state's first peak and μ's largest peak a part (reproduced when its whole interval lies
    inside the band, partly when its mean does), combined as every threshold statement of several parts: reproduced
    when every part is, not reproduced when every part is not, partly otherwise (no count of parts decides)."""
    from aca_warp.studies.validation import multiscale as VMS

    row = next(r for r in VB.ROWS if r.statement.startswith("the characteristic friction and synchronisation"))
    groups = {
        g: {"pads": [_pad(s, {"f1": f1(s), "mu_peak_hz": mu(s)}, member=m) for m in members for s in range(1, 5)]}
        for g, members in VMS.GROUPS.items()
    }
    v = row.measure(groups, VB.Config())
    assert v.verdict == verdict
    assert (
        f"first velocity peak inside 20–80 kHz: {inside[0]} of 8; with μ's largest peak inside: {inside[1]} of 8"
        in v.value
    )


@pytest.mark.parametrize(
    ("corr", "verdict"), [(lambda s: 0.1 + 0.01 * s, V.REPRODUCED), (lambda s: -0.1 - 0.01 * s, V.NOT_REPRODUCED)]
)
def test_the_clustering_row_combines_its_states_as_every_statement_of_several_parts(corr, verdict):
    """§3.3's clustering in every state: reproduced when every state's C lies above 0, not reproduced when none does,
    partly when one state of eight does (a rule of its own had needed half of them)."""
    from aca_warp.studies.validation import multiscale as VMS

    row = next(r for r in VB.ROWS if r.statement.startswith("a degree of local clustering"))
    first = next(iter(VMS.GROUPS.values()))[0]

    def groups(value):
        return {
            g: {
                "pads": [
                    _pad(s, {"corr_near": value(s, m), "corr_zero": 1e-3}, member=m) for m in ms for s in range(1, 5)
                ]
            }
            for g, ms in VMS.GROUPS.items()
        }

    assert row.measure(groups(lambda s, m: corr(s)), VB.Config()).verdict == verdict
    v = row.measure(groups(lambda s, m: 0.1 + 0.01 * s if m == first else -0.1 - 0.01 * s), VB.Config())
    assert v.verdict == V.PARTLY and "lies above 0: 1 of 8" in v.value


@pytest.mark.parametrize("case", [1, 2, 3, 4])
def test_table_a2_rows(case):
    row = next(r for r in VB.ROWS if r.statement.startswith(f"case {case} "))
    assert VB.evaluate_rows({}, VB.Config(), [row])[0]["verdict"] == V.REPRODUCED


# ------------------------------------------------------------------------------------------------ measures


def _globals(t: np.ndarray, mu: np.ndarray, vsum: np.ndarray, radius: np.ndarray | None = None) -> np.ndarray:
    g = np.zeros((t.size, 6))
    g[:, 0], g[:, 1] = mu, mu * 0.1
    g[:, 2] = 0.1 if radius is None else radius
    g[:, 3], g[:, 4] = vsum, 10.0 + np.abs(vsum)
    return g


def test_velocity_sum_peak_of_a_synthetic_record():
    """Σu̇: a line at 33.2 kHz, a weaker harmonic at 66.4 kHz and broad-band noise: the primary reads 33.2 kHz."""
    rng = np.random.default_rng(1)
    dt, n = 1e-6, 20000
    t = np.arange(n) * dt
    v = np.sin(2 * np.pi * 33.2e3 * t) + 0.6 * np.sin(2 * np.pi * 66.4e3 * t) + 0.3 * rng.normal(size=n)
    out = VM.velocity_sum_peaks(_globals(t, 0.5 + 0.001 * v, v), dt, 1e3)
    assert out["f1"] == pytest.approx(33.2e3, rel=0.005) and out["f1_first_half"] == pytest.approx(33.2e3, rel=0.005)
    assert out["f1_is_first"] and out["sum_resolution_hz"] == pytest.approx(200.0)
    v2 = 0.6 * np.sin(2 * np.pi * 33.2e3 * t) + np.sin(2 * np.pi * 66.4e3 * t) + 0.05 * rng.normal(size=n)
    out2 = VM.velocity_sum_peaks(_globals(t, 0.5 + 0.001 * v2, v2), dt, 1e3)
    assert out2["f1"] == pytest.approx(66.4e3, rel=0.005) and not out2["f1_is_first"]  # the harmonic is larger
    assert out2["f1_first_half"] == pytest.approx(33.2e3, rel=0.005)
    # Σ|u̇| = 10 + |Σu̇| of a symmetric line: rectifying doubles it (why Σu̇, not Σ|u̇|, is the primary reading)
    v3 = np.sin(2 * np.pi * 33.2e3 * t) + 0.05 * rng.normal(size=n)
    out3 = VM.velocity_sum_peaks(_globals(t, 0.5 + 0.001 * v3, v3), dt, 1e3)
    assert out3["f1"] == pytest.approx(33.2e3, rel=0.005) and out3["f1_abs"] == pytest.approx(66.4e3, rel=0.005)
    assert out3["f1_abs_first_half"] == pytest.approx(66.4e3, rel=0.005)


def test_shape_at_reads_the_named_velocity_spectrum_with_its_suffix():
    """The Fig. 8 shape measures at a frequency of the chosen velocity spectrum: a line there stands out of its own
    spectrum, and the keys carry the suffix (Σ|u̇|'s readings beside Σu̇'s)."""
    freq = np.arange(0.0, 500e3, 100.0)
    line = 1e-3 + np.exp(-(((freq - 66.4e3) / 200) ** 2))
    flat = np.full(freq.size, 1e-3)
    spectra = {"velocity": flat, "abs_velocity": line, "mu": line, "torque": flat, "friction_radius": flat}
    out = VM.shape_at(freq, spectra, 66.4e3, velocity="abs_velocity", suffix="_abs")
    assert set(out) == {f"{m}_{q}_abs" for m in ("contrast", "plateau") for q in ("velocity", "mu", "torque", "radius")}
    assert out["contrast_velocity_abs"] > 100 and out["contrast_torque_abs"] == pytest.approx(1.0)
    assert VM.shape_at(freq, spectra, 66.4e3)["contrast_velocity"] == pytest.approx(1.0)


def test_per_patch_first_peak_depends_on_the_threshold():
    f = np.arange(1e3, 150e3, 100.0)
    amp = 0.04 * np.exp(-(((f - 33e3) / 300) ** 2)) + np.exp(-(((f - 41e3) / 300) ** 2)) + 1e-4
    out = VM.patch_first_peaks(f, amp, 1e3)
    assert out["0p02"] == pytest.approx(33e3, abs=100) and out["0p05"] == pytest.approx(41e3, abs=100)


def test_coherence_of_the_velocity_sum_with_mu():
    rng = np.random.default_rng(2)
    dt, n = 1e-6, 32768
    t = np.arange(n) * dt
    line = np.sin(2 * np.pi * 70e3 * t)
    together = VM.coherence_measures(_globals(t, 0.5 + 0.01 * line + 0.002 * rng.normal(size=n),
                                              line + 0.2 * rng.normal(size=n)), dt, 70e3)  # fmt: skip
    apart = VM.coherence_measures(_globals(t, 0.5 + 0.01 * rng.normal(size=n), line + 0.2 * rng.normal(size=n)), dt,
                                  70e3)  # fmt: skip
    assert together["coherence_f1"] > 0.9 and apart["coherence_f1"] < 0.3


def test_radial_imbalance_follows_the_friction_radius():
    rng = np.random.default_rng(3)
    m, n, dec = 3000, 50, 3
    r = rng.uniform(0.08, 0.12, n)
    s = np.sin(2 * np.pi * np.arange(m) / 37.0)
    v = (s[:, None] * (r - r.mean())[None, :] * 100.0 + 0.1 * rng.normal(size=(m, n))).astype(np.float32)
    g = np.zeros((m * dec, 6))
    g[:, 0] = 0.5 + 0.001 * rng.normal(size=m * dec)
    g[::dec, 2] = 0.1 + 1e-4 * s
    g[::dec, 1] = g[::dec, 0] * 12.0 * g[::dec, 2]
    out = VS.radial_measures(g, v, r, dec)
    assert out["radial_rho_radius"] > 0.8 and out["radial_rho_torque"] > out["radial_rho_mu"]
    out_neg = VS.radial_measures(g, -v, r, dec)
    assert out_neg["radial_rho_radius"] < -0.8


def test_permutation_leaves_s_and_changes_the_neighbours_coherence():
    rng = np.random.default_rng(4)
    n, f = 200, 40
    x, y = rng.uniform(0, 0.05, n), rng.uniform(0, 0.02, n)
    phase = (x > 0.025)[None, :] * np.pi + 0.1 * rng.normal(size=(f, n))  # two halves in antiphase: islands
    X = np.exp(1j * phase) * rng.uniform(0.5, 1.0, (f, n))
    freq = np.linspace(20e3, 80e3, f)
    from aca_warp.analysis.measures import neighbour_coherence

    c = neighbour_coherence(x, y, X, VS.COUPLING_RADIUS)
    out = VS.permutation_measures(X, freq, x, y, c)
    assert out["perm_max_dS"] == 0.0
    assert out["perm_coherence"] > 0.8 and out["perm_coherence"] - out["perm_coherence_permuted"] > 0.2


def test_peak_features_of_synthetic_sync_spectra():
    f = np.arange(1e3, 150e3, 100.0)
    f1 = 33e3
    null = np.full(f.size, 0.1)
    S = np.where((f >= 0.9 * f1) & (f <= 2 * f1), 0.4, 0.12)  # synchronised over the first peak and its plateau
    phi = np.where((f >= 0.9 * f1) & (f <= 2 * f1), 80, 30).astype(np.int64)
    mu = np.full(f.size, 1e-4)
    for fp in (90e3, 110e3, 130e3):  # μ peaks above 2 f1 where S is at its null level
        mu[np.argmin(np.abs(f - fp))] = 1e-2
    out = VS.peak_features(f, S, null, phi, mu, f1)
    assert out["excess_peak_plateau"] == pytest.approx(0.28)
    assert out["f_sync"] == pytest.approx(0.9 * f1, abs=300)
    assert out["mu_hf_peaks"] == 3 and out["mu_hf_unmatched"] == 1.0 and out["mu_hf_phi_ratio"] == 1.0
    assert out["mu_peaks_synced"] == 0.0 and 0.2 < out["mu_peaks_synced_chance"] < 0.3
    assert 0.99 < out["mu_hf_unmatched_chance"] < 1.0  # above 2 f1 only the 2 bins next to the plateau's end are near S
    bands = VS.band_summaries(f, S, null, phi, f1)
    assert bands["spread"] > bands["spread_all"] > 0 and bands["prevalence_all"] < bands["prevalence"]


@pytest.mark.parametrize(("unmatched", "verdict"), [(0.8, V.REPRODUCED), (0.5, V.NOT_REPRODUCED)])
def test_unmatched_peaks_read_against_chance_in_the_notes(unmatched, verdict):
    """ "Many μ peaks do not correspond to S": beside the fixed threshold, the share against the share of the bins
    above 2 f1 that chance leaves unmatched (0.8 here): peaks at S no more often than at random reproduce it, peaks at
    S far more often do not; a results file without the chance share leaves that reading out."""
    from aca_warp.studies.validation import hf_peaks as VP

    row = next(r for r in VB.ROWS if r.statement.startswith("many μ peaks at higher frequencies"))

    def res(chance: bool) -> dict:
        return {"pads": [_pad(s, {"sync_relative": {"mu_hf_unmatched": unmatched + 0.01 * s, "mu_hf_peaks": 10,
                                                    **({"mu_hf_unmatched_chance": 0.8} if chance else {})},
                                  "sync_snr": {"mu_hf_unmatched": unmatched}}) for s in range(1, 9)]}  # fmt: skip

    v = row.measure({n: res(True) for n in VP.PRESETS}, VB.Config())
    assert "against chance (the share − that of the bins above 2 f1" in v.notes and f"({verdict}: ≥ −0.05" in v.notes
    assert "against chance" not in row.measure({n: res(False) for n in VP.PRESETS}, VB.Config()).notes


def test_the_states_unmatched_peaks_against_chance_pair_each_states_own_shares():
    """§3.3's chance reading takes each state's share less that state's chance share, then the mean over the states:
    a state without μ peaks (no share) leaves its chance share out too."""
    from aca_warp.studies.validation import multiscale as VMS

    row = next(r for r in VB.ROWS if r.statement == "some μ-spectrum peaks do not correspond to the S results")
    first = VMS.GROUPS[VMS.MAIN[0]][0]

    def sync(s: int, m: str) -> dict:
        if s == 1 and m == first:  # no μ peaks in this state: no share, and a chance share far from the others'
            return {"mu_peaks_synced": None, "mu_peaks_synced_chance": 0.9}
        return {"mu_peaks_synced": 0.4, "mu_peaks_synced_chance": 0.5}

    groups = {g: {"pads": [_pad(s, {"sync_relative": sync(s, m), "sync_snr": sync(s, m)}, member=m)
                           for m in members for s in range(1, 5)]} for g, members in VMS.GROUPS.items()}  # fmt: skip
    v = row.measure(groups, VB.Config())
    assert f"no synchronised bin within 2 bins) {VB.interval(np.full(4, 0.1))} (reproduced" in v.notes


def test_table_rows_and_every_registered_row_has_a_known_kind():
    assert len(VB.ROWS) >= 45
    assert {r.kind for r in VB.ROWS} <= set(V.CRITERIA)
    assert len({(r.section, r.statement) for r in VB.ROWS}) == len(VB.ROWS)
    assert math.isclose(VB.SYNC_EXCESS, 0.05) and VB.CHARACTERISTIC_BAND == (20.0e3, 80.0e3)  # §4


# ------------------------------------------------------------------------------------------------ settings and cost


def test_stepping_is_each_regimes_pick_of_the_statistical_work_precision_or_an_override():
    from pathlib import Path

    from aca_warp.hf.solver import StepEstimate, friction_step
    from aca_warp.studies import work_precision_stats_report as wps_report
    from aca_warp.studies import work_precision_stats_rule as rule
    from aca_warp.studies.validation import settings as VSet
    from aca_warp.studies.validation.base import EXPERIMENTS
    from aca_warp.studies.validation.hf_experiments import PRESETS
    from aca_warp.studies.validation.multiscale import GROUPS

    cfg = VB.Config()
    # each entry is the rule's pick from the committed result files of docs/work_precision_statistics.md
    wps = Path(__file__).resolve().parent.parent / "docs" / "figures" / "work_precision_statistics"
    files = {"hf1": "wps_cuda0_hf1.json", "hf2": "wps_cuda0_hf2.json", "hf3": "wps_cuda0_hf3.json",
             "hf4": "wps_cuda0_hf4.json", "va_full": "growth_events/wps_cuda01_va_full.json",
             "ms_fast": "wps_cuda0_ms_fast.json",
             "ms_short": "wps_cuda01_ms_short.json", "ms_mid": "wps_cuda01_ms_mid.json",
             "ms_app3": "wps_cuda0123_ms_app3.json"}  # fmt: skip
    picks = {}
    for regime, name in files.items():
        label = rule.settings_for(rule.load_results(wps / name), regime).setting
        integrator, rest = label.split("@")
        precision, dt = rest.split(":dt=")
        dt, _, spacing = dt.partition(":growth_dt=")
        picks[regime] = (integrator, precision, float(dt), float(spacing) if spacing else None)
    assert picks["hf1"] == picks["hf2"] == picks["hf3"] == ("strang", "fp32", 1e-7, None)  # hf1, hf2 over 96 seeds
    assert picks["hf4"] == ("strang", "fp32", 5e-7, None)
    hf = cfg.stepping("hf")  # the presets' batches: the finest of their picks
    assert (hf.integrator, hf.precision, hf.dt, hf.growth_dt) == min((picks[r] for r in PRESETS), key=lambda p: p[2])
    # the growth experiments run at the paper-clock record's pick (96 seeds of 0.36 s); in the compressed regime
    # (128 seeds) that setting, cheaper than the pick there, moves no measure and leaves only the STFT maximum
    # undecided, by one seed whose pad turns tonal in its runs and not in the reference's
    assert picks["va_full"] == ("strang", "fp32", 1e-7, 5e-6)
    va = rule.load_results(wps / "wps_cuda0_va.json")["regimes"]["va"]
    growth = next(s for s in va["settings"] if s["label"] == "strang@fp32:dt=1e-07:growth_dt=5e-06")
    verdicts = {m: rule.verdict(va, growth, m, 0.25) for m in rule.measures_of(va["kind"])}
    assert {m for m, v in verdicts.items() if not rule.kept(v)} == {"stft_amplitude"}
    assert verdicts["stft_amplitude"] == "undecided"
    calm = wps_report.without_seeds(va, {3})
    growth = next(s for s in calm["settings"] if s["label"] == growth["label"])
    assert all(rule.kept(rule.verdict(calm, growth, m, 0.25)) for m in verdicts)
    for key, regime in (("growth", "va_full"), ("ms_fast", "ms_fast"), ("ms_short", "ms_short"), ("ms_mid", "ms_mid"),
                        ("ms_app3", "ms_app3")):  # fmt: skip
        st = cfg.stepping(key)
        assert (st.integrator, st.precision, st.dt, st.growth_dt) == picks[regime], key
    hf3 = [n for n in EXPERIMENTS if n.startswith("hf3")]
    assert sorted(hf3) == ["hf3", "hf3_equal", "hf3_equal_lin", "hf3_lin", "hf3_rest"]
    assert {(EXPERIMENTS[n].stepping, EXPERIMENTS[n].batch) for n in hf3} == {
        ("hf", "s31"),
        ("hf", "rest"),
        ("hf", "lin"),
    }
    assert (cfg.stepping("ms_fast").dt, cfg.stepping("ms_fast").precision) == (5e-8, "fp64")  # over 128 LF seeds
    # each LF group (and its from-rest and linear-phase variants) runs at its own regime's pick
    for g in GROUPS:
        assert EXPERIMENTS[g].stepping == EXPERIMENTS[f"{g}_rest"].stepping == EXPERIMENTS[f"{g}_lin"].stepping == g
    assert "ms_lin" not in EXPERIMENTS and EXPERIMENTS["ms_order"].stepping == "ms_order"
    assert all(e.stepping in VSet.STEPPING for e in EXPERIMENTS.values())
    # the friction step is h γ_max = 4 (logged beside the step): twice the explicit friction estimate 2/γ_max
    assert friction_step(StepEstimate(spring=2e-6, friction=4.82e-8, explicit=4.8e-8)) == pytest.approx(9.64e-8)
    over = VB.Config(dt=5e-9, precision="fp64")
    assert {(over.stepping(k).dt, over.stepping(k).precision) for k in VSet.STEPPING} == {(5e-9, "fp64")}
    quick = VB.Config(quick=True).stepping("ms_fast")
    assert quick.dt == 1e-7 and quick.precision == "fp32" and quick.force and "forced" in quick.describe()
    assert cfg.stepping("ms_mid").describe() == "strang, dt = 1e-07 s, fp32"


def test_cost_model_follows_the_measured_waves_and_the_shared_memory():
    from aca_warp.hf.onchip_layout import default_cluster
    from aca_warp.studies.validation import cost as VC

    # the model's blocks per pad are the engine's on 132 SMs (H100, H200), and each K's clusters fit one wave
    assert [VC.cluster(p) for p in range(1, 300)] == [default_cluster(p, 132) for p in range(1, 300)]
    assert all(VC.cluster(VC.WAVE[k]) == k != VC.cluster(VC.WAVE[k] + 1) for k in (8, 5, 4, 2))
    one = VC.step_seconds(14, 1758, 20904, "fp32", False, "cuda:0")
    assert one == pytest.approx(1.16e-6 + 5.14e-6 / 8)  # one wave of clusters of 8
    assert VC.step_seconds(64, 1758, 20904, "fp32", False, "cuda:0") == pytest.approx(1.16e-6 + 5.14e-6 / 2)
    assert VC.step_seconds(264, 1758, 20904, "fp32", False, "cuda:0") == pytest.approx(2 * (1.16e-6 + 5.14e-6))
    assert VC.fits_on_chip(1758, 20904, 1, "fp32") and not VC.fits_on_chip(4329, 31 * 4329, 4, "fp64")
    dense = VC.step_seconds(8, 4329, 31 * 4329, "fp64", False, "cuda:0")
    assert dense > 4 * VC.step_seconds(8, 1758, 20904, "fp64", False, "cuda:0")  # lists off chip
    # 16 pads of dense LF states: off chip on clusters of 5, on chip on 16 (as the engine widens them), 3 waves of 7
    w = 0.5 * 2967 / 1758 + 0.5 * 220652 / 20904
    assert not VC.fits_on_chip(2967, 220652, 8, "fp32") and VC.fits_on_chip(2967, 220652, 16, "fp32")
    wide = VC.step_seconds(16, 2967, 220652, "fp32", False, "cuda:0")
    assert wide == pytest.approx(3 * (1.16e-6 + 5.14e-6 * w / 16)) and wide < 1.16e-6 + VC.OFF_CHIP * 5.14e-6 * w / 5
    assert VC.step_seconds(1, 1758, 20904, "fp32", True, "cuda:0") == VC.GROWTH_FLOOR_S["fp32"]
    assert VC.step_seconds(2, 500, 100, "fp64", False, "cpu") == pytest.approx(1000 / VC.CPU_PATCH_STEPS)


def test_fig8_plateau_is_none_where_its_far_band_lies_beyond_the_spectrum():
    """A first peak above a 2.5th of the spectrum's top (an LF state whose f1 is 235 kHz in a 500 kHz spectrum) has no
    far band: its plateau measures are None and the pad keeps every other Fig. 8 measure (before, the pad's whole
    analysis failed); a peak well inside keeps its plateau, and so does one whose far band starts inside the spectrum
    and ends beyond it (a linear-phase app3_start pad at 190 kHz: 475–760 kHz, read over 475–500 kHz)."""
    freq = np.linspace(0.0, 500.0e3, 2001)
    rng = np.random.default_rng(3)
    spectra = {k: np.abs(rng.normal(1.0, 0.1, freq.size)) for k in ("velocity", "mu", "torque", "friction_radius")}
    for f1, has_plateau in ((235.0e3, False), (190.0e3, True), (60.0e3, True)):
        for amp in spectra.values():
            amp[np.argmin(np.abs(freq - f1))] = 20.0
        out = VM.fig8_measures(freq, spectra, f1)
        assert (out["plateau_velocity"] is not None) is has_plateau
        assert all((out[f"plateau_{k}"] is None) is not has_plateau for k in ("mu", "torque", "radius"))
        assert out["contrast_velocity"] > 5.0 and math.isfinite(out["peak_width"])


def test_a_number_that_rounds_to_zero_is_printed_without_its_sign():
    """The page's ranges and the plan's log print a slightly negative σ_i (a damped patch) as "0", not "-0"."""
    from aca_warp.studies.report import unsigned_zero
    from aca_warp.studies.validation.page import _range

    assert [unsigned_zero(format(x, ".0f")) for x in (-0.3, -0.0, -1.2, 0.4, -12.0)] == ["0", "0", "-1", "0", "-12"]
    assert unsigned_zero("-0.00") == "0.00" and unsigned_zero("-0.01") == "-0.01"
    assert unsigned_zero("-1e-05") == "-1e-05"
    assert _range([-0.3, 2562.0, 1296.0], spec=".0f") == "1286 (0–2562)"
