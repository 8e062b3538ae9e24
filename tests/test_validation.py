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

from aca_warp.studies import validation as V

# ------------------------------------------------------------------------------------------------ scenes and plan


def test_seeds_layouts_and_reduced_pads():
    cfg = V.Config(seeds=2, patches=60)
    a0, a1 = (V.experiment_scene(V.EXPERIMENTS["hf1"], k, cfg) for k in (0, 1))
    c0 = V.experiment_scene(V.EXPERIMENTS["hf3"], 0, cfg)
    assert a0.patches.count == 60 and (a0.initial.seed, a1.initial.seed) == (1, 2)
    assert not np.array_equal(a0.patches.x, a1.patches.x)  # another seed, another layout
    np.testing.assert_array_equal(a0.patches.x, c0.patches.x)  # hf1 and hf3 share it: paired comparisons
    assert (a0.friction.M, c0.friction.M) == (0.8, 0.4)
    full = V.experiment_scene(V.EXPERIMENTS["hf1"], 0, V.Config(seeds=1))
    assert full.patches.count == 1758 and full.initial.state == "equilibrium" and full.initial.perturbation == 1e-2
    # the sector keeps the preset's patch density and pressure
    assert a0.patches.count / a0.pad.area == pytest.approx(1758 / full.pad.area)
    assert a0.normal_force / a0.patches.count == pytest.approx(full.normal_force / 1758)
    rest = V.experiment_scene(V.EXPERIMENTS["hf1_rest"], 0, cfg)
    assert rest.initial.state == "rest" and rest.initial.perturbation == 0.0


def test_sweep_heights_put_the_load_ten_percent_above_all_in_contact():
    from aca_warp.hf.contact import load_window, solve_scene_contact

    cfg = V.Config(seeds=1, patches=80)
    s = V.experiment_scene(V.EXPERIMENTS["sweep_0p3"], 0, cfg)
    assert s.patches.area.mean() == pytest.approx(0.3e-6, rel=0.1)
    assert s.normal_force == pytest.approx(V.HF1_PRESSURE * 80 * 0.3e-6)
    win = load_window(s)
    assert s.normal_force / win.all_in_contact == pytest.approx(1.0 + V.HEIGHT_MARGIN, rel=1e-9)
    sol = solve_scene_contact(s)
    assert np.all(sol.patch_force > 0) and sol.matrix_force.sum() == 0.0
    from aca_warp.scene import PatchGenerator

    gen = s.origin["patches"]  # the origin names the generator that draws exactly these heights
    np.testing.assert_allclose(PatchGenerator(**gen).generate(s.pad).height, s.patches.height, rtol=1e-12)


def test_plan_follows_the_predicted_growth_and_aligns_the_window():
    cfg = V.Config(seeds=2, patches=60, window=3e-3)
    prep = V.prepare(V.EXPERIMENTS["hf1"], cfg)
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
    rest = V.prepare(V.EXPERIMENTS["hf1_rest"], cfg).plan
    assert 0.05 < rest.v0 < 1.0 and rest.settle < p.settle  # released from rest: a larger start, fewer e-folds


# ------------------------------------------------------------------------------------------------ verdicts


def test_verdicts_follow_the_stated_criteria():
    rng = np.random.default_rng(0)
    near = 73e3 + rng.normal(0, 200.0, 8)
    assert V.value_verdict(near, 73e3, 0.05 * 73e3) == "reproduced"
    assert V.value_verdict(np.array([70e3, 76.5e3]), 73e3, 3.65e3) == "partly"  # mean in, wide interval out
    assert V.value_verdict(near + 10e3, 73e3, 3.65e3) == "not reproduced"
    up, flat, down = rng.normal(1.0, 0.1, 8), rng.normal(0.0, 1.0, 8), rng.normal(-1.0, 0.1, 8)
    assert (V.side(up), V.side(flat), V.side(down), V.side(down, -1.0)) == (1, 0, -1, 1)
    assert V.direction_verdict([1, 1]) == "reproduced" and V.direction_verdict([1, 0]) == "partly"
    assert V.direction_verdict([0]) == "not reproduced" and V.direction_verdict([0], [1]) == "partly"
    assert V.direction_verdict([1], [-1]) == "partly"
    assert V.equal_verdict(rng.normal(0, 0.01, 8), 0.05) == "reproduced"
    assert V.equal_verdict(np.array([-0.3, 0.32]), 0.05) == "partly"
    assert V.equal_verdict(up, 0.05) == "not reproduced"
    assert V.threshold_verdict(np.full(3, 0.1) + [0, 0.01, -0.01], 0.223, below=True) == "reproduced"
    assert V.threshold_verdict(np.array([0.6, 0.7, 0.65]), 0.5, below=False) == "reproduced"
    assert V.threshold_verdict(np.array([0.3, 0.35]), 0.5, below=False) == "not reproduced"


def test_interval_is_the_ensemble_interval_over_seeds():
    from aca_warp.analysis.measures import ensemble_interval

    v = np.array([70.1e3, 72.4e3, 71.0e3])
    e = ensemble_interval(v * 1e-3)
    assert V.interval(v, ".1f", 1e-3, "kHz") == f"{e.mean:.1f} [{e.mean_low:.1f}, {e.mean_high:.1f}] kHz (n = 3)"
    assert V.interval(np.array([np.nan, 4.0])) == "4 (n = 1, no interval)" and V.interval(np.array([])) == "–"


def test_a_failing_row_is_marked_and_a_missing_experiment_is_not_measured():
    def broken(results, cfg):
        raise RuntimeError("boom")

    pad = {"seed": 1, "status": "saturated", "measures": {"f1": 7.3e4}}
    results = {"hf1": {"pads": [pad, {**pad, "seed": 2}]}}
    rows = [
        V.Row("§x", "breaks", "–", "value", ("hf1",), broken),
        V.Row("§x", "needs hf2", "–", "value", ("hf2",), broken),
        V.ROWS[0],
    ]
    out = V.evaluate_rows(results, V.Config(), rows)
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
    sat = V.pad_saturation(t, glob, 40e-3, 8e-3)
    assert sat["status"] == "saturated" and 5e-3 < sat["t_start"] < 32e-3
    assert sat["growth_rate"] == pytest.approx(600.0, rel=0.1)
    short = slice(0, 8000)  # still growing at the end
    grow = V.pad_saturation(t[short], glob[short], 8e-3, 8e-3)
    assert grow["status"] == "not saturated" and grow["t_start"] is None
    late = V.pad_saturation(t, glob, 40e-3, 2 * 40e-3)  # settles, but not half a window before the end
    assert late["status"] == "saturated too late"


# ------------------------------------------------------------------------------------------------ end to end


@pytest.fixture
def short_experiment():
    """hf1 cut short at 3 ms: still growing, so its pads cannot saturate."""
    exp = V.register_experiment(V.Experiment("hf1_short", "§3.1", "hf1 cut short (test)", "hf1", duration=3e-3))
    yield exp
    V.EXPERIMENTS.pop(exp.name)


def test_reduced_run_end_to_end(tmp_path, short_experiment, capsys):
    out, page = tmp_path / "val", tmp_path / "page.md"
    page.write_text("# Validation\n\nMethod text that stays.\n")
    argv = [
        "--device", "cpu", "--quick", "--seeds", "2", "--patches", "50", "--dt", "1e-7", "--window", "3e-3",
        "--only", "hf1", "hf1_short", "--out", str(out), "--page", str(page),
    ]  # fmt: skip
    assert V.main(argv) == 0
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
    assert text.count(f"<!-- BEGIN GENERATED ({V.MARKER}) -->") == 1
    assert "| § | statement | ours: mean [95 % interval] (n seeds) | paper | verdict (criterion) |" in text
    assert "hf1_short, seed 1: **not saturated**" in text
    rows = json.loads((out / "validation.json").read_text())["rows"]
    assert len(rows) == len(V.ROWS)
    first = next(r for r in rows if r["statement"] == "HF1: first velocity-spectrum peak")
    assert first["value"] == V.interval(V.values(res, "f1"), ".1f", 1e-3, "kHz") and "(n = 2)" in first["value"]
    assert first["verdict"] in ("reproduced", "partly", "not reproduced")
    assert all(r["verdict"] == "not measured" for r in rows if "hf2" in r["experiments"])
    capsys.readouterr()
    assert V.main(argv) == 0  # checkpoints: nothing is run again
    assert "reusing the saved result" in capsys.readouterr().out
    assert V.main([*argv[:-4], "--out", str(tmp_path / "none"), "--max-wall", "0"]) == 0
    assert not (tmp_path / "none" / "hf1" / "result.json").exists()


def test_script_help_and_list():
    script = Path(__file__).resolve().parent.parent / "scripts" / "validation.py"
    out = subprocess.run([sys.executable, str(script), "--help"], capture_output=True, text=True, check=True).stdout
    assert "--max-wall" in out and "--only" in out and "--quick" in out
    listed = subprocess.run([sys.executable, str(script), "--list"], capture_output=True, text=True, check=True).stdout
    assert all(f"experiment {n}" in listed for n in V.EXPERIMENTS)
