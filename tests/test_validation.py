"""``aca_warp.studies.validation`` (``scripts/validation.py``): scenes, plans and segments, batches, the saturation
gate, a reduced run end to end (two seeds of a 50-patch hf1 sector that must saturate, and a run cut short that
cannot), the results file and the page rendered from it (the committed page included)."""

from __future__ import annotations

import dataclasses
import json
import math
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from scriptload import load_script

from aca_warp.studies.validation import analysis as VAN
from aca_warp.studies.validation import base as VB
from aca_warp.studies.validation import cli as VL
from aca_warp.studies.validation import experiments as VE
from aca_warp.studies.validation import plan as VP
from aca_warp.studies.validation.sync_measures import local_sync_measures

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
    assert p.duration >= p.settle + cfg.window - dtp and p.steps(1e-8, 1e-6) == round(p.duration / 1e-8)
    first = round(p.window_start / cfg.sample_dt)  # the per-patch rows: first, first + 3, ..., n
    assert (n - first) % cfg.decimation == 0 and (n - first) // cfg.decimation + 1 == p.patch_samples
    assert p.segments == ((0.0, p.window_start, False), (p.window_start, p.duration, True))
    rest = VE.prepare(VB.EXPERIMENTS["hf1_rest"], cfg).plan
    assert rest.duration == pytest.approx(cfg.paper_length) and len(rest.tracks) == cfg.track_windows
    assert 0.05 < rest.v0 < 1.0  # released from rest: a large start
    # the segments cover the run in order, per-patch ones exactly at the track windows and the final window
    assert rest.segments[0][0] == 0.0 and rest.segments[-1][1] == pytest.approx(rest.duration)
    assert all(a[1] == pytest.approx(b[0]) for a, b in zip(rest.segments[:-1], rest.segments[1:], strict=True))
    patch_segments = [s[:2] for s in rest.segments if s[2]]
    assert np.allclose(patch_segments, [*rest.tracks, (rest.window_start, rest.duration)], rtol=0, atol=1e-12)
    starts = [a for a, _ in rest.tracks]
    assert starts == sorted(starts) and starts[0] == pytest.approx(2 * cfg.track_window, abs=dtp)


def test_segments_are_whole_samples_on_one_clock():
    """Every segment of a from-rest plan with track windows (the full variant's settings) is at least one sample
    long, on whole samples, and starts exactly where the one before ends: a window that rounding brought within a
    sample of the next (a segment of 0.9999996 samples) was refused by the run loop."""
    from aca_warp.hf.recorder import check_run
    from aca_warp.scene import Record

    for cfg in (VB.Config(seeds=1, patches=60), VB.Config(seeds=1, patches=60, window=3e-3)):
        for name in ("hf1_rest", "hf2_rest", "hf1"):
            plan = VE.prepare(VB.EXPERIMENTS[name], cfg).plan
            seg = plan.segments
            assert seg[0][0] == 0.0 and seg[-1][1] == plan.duration
            assert all(a[1] == b[0] for a, b in zip(seg[:-1], seg[1:], strict=True))
            for a, b, _ in seg:
                n = (b - a) / cfg.sample_dt
                assert n >= 1.0 - 1e-9 and abs(n - round(n)) < 1e-6
                assert check_run(b - a, Record(sample_dt=cfg.sample_dt)) == round(n)  # the run loop takes it


def test_a_batch_runs_as_long_as_its_longest_member_and_refuses_mixed_kinds():
    cfg = VB.Config(seeds=1, patches=40, window=3e-3)
    a, b = (VE.prepare(VB.EXPERIMENTS[n], cfg) for n in ("hf1", "hf4"))
    batch = VE.make_batch("s31", [a, b], cfg)
    assert b.plan.duration > a.plan.duration  # M = 0.4 grows more slowly
    assert [m.plan.duration for m in batch.members] == [b.plan.duration] * 2 and len(batch.scenes) == 2
    assert batch.members[0].plan.segments == batch.members[1].plan.segments
    with pytest.raises(ValueError, match="differ in kind"):
        VE.make_batch("x", [a, VE.prepare(VB.EXPERIMENTS["hf1_rest"], cfg)], cfg)
    own = dataclasses.replace(VB.EXPERIMENTS["hf3"], stepping="ms_fast")  # a batch is one run: one stepping
    with pytest.raises(ValueError, match="stepping"):
        VE.make_batch("x", [a, VE.prepare(own, cfg)], cfg)
    va = VE.prepare(VB.EXPERIMENTS["va"], cfg)  # a growing run counts its growth events from its start
    assert len(VE.make_batch("va", [va], cfg).plan.segments) == 1
    cut = dataclasses.replace(va, plan=VE.split_segments(va.plan, 1e-3))
    with pytest.raises(ValueError, match="a growing batch runs as one segment, planned 2"):
        VE.make_batch("va", [cut], cfg)


def test_collector_joins_segments_on_one_clock():
    from aca_warp.hf.recorder import Chunk

    c = VE.Collector()
    for start, n in ((0.0, 4), (3e-6, 3)):  # every segment records its start again
        c.segment(start)
        t = np.arange(n) * 1e-6
        g = np.full((n, 1, 6), start)
        c(Chunk(t, g, t[1:], np.ones((n - 1, 2)), None))
    t, g, pt, v = c.arrays()
    np.testing.assert_allclose(t, [0, 1e-6, 2e-6, 3e-6, 4e-6, 5e-6])
    assert g[3, 0, 0] == 0.0 and g[4, 0, 0] == 3e-6  # the repeated start sample is dropped
    np.testing.assert_allclose(pt, [1e-6, 2e-6, 3e-6, 4e-6, 5e-6]) and v.dtype == np.float32


def test_the_probe_projects_the_step_time_against_what_the_budget_leaves(monkeypatch):
    """The probe segment's step time, projected over the batch, against the budget less the time already spent:
    a run that fits goes on through its segments as planned, one that does not stops after the probe, no budget
    never stops, and a plan of one segment is not probed (nothing left to stop)."""
    import aca_warp.studies.runs as runs

    def fake(per_step: float):
        calls = []

        def run_engine(model, state, *, duration, record, **_):
            calls.append((round(duration, 9), bool(record.patches)))
            steps = round(duration / 1e-7)
            return SimpleNamespace(complete=True, steps=steps, wall_time=per_step * steps)

        return calls, run_engine

    cfg = SimpleNamespace(sample_dt=1e-6, decimation=1, engine="onchip")
    step = SimpleNamespace(integrator="strang", force=False, growth_dt=None)
    sink = SimpleNamespace(segment=lambda a: None)

    def run(segments, per_step: float, budget: float | None, spent: float = 0.0):
        calls, engine = fake(per_step)
        monkeypatch.setattr(runs, "run_engine", engine)
        lines: list[str] = []
        probe = VE.BudgetProbe("s31", 300_000, budget, time.perf_counter() - spent, lines.append)  # 30 ms, 1e-7 s
        VE.run_segments(None, None, SimpleNamespace(segments=segments), cfg, step, 1e-7, sink, probe)
        return calls, probe.stopped, lines

    plan = ((0.0, 5e-4, False), (5e-4, 20e-3, False), (20e-3, 30e-3, True))
    calls, stopped, lines = run(plan, 1e-5, 10.0)  # 3 s projected: the segments as planned
    assert calls == [(5e-4, False), (19.5e-3, False), (10e-3, True)] and not stopped
    assert lines == ["s31: probe 5,000 steps at 10.00 µs/step: 3 s projected"]
    calls, stopped, lines = run(plan, 4e-4, 10.0)  # 120 s projected: stopped after the probe
    assert calls == [(5e-4, False)] and stopped and lines[0].endswith("120 s projected")
    assert run(plan, 4e-4, None)[:2] == ([(5e-4, False), (19.5e-3, False), (10e-3, True)], False)  # no budget
    assert run(plan, 1e-5, 10.0, spent=8.0)[1]  # 3 s fits the budget, not what 8 s spent leave of it
    calls, stopped, lines = run(((0.0, 5e-4, False),), 4e-4, 10.0)  # one segment: run, not probed
    assert calls == [(5e-4, False)] and not stopped and lines == []


def test_the_warm_up_leaves_the_batch_s_numbers_as_they_are():
    """The warm-up (one sample from a spare initial state, which takes a batch's first launches' one-off costs
    out of its probe) leaves every global output and recorded patch velocity of the run after it the same, bit
    for bit (a 40-patch hf1 pad on the CPU); cutting a segment in two does not: the segments are part of the
    arithmetic, which is why the probe does not measure again on another cut."""
    from aca_warp.studies.runs import batch_at_start

    cfg = VB.Config(seeds=1, patches=40, window=3e-3)
    prep = VE.prepare(VB.EXPERIMENTS["hf1"], cfg)
    run_cfg = SimpleNamespace(sample_dt=cfg.sample_dt, decimation=cfg.decimation, engine="auto")
    step = SimpleNamespace(integrator="strang", force=False, growth_dt=None)

    def run(segments, warm: bool):
        model, state = batch_at_start(prep.scenes, "cpu", "fp32")
        if warm:
            assert VE.warm_up(model, run_cfg, step, 1e-7) > 0.0
        sink = VE.Collector()
        VE.run_segments(model, state, SimpleNamespace(segments=segments), run_cfg, step, 1e-7, sink)
        return sink.arrays()

    plan = ((0.0, 3e-4, False), (3e-4, 5e-4, True))
    plain, warmed = run(plan, False), run(plan, True)
    for a, b in zip(plain, warmed, strict=True):
        assert a.size > 0 and a.shape == b.shape and np.array_equal(a, b)
    cut = run(((0.0, 1e-4, False), (1e-4, 3e-4, False), (3e-4, 5e-4, True)), False)
    assert not np.array_equal(plain[1], cut[1])  # the globals part after the cut


# ------------------------------------------------------------------------------------------------ verdicts


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
        next(r for r in VB.ROWS if r.statement == "HF1: first velocity-spectrum peak"),
    ]
    for p in results["hf1"]["pads"]:
        p["measures"].update(f1_first_half=7.3e4, f1_periodogram=7.3e4, f1_patch={})
    out = VB.evaluate_rows(results, VB.Config(), rows)
    assert out[0]["verdict"] == "failed" and "boom" in out[0]["notes"]
    assert out[1]["verdict"] == "not measured" and "hf2 (0 usable pads)" in out[1]["notes"]
    assert out[2]["verdict"] == "reproduced" and out[2]["value"].startswith("73.0 [73.0, 73.0] kHz (n = 2)")


def test_saturation_status_of_a_growing_and_a_saturating_record():
    t = np.arange(0.0, 40e-3, 1e-6)
    a = 1.0 / np.sqrt(1.0 + (1e6 - 1.0) * np.exp(-2 * 600.0 * t))  # Landau envelope from 1e-3 to 1
    carrier = np.abs(np.sin(2 * np.pi * 70e3 * t))
    glob = np.zeros((t.size, 6))
    glob[:, 4] = 100.0 * a * carrier
    glob[:, 0] = 0.5 + 0.01 * a * np.sin(2 * np.pi * 70e3 * t)
    sat = VAN.pad_saturation(t, glob, 40e-3, 8e-3)
    assert sat["status"] == "saturated" and 5e-3 < sat["t_start"] < 32e-3
    assert sat["growth_rate"] == pytest.approx(600.0, rel=0.1)
    short = slice(0, 8000)  # still growing at the end
    grow = VAN.pad_saturation(t[short], glob[short], 8e-3, 8e-3)
    assert grow["status"] == "not saturated" and grow["t_start"] is None
    late = VAN.pad_saturation(t, glob, 40e-3, 2 * 40e-3)  # settles, but not half a window before the end
    assert late["status"] == "saturated too late"
    # released from rest: near its saturated level from the start, no growth phase; counts only from rest
    flat = glob.copy()
    flat[:, 4] = 100.0 * carrier * (1 + 0.3 * np.exp(-t / 2e-3))
    assert VAN.pad_saturation(t, flat, 40e-3, 8e-3)["status"] == "no growth phase"
    rest = VAN.pad_saturation(t, flat, 40e-3, 8e-3, from_rest=True)
    assert rest["status"] == "saturated" and 0 < rest["t_start"] < 20e-3


def test_a_pad_from_rest_whose_rise_is_not_exponential_counts_as_released():
    """HF2 from rest: Σ|u̇| rises within a few windows, then drifts slowly; the growth fit over both (R² ≈ 0.1) is
    no growth phase for a pad from rest of an experiment analysed once saturated (``REST_GROWTH_R2``), which then
    saturates by its level; a pad from equilibrium, or one whose fit is kept, is not saturated. The linear phases
    keep every fit (their growth rate is a measure)."""
    t = np.arange(0.0, 0.12, 1e-6)
    level = (
        (1 - 0.95 * np.exp(-t / 2.5e-3)) * (1 + 0.06 * (1 - np.exp(-t / 30e-3))) * (1 + 0.01 * np.sin(90 * np.pi * t))
    )
    glob = np.zeros((t.size, 6))
    glob[:, 4] = 100 * level * np.abs(np.sin(2 * np.pi * 70e3 * t))
    glob[:, 0] = 0.5 + 0.01 * np.sin(2 * np.pi * 70e3 * t)
    grown = VAN.pad_saturation(t, glob, 0.12, 0.02)
    assert grown["status"] == "not saturated" and grown["growth_r2"] < VAN.REST_GROWTH_R2
    assert VAN.pad_saturation(t, glob, 0.12, 0.02, from_rest=True)["status"] == "not saturated"
    released = VAN.pad_saturation(t, glob, 0.12, 0.02, from_rest=True, min_growth_r2=VAN.REST_GROWTH_R2)
    assert released["status"] == "saturated" and 0 < released["t_start"] < 20e-3
    floors = {n: VAN.growth_r2_floor(e) for n, e in VB.EXPERIMENTS.items()}
    assert floors["hf2_rest"] == floors["hf1_rest"] == VAN.REST_GROWTH_R2
    assert floors["hf2"] == floors["hf2_lin"] == floors["ms_fast_lin"] == 0.0
    assert released["growth_rate"] is None and "no exponential growth phase" in released["verdict_sum_abs_velocity"]


# ------------------------------------------------------------------------------------------------ end to end


@pytest.fixture
def short_experiment():
    """hf1 cut short at 3 ms: still growing, so its pads cannot saturate."""
    exp = VB.register_experiment(VB.Experiment("hf1_short", "§3.1", "hf1 cut short (test)", "hf1", duration=3e-3))
    yield exp
    VB.EXPERIMENTS.pop(exp.name)


def test_reduced_run_end_to_end(tmp_path, short_experiment, capsys):
    out, page, res_dir = tmp_path / "val", tmp_path / "page.md", tmp_path / "results"
    page.write_text("# Validation\n\nMethod text that stays.\n")
    argv = [
        "--device", "cpu", "--quick", "--seeds", "2", "--patches", "50", "--window", "3e-3", "--workers", "1",
        "--only", "hf1", "hf1_short", "--out", str(out), "--results", str(res_dir), "--page", str(page),
    ]  # fmt: skip
    assert VL.main(argv) == 0
    res = json.loads((out / "hf1" / "result.json").read_text())
    assert [p["status"] for p in res["pads"]] == ["saturated", "saturated"]
    for p in res["pads"]:
        assert p["growth_rate"] > 0 and 0 < p["t_s_sum_abs_velocity"] < res["plan"]["duration_s"]
        assert 0.3 * p["sigma_median"] < p["growth_rate"] < 3 * p["sigma_median"]
        assert p["in_contact"] == p["patches"] == 50
        assert 20e3 < p["measures"]["f1"] < 150e3 and p["measures"]["global_span_s"] > 3e-3
    assert res["run"]["segments"] == 3 and res["run"]["dt"] == pytest.approx(1e-7)  # a probe, the rest, the window
    short = json.loads((out / "hf1_short" / "result.json").read_text())
    assert [p["status"] for p in short["pads"]] == ["not saturated", "not saturated"]
    assert "measures" not in short["pads"][0]
    text = page.read_text()
    assert text.startswith("# Validation\n\nMethod text that stays.") and "QUICK variant" in text
    assert text.count(f"<!-- BEGIN GENERATED ({VL.MARKER}) -->") == 1
    assert "| § | statement | ours: mean [95 % interval] (n seeds) | paper | verdict (criterion) |" in text
    assert "hf1_short, seed 1: **not saturated**" in text
    assert (res_dir / "validation.log").read_text().count("s31 (hf1, hf1_short)") == 0  # batches of their own
    doc = json.loads((res_dir / "results.json").read_text())
    assert set(doc["results"]) == {"hf1", "hf1_short"} and doc["meta"]["config"]["quick"] is True
    # the page is rendered from results.json alone: --report writes the same section
    again = tmp_path / "again.md"
    again.write_text("# Validation\n\nMethod text that stays.\n")
    assert VL.main(["--report", str(res_dir / "results.json"), "--page", str(again)]) == 0
    assert again.read_text() == text
    capsys.readouterr()
    assert VL.main(argv) == 0  # checkpoints: nothing is run again
    assert "reusing the saved result" in capsys.readouterr().out
    assert VL.main([*argv[:-6], "--out", str(tmp_path / "none"), "--max-wall", "0"]) == 0
    assert not (tmp_path / "none" / "hf1" / "result.json").exists()
    # a second call on a bare machine takes the first call's results file as done (--with)
    second = [*argv[:-6], "--out", str(tmp_path / "bare"), "--with", str(res_dir / "results.json")]
    assert VL.main(second) == 0 and not (tmp_path / "bare" / "hf1").exists()
    again = json.loads((tmp_path / "bare" / "results.json").read_text())["results"]
    assert again["hf1"]["pads"][0]["measures"]["f1"] == doc["results"]["hf1"]["pads"][0]["measures"]["f1"]
    # runs made side by side (--only on several GPUs) are joined by giving each results file to --with
    halves = []
    for name in ("hf1", "hf1_short"):
        half = tmp_path / f"{name}.json"
        half.write_text(json.dumps({**doc, "results": {name: doc["results"][name]}}))
        halves.append(str(half))
    joined = tmp_path / "joined"
    assert VL.main([*argv[:-6], "--out", str(tmp_path / "bare2"), "--results", str(joined), "--with", *halves]) == 0
    both = json.loads((joined / "results.json").read_text())
    assert both["results"] == doc["results"] and not (tmp_path / "bare2" / "hf1").exists()
    assert [p["experiments"] for p in both["meta"]["with"]] == [["hf1"], ["hf1_short"]]
    assert "--with EARLIER_RESULTS_JSON EARLIER_RESULTS_JSON" in both["meta"]["command"]
    assert "took the finished experiments of 2 earlier run(s) as done" in (joined / "validation.md").read_text()
    # with --only the earlier results of the other experiments stay; a file of other settings is left out (logged)
    other = tmp_path / "other.json"
    other.write_text(json.dumps({**doc, "meta": {**doc["meta"], "config": {**doc["meta"]["config"], "seeds": 3}}}))
    only = [*argv[: argv.index("--only") + 2], "--out", str(tmp_path / "bare4"), "--results", str(tmp_path / "r4")]
    assert VL.main([*only, "--with", str(res_dir / "results.json"), str(other), f"--lf-dir={tmp_path}"]) == 0
    four = json.loads((tmp_path / "r4" / "results.json").read_text())
    assert four["results"] == doc["results"] and str(tmp_path) not in four["meta"]["command"]
    assert "--with EARLIER_RESULTS_JSON EARLIER_RESULTS_JSON --lf-dir=LF_DIR" in four["meta"]["command"]
    assert f"{other}: other settings than this run's; not used" in (tmp_path / "r4" / "validation.log").read_text()
    # an experiment finished in two of the files is refused before anything is written
    capsys.readouterr()
    twice = [*argv[:-6], "--out", str(tmp_path / "b3"), "--results", str(tmp_path / "r3"), "--with", *halves, halves[0]]
    assert VL.main(twice) == 2 and "hf1 finished in" in capsys.readouterr().err
    assert not (tmp_path / "r3").exists() and not (tmp_path / "b3").exists()


def test_report_refuses_a_file_that_is_not_a_results_file(tmp_path, capsys):
    bad = tmp_path / "x.json"
    bad.write_text('{"rows": []}')
    assert VL.main(["--report", str(bad), "--page", str(tmp_path / "p.md")]) == 2
    assert "not a validation results file" in capsys.readouterr().err and not (tmp_path / "p.md").exists()
    assert VL.main(["--report", str(tmp_path / "missing.json")]) == 2
    bad.write_text("[1, 2]")  # JSON, but not an object; also as --with, before anything is written
    assert VL.main(["--report", str(bad)]) == 2 and "not a validation results file" in capsys.readouterr().err
    assert VL.main(["--quick", "--out", str(tmp_path / "o"), "--with", str(bad)]) == 2
    assert "not a validation results file" in capsys.readouterr().err and not (tmp_path / "o").exists()


def test_committed_page_is_rendered_from_the_committed_results():
    """docs/validation.md's generated section is exactly what --report writes from the committed 32-seed results
    (docs/validation/seeds32/results.json.gz)."""
    repo = Path(__file__).resolve().parent.parent
    page = repo / "docs" / "validation.md"
    from aca_warp.studies.report import generated_markers
    from aca_warp.studies.validation.results import render_report

    body, rows, _ = render_report(repo / "docs" / "validation" / "seeds32" / "results.json.gz")
    begin, end = generated_markers(VL.MARKER)
    committed = page.read_text().split(begin, 1)[1].split(end, 1)[0]
    assert committed == "\n" + "\n".join(body) + "\n"
    assert len(rows) == len(VB.ROWS) >= 45


def test_the_pages_cost_tables_are_the_scripts_output():
    """Each per-batch stepping table of docs/validation.md is what ``scripts/validation_cost.py`` prints from the
    committed results file it names, and its sum is the sum of the batches' stepping walls: the committed file's
    calls (15 lines: 14 batches and hf2_rest run again) and the current code's one call (14)."""
    repo = Path(__file__).resolve().parent.parent
    text = (repo / "docs" / "validation.md").read_text()
    blocks = [b.split(" -->\n", 1) for b in text.split("<!-- COST ")[1:]]
    assert [path for path, _ in blocks] == ["docs/validation/results.json", "docs/validation/rerun_twice/results.json"]
    for (path, table), count in zip(blocks, (15, 14), strict=True):
        lines = load_script("validation_cost").table(repo / path)
        assert table.split("<!-- END COST -->", 1)[0] == "\n".join(lines) + "\n"
        walls = [float(row.split("|")[7].split()[0]) for row in lines[2:] if row.startswith("| ")]
        total = float(lines[-1].split("Stepping: ", 1)[1].split(" s", 1)[0])
        assert len(walls) == count and abs(total - sum(walls)) <= 0.05 * len(walls)  # rounding


def test_cost_table_of_a_results_file_without_estimates_or_blocks(tmp_path):
    """A results file whose runs did not record the blocks per pad or the estimate gives "–" there."""
    import json

    committed = Path(__file__).resolve().parent.parent / "docs" / "validation" / "results.json"
    data = json.loads(committed.read_text())
    del data["results"]["ms_fast"]["plan"]["estimate_s"], data["results"]["ms_fast"]["run"]["blocks_per_pad"]
    (tmp_path / "results.json").write_text(json.dumps(data))
    lines = load_script("validation_cost").table(tmp_path / "results.json")
    per_step = data["results"]["ms_fast"]["run"]["us_per_step"]
    assert [r for r in lines if "`ms_fast`" in r][0].endswith(f"| {per_step:.2f} | – | – |")


def test_cost_rows_group_a_batch_and_letter_the_shares():
    """``cost.measured``: experiments of one batch name make one row (their pads added), the share is the letter of
    the earlier results file that finished them, and rows without a finished run are left out."""
    from aca_warp.studies.validation.cost import measured

    run = {"stepping": {"precision": "fp32", "dt": 1e-7}, "steps": 10, "wall_s": 2.0, "us_per_step": 0.2}
    plan = {"duration_s": 1e-3, "estimate_s": 1.0}
    res = {"status": "done", "run": run, "plan": plan}
    results = {
        "hf1": {**res, "pads": [{"patches": 100}] * 2},
        "hf2": {**res, "pads": [{"patches": 300}]},
        "ms_fast": {**res, "pads": [{"patches": 4000}]},
        "ms_short": {"status": "failed: x", "pads": []},
    }
    rows = measured(results, [{"experiments": ["ms_fast"]}, {"experiments": ["hf1", "hf2"]}])
    assert [r["batch"] for r in rows] == ["ms_fast", "s31"]
    assert [r["share"] for r in rows] == ["A", "B"]
    assert rows[1]["experiments"] == ["hf1", "hf2"] and rows[1]["pads"] == 3 and rows[1]["patches"] == [100, 300]
    assert measured(results)[0]["share"] == "–"
    # hf1 ran again in this run (--without hf1): its batch is a row of its own, not added to the earlier file's
    split = measured(results, [{"experiments": ["ms_fast", "hf2"]}])
    assert [(r["share"], r["batch"], r["experiments"]) for r in split] == [
        ("A", "s31", ["hf2"]),
        ("A", "ms_fast", ["ms_fast"]),
        ("–", "s31", ["hf1"]),
    ]


def test_page_states_the_stepping_its_results_ran_with():
    """The page's settings line reads the stepping from the results file, not from today's table, and the run key
    carries the stepping, so results of another stepping or friction scheme are neither described nor reused as
    this run's."""
    from aca_warp.studies.validation.page import _header_lines
    from aca_warp.studies.validation.settings import STEPPING

    repo = Path(__file__).resolve().parent.parent
    meta = json.loads((repo / "docs" / "validation" / "results.json").read_text())["meta"]
    meta["config"]["stepping"] = {"hf": "strang, dt = 3.3e-08 s, fp64"}
    assert "stepping hf: strang, dt = 3.3e-08 s, fp64;" in "\n".join(_header_lines(meta))
    produced = next(t for t in _header_lines(meta) if t.startswith("Produced"))  # the kernels where recorded
    assert f"aca-warp 0.1.0, kernels {meta['versions']['kernels']}; wall time" in produced
    del meta["versions"]["kernels"]  # a file written before the record
    assert "aca-warp 0.1.0; wall time" in "\n".join(_header_lines(meta))
    meta["versions"] = {**meta["versions"], "kernels": "0123456789ab"}
    assert "aca-warp 0.1.0, kernels 0123456789ab; wall time" in "\n".join(_header_lines(meta))
    meta["config"] = VB.QUICK.run_key()  # the quick variant: one stepping, the growing kind's events named
    line = next(t for t in _header_lines(meta) if t.startswith("Settings"))
    assert (
        "stepping every experiment strang, dt = 1e-07 s (forced), fp32; growth: strang, dt = 1e-07 s (forced), "
        "fp32, growth events every 5e-06 s;" in line
    )
    key = VB.FULL.run_key()
    assert key["stepping"] == {kind: VB.FULL.stepping(kind).describe() for kind in STEPPING}
    assert key != {**key, "stepping": meta["config"]["stepping"]}


def test_script_help_and_list(capsys):
    """``scripts/validation.py`` (loaded as the script, run in this process): its help and its list of experiments."""
    script = load_script("validation")
    with pytest.raises(SystemExit) as done:
        script.main(["--help"])
    out = capsys.readouterr().out
    assert done.value.code == 0 and "--max-wall" in out and "--only" in out and "--quick" in out
    assert script.main(["--list"]) == 0
    listed = capsys.readouterr().out
    assert all(f"experiment {n}" in listed for n in VB.EXPERIMENTS)
    for bad in ("0", "abc", "-1e-6"):  # --growth-dt: a positive number of seconds or "scene"
        with pytest.raises(SystemExit) as done:
            script.main(["--dry-run", "--growth-dt", bad])
        assert done.value.code == 2 and "--growth-dt" in capsys.readouterr().err


# ------------------------------------------------------------------------------------------------ §3.2 (synthetic)

from aca_warp.studies.validation import area as VA  # noqa: E402
from aca_warp.studies.validation import causes as VC  # noqa: E402
from aca_warp.studies.validation import multiscale as VM  # noqa: E402
from aca_warp.studies.validation import multiscale_rows as VMR  # noqa: E402


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
    # the largest values of the CWT follow the line, with a trend that explains nearly all of ln f, and it emerges
    # there; the first line too once the line stands out (in the first window, at half the noise's level, a bump of
    # the noise at lower frequencies reaches a quarter of the largest value)
    c = m["cwt"]
    lines = VA.cwt_lines(c)
    for line in ("band", "largest", "largest_l1"):
        x = lines[line]
        assert x["dlnf"] == pytest.approx(np.log(0.5) * 35 / 36, abs=0.03) and x["dlnf_ci"][1] < 0 and x["r2"] > 0.99
        assert len(x["hz"]) == len(c["times"]) == 8
    # the first line too once the line stands out; before, low-frequency bumps of the noise reach a quarter
    assert np.allclose(lines["first"]["hz"][2:], lines["largest"]["hz"][2:], rtol=1e-6)
    assert lines["first"]["hz"][0] < 1e4
    assert c["times"][0] == pytest.approx(1e-3 + 2048e-6, rel=0.01) and c["record_s"] == [1e-3, t[-1]]
    assert np.shape(c["amplitude"]) == (VA.CWT_FREQUENCIES.size, 8) and np.shape(c["thirds"]) == (48, 3)
    for norm in ("L1", "L2"):
        ptm = VA.cwt_peak_to_median(c, norm)
        assert ptm[2] > ptm[0] + 0.3
    assert m["line"]["mu_first_hz"][1:] == m["line"]["dominant_hz"][1:]  # μ's STFT by the same rule: as above
    assert m["line"]["mu_band_hz"] == m["line"]["dominant_hz"]  # the line lies within 20–80 kHz throughout
    assert m["line"]["dominant_r2"] > 0.99 and 0 <= m["line"]["mu_first_r2"] < m["line"]["dominant_r2"]
    steady = VA.growth_measures(*_growing_mu(1, falling=False), _va_scene(), t_start=1e-3)
    assert abs(steady["line"]["dominant_dlnf"]) < 0.02
    for line in ("largest", "largest_l1"):  # a steady 50 kHz line: within 2 % of it (÷ √f: 1.3 % low)
        x = VA.cwt_lines(steady["cwt"])[line]
        assert abs(x["dlnf"]) < 0.01 and np.allclose(x["hz"], 50e3, rtol=0.02)
    # STFT maximum: the line in the last full window (amplitude 1e-3 (1 + 4 t/T) at its centre) over the mean μ
    w = next(w for w in steady["stft"] if w["samples"] == 4096)
    centre = w["time"] / 36e-3
    mean = np.mean(0.40 + 0.10 * np.arange(1000, 36000) / 35999)
    assert w["frequency"] == pytest.approx(50e3, rel=2e-3)
    assert w["amplitude"] == pytest.approx(1e-3 * (1 + 4 * centre) / mean, rel=0.05)
    assert [x["samples"] for x in steady["stft"]] == [4096, 8192, 16384, 32768]  # 2^12 … 2^15 fit 35 ms


def test_cwt_lines_need_three_windows_interpolate_between_grid_frequencies_and_differ_by_rule():
    t = np.arange(20000) * 1e-6
    for f in (50e3, 53.7e3):  # on the grid's 8 % spacing and between two of its frequencies
        c = VA.cwt_lines(VA.cwt_measures(np.sin(2 * np.pi * f * t), 1e-6, 4096))
        for line in ("first_l1", "largest_l1"):
            assert np.allclose(c[line]["hz"], f, rtol=0.003) and len(c[line]["hz"]) == 4
        # ÷ √f moves a line's maximum down by ≈ 1.3 % (the wavelet's response is σ_f ≈ 0.18 f wide): a constant
        # factor, which leaves Δ ln f alone
        for line in ("first", "largest"):
            assert np.allclose(c[line]["hz"], 0.9865 * f, rtol=0.003)
    # two lines, 30 kHz at amplitude 1 and 120 kHz at 1.5: the largest amplitude-true value is the upper one, the
    # energy-normalised (÷ √f: 1 against 0.75) and the first lines (1 ≥ ¼ of 1.5) the lower one
    two = VA.cwt_lines(VA.cwt_measures(np.sin(2 * np.pi * 30e3 * t) + 1.5 * np.sin(2 * np.pi * 120e3 * t), 1e-6, 4096))
    assert np.allclose(two["largest_l1"]["hz"], 120e3, rtol=0.003)
    assert np.allclose(two["first_l1"]["hz"], 30e3, rtol=0.003)
    for line in ("first", "largest"):
        assert np.allclose(two[line]["hz"], 0.9865 * 30e3, rtol=0.003)
    # a band edge is no line: a rising low-frequency floor (μ's drift) leaves the first line at the interior peak
    edge = np.exp(-np.log(VA.CWT_FREQUENCIES / 5e3)) + np.exp(-(np.log(VA.CWT_FREQUENCIES / 60e3) ** 2) / 0.02)
    # (a column per block: the same block twice, and a block of the floor alone, whose line is its largest value)
    blocks = np.stack([edge, edge, np.exp(-np.log(VA.CWT_FREQUENCIES / 5e3))], axis=1)
    lines = VA._line_peaks(VA.CWT_FREQUENCIES, blocks, 0.25)
    assert lines == pytest.approx([60e3, 60e3, VA.CWT_FREQUENCIES[0]], rel=0.02)
    with pytest.raises(ValueError, match="at least 3"):
        VA.cwt_measures(np.sin(2 * np.pi * 50e3 * t[:8000]), 1e-6, 4096)


def test_growth_contact_falls_from_the_start_to_its_end():
    s = _va_scene()
    c = VA.growth_contact(s, s.duration)
    track = c["contact_track"]
    share = np.array(track["matrix_share"])
    assert len(track["times_s"]) == share.size == VA.CONTACT_INSTANTS and track["times_s"][-1] == s.duration
    end, start = VA.contact_at(s, s.duration), VA.contact_at(s, 0.0)
    assert {k: c[f"end_{k}"] for k in end} == end and share[-1] == end["matrix_share"]
    assert share[0] == start["matrix_share"] and share[0] > share[-1]
    assert end["mean_area_m2"] > start["mean_area_m2"] and 0.0 < end["in_contact"] <= 1.0
    assert np.all(np.diff(share) <= 1e-12)


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


def _synthetic_cwt(dlnf: float, emerge: float) -> dict:
    """A stored CWT (``cwt_measures``' form) of 10 blocks over 0.3 s: one line whose ln f falls by ``dlnf`` over the
    record (± 0.05 about its trend, block by block), a Gaussian in ln f over a floor flat in the energy-normalised
    CWT; its thirds a floor with a bump whose ln(1 + height) rises by ``emerge`` from the first to the last."""
    f = VA.CWT_FREQUENCIES
    frac = (np.arange(10) + 0.5) / 10
    line = np.log(60e3) + dlnf * frac + 0.05 * (-1.0) ** np.arange(10)
    l2 = 0.01 + np.exp(-((np.log(f)[:, None] - line) ** 2) / (2 * 0.1**2))
    bump = (np.abs(f - 50e3) < 2e3).astype(float)[:, None]
    thirds = 1.0 + bump * (np.exp([[1.0, 1.2, 1.0 + emerge]]) - 1.0)
    weight = VA.l2_weight(f)[:, None]
    return {"record_s": [0.0, 0.3], "times": (0.3 * frac).tolist(), "freqs_hz": f.tolist(),
            "amplitude": (l2 / weight).tolist(), "thirds": (thirds / weight).tolist()}  # fmt: skip


def _va_result(
    rise: float,
    dlnf: float,
    freq: float,
    ptm: float,
    matrix_end: float,
    area_end: float,
    hf_std: float = 0.01,
    cwt_gain: float = 0.3,
    share_rise: float = 0.0,
) -> dict:
    """A ``va_full`` result of 5 seeds: μ rising by ``rise``, the lines' Δ ln f ``dlnf`` (the CWT ridge's R²
    ``cwt_gain`` above its STFT counterpart's), the STFT maximum at ``freq``, the late − early ln(peak/median)
    ``ptm`` − 1 (spectrum and CWT), the matrix share 0.8 → ``matrix_end`` (rising by ``share_rise`` once on its way),
    the areas ending at ``area_end``."""
    pads = []
    for s in range(1, 6):
        e = 0.02 * (s - 3)
        cwt = _synthetic_cwt(dlnf + e, ptm + e - 1.0)
        lines = VA.cwt_lines(cwt)  # each STFT counterpart's R² ``cwt_gain`` below its CWT line's, each its own
        r2 = {k: lines[c]["r2"] - cwt_gain - e for k, c in (("dominant", "largest"), ("mu_first", "first"),
                                                          ("mu_band", "band"))}  # fmt: skip
        share = np.linspace(0.8, matrix_end, 37)
        share[20] += share_rise
        pads.append(_pad(s, {
            "mu_rise": rise + e * 0.1, "mu_thirds": [0.4, 0.45, 0.4 + rise], "mu_mean": 0.45, "mu_hf_std": hf_std,
            "line": {"dominant_dlnf": dlnf + e, "first_dlnf": dlnf + e, "predicted_dlnf": -0.8,
                     "window_samples": 4096, "first_dlnf_ci": [dlnf - 0.1, dlnf + 0.1],
                     **{f"{k}_r2": v for k, v in r2.items()}},
            "cwt": cwt,
            "stft": [{"window": "w4096", "samples": 4096, "amplitude": 0.003, "frequency": freq * (1 + e / 10),
                      "mean": 0.45},
                     {"window": "w8192", "samples": 8192, "amplitude": 0.004, "frequency": 69.0e3, "mean": 0.45}],
            "tonality": {"peak_to_median": [1.0, 1.2, ptm + e], "flatness": [0.5, 0.4, 0.5 - (ptm - 1) / 5],
                         "std": [0.01, 0.02, 0.01 * np.exp(ptm - 1)], "peak_hz": [7e4, 5e4, 3.5e4]},
        }, matrix_share=0.8, end_matrix_share=matrix_end + 0.001 * e, end_in_contact=1.0,
            end_mean_area_m2=area_end * (1 + e / 10), end_area_range_m2=[0.5e-6, 2.0e-6],
            contact_track={"times_s": np.linspace(0.0, 0.36, 37).tolist(),
                           "matrix_share": share.tolist()}))  # fmt: skip
    return {"pads": pads}


def test_varying_area_rows_follow_their_criteria():
    cfg = VB.Config()
    good = {"va_full": _va_result(0.1, -0.8, 69.5e3, 2.0, 0.0, 1.24e-6)}
    bad = {"va_full": _va_result(-0.05, 0.5, 35.6e3, 0.5, 0.3, 0.6e-6, hf_std=0.5, cwt_gain=-0.2, share_rise=0.05)}
    rows = {r.statement: r for r in VB.ROWS if r.experiments == ("va_full",)}
    assert len(rows) == 14
    for r in rows.values():
        if r.kind == "not comparable":
            assert r.measure(good, cfg).verdict == "not comparable", r.statement
            continue
        if r.statement.startswith(("under the HF2 load all patches", "at the start the pad-matrix", "as the patches")):
            continue  # the same pad facts in both; the load's path below
        assert r.measure(good, cfg).verdict == "reproduced", r.statement
        assert r.measure(bad, cfg).verdict == "not reproduced", r.statement
    # the STFT-window variant reads the 2^13 window: its peak sits at the paper's 69 kHz
    peak = rows["largest STFT peak of μ"]
    assert peak.measure(VC.stft_window(8192)(bad), cfg).verdict != "not reproduced"
    # each part of the CWT row and of the emergence row decides: a falling ridge no clearer than the STFT's line is
    # partly, a CWT whose lines do not emerge keeps the spectrum's emergence from reproduced
    cwt = next(r for r in rows.values() if r.statement.startswith("in the CWT of μ"))
    assert cwt.measure({"va_full": _va_result(0.1, -0.8, 69.5e3, 2.0, 0.0, 1.24e-6, cwt_gain=0.0)}, cfg).verdict == (
        "partly"
    )
    emerge = next(r for r in rows.values() if r.statement.startswith("individual dominant frequencies emerge"))
    mixed = _va_result(0.1, -0.8, 69.5e3, 2.0, 0.0, 1.24e-6)
    for p in mixed["pads"]:
        p["measures"]["cwt"]["thirds"] = _synthetic_cwt(-0.8, -0.1)["thirds"]
    assert emerge.measure({"va_full": mixed}, cfg).verdict == "partly"
    # a rise of the matrix share within the contact solve's rounding is none; the notes give the track; a share that
    # rises once on its way down, or stays, is partly; one that rises throughout is not reproduced
    portion = next(r for r in rows.values() if r.statement.startswith("as the patches grow"))
    flat = portion.measure({"va_full": _va_result(0.1, -0.8, 69.5e3, 2.0, 0.0, 1.24e-6, share_rise=5e-7)}, cfg)
    assert flat.verdict == "reproduced" and "pads whose share never rises: 5 of 5" in flat.notes
    assert "0.800 at 0 ms" in flat.notes and "0.000 at 360 ms" in flat.notes
    assert portion.measure(bad, cfg).verdict == "partly"  # falls by 0.5, rising by 0.05 once
    for track, want in (([0.5] * 37, "partly"), (np.linspace(0.3, 0.8, 37).tolist(), "not reproduced")):
        res = _va_result(0.1, -0.8, 69.5e3, 2.0, 0.0, 1.24e-6)
        for p in res["pads"]:
            p["contact_track"]["matrix_share"] = track
        assert portion.measure({"va_full": res}, cfg).verdict == want
    # results made before the CWT was measured read "not measured" in its two rows, before the load's track in its row
    old = _va_result(0.1, -0.8, 69.5e3, 2.0, 0.0, 1.24e-6)
    for p in old["pads"]:
        del p["measures"]["cwt"]
        del p["contact_track"]
    assert (
        cwt.measure({"va_full": old}, cfg).verdict == emerge.measure({"va_full": old}, cfg).verdict == ("not measured")
    )
    assert portion.measure({"va_full": old}, cfg).verdict == "not measured"


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
                    "sync_snr": {"agreement": 0.3 * e, "top_excess": top.get(m, 0.2) * e,
                                 "cluster_phi_rho": 0.4 * e},
                }, member=m))  # fmt: skip
        out[group] = {"pads": pads}
    out["ms_order"] = {"pads": [_pad(s, {"mu_std": after_low * (1 + 0.01 * s), "sync_relative": {"top_excess": 0.1}},
                                     "app2_start") for s in range(1, 6)]}  # fmt: skip
    return out


def test_multiscale_rows_follow_their_criteria():
    cfg = VB.Config()
    rows = {r.statement: r for r in VB.ROWS if r.section.startswith(("§3.3", "§4"))}
    assert len(rows) == 16
    std = dict.fromkeys(VM.STATES, 0.01)
    res = _ms_results({**std, "app3_start": 0.02, "app3_end": 0.015}, top={"app3_start": 0.5})
    amplitude = [r for r in rows.values() if r.criterion == VMR.AMPLITUDE_CRITERION]
    assert len(amplitude) == 5 and all(r.kind == "direction" for r in amplitude)
    for r in amplitude:  # μ's amplitudes read on this LF automaton, the caveat in the notes
        v = r.measure(res, cfg)
        assert v.verdict == "reproduced" and v.notes.startswith(VMR.ON_THIS_LF), r.statement
    for key in ("individual high-valued S at the start of application 3",
                "end of application 3: local clustering correlates with the number of patches in S"):  # fmt: skip
        assert rows[key].measure(res, cfg).verdict == "reproduced"
    res = _ms_results({**std, "app1_start": 0.03, "app3_start": 0.015}, after_low=0.05)
    largest = rows["the maximum amplitudes occur at the beginning of application 3"].measure(res, cfg)
    assert largest.verdict == "not reproduced" and "app1_start ×5" in largest.notes


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
    sweep = next(r for r in VB.ROWS if r.statement.startswith("f_p ∝ A_p^(−1/4): exponent"))
    assert lin.applies(peak2) and lin.applies(m_row) and rest.applies(peak2) and rest.applies(m_row)
    assert not rest.applies(sweep)  # the sweep points have no run from rest
    snr = next(v for v in vs.values() if v.cause == "Φ rule")
    assert snr.applies(m_row) and not snr.applies(peak2)
    res = {"hf1": {"pads": [_pad(1, {"sync_relative": {"a": 1}, "sync_snr": {"a": 2}})]}}
    assert VC.snr_rule(res)["hf1"]["pads"][0]["measures"]["sync_relative"] == {"a": 2}
    assert res["hf1"]["pads"][0]["measures"]["sync_relative"] == {"a": 1}  # the input is not changed
    halves = VC.seed_half(True, 8, 1)({"x": {"pads": [_pad(s, {}) for s in range(1, 9)]}})
    assert [p["seed"] for p in halves["x"]["pads"]] == [1, 2, 3, 4]


def test_a_variant_that_moves_a_verdict_is_marked():
    def f1_pads(f: float) -> dict:
        return {"pads": [_pad(s, {"f1": f + 30.0 * s, "f1_patch": {}}) for s in range(1, 5)]}

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
        "--device", "cpu", "--quick", "--seeds", "2", "--patches", "30", "--state-patches", "30", "--window", "3e-3",
        "--growth-speedup", "60", "--workers", "1", "--only", "va", "hf1_lin", "ms_test", "--out", str(out),
    ]  # fmt: skip
    assert VL.main(argv) == 0
    va = json.loads((out / "va" / "result.json").read_text())
    assert va["plan"]["patch_samples"] == 0 and va["plan"]["duration_s"] == pytest.approx(0.36 / 60)
    assert va["run"]["segments"] == 1  # a growing run is one segment: its growth clock runs from its start
    assert va["run"]["stepping"]["growth_dt"] == 5e-6  # the stepping table's growth events, in the quick variant too
    for p in va["pads"]:
        assert p["status"] == "saturated" and 0 < p["t_start"] < 3e-3, p["verdict_sum_abs_velocity"]
        m = p["measures"]
        assert m["mu_rise"] > 0 and m["line"]["predicted_dlnf"] < 0 and len(m["tonality"]["std"]) == 3
        assert m["stft_floor_hz"] == pytest.approx(10.0 * 60) and m["mu_hf_std"] > 0
        assert 0 <= p["end_matrix_share"] < p["matrix_share"] and p["end_mean_area_m2"] > 0.5e-6
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
    doc = json.loads((out / "results.json").read_text())["results"]
    assert [p["seed"] for p in doc["lf_states"]["pads"]] == [1, 2]
    assert 0 <= doc["lf_states"]["pads"][0]["measures"]["match_app2_end"] <= 1
    text = (out / "validation.md").read_text()
    assert "### §3.2: the growth runs" in text and "### Which change moves which verdict" in text


def test_state_sector_keeps_the_gap_of_the_full_state(tmp_path, monkeypatch):
    from aca_warp.hf.contact import solve_scene_contact
    from aca_warp.lf.io import scene_from_snapshot

    monkeypatch.setattr(VM, "QUICK_DURATIONS", (0.3, 0.1))
    cfg = VB.Config(seeds=1, quick=True, lf_dir=str(tmp_path))
    VM._run_lf_job((1, None, VM.QUICK_DURATIONS, str(VM.lf_path(cfg, 1, None)), "cpu"))
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


def test_results_of_different_lf_runs_are_neither_reused_nor_joined(tmp_path):
    """An LF run on a GPU is not bit-reproducible, so a §3.3 result records the digests of the LF run files its pads
    were cut from: a saved result is reused only while those files are the same, results of different LF runs are not
    joined by --with, and a §3.3 experiment is not run against another LF folder than the joined results'."""
    from aca_warp.studies.report import Log, clean
    from aca_warp.studies.validation.results import read_results

    cfg = VB.Config(seeds=2, lf_dir=str(tmp_path / "lf"))
    exp = VB.EXPERIMENTS["ms_fast"]
    import h5py

    def lf_file(seed: int, alive: list[int], wall: float) -> None:  # as an LF run writes it: a file renamed
        tmp = tmp_path / "lf" / "run.tmp.h5"
        with h5py.File(tmp, "w") as f:
            f.attrs.update(scene="multiscale", wall_time=wall)
            f.create_dataset("snapshots/app1_start/alive", data=np.array(alive))
        tmp.replace(VM.lf_path(cfg, seed, None))

    (tmp_path / "lf").mkdir()
    for seed in (1, 2):
        lf_file(seed, [1, 0, seed], wall=1.0)
    runs = VM.lf_runs(exp, cfg)
    assert (
        sorted(runs) == ["lf_full_preset_seed1.h5", "lf_full_preset_seed2.h5"]
        and VM.lf_runs(VB.EXPERIMENTS["hf1"], cfg) == {}
    )
    folder = tmp_path / "ms_fast"
    folder.mkdir()
    saved = {"experiment": clean(exp.key()), "config": cfg.run_key(), "status": "done", "lf_runs": runs, "pads": []}
    (folder / "result.json").write_text(json.dumps(saved))
    assert VE.load_result(folder, exp, cfg) is not None
    lf_file(2, [1, 0, 2], wall=7.5)  # the same run made again (bit-identical, another wall time): the same states
    assert VM.lf_runs(exp, cfg) == runs and VE.load_result(folder, exp, cfg) is not None
    lf_file(2, [1, 1, 2], wall=1.0)  # one birth otherwise
    assert VE.load_result(folder, exp, cfg) is None  # cut from other LF runs: run again
    (folder / "records.npz").write_bytes(b"")  # nor are its kept records analysed against the new states
    assert VE.reanalyse(SimpleNamespace(exp=exp), cfg, tmp_path, Log()) is None
    # --with: two files whose §3.3 results come from different LF runs are refused
    doc = json.loads((Path(__file__).resolve().parent.parent / "docs" / "validation" / "results.json").read_text())
    _, _, committed = read_results(Path(__file__).resolve().parent.parent / "docs" / "validation" / "results.json")
    files = []
    for name, digest in (("ms_fast", "aaaa"), ("ms_short", "bbbb")):
        half = tmp_path / f"{name}.json"
        result = {**doc["results"][name], "config": committed.run_key(), "lf_runs": {"lf_full_preset_seed1.h5": digest}}
        meta = {**doc["meta"], "config": committed.run_key()}  # made with this code's settings
        half.write_text(json.dumps({**doc, "meta": meta, "results": {name: result}}))
        files.append(half)
    with pytest.raises(ValueError, match="different LF runs: lf_full_preset_seed1.h5"):
        VL.earlier_results(files, committed, Log())
    files[1].write_text(files[1].read_text().replace("bbbb", "aaaa"))
    got = VL.earlier_results(files, committed, Log())
    assert sorted(got.results) == ["ms_fast", "ms_short"] and len(got.parts) == 2
    # a §3.3 experiment of this call is not run against LF runs other than the joined results'
    local = VB.Config(**{**committed.__dict__, "lf_dir": str(tmp_path / "lf")})
    why = VL.lf_refusals(["ms_fast", "hf1"], got.results, local)
    assert list(why) == ["ms_fast"] and "give --lf-dir their folder" in why["ms_fast"]
    # nor is a result saved in the joining call's --out from those LF runs taken; the earlier result comes first
    out = tmp_path / "out"
    for name in ("ms_mid", "ms_fast"):
        e = VB.EXPERIMENTS[name]
        mine = {"experiment": clean(e.key()), "config": committed.run_key(), "status": "done"}
        (out / name).mkdir(parents=True)
        (out / name / "result.json").write_text(json.dumps({**mine, "lf_runs": VM.lf_runs(e, local)}))
    assert VE.load_result(out / "ms_mid", VB.EXPERIMENTS["ms_mid"], local) is not None
    assert VL.reusable("ms_mid", out, local, got.results) is None
    assert VL.reusable("ms_mid", out, local, {}) is not None and VL.reusable("hf1", out, local, got.results) is None
    assert VL.reusable("ms_fast", out, local, got.results) is got.results["ms_fast"]
    # a §3.3 result that does not record its LF runs cannot be checked: left out, and the log says so
    blind = {k: v for k, v in doc["results"]["ms_mid"].items() if k != "lf_runs"}
    files[1].write_text(json.dumps({**doc, "meta": {**doc["meta"], "config": committed.run_key()},
                                    "results": {"ms_mid": blind, "hf1": doc["results"]["hf1"]}}))  # fmt: skip
    notes: list[str] = []
    got = VL.earlier_results(files, committed, notes.append)
    assert sorted(got.results) == ["hf1", "ms_fast"] and any("ms_mid not used" in n for n in notes)
    # nor is a result made with another definition of its experiment (here: hf1 under another description)
    other = {**doc["results"]["hf1"], "experiment": {**doc["results"]["hf1"]["experiment"], "description": "x"}}
    files[1].write_text(json.dumps({**doc, "meta": {**doc["meta"], "config": committed.run_key()},
                                    "results": {"hf1": other}}))  # fmt: skip
    notes.clear()
    got = VL.earlier_results(files, committed, notes.append)
    assert sorted(got.results) == ["ms_fast"] and any("hf1 not used: made with another definition" in n for n in notes)


def test_without_leaves_named_experiments_of_the_earlier_results_out(tmp_path, capsys):
    """``--without``: the named experiments of a ``--with`` file are not taken as done (they run again), the others
    are, and the log says which were left out; an unknown name, or ``--without`` without ``--with``, is refused
    before anything is written."""
    from aca_warp.studies.validation.results import read_results

    committed_path = Path(__file__).resolve().parent.parent / "docs" / "validation" / "results.json"
    results, _, cfg = read_results(committed_path)
    notes: list[str] = []
    got = VL.earlier_results([committed_path], cfg, notes.append, ["ms_mid", "ms_app3"])
    finished = {n for n, r in results.items() if n in VB.EXPERIMENTS and r.get("status") in ("done", "stopped")}
    stale = _restepped(committed_path)  # made with a stepping the table has changed since: they run again
    assert set(got.results) == finished - stale - {"ms_mid", "ms_app3"} and "hf1" in got.results
    # each experiment is credited to the call that ran it: the committed file joins six calls, the earlier ones' less
    # the left-out experiments, then the file's own (the five growth experiments, run again with every other
    # experiment taken as done)
    meta = json.loads(committed_path.read_text())["meta"]
    assert len(meta["with"]) == 5
    assert [p["command"] for p in got.parts] == [*(w["command"] for w in meta["with"]), meta["command"]]
    for part, earlier in zip(got.parts, meta["with"], strict=False):
        assert part["experiments"] == sorted(set(earlier["experiments"]) - stale - {"ms_mid", "ms_app3"})
    assert (
        got.parts[-1]["experiments"]
        == sorted(set(got.results) - {n for w in meta["with"] for n in w["experiments"]})
        == ["va", "va_equal", "va_full", "va_full_rest", "va_rest"]
    )
    assert sorted(n for p in got.parts for n in p["experiments"]) == sorted(got.results)
    assert any("ms_app3, ms_mid not used: run again (--without)" in n for n in notes)
    out = tmp_path / "out"
    assert VL.main(["--out", str(out), "--with", str(committed_path), "--without", "nope"]) == 2
    assert "unknown experiment(s) nope" in capsys.readouterr().err
    assert VL.main(["--out", str(out), "--without", "ms_short"]) == 2
    assert "give --with" in capsys.readouterr().err and not out.exists()


def _restepped(path: Path) -> set[str]:
    """The experiments of a results file whose kind of stepping the table (``settings.STEPPING``) has changed since
    the file was made: a call that takes the file with ``--with`` runs them again."""
    made = json.loads(path.read_text())["meta"]["config"]["stepping"]
    now = VB.FULL.run_key()["stepping"]
    kinds = {k for k in now if made.get(k) != now[k]}
    return {
        n
        for n in json.loads(path.read_text())["results"]
        if n in VB.EXPERIMENTS and VB.EXPERIMENTS[n].stepping in kinds
    }


def test_committed_results_ran_every_experiment_at_the_stepping_table_s_entry():
    """The committed results ran every experiment at the table's current entry (a call that takes the file with
    ``--with`` runs nothing again), while the kept ms_short results at the table's earlier entry, the reference
    fp64 at 1e-8 s, would run again (docs/validation.md, "Stepping")."""
    folder = Path(__file__).resolve().parent.parent / "docs" / "validation"
    assert _restepped(folder / "results.json") == set()
    assert _restepped(folder / "ms_short_reference_step" / "results.json") == {"ms_short", "ms_short_lin"}
    made = json.loads((folder / "ms_short_reference_step" / "results.json").read_text())["meta"]["config"]["stepping"]
    assert made["ms_short"] == "strang, dt = 1e-08 s, fp64" and VB.FULL.stepping("ms_short").describe() == (
        "strang, dt = 5e-08 s, fp64"
    )


def test_earlier_results_are_taken_per_kind_of_stepping(tmp_path):
    """A results file made under another stepping of one kind gives up that kind's experiments only (they run
    again, the log says why) and keeps the others; another setting of any other name leaves the whole file out. A
    saved checkpoint is judged the same way."""
    from aca_warp.studies.validation.base import same_settings
    from aca_warp.studies.validation.results import read_results

    committed_path = Path(__file__).resolve().parent.parent / "docs" / "validation" / "results.json"
    results, _, cfg = read_results(committed_path)
    doc = json.loads(committed_path.read_text())
    for part in (doc["meta"], *doc["results"].values()):  # the growth stepping before, in the file and each result
        if isinstance(part, dict) and "config" in part:
            part["config"]["stepping"]["growth"] = "strang, dt = 5e-08 s, fp32"
    older = tmp_path / "older.json"
    older.write_text(json.dumps(doc))
    notes: list[str] = []
    got = VL.earlier_results([older], cfg, notes.append)
    growth = {n for n in results if n in VB.EXPERIMENTS and VB.EXPERIMENTS[n].stepping == "growth"}
    assert growth == {"va", "va_equal", "va_full", "va_full_rest", "va_rest"}
    finished = {n for n, r in results.items() if n in VB.EXPERIMENTS and r.get("status") in ("done", "stopped")}
    stale = _restepped(committed_path)
    assert set(got.results) == finished - growth - stale and "hf1" in got.results and "ms_mid" in got.results
    assert any("va, va_equal, va_full, va_full_rest, va_rest not used: made with another stepping" in n for n in notes)
    doc["meta"]["config"]["window"] = 0.01  # another setting than the stepping: nothing is taken
    older.write_text(json.dumps(doc))
    notes.clear()
    assert VL.earlier_results([older], cfg, notes.append).results == {} and "other settings" in notes[0]
    # a checkpoint: hf1's result made under the older growth stepping still fits; va's would not
    older_key = doc["results"]["hf1"]["config"]
    assert VE.fits({**results["hf1"], "config": older_key}, VB.EXPERIMENTS["hf1"], cfg)
    assert VE.fits(results["va"], VB.EXPERIMENTS["va"], cfg)
    assert not VE.fits({**results["va"], "config": older_key}, VB.EXPERIMENTS["va"], cfg)
    key = cfg.run_key()
    other = {**key, "stepping": {**key["stepping"], "growth": "strang, dt = 5e-08 s, fp32"}}
    assert same_settings(other, key, "hf") and same_settings(other, key, None)
    assert not same_settings(other, key, "growth")
    # --growth-dt: the growing kind's stepping only, "scene" the scenes' own clock
    assert cfg.stepping("growth").growth_dt == 5e-6 and cfg.stepping("hf").growth_dt is None
    scene = dataclasses.replace(cfg, growth_dt="scene")
    assert scene.stepping("growth").growth_dt is None and "growth events" not in scene.run_key()["stepping"]["growth"]
    assert same_settings(scene.run_key(), key, "hf") and not same_settings(scene.run_key(), key, "growth")
    assert key["growth_dt"] is None and scene.run_key()["growth_dt"] == "scene"  # the page names the override
    finer = dataclasses.replace(cfg, growth_dt=1e-6)
    assert finer.stepping("growth").describe().endswith("growth events every 1e-06 s")
    # a file made with the option reads back with it (read_results rebuilds the settings from the run key)
    doc["meta"]["config"] = finer.run_key()
    older.write_text(json.dumps(doc))
    assert read_results(older)[2].stepping("growth").growth_dt == 1e-6


def test_runs_of_credits_each_experiment_to_the_call_that_ran_it_once():
    """A joined file's experiments go to the earlier calls of its ``with`` that ran them, in their order, the rest to
    the file's own call; a call none of whose experiments are taken is not named, and none is named twice."""
    call = {"command": "c", "created": "t", "machine": "m", "wall_s": 1.0}
    meta = {**call, "command": "join", "wall_s": 0.01, "with": [
        {**call, "command": "A", "experiments": ["a", "b", "x"]},
        {**call, "command": "B", "experiments": ["y"]},
        {**call, "command": "C", "experiments": ["c", "a"]},
    ]}  # fmt: skip
    got = VL.runs_of(meta, ["a", "b", "c", "d"])
    assert [(p["command"], p["experiments"]) for p in got] == [("A", ["a", "b"]), ("C", ["c"]), ("join", ["d"])]
    assert got[-1] == {**call, "command": "join", "wall_s": 0.01, "experiments": ["d"]}
    assert [p["command"] for p in VL.runs_of({**call, "with": None}, ["a"])] == ["c"] and VL.runs_of(meta, []) == []


def test_dry_run_plans_lf_states_from_every_seed_where_their_lf_runs_are_there(monkeypatch):
    """The dry run plans an LF-state experiment from every seed's states when the LF folder holds them all (the first
    seed's made here if it alone is missing); else from the first seed's, repeated, and the log says so (seed 1's
    states are sparser than others': its plan put the 16-pad batches' neighbour lists on chip where every seed's put
    them off)."""
    from aca_warp.studies.validation.experiments import Prepared

    seen: list[int] = []
    missing: set[int] = set()  # seeds whose LF run the folder lacks

    def fake_prepare(exp, cfg):
        seen.append(cfg.seeds)
        return Prepared(exp, ["s"] * cfg.seeds, ["c"] * cfg.seeds, ["σ"] * cfg.seeds, "plan", ["m"] * cfg.seeds)

    def fake_jobs(names, cfg, first_only=False):
        return sorted(k for k in missing if k < cfg.first_seed + (1 if first_only else cfg.seeds))

    monkeypatch.setattr(VL, "prepare", fake_prepare)
    monkeypatch.setattr(VM, "lf_jobs", fake_jobs)
    monkeypatch.setattr(VM, "ensure_lf", lambda names, cfg, log, first_only=False: missing.difference_update(
        fake_jobs(names, cfg, first_only)))  # fmt: skip
    notes: list[str] = []
    for seeds, gone, plan in ((3, set(), 3), (3, {1}, 3), (1, {1}, 1), (3, {1, 2}, 1)):
        seen.clear()
        missing.update(gone)
        got = VL.dry_prepare(VB.EXPERIMENTS["ms_short"], VB.Config(seeds=seeds), notes.append)
        assert seen == [plan] and got.scenes == ["s"] * seeds and missing == (gone - {1}), (seeds, gone)
        missing.clear()
    assert len(notes) == 1 and "planned from LF seed 1's states for all 3" in notes[0]
    assert VL.dry_prepare(VB.EXPERIMENTS["hf1"], VB.Config(seeds=3), notes.append).scenes == ["s"] * 3
    assert len(notes) == 1


def test_committed_lf_state_results_come_from_one_set_of_lf_runs():
    """Every §3.3 result of the committed results file records the LF runs it was cut from, and they agree."""
    from aca_warp.studies.validation.results import read_results

    results, _, _ = read_results(Path(__file__).resolve().parent.parent / "docs" / "validation" / "results.json")
    runs = {n: r.get("lf_runs", {}) for n, r in results.items() if n in VB.EXPERIMENTS
            and VB.EXPERIMENTS[n].builder is VM.state_scene}  # fmt: skip
    assert set(runs) >= {*VM.MAIN, "ms_order", *(f"{g}_lin" for g in VM.MAIN)}  # each group's linear phase too
    assert all(runs.values()) and VM.lf_conflicts(runs) == []
    assert VM.lf_conflicts({**runs, "lf facts": results["lf_states"]["lf_runs"]}) == []


def test_compare_two_results_files(tmp_path, capsys, monkeypatch):
    """``scripts/validation_compare.py``: the committed file against itself is the same (exit 0); a copy with one
    per-pad number changed, one entry dropped, the LF facts' cap moved, an experiment only in it and a row's input
    moved names each (exit 1), its timings and provenance do not count; a file that is not a results file exits 2.
    The committed comparison of the results with the file before the fp32 fix is the script's output."""
    import hashlib

    from aca_warp.studies.validation import compare

    page_said, memo = compare._said, {}

    def said_once(results: dict, cfg: object) -> dict:  # what the page says, evaluated once per distinct content
        key = hashlib.sha256(json.dumps([results, repr(cfg)], sort_keys=True, default=str).encode()).hexdigest()
        if key not in memo:
            memo[key] = page_said(results, cfg)
        return memo[key]

    monkeypatch.setattr(compare, "_said", said_once)
    repo = Path(__file__).resolve().parent.parent
    committed = repo / "docs" / "validation" / "results.json"
    script = load_script("validation_compare")
    assert script.main([str(committed), str(committed)]) == 0
    assert "0 of " in capsys.readouterr().out
    doc = json.loads(committed.read_text())
    pad = doc["results"]["hf1"]["pads"][0]
    pad["patches"] += 1
    del pad["seed"]
    for p in doc["results"]["va_full"]["pads"]:  # μ falls instead of rising: the row's verdict moves
        p["measures"]["mu_rise"] = -abs(p["measures"]["mu_rise"])
    doc["results"]["lf_states"]["cap_frequency_hz"] *= 2
    doc["results"]["hf2"]["run"]["wall_s"] = 1e9  # timings and provenance are not compared
    doc["results"]["hf2"]["run"]["device"] = "cuda:7"
    other = tmp_path / "results.json"
    other.write_text(json.dumps(doc))
    assert script.main([str(committed), str(other)]) == 1
    out = capsys.readouterr().out.splitlines()
    row = {line.split("|")[1].strip(): line for line in out if line.startswith("| ")}
    assert "| 1 |" in row["hf1"] and "pads[0].patches: 1758 against 1759" in row["hf1"] and "pads[0].seed" in row["hf1"]
    assert row["hf2"].split("|")[3].strip() == "0" and "cap_frequency_hz" in row["lf_states"]
    assert any(line.startswith("* rows: μ rises as the load moves from the matrix") for line in out)
    one = {**doc, "results": {k: v for k, v in doc["results"].items() if k != "ms_order"}}
    other.write_text(json.dumps(one))
    assert script.main([str(other), str(committed)]) == 1  # an experiment in the second file only
    assert "(the whole experiment)" in capsys.readouterr().out
    # a partial first file: the experiments it lacks come from the second, only its own are compared
    part = {**doc, "results": {k: v for k, v in doc["results"].items() if k in ("va_full", "hf2")}}
    other.write_text(json.dumps(part))
    assert script.main(["--partial", str(other), str(committed)]) == 1
    out = capsys.readouterr().out.splitlines()
    row = {line.split("|")[1].strip(): line for line in out if line.startswith("| ")}
    assert set(row) == {"experiment", "va_full", "hf2"} and row["hf2"].split("|")[3].strip() == "0"
    assert any(line.startswith("* rows: μ rises as the load moves from the matrix") for line in out)
    full = json.loads(committed.read_text())  # the same as a whole file with that one experiment changed
    full["results"]["va_full"] = doc["results"]["va_full"]
    whole = tmp_path / "whole.json"
    whole.write_text(json.dumps(full))
    assert script.main([str(whole), str(committed)]) == 1
    said = [line.split("what the page says")[1] for line in capsys.readouterr().out.splitlines() if "page says" in line]
    assert said[-1] == out[-1 - sum(line.startswith("* ") for line in out)].split("what the page says")[1]
    assert said[-1].endswith("; the verdict moved in 2 rows, 0 from rest, 10 variants.")
    other_settings = {**part, "meta": {**part["meta"], "config": {**part["meta"]["config"], "seeds": 3}}}
    other.write_text(json.dumps(other_settings))
    assert script.main(["--partial", str(other), str(committed)]) == 2
    assert "other settings (besides the stepping)" in capsys.readouterr().err
    part = {**doc, "results": {"hf2": doc["results"]["hf2"]}}
    other.write_text(json.dumps(part))
    assert script.main(["--partial", str(other), str(committed)]) == 0
    assert "the verdict moved in 0 rows, 0 from rest, 0 variants" in capsys.readouterr().out
    other.write_text("{}")
    assert script.main([str(committed), str(other)]) == 2
    assert "not a validation results file" in capsys.readouterr().err
    other.write_text(json.dumps({"format": doc["format"], "results": {}}))
    assert script.main([str(committed), str(other)]) == 2
    assert "not a complete validation results file" in capsys.readouterr().err
    monkeypatch.chdir(repo)  # the committed comparison, as its page names it: the results before the fp32 fix
    assert script.main(["docs/validation/before_fix/results.json", "docs/validation/results.json"]) == 1
    assert capsys.readouterr().out == (repo / "docs" / "validation" / "before_fix" / "compare.md").read_text()
    kept = "docs/validation/ms_short_reference_step"  # ms_short at the reference step: no verdict moved
    assert script.main(["--partial", f"{kept}/results.json", "docs/validation/results.json"]) == 1
    out = capsys.readouterr().out
    assert out == (repo / kept / "compare.md").read_text()
    assert "the verdict moved in 0 rows, 0 from rest, 0 variants" in out
    twice = "docs/validation/rerun_twice"  # the eight seeds run twice from scratch on one code: every entry alike
    assert script.main([f"{twice}/results.json", f"{twice}/results_b.json.gz"]) == 0
    out = capsys.readouterr().out
    assert out == (repo / twice / "compare_b.md").read_text()
    assert out.splitlines()[-1].startswith("0 of 262137 entries differ, 0 on one side only")
    sample = "docs/validation/step_sample"  # after samples came to read the next step's solve: no row's verdict moved
    assert script.main(["docs/validation/rerun_twice/results.json", f"{sample}/results.json.gz"]) == 1
    out = capsys.readouterr().out
    assert out == (repo / sample / "compare.txt").read_text()
    assert "the verdict moved in 0 rows, 0 from rest, 14 variants" in out


def test_validation_figures_of_the_committed_files(tmp_path, capsys):
    """``scripts/validation_figures.py`` draws the first peaks and the growth runs' CWT from the committed eight-seed
    file; from a results file made before the CWT was measured it writes the first peaks, not the CWT, and says so
    (exit status 2); a file in place of the folder is refused."""
    script = load_script("validation_figures")
    docs = Path(__file__).resolve().parent.parent / "docs" / "validation"
    out = tmp_path / "fig"
    assert script.main([str(docs / "results.json"), str(out)]) == 0
    for name in ("verdicts.png", "first_peaks.png", "va_cwt.png"):
        png = out / name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    old = tmp_path / "old"
    assert script.main([str(docs / "recheck_warp_parts" / "results.json"), str(old)]) == 2
    assert "va_cwt.png not written" in capsys.readouterr().err
    assert (old / "first_peaks.png").is_file() and not (old / "va_cwt.png").exists()
    with pytest.raises(SystemExit):
        script.main([str(docs / "results.json"), str(out / "first_peaks.png")])
    assert "not a folder" in capsys.readouterr().err


def test_first_peak_figure_reads_the_rows_values():
    """The figure's values are the rows': the primary's first peaks and the two-size exponents from equilibrium and
    from rest, per seed, as ``values`` and ``two_area_exponent`` give them; a file without §3.1 runs is refused."""
    from aca_warp.studies.validation.hf_peaks import two_area_exponent
    from aca_warp.studies.validation.peaks_figure import READINGS, exponents, first_peaks, peaks_figure
    from aca_warp.studies.validation.results import read_results

    docs = Path(__file__).resolve().parent.parent / "docs" / "validation"
    results, _, _ = read_results(docs / "results.json")
    peaks, fits = first_peaks(results), exponents(results)
    assert len(peaks) == 4 * 2 * len(READINGS) and READINGS[0][1] == "f1"
    np.testing.assert_array_equal(peaks[("hf2", "_rest", "f1")], VB.values(results["hf2_rest"], "f1"))
    rest = two_area_exponent(results, "f1", (("hf2_rest", "hf1_rest"),))
    np.testing.assert_array_equal(fits[("two sizes, from rest", "f1")], rest)
    assert abs(rest.mean() + 0.25) < 0.025  # from rest the primary's exponent lies within the row's tolerance
    with pytest.raises(ValueError, match="none of the §3.1 experiments"):
        peaks_figure({"va_full": results["va_full"]}, Path("unused.png"))


def test_verdicts_figure_counts_the_pages_verdicts(tmp_path):
    """The verdict figure's tallies are the page's counts: every row once in the primary's bars, the rows measured
    from rest once in each of the other two, the construction marks as the page counts them; results without any
    experiment still give a figure: the rows that need none measured, the others not measured."""
    from aca_warp.studies.validation.causes import beside_rest
    from aca_warp.studies.validation.results import read_results
    from aca_warp.studies.validation.verdicts import VERDICTS
    from aca_warp.studies.validation.verdicts_figure import BARS, tallies, verdicts_figure

    docs = Path(__file__).resolve().parent.parent / "docs" / "validation"
    results, _, cfg = read_results(docs / "results.json")
    order, counts = tallies(results, cfg)
    rows, rest = VB.evaluate_rows(results, cfg), beside_rest(results, cfg)

    def total(bar: str, verdict: str | None = None, built: bool = False) -> int:
        return sum(sum(f) if built else len(f) for (_, b), c in counts.items() if b == bar
                   for v, f in c.items() if verdict in (None, v))  # fmt: skip

    assert order[0] == "§2.2" and order[-1] == "Appendix" and total(BARS[0]) == len(rows) == len(VB.ROWS)
    for verdict in {r["verdict"] for r in rows}:
        assert total(BARS[0], verdict) == sum(r["verdict"] == verdict for r in rows)
    built = sum(r["verdict"] == "reproduced" and bool(r["construction"]) for r in rows)
    assert total(BARS[0], "reproduced", built=True) == built > 0
    measured = [(r, b) for r, b in zip(rows, rest, strict=True) if b is not None and b["verdict"] in VERDICTS]
    assert total(BARS[1]) == total(BARS[2]) == len(measured) > 0
    assert total(BARS[2], "reproduced") == sum(b["verdict"] == "reproduced" for _, b in measured)
    _, empty = tallies({}, cfg)
    assert sum(len(f) for c in empty.values() for v, f in c.items() if v != "not measured") < len(rows)
    assert verdicts_figure({}, cfg, tmp_path / "none.png").stat().st_size > 10_000
