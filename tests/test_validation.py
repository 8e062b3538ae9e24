"""``aca_warp.studies.validation`` (``scripts/validation.py``): planning, scenes, verdicts, and a reduced run end to end
(two seeds of a 50-patch hf1 sector that must saturate, and a run cut short that cannot)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from aca_warp.studies.validation import base as VB
from aca_warp.studies.validation import cli as VL
from aca_warp.studies.validation import experiments as VE
from aca_warp.studies.validation import plan as VP
from aca_warp.studies.validation.measures import local_sync_measures

# ------------------------------------------------------------------------------------------------ scenes and plan


def test_seeds_layouts_and_reduced_pads():
    cfg = VB.Config(seeds=2, patches=60)
    a0, a1 = (VP.experiment_scene(VB.EXPERIMENTS["hf1"], k, cfg) for k in (0, 1))
    c0 = VP.experiment_scene(VB.EXPERIMENTS["hf3"], 0, cfg)
    assert a0.patches.count == 60 and (a0.initial.seed, a1.initial.seed) == (1, 2)
    assert not np.array_equal(a0.patches.x, a1.patches.x)  # another seed, another layout
    np.testing.assert_array_equal(a0.patches.x, c0.patches.x)  # hf1 and hf3 share it: paired comparisons
    assert (a0.friction.M, c0.friction.M) == (0.8, 0.4)
    full = VP.experiment_scene(VB.EXPERIMENTS["hf1"], 0, VB.Config(seeds=1))
    assert full.patches.count == 1758 and full.initial.state == "equilibrium" and full.initial.perturbation == 1e-2
    # the sector keeps the preset's patch density and pressure
    assert a0.patches.count / a0.pad.area == pytest.approx(1758 / full.pad.area)
    assert a0.normal_force / a0.patches.count == pytest.approx(full.normal_force / 1758)
    rest = VP.experiment_scene(VB.EXPERIMENTS["hf1_rest"], 0, cfg)
    assert rest.initial.state == "rest" and rest.initial.perturbation == 0.0


def test_sweep_heights_put_the_load_ten_percent_above_all_in_contact():
    from aca_warp.hf.contact import load_window, solve_scene_contact

    cfg = VB.Config(seeds=1, patches=80)
    s = VP.experiment_scene(VB.EXPERIMENTS["sweep_0p3"], 0, cfg)
    assert s.patches.area.mean() == pytest.approx(0.3e-6, rel=0.1)
    assert s.normal_force == pytest.approx(VP.HF1_PRESSURE * 80 * 0.3e-6)
    win = load_window(s)
    assert s.normal_force / win.all_in_contact == pytest.approx(1.0 + VP.HEIGHT_MARGIN, rel=1e-9)
    sol = solve_scene_contact(s)
    assert np.all(sol.patch_force > 0) and sol.matrix_force.sum() == 0.0
    from aca_warp.scene import PatchGenerator

    gen = s.origin["patches"]  # the origin names the generator that draws exactly these heights
    np.testing.assert_allclose(PatchGenerator(**gen).generate(s.pad).height, s.patches.height, rtol=1e-12)


def test_plan_follows_the_predicted_growth_and_aligns_the_window():
    cfg = VB.Config(seeds=2, patches=60, window=3e-3)
    prep = VE.prepare(VB.EXPERIMENTS["hf1"], cfg)
    p = prep.plan
    q25 = np.percentile(np.concatenate(prep.sigma), 25)
    assert p.sigma_q25 == pytest.approx(q25)
    assert p.settle == pytest.approx(cfg.settle_safety * math.log(10.0 / 0.01) / q25)
    dtp = cfg.sample_dt * cfg.decimation
    assert p.patch_samples == round(cfg.window / dtp)
    n = round(p.duration / cfg.sample_dt)
    assert p.duration >= p.settle + cfg.window - dtp and p.steps == round(p.duration / cfg.dt)
    first = round(p.window_start / cfg.sample_dt)  # the recorder's per-patch rows: first, first + 3, ..., n
    assert (n - first) % cfg.decimation == 0 and (n - first) // cfg.decimation + 1 == p.patch_samples
    rest = VE.prepare(VB.EXPERIMENTS["hf1_rest"], cfg).plan
    assert 0.05 < rest.v0 < 1.0 and rest.settle < p.settle  # released from rest: a larger start, fewer e-folds


# ------------------------------------------------------------------------------------------------ verdicts


def test_verdicts_follow_the_stated_criteria():
    rng = np.random.default_rng(0)
    near = 73e3 + rng.normal(0, 200.0, 8)
    assert VB.value_verdict(near, 73e3, 0.05 * 73e3) == "reproduced"
    assert VB.value_verdict(np.array([70e3, 76.5e3]), 73e3, 3.65e3) == "partly"  # mean in, wide interval out
    assert VB.value_verdict(near + 10e3, 73e3, 3.65e3) == "not reproduced"
    up, flat, down = rng.normal(1.0, 0.1, 8), rng.normal(0.0, 1.0, 8), rng.normal(-1.0, 0.1, 8)
    assert (VB.side(up), VB.side(flat), VB.side(down), VB.side(down, -1.0)) == (1, 0, -1, 1)
    assert VB.direction_verdict([1, 1]) == "reproduced" and VB.direction_verdict([1, 0]) == "partly"
    assert VB.direction_verdict([0]) == "not reproduced" and VB.direction_verdict([0], [1]) == "partly"
    assert VB.direction_verdict([1], [-1]) == "partly"
    assert VB.equal_verdict(rng.normal(0, 0.01, 8), 0.05) == "reproduced"
    assert VB.equal_verdict(np.array([-0.3, 0.32]), 0.05) == "partly"
    assert VB.equal_verdict(up, 0.05) == "not reproduced"
    assert VB.threshold_verdict(np.full(3, 0.1) + [0, 0.01, -0.01], 0.223, below=True) == "reproduced"
    assert VB.threshold_verdict(np.array([0.6, 0.7, 0.65]), 0.5, below=False) == "reproduced"
    assert VB.threshold_verdict(np.array([0.3, 0.35]), 0.5, below=False) == "not reproduced"


def test_interval_is_the_ensemble_interval_over_seeds():
    from aca_warp.analysis.measures import ensemble_interval

    v = np.array([70.1e3, 72.4e3, 71.0e3])
    e = ensemble_interval(v * 1e-3)
    assert VB.interval(v, ".1f", 1e-3, "kHz") == f"{e.mean:.1f} [{e.mean_low:.1f}, {e.mean_high:.1f}] kHz (n = 3)"
    assert VB.interval(np.array([np.nan, 4.0])) == "4 (n = 1, no interval)" and VB.interval(np.array([])) == "–"


def test_a_failing_row_is_marked_and_a_missing_experiment_is_not_measured():
    def broken(results, cfg):
        raise RuntimeError("boom")

    pad = {"seed": 1, "status": "saturated", "measures": {"f1": 7.3e4}}
    results = {"hf1": {"pads": [pad, {**pad, "seed": 2}]}}
    rows = [
        VB.Row("§x", "breaks", "–", "value", ("hf1",), broken),
        VB.Row("§x", "needs hf2", "–", "value", ("hf2",), broken),
        VB.ROWS[0],
    ]
    out = VB.evaluate_rows(results, VB.Config(), rows)
    assert out[0]["verdict"] == "failed" and "boom" in out[0]["notes"]
    assert out[1]["verdict"] == "not measured" and "hf2 (0 usable pads)" in out[1]["notes"]
    assert out[2]["verdict"] == "reproduced" and out[2]["value"].startswith("73.0 [73.0, 73.0] kHz (n = 2)")


def test_saturation_status_of_a_growing_and_a_saturating_record():
    t = np.arange(0.0, 40e-3, 1e-6)
    a = 1.0 / np.sqrt(1.0 + (1e6 - 1.0) * np.exp(-2 * 600.0 * t))  # Landau envelope from 1e-3 to 1
    carrier = np.abs(np.sin(2 * np.pi * 70e3 * t))
    glob = np.zeros((t.size, 5))
    glob[:, 4] = 100.0 * a * carrier
    glob[:, 0] = 0.5 + 0.01 * a * np.sin(2 * np.pi * 70e3 * t)
    sat = VE.pad_saturation(t, glob, 40e-3, 8e-3)
    assert sat["status"] == "saturated" and 5e-3 < sat["t_start"] < 32e-3
    assert sat["growth_rate"] == pytest.approx(600.0, rel=0.1)
    short = slice(0, 8000)  # still growing at the end
    grow = VE.pad_saturation(t[short], glob[short], 8e-3, 8e-3)
    assert grow["status"] == "not saturated" and grow["t_start"] is None
    late = VE.pad_saturation(t, glob, 40e-3, 2 * 40e-3)  # settles, but not half a window before the end
    assert late["status"] == "saturated too late"


# ------------------------------------------------------------------------------------------------ end to end


@pytest.fixture
def short_experiment():
    """hf1 cut short at 3 ms: still growing, so its pads cannot saturate."""
    exp = VB.register_experiment(VB.Experiment("hf1_short", "§3.1", "hf1 cut short (test)", "hf1", duration=3e-3))
    yield exp
    VB.EXPERIMENTS.pop(exp.name)


def test_reduced_run_end_to_end(tmp_path, short_experiment, capsys):
    out, page = tmp_path / "val", tmp_path / "page.md"
    page.write_text("# Validation\n\nMethod text that stays.\n")
    argv = [
        "--device", "cpu", "--quick", "--seeds", "2", "--patches", "50", "--dt", "1e-7", "--window", "3e-3",
        "--workers", "1", "--only", "hf1", "hf1_short", "--out", str(out), "--page", str(page),
    ]  # fmt: skip
    assert VL.main(argv) == 0
    res = json.loads((out / "hf1" / "result.json").read_text())
    assert [p["status"] for p in res["pads"]] == ["saturated", "saturated"]
    for p in res["pads"]:
        assert p["growth_rate"] > 0 and 0 < p["t_s_sum_abs_velocity"] < res["plan"]["duration_s"]
        assert 0.3 * p["sigma_median"] < p["growth_rate"] < 3 * p["sigma_median"]
        assert p["in_contact"] == p["patches"] == 50
    short = json.loads((out / "hf1_short" / "result.json").read_text())
    assert [p["status"] for p in short["pads"]] == ["not saturated", "not saturated"]
    assert "measures" not in short["pads"][0]
    text = page.read_text()
    assert text.startswith("# Validation\n\nMethod text that stays.") and "QUICK variant" in text
    assert text.count(f"<!-- BEGIN GENERATED ({VL.MARKER}) -->") == 1
    assert "| § | statement | ours: mean [95 % interval] (n seeds) | paper | verdict (criterion) |" in text
    assert "hf1_short, seed 1: **not saturated**" in text
    rows = json.loads((out / "validation.json").read_text())["rows"]
    assert len(rows) == len(VB.ROWS)
    first = next(r for r in rows if r["statement"] == "HF1: first velocity-spectrum peak")
    assert first["value"] == VB.interval(VB.values(res, "f1"), ".1f", 1e-3, "kHz") and "(n = 2)" in first["value"]
    assert first["verdict"] in ("reproduced", "partly", "not reproduced")
    assert all(r["verdict"] == "not measured" for r in rows if "hf2" in r["experiments"])
    capsys.readouterr()
    assert VL.main(argv) == 0  # checkpoints: nothing is run again
    assert "reusing the saved result" in capsys.readouterr().out
    assert VL.main([*argv[:-4], "--out", str(tmp_path / "none"), "--max-wall", "0"]) == 0
    assert not (tmp_path / "none" / "hf1" / "result.json").exists()


def test_script_help_and_list():
    script = Path(__file__).resolve().parent.parent / "scripts" / "validation.py"
    out = subprocess.run([sys.executable, str(script), "--help"], capture_output=True, text=True, check=True).stdout
    assert "--max-wall" in out and "--only" in out and "--quick" in out
    listed = subprocess.run([sys.executable, str(script), "--list"], capture_output=True, text=True, check=True).stdout
    assert all(f"experiment {n}" in listed for n in VB.EXPERIMENTS)


# ------------------------------------------------------------------------------------------------ §3.2 (synthetic)

from aca_warp.studies.validation import area as VA  # noqa: E402
from aca_warp.studies.validation import causes as VC  # noqa: E402
from aca_warp.studies.validation import multiscale as VM  # noqa: E402


def _growing_mu(seed: int, falling: bool = True, periodic: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """μ(t) and Σu̇(t) over 36 ms at 1 µs: a mean rising 0.40 → 0.50, a line falling 70 → 35 kHz (ln f linear in t),
    its amplitude growing 5× when ``periodic`` (over broad-band noise of fixed level)."""
    rng = np.random.default_rng(seed)
    t = np.arange(36000) * 1e-6
    frac = t / t[-1]
    f = 70e3 * np.exp(np.log(0.5) * frac) if falling else np.full_like(t, 50e3)
    phase = 2 * np.pi * np.cumsum(f) * 1e-6
    amp = 1e-3 * (1 + 4 * frac) if periodic else 1e-3
    noise = rng.normal(0.0, 2e-3, t.size)
    mu = 0.40 + 0.10 * frac + amp * np.sin(phase) + noise
    vel = np.sin(phase) + 0.1 * rng.normal(0.0, 1.0, t.size)
    return t, mu, vel


def _va_scene():
    return VP.experiment_scene(VB.EXPERIMENTS["va"], 0, VB.Config(seeds=1, patches=40))


def test_growth_measures_of_a_synthetic_record():
    t, mu, vel = _growing_mu(0)
    m = VA.growth_measures(t, mu, vel, _va_scene(), t_start=1e-3)
    assert m["mu_rise"] == pytest.approx(0.10 * (35e-3 / 36e-3), rel=0.05)
    assert m["mu_thirds"][0] < m["mu_thirds"][1] < m["mu_thirds"][2]
    for k in ("dominant_dlnf", "first_dlnf"):  # ln f falls by ln 2 over the record (35/36 of it analysed)
        assert m["line"][k] == pytest.approx(np.log(0.5) * 35 / 36, abs=0.08)
        assert m["line"][f"{k}_ci"][1] < 0
    assert m["line"]["window_samples"] == 4096
    tn = m["tonality"]
    assert tn["peak_to_median"][2] > tn["peak_to_median"][0] and tn["flatness"][2] < tn["flatness"][0]
    steady = VA.growth_measures(*_growing_mu(1, falling=False), _va_scene(), t_start=1e-3)
    assert abs(steady["line"]["dominant_dlnf"]) < 0.02
    # STFT maximum: the line in the last full window (amplitude 1e-3 (1 + 4 t/T) at its centre) over the mean μ
    w = next(w for w in steady["stft"] if w["samples"] == 4096)
    centre = w["time"] / 36e-3
    mean = np.mean(0.40 + 0.10 * np.arange(1000, 36000) / 35999)
    assert w["frequency"] == pytest.approx(50e3, rel=2e-3)
    assert w["amplitude"] == pytest.approx(1e-3 * (1 + 4 * centre) / mean, rel=0.05)
    assert [x["samples"] for x in steady["stft"]] == [4096, 8192, 16384, 32768]  # 2^12 … 2^15 fit 35 ms


def test_predicted_line_change_follows_eq10():
    s = _va_scene()
    g = s.growth
    sq = np.sqrt(s.patches.area)
    end = sq + 0.5 * g.increment / g.interval * s.duration  # √A grows by increment/2 per event
    assert VA.predicted_line_change(s, 0.0, s.duration) == pytest.approx(np.mean(-0.5 * np.log(end / sq)))
    # the whole compressed growth takes the mean area from ≈ 0.05 to ≈ 1.2 mm²: Δ ln f ≈ −¼ ln 24
    assert VA.predicted_line_change(s, 0.0, s.duration) == pytest.approx(-0.25 * np.log(1.2 / 0.05), abs=0.1)
    assert VA.line_window(36000) == 4096 and VA.line_window(18000) == 2048 and VA.line_window(100) == 256


def _pad(seed: int, measures: dict, member: str | None = None, **extra) -> dict:
    p = {"seed": seed, "status": "saturated", "measures": measures, **extra}
    if member is not None:
        p["member"] = member
    return p


def _va_result(rise: float, dlnf: float, freq: float, amp: float, ptm: tuple[float, float]) -> dict:
    pads = []
    for s in range(1, 6):
        e = 0.02 * (s - 3)
        pads.append(_pad(s, {
            "mu_rise": rise + e * 0.1, "mu_thirds": [0.4, 0.45, 0.4 + rise],
            "line": {"dominant_dlnf": dlnf + e, "first_dlnf": dlnf + e, "predicted_dlnf": -0.8,
                     "window_samples": 4096, "dominant_dlnf_ci": [dlnf - 0.1, dlnf + 0.1]},
            "stft": [{"window": "w4096", "samples": 4096, "amplitude": amp * (1 + e), "frequency": freq * (1 + e / 10)},
                     {"window": "w8192", "samples": 8192, "amplitude": 0.004, "frequency": 69.0e3}],
            "tonality": {"peak_to_median": [1.0, 1.2, ptm[1] + e], "flatness": [0.5, 0.4, 0.5 - (ptm[1] - 1) / 10],
                         "std": [0.01, 0.02, 0.03], "peak_hz": [7e4, 5e4, 3.5e4]},
        }))  # fmt: skip
    return {"pads": pads}


def test_varying_area_rows_follow_their_criteria():
    cfg = VB.Config()
    good = {"va": _va_result(0.1, -0.8, 69.5e3, 0.0041, (1.0, 2.0))}
    bad = {"va": _va_result(-0.05, 0.5, 35.6e3, 0.025, (1.0, 0.5))}
    rows = {r.statement: r for r in VB.ROWS if r.experiments == ("va",)}
    assert len(rows) == 5
    for r in rows.values():
        assert r.measure(good, cfg).verdict == "reproduced", r.statement
        assert r.measure(bad, cfg).verdict == "not reproduced", r.statement
    # the STFT-window variant reads the 2^13 window, where these synthetic pads sit at the paper's values
    amp_row = rows["its amplitude, normalised to mean μ (one-sided)"]
    moved = VC.stft_window(8192)(bad)
    assert amp_row.measure(moved, cfg).verdict == "reproduced"


# ------------------------------------------------------------------------------------------------ §3.3 (synthetic)


def _ms_results(std: dict[str, float], top: dict[str, float] | None = None, after_low: float = 0.01) -> dict:
    """Results of the four state groups and ms_order for 5 seeds, every measure of the §3.3 rows set."""
    top = top or {}
    out: dict[str, dict] = {}
    for group, members in VM.GROUPS.items():
        pads = []
        for m in members:
            for s in range(1, 6):
                e = 1 + 0.01 * (s - 3)
                pads.append(_pad(s, {
                    "mu_std": std[m] * e, "f1": 50e3 * e, "mu_peak_hz": 60e3,
                    "sync_relative": {"top_excess": top.get(m, 0.2) * e,
                                      "phi_sync": (60 if m == "app3_end" else 40) * e,
                                      "phi_sync_share": (0.1 if m == "app3_end" else 0.05) * e,
                                      "cluster_phi_rho": 0.4 * e, "agreement": 0.2 * e},
                    "sync_snr": {"agreement": 0.3 * e},
                }, member=m))  # fmt: skip
        out[group] = {"pads": pads}
    out["ms_order"] = {"pads": [_pad(s, {"mu_std": after_low, "sync_relative": {"top_excess": 0.1}}, "app2_start")
                                for s in range(1, 6)]}  # fmt: skip
    return out


def test_multiscale_rows_follow_their_criteria():
    cfg = VB.Config()
    rows = {r.statement: r for r in VB.ROWS if r.section.startswith(("§3.3", "§4"))}
    assert len(rows) == 7
    std = dict.fromkeys(VM.STATES, 0.01)
    app3_high = {**std, "app3_start": 0.02}
    res = _ms_results(app3_high, top={"app3_start": 0.5})
    verdicts = {k: r.measure(res, cfg).verdict for k, r in rows.items()}
    assert set(verdicts.values()) == {"reproduced"}, verdicts
    res = _ms_results({**std, "app1_start": 0.03, "app3_start": 0.015}, after_low=0.05)
    largest = rows["μ oscillates with the greatest amplitudes at the start of application 3"].measure(res, cfg)
    assert largest.verdict == "not reproduced" and "app1_start ×5" in largest.notes
    history = rows["a low-load application right after a high-load one oscillates more (load history)"]
    assert history.measure(res, cfg).verdict == "not reproduced"
    # one state's first peak outside 20–80 kHz: partly
    for p in res["ms_app3"]["pads"]:
        if p["member"] == "app3_end":
            p["measures"]["f1"] = 120e3 + p["seed"]
    assert rows["the characteristic HF behaviour lies within 20–80 kHz"].measure(res, cfg).verdict == "partly"


def test_local_sync_measures():
    S = np.array([0.9, 0.2, 0.5, np.nan, 0.3])
    null = np.array([0.1, 0.1, 0.2, 0.1, 0.4])
    phi = np.array([40, 10, 20, 1, 30])
    coh = np.array([0.8, 0.1, 0.5, np.nan, 0.6])
    m = local_sync_measures(S, null, phi, 100, coh)
    assert m["top_excess"] == pytest.approx(0.8)  # top 1 % of 4 defined bins: the largest
    assert m["phi_sync"] == pytest.approx((40 + 10 + 20) / 3) and m["sync_bins"] == 3
    assert m["phi_sync_share"] == pytest.approx(70 / 3 / 100)
    assert m["cluster_phi_rho"] == pytest.approx(1.0)  # C and Φ in the same order over the bins with Φ ≥ 2


# ------------------------------------------------------------------------------------------------ causes


def test_variants_apply_only_where_they_replace_every_experiment():
    vs = {(v.cause, tuple(v.substitute)): v for v in VC.variants(VB.Config())}
    lin = next(v for v in vs.values() if v.cause == "run length" and ("hf2", "hf2_lin") in v.substitute)
    rest = next(v for v in vs.values() if v.cause == "initial state" and ("hf1", "hf1_rest") in v.substitute)
    peak2 = next(r for r in VB.ROWS if r.statement == "HF2: first velocity-spectrum peak")
    m_row = next(r for r in VB.ROWS if r.statement.startswith("lower M raises S significantly"))
    assert lin.applies(peak2) and lin.applies(m_row) and rest.applies(peak2) and not rest.applies(m_row)
    snr = next(v for v in vs.values() if v.cause == "Φ rule")
    assert snr.applies(m_row) and not snr.applies(peak2)
    res = {"hf1": {"pads": [_pad(1, {"sync_relative": {"a": 1}, "sync_snr": {"a": 2}})]}}
    assert VC.snr_rule(res)["hf1"]["pads"][0]["measures"]["sync_relative"] == {"a": 2}
    assert res["hf1"]["pads"][0]["measures"]["sync_relative"] == {"a": 1}  # the input is not changed
    halves = VC.seed_half(True, 8, 1)({"x": {"pads": [_pad(s, {}) for s in range(1, 9)]}})
    assert [p["seed"] for p in halves["x"]["pads"]] == [1, 2, 3, 4]


def test_a_variant_that_moves_a_verdict_is_marked():
    def f1_pads(f: float) -> dict:
        return {"pads": [_pad(s, {"f1": f + 30.0 * s, "peak_frequency": f, "f_largest": f}) for s in range(1, 5)]}

    results = {"hf2": f1_pads(39e3), "hf2_lin": f1_pads(32.9e3)}
    rows = VB.evaluate_rows(results, VB.Config())
    causes = VC.evaluate_causes(results, VB.Config(), rows)
    lin = [c for c in causes if c["statement"] == "HF2: first velocity-spectrum peak" and c["cause"] == "run length"]
    assert len(lin) == 1 and lin[0]["main_verdict"] == "not reproduced"
    assert lin[0]["verdict"] == "reproduced" and lin[0]["moved"] and lin[0]["experiments"] == ["hf2_lin"]
    assert not any(c["cause"] == "height spread" for c in causes)  # hf2_equal was not run: left out
    header, table = VC.cause_summary(causes)
    assert header[:3] == ["§", "statement", "main"] and any("**✓**" in " ".join(r) for r in table)


# ------------------------------------------------------------------------------------------------ new kinds end to end


@pytest.fixture
def lf_window_experiment(monkeypatch):
    """Two LF states as a fixed 1 ms window run (a tiny stand-in for the §3.3 groups) on a shortened schedule."""
    monkeypatch.setattr(VM, "QUICK_DURATIONS", (0.3, 0.1))
    exp = VB.register_experiment(
        VB.Experiment("ms_test", "§3.3", "two LF states (test)", "multiscale", builder=VM.state_scene,
                     members=("app1_start", "app3_start"), initial="rest", kind="window", duration=1e-3,
                     window_start=0.2e-3)
    )  # fmt: skip
    yield exp
    VB.EXPERIMENTS.pop(exp.name)


def test_growth_window_and_lf_state_experiments_end_to_end(tmp_path, lf_window_experiment):
    out = tmp_path / "val"
    argv = [
        "--device", "cpu", "--quick", "--seeds", "2", "--patches", "30", "--state-patches", "30", "--dt", "1e-7",
        "--window", "3e-3", "--growth-speedup", "60", "--workers", "1", "--only", "va", "hf1_lin", "ms_test",
        "--out", str(out),
    ]  # fmt: skip
    assert VL.main(argv) == 0
    va = json.loads((out / "va" / "result.json").read_text())
    assert va["plan"]["patch_samples"] == 0 and va["plan"]["duration_s"] == pytest.approx(0.36 / 60)
    for p in va["pads"]:
        assert p["status"] == "saturated" and 0 < p["t_start"] < 3e-3, p["verdict_sum_abs_velocity"]
        m = p["measures"]
        assert m["mu_rise"] > 0 and m["line"]["predicted_dlnf"] < 0 and len(m["tonality"]["std"]) == 3
        assert m["stft_floor_hz"] == pytest.approx(10.0 * 60)
    lin = json.loads((out / "hf1_lin" / "result.json").read_text())
    assert [p["status"] for p in lin["pads"]] == ["linear phase"] * 2
    assert all(p["detector_status"] != "saturated" and "measures" in p for p in lin["pads"])
    assert lin["segment"]["start_s"] == pytest.approx(0.2e-3, abs=3e-6)
    ms = json.loads((out / "ms_test" / "result.json").read_text())
    assert sorted((p["member"], p["seed"]) for p in ms["pads"]) == [
        ("app1_start", 1), ("app1_start", 2), ("app3_start", 1), ("app3_start", 2)
    ]  # fmt: skip
    assert all(p["status"] == "linear phase" and p["patches"] <= 40 for p in ms["pads"])
    assert sorted(f.name for f in (out / "lf").iterdir()) == [
        "lf_quick-0.3-0.1_preset_seed1.h5", "lf_quick-0.3-0.1_preset_seed2.h5"
    ]  # fmt: skip
    doc = json.loads((out / "validation.json").read_text())
    va_rows = [r for r in doc["rows"] if r["experiments"] == ["va"]]
    assert len(va_rows) == 5 and not any(r["verdict"] in ("failed", "not measured") for r in va_rows[:2])
    assert isinstance(doc["causes"], list)
    text = (out / "validation.md").read_text()
    assert "### §3.2: the growth runs" in text and "### Which change moves which verdict" in text


def test_state_sector_keeps_the_gap_of_the_full_state(tmp_path, monkeypatch):
    from aca_warp.hf.contact import solve_scene_contact
    from aca_warp.lf.io import scene_from_snapshot

    monkeypatch.setattr(VM, "QUICK_DURATIONS", (0.3, 0.1))
    cfg = VB.Config(seeds=1, quick=True, lf_dir=str(tmp_path))
    VM._run_lf_job((1, None, VM.QUICK_DURATIONS, str(VM.lf_path(cfg, 1, None))))
    full = scene_from_snapshot(VM.lf_path(cfg, 1, None), "app2_end")
    part = VM.state_sector(full, 40)
    assert 0 < part.patches.count < full.patches.count and part.pad.span_deg < full.pad.span_deg
    cf, cp = solve_scene_contact(full), solve_scene_contact(part)
    assert cp.gap == pytest.approx(cf.gap, rel=1e-9, abs=1e-15)
    keep = np.isin(full.patches.x, part.patches.x)
    np.testing.assert_allclose(cp.patch_force, cf.patch_force[keep], rtol=1e-9)
    q = part.pad.span_deg / full.pad.span_deg
    assert cp.matrix_force.sum() == pytest.approx(q * cf.matrix_force.sum(), rel=1e-9)
    assert VM.state_sector(full, 10**6) is full
