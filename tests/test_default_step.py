"""The step and crossing treatment a fixed-step run takes when none is asked for: strang's are those at which the
saturated statistics were shown to hold, with the crossings averaged for a scene with a shipped preset's physics (any
patch seed, initial state, recording) 1e-6/3 s (three steps a 1 µs sample) for the regimes that keep every measure
there and 2.5e-7 s for the others, and 5e-8 s with the point treatment for any other scene; a batch of both is
refused, so that a pad's run never depends on its batch. The other fixed-step integrators keep 1e-8 s."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from aca_warp.common.errors import SceneError
from aca_warp.hf.loop import run_hf
from aca_warp.hf.model import build_model
from aca_warp.hf.options import (
    DEFAULT_DT,
    PRESET_CROSSING,
    PRESET_STEP,
    REGIME_STEPS,
    STATISTICS_STEP,
    THREE_STEP,
    RunOptions,
    default_crossing,
    default_step,
    regime_step,
)
from aca_warp.hf.runner import plan_run
from aca_warp.hf.state import initial_state
from aca_warp.scene import PRESETS, Initial, Matrix, PatchGenerator, Record, load_scene, preset, preset_document
from aca_warp.scene.regimes import preset_regime
from tests.test_small_defects import tiny_scene


def test_default_steps_by_integrator():
    hf1 = preset("hf1")
    assert default_step("strang") == default_step("strang", [tiny_scene(1e-6)]) == STATISTICS_STEP == 5e-8
    assert default_step("strang", [hf1, preset("varying_area_equal")]) == PRESET_STEP == 2.5e-7  # the shorter
    assert default_step("strang", [hf1, preset("hf3_equal")]) == THREE_STEP == 1e-6 / 3
    steps = {name: default_step("strang", [preset(name)]) for name in PRESETS}
    assert steps == {name: regime_step(name) for name in PRESETS}
    assert {name for name, step in steps.items() if step == THREE_STEP} == set(REGIME_STEPS)
    assert {"hf2", "hf4_equal", "varying_area", "varying_area_equal"} == {n for n in PRESETS if steps[n] == PRESET_STEP}
    for integrator in ("implicit-friction", "symplectic-euler"):
        assert default_step(integrator) == default_step(integrator, [hf1]) == DEFAULT_DT == 1e-8
    with pytest.raises(
        SceneError,
        match=r"mixes 1 pad\(s\) of a measured regime \(hf1: .* and 1 other pad\(s\) .*first is pad 1\); give the step",
    ):
        default_step("strang", [hf1, tiny_scene(1e-6)])


def test_default_crossing_by_regime_and_integrator():
    """strang averages the crossings of a measured regime's pads whatever the step, and takes the point treatment
    for any other scene and for the other integrators; a batch of both is refused, naming the crossing treatment."""
    hf1 = preset("hf1")
    assert default_crossing("strang", [hf1, preset("varying_area")]) == PRESET_CROSSING == "mean"
    assert default_crossing("strang") == default_crossing("strang", [tiny_scene(1e-6)]) == "point"
    assert default_crossing("adaptive", [hf1]) == default_crossing("implicit-friction", [hf1]) == "point"
    with pytest.raises(SceneError, match=r"\(hf1: strang's default crossing treatment mean\) .* give the crossing"):
        default_crossing("strang", [hf1, tiny_scene(1e-6)])


def test_a_scene_shares_a_presets_physics_whatever_its_seed_state_and_recording():
    """Every preset is its own regime; another patch seed, initial state, recording or duration keeps it; another
    load, speed, friction, patch count or height law, patches from elsewhere or a matrix of several cells do not."""
    for name in PRESETS:
        assert preset_regime(preset(name)) == name
    hf1 = preset("hf1")
    gen = PatchGenerator(**preset_document("hf1")["patches"])
    reseeded = hf1.replace(patches=PatchGenerator(**{**dataclasses.asdict(gen), "seed": 17}).generate(hf1.pad))
    assert reseeded.patches.source != hf1.patches.source and preset_regime(reseeded) == "hf1"
    same = hf1.replace(initial=Initial(state="equilibrium"), record=Record(2e-7), duration=0.03, name="mine")
    assert preset_regime(same) == "hf1"
    others = [
        hf1.replace(normal_force=480.0),
        hf1.replace(angular_velocity=hf1.angular_velocity * 0.5),
        hf1.replace(friction=dataclasses.replace(hf1.friction, M=0.7)),
        hf1.replace(patches=dataclasses.replace(gen, count=1000).generate(hf1.pad)),
        hf1.replace(patches=dataclasses.replace(gen, height_law="uniform").generate(hf1.pad)),
        hf1.replace(patches=dataclasses.replace(hf1.patches, source="python")),
        tiny_scene(1e-6),
    ]
    m = hf1.matrix
    others += [hf1.replace(matrix=Matrix(np.r_[m.area, 1e-4], np.r_[m.radius, 0.13], np.zeros(2))),
               hf1.replace(matrix=Matrix(m.area, m.radius, np.array([1e-6])))]  # fmt: skip
    assert [preset_regime(s) for s in others] == [None] * 9
    equal = hf1.replace(patches=dataclasses.replace(gen, height_spread=0.0).generate(hf1.pad))
    assert preset_regime(equal) == "hf1_equal"  # hf1 with equal heights is hf1_equal, by its physics


def test_a_run_without_dt_takes_the_default_step():
    """run_hf, the plan a command announces, and the presets, growing or not, take strang's default for their
    scenes; a batch that mixes them with another scene is refused before anything runs."""
    s = tiny_scene(1e-6)
    model = build_model([s])
    res = run_hf(model, initial_state(model), RunOptions(duration=2e-6), record=Record(1e-6))
    assert res.complete and res.dt == STATISTICS_STEP and res.steps == 40
    res = run_hf(model, initial_state(model), RunOptions(duration=2e-6, integrator="implicit-friction"),
                 record=Record(1e-6))  # fmt: skip
    assert res.dt == DEFAULT_DT and res.steps == 200
    plan = plan_run(s, RunOptions(duration=1e-3))
    assert plan.step == STATISTICS_STEP and plan.steps == 20_000 and "steps of 5e-08 s" in plan.describe()
    va = preset("varying_area")
    plan = plan_run(va, RunOptions(duration=1e-3))
    assert plan.step == PRESET_STEP and plan.steps == 4_000 and "steps of 2.5e-07 s" in plan.describe()
    assert load_scene("hf1").record.sample_dt >= PRESET_STEP  # the presets' sample intervals hold whole steps
    hf1 = preset("hf1")
    model = build_model([hf1, hf1.replace(patches=PatchGenerator(count=1758, seed=3, height_spread=2.42e-7)
                                          .generate(hf1.pad))])  # fmt: skip
    res = run_hf(model, initial_state(model), RunOptions(duration=1e-6), record=Record(1e-6))
    assert res.complete and res.dt == THREE_STEP and res.steps == 3  # whole steps: 1e-6 / 3 taken as it is
    with pytest.raises(SceneError, match="give the step"):
        run_hf(build_model([hf1, s]), None, RunOptions(duration=1e-6))
    with pytest.raises(SceneError, match="give the crossing treatment"):  # the step given, the treatment not
        run_hf(build_model([hf1, s]), None, RunOptions(duration=1e-6, dt=1e-7))


def test_run_files_keep_the_step_they_ran_at(tmp_path, capsys):
    """A run at the default step stores that step in its options, so a rerun repeats it; a file that stores no
    step (written while every fixed-step default was 1e-8 s) is repeated at 1e-8 s, not at today's default."""
    import json

    import h5py

    from aca_warp.cli import main
    from aca_warp.hf.rerun import read_settings
    from aca_warp.hf.runner import run_scene

    s = tiny_scene(1e-6)
    new = tmp_path / "new.h5"
    run_scene(s, new, RunOptions(duration=5e-6))
    assert read_settings(new).options.dt == STATISTICS_STEP
    old = tmp_path / "old.h5"
    res = run_scene(s, old, RunOptions(duration=5e-6, dt=1e-8))
    with h5py.File(old, "r+") as f:  # as a file written before the step was stored
        doc = json.loads(f.attrs["run_options"])
        f.attrs["run_options"] = json.dumps({**doc, "dt": None})
    assert read_settings(old).options.dt == DEFAULT_DT == res.dt
    stopped = tmp_path / "stopped.h5"  # stopped before it closed: no step taken on record, the default of its time
    stopped.write_bytes(old.read_bytes())
    with h5py.File(stopped, "r+") as f:
        del f.attrs["dt"]
    assert read_settings(stopped).options.dt == DEFAULT_DT
    again = tmp_path / "again.h5"
    assert main(["rerun", str(old), "-o", str(again), "--no-progress"]) == 0
    with h5py.File(old, "r") as a, h5py.File(again, "r") as b:
        assert a.attrs["dt"] == b.attrs["dt"] == 1e-8 and a.attrs["steps"] == b.attrs["steps"] == 500
        assert (a["global/mu"][()] == b["global/mu"][()]).all()


def test_a_sweep_spec_writes_its_default_step_out():
    """A sweep without run.dt takes the integrator's default step, written into its run settings and hash (a sweep
    directory begun under another default is then another sweep, not continued at another step): the base scene's
    where every pad shares its physics (seeds and initial states vary, and any other parameter lists the base's own
    values only), else the step for any scene."""
    from aca_warp.sweep import SweepError, load_spec

    doc = {"sweep": {"base": "hf1"}, "run": {"duration": 1e-5}, "parameters": {"friction.M": [0.6, 0.7]}}
    spec = load_spec(doc)
    assert spec.dt == STATISTICS_STEP and spec.run_settings()["dt"] == STATISTICS_STEP
    assert load_spec({**doc, "run": {"duration": 1e-5, "dt": 5e-8}}).hash == spec.hash
    assert load_spec({**doc, "run": {"duration": 1e-5, "dt": 1e-8}}).hash != spec.hash
    assert load_spec({**doc, "run": {"duration": 1e-5, "integrator": "implicit-friction"}}).dt == DEFAULT_DT
    assert load_spec({**doc, "run": {"duration": 1e-5, "integrator": "adaptive"}}).dt is None
    with pytest.raises(SweepError, match="shorter than the step 1e-08 s"):  # checked against the first trial's bound
        load_spec({**doc, "run": {"duration": 1e-5, "integrator": "adaptive", "sample_dt": 5e-9}})
    seeds = {**doc, "parameters": {"patches.seed": [1, 2], "initial.state": ["rest", "equilibrium"]}}
    assert load_spec(seeds).dt == THREE_STEP and load_spec(seeds).run_settings()["dt"] == THREE_STEP
    custom = {**seeds, "sweep": {"base": "hf1"}, "base": {"load": {"normal_force": 400.0}}}
    assert load_spec(custom).dt == STATISTICS_STEP
    own = {"friction.M": [0.8, 0.8], "load.normal_force": [487.2], "patches.count": [1758], "patches.seed": [1, 2]}
    assert load_spec({**doc, "parameters": own}).dt == THREE_STEP  # hf1's own M, load and count
    for key, other in (("friction.M", 0.7), ("load.normal_force", 400.0), ("patches.count", 1000)):
        changed = {**own, key: [*own[key], other]}
        assert load_spec({**doc, "parameters": changed}).dt == STATISTICS_STEP, key


def test_a_sweep_spec_writes_its_default_crossing_out(tmp_path):
    """A sweep of a preset whose pads share its physics averages the crossings by default, written into its run
    settings (a sweep of any other physics, and one asked for the point treatment, store none, as every sweep did
    before); a sweep directory begun with the point treatment is continued with ``--crossing point``, which the
    refusal names."""
    from aca_warp.sweep import SweepError, load_spec
    from aca_warp.sweep.manifest import prepare_dir

    seeds = {"sweep": {"base": "hf1"}, "run": {"duration": 1e-5}, "parameters": {"patches.seed": [1, 2]}}
    spec = load_spec(seeds)
    assert spec.crossing == "mean" and spec.run_settings()["crossing"] == "mean"
    point = load_spec(seeds, crossing="point")
    assert point.crossing == "point" and "crossing" not in point.run_settings()
    other = load_spec({**seeds, "parameters": {"friction.M": [0.6, 0.7]}})
    assert other.crossing == "point" and "crossing" not in other.run_settings()
    prepare_dir(point, tmp_path / "sw")  # as a sweep of hf1 began before the default averaged the crossings
    with pytest.raises(SweepError, match=r"crossing unset there, mean here\) \(to continue it: --crossing point\)"):
        prepare_dir(spec, tmp_path / "sw")


@pytest.mark.parametrize("crossing", ["point", "mean"])
def test_a_pad_of_a_preset_sweep_keeps_its_crossing_treatment(tmp_path, crossing):
    """A pad taken out of a shard of an hf1 seed sweep (``aca-warp analyze SHARD --pad K``) is rebuilt with the
    treatment the shard ran (point: not stored in the run settings; mean: the default there) and stores it, so that
    ``rerun`` repeats the pad's run."""
    from aca_warp.analysis.pads import write_pad_run
    from aca_warp.cli import main
    from aca_warp.hf.rerun import read_settings

    spec = tmp_path / "s.toml"
    spec.write_text(
        '[sweep]\nbase = "hf1"\nshard_size = 2\n[run]\nduration = 2e-6\n[parameters]\n"patches.seed" = [1, 2]\n'
    )
    argv = ["sweep", str(spec), "-o", str(tmp_path / "sw"), "--workers", "0", "--quiet"]
    assert main(argv + (["--crossing", "point"] if crossing == "point" else [])) == 0
    pad = write_pad_run(tmp_path / "sw" / "shard-00000.h5", 1, tmp_path / "pad1.h5")
    assert read_settings(pad).options.crossing == crossing


def test_the_summary_line_says_why_the_step(tmp_path, capsys):
    """``aca-warp hf`` without --dt names the default it took: the preset's physics, or a scene outside the measured
    regimes."""
    from procs import small_scene_toml

    from aca_warp.cli import main

    (tmp_path / "s.toml").write_text(small_scene_toml("small", count=10, duration=2.0e-6))
    for scene, words in (
        ("hf2", "(2.5e-07 s, the default step for hf2's physics, strang, fp32, crossings averaged)"),
        (str(tmp_path / "s.toml"), "(5e-08 s, the default step for a scene outside the regimes the statistics"),
    ):
        assert main(["hf", scene, "--duration", "2e-6", "-o", str(tmp_path / "r.h5"), "--overwrite",
                     "--no-progress"]) == 0  # fmt: skip
        assert words in capsys.readouterr().out
    assert main(["hf", "hf2", "--duration", "2e-6", "--sample-dt", "5e-8", "-o", str(tmp_path / "r.h5"), "--overwrite",
                 "--no-progress"]) == 0  # fmt: skip
    words = "(5e-08 s, the sample interval, shorter than the default step for hf2's physics (2.5e-07 s), strang, fp32"
    assert words in capsys.readouterr().out
    assert main(["hf", "hf2", "--duration", "2e-6", "--dt", "1e-7", "-o", str(tmp_path / "r.h5"), "--overwrite",
                 "--no-progress"]) == 0  # fmt: skip
    assert "(1e-07 s, strang, fp32, crossings averaged)" in capsys.readouterr().out  # the regime's treatment
    assert main(["hf", "hf2", "--duration", "2e-6", "--crossing", "point", "-o", str(tmp_path / "r.h5"),
                 "--overwrite", "--no-progress"]) == 0  # fmt: skip
    assert "(2.5e-07 s, the default step for hf2's physics, strang, fp32), mean mu" in capsys.readouterr().out
    # the step a sample interval forces below the statistics' least, and the default shortened to whole steps
    physics = "the default step for hf2's physics (2.5e-07 s)"
    for sample_dt, forced, words in (
        ("3e-8", ["--force"], f"(3e-08 s, the sample interval, shorter than {physics}, strang"),
        ("3e-7", [], f"(1.5e-07 s, {physics} shortened to fill the sample interval in whole steps, strang"),
    ):
        assert main(["hf", "hf2", "--duration", "1e-6", "--sample-dt", sample_dt, "-o", str(tmp_path / "r.h5"),
                     "--overwrite", "--no-progress", *forced]) == 0  # fmt: skip
        assert words in capsys.readouterr().out


def test_the_validation_runs_the_presets_at_the_setting_of_its_ensembles():
    """The validation's stepping table holds the setting its committed ensembles ran at for the presets' regimes (hf,
    growth): 1e-7 s with the point treatment (the validation's runs pass it) and strang's growth spacing; ms_order
    (no measured regime) at strang's step for any scene. A change of the table must be made on purpose."""
    import inspect

    from aca_warp.hf.options import STATISTICS_GROWTH_DT
    from aca_warp.studies.runs import run_engine
    from aca_warp.studies.validation.settings import STEPPING

    assert STEPPING["hf"].dt == STEPPING["growth"].dt == 1e-7 != PRESET_STEP
    assert inspect.signature(run_engine).parameters["crossing"].default == "point"
    assert STEPPING["growth"].growth_dt == STATISTICS_GROWTH_DT and STEPPING["ms_order"].dt == STATISTICS_STEP


def test_a_scene_read_back_from_its_run_file_keeps_its_regime(tmp_path):
    """A run file stores the patches themselves; the scene read back names its generator in ``origin``, which is what
    decides (a Python rerun at the default step repeats the step of the original)."""
    from aca_warp.hf.rerun import read_settings
    from aca_warp.hf.runner import run_scene

    run_scene(preset("hf2"), tmp_path / "r.h5", RunOptions(duration=2e-6))
    scene = read_settings(tmp_path / "r.h5").scene
    assert scene.patches.source.endswith(":/patches") and preset_regime(scene) == "hf2"


def test_a_sweep_names_its_step(tmp_path, capsys):
    """``aca-warp sweep`` says the step it runs at: here hf1's default, the sweep varying only patch seeds."""
    from aca_warp.cli import main

    spec = tmp_path / "s.toml"
    spec.write_text(
        '[sweep]\nbase = "hf1"\nshard_size = 2\n[run]\nduration = 2e-6\n[parameters]\n"patches.seed" = [1, 2]\n'
    )
    assert main(["sweep", str(spec), "-o", str(tmp_path / "sw"), "--workers", "0"]) == 0
    assert "2e-06 s each, strang fp32 at 3.33e-07 s, crossings averaged, spec hash" in capsys.readouterr().out


def test_a_sample_interval_between_the_defaults_sets_the_step():
    """Samples every 5e-8 s to 1e-7 s on a preset: the default step becomes the sample interval (what ran under the
    one default of 5e-8 s still runs); below 5e-8 s the sample interval is refused as for any step, and the message
    names 5e-8 s as the shortest interval (for a step asked for, the step itself), in a run and in a sweep."""
    hf1 = preset("hf1")
    for sample, step in ((5e-8, 5e-8), (8e-8, 8e-8), (2e-7, 2e-7), (5e-7, 2.5e-7), (1e-6, 1e-6 / 3)):
        plan = plan_run(hf1.replace(record=Record(sample)), RunOptions(duration=1e-6))
        assert plan.step == pytest.approx(step) and plan.steps == round(1e-6 / step)
    shortest = r"shorter than the default step 3.33e-07 s \(which a sample interval down to 5e-08 s would shorten\).*"
    with pytest.raises(SceneError, match=shortest + "at least 5e-08 s"):
        plan_run(hf1.replace(record=Record(2e-8)), RunOptions(duration=1e-6))
    with pytest.raises(SceneError, match=r"shorter than the step 1e-07 s: .* at least 1e-07 s"):
        plan_run(hf1.replace(record=Record(2e-8)), RunOptions(duration=1e-6, dt=1e-7))
    from aca_warp.sweep import SweepError, load_spec

    doc = {"sweep": {"base": "hf1"}, "run": {"duration": 1e-5, "sample_dt": 5e-8}, "parameters": {"patches.seed": [1]}}
    assert load_spec(doc).dt == 5e-8
    doc["run"]["sample_dt"] = 2e-8
    with pytest.raises(SweepError, match=shortest + "at least 5e-08 s"):
        load_spec(doc)


def test_an_lf_state_of_a_measured_group_takes_the_preset_step(tmp_path):
    """An HF scene of an LF state takes 2.5e-7 s with the crossings averaged where the LF run was the multiscale
    preset (any seed) and the state is of a group measured there (app3_start), 5e-8 s with the point treatment
    otherwise; a state changed afterwards is no longer measured."""
    import json

    import h5py

    from aca_warp.lf.commands import run_lf
    from aca_warp.lf.io import STATES_AT_PRESET_STEP, lf_state_regime, scene_from_snapshot
    from aca_warp.lf.scene import lf_scene_to_dict, load_lf_scene
    from aca_warp.studies.validation import multiscale as VM
    from aca_warp.studies.validation.settings import STEPPING
    from tests.test_lf import _scene

    # the list is the groups that the statistics keep at the preset step, as the validation runs them
    assert set(STATES_AT_PRESET_STEP) == set(VM.GROUPS["ms_mid"] + VM.GROUPS["ms_app3"])
    assert [STEPPING[g].dt == 1e-7 for g in VM.GROUPS] == [g in ("ms_mid", "ms_app3") for g in VM.GROUPS]
    out = tmp_path / "lf.h5"
    run_lf(_scene(), out, duration=0.35)  # a small LF scene: no preset's
    plain = scene_from_snapshot(out, "app1_start")
    assert preset_regime(plain) is None and default_step("strang", [plain]) == STATISTICS_STEP
    doc = json.loads(json.dumps(lf_scene_to_dict(load_lf_scene("multiscale"))))
    doc["lf"]["seed"] = doc["patches"]["seed"] = 7
    with h5py.File(out, "r+") as f:  # as the preset's LF run of seed 7 stores it, its state named as a measured one
        f.attrs["scene"] = json.dumps(doc)
        f.move("snapshots/app1_start", "snapshots/app3_start")
    state = scene_from_snapshot(out, "app3_start")
    assert preset_regime(state) == "multiscale app3_start" and default_step("strang", [state]) == PRESET_STEP
    assert default_crossing("strang", [state]) == "mean" and default_crossing("strang", [plain]) == "point"
    same = state.replace(record=Record(2e-7), initial=Initial(state="equilibrium"), duration=1e-3, name="mine")
    assert preset_regime(same) == "multiscale app3_start"
    assert preset_regime(state.replace(normal_force=np.float64(state.normal_force))) == "multiscale app3_start"
    m = state.matrix
    changed = [
        state.replace(normal_force=state.normal_force * 1.01),
        state.replace(angular_velocity=state.angular_velocity * 0.5),
        state.replace(friction=dataclasses.replace(state.friction, M=0.7)),
        state.replace(material=dataclasses.replace(state.material, K_T=state.material.K_T * 2)),
        state.replace(matrix=Matrix(m.area, m.radius, m.height + 1e-9)),
    ]
    assert [preset_regime(s) for s in changed] == [None] * 5
    # the document: the validation's own LF scenes are the preset's; another schedule or LF constant is not
    assert lf_state_regime(json.loads(json.dumps(lf_scene_to_dict(VM.lf_scene(3, None, None)))), "app1_end")
    renamed = {**doc, "scene": {"name": "copy"}, "snapshots": {"applications": True, "times": [1.0, 2.0]}}
    assert lf_state_regime(renamed, "app4_end") == "multiscale app4_end"
    for variant in (VM.lf_scene(3, (10.0, 5.0, 30.0, 15.0), None), VM.lf_scene(3, None, (1.0, 0.5))):
        assert lf_state_regime(json.loads(json.dumps(lf_scene_to_dict(variant))), "app3_start") is None
    louder = json.loads(json.dumps(doc))
    louder["schedule"][0]["normal_force"] *= 1.2
    constant = json.loads(json.dumps(doc))
    constant["lf"]["dt"] = 0.02
    assert lf_state_regime(louder, "app3_start") is None and lf_state_regime(constant, "app3_start") is None
    assert lf_state_regime(doc, "app2_start") is None and lf_state_regime({"lf": 1}, "app3_start") is None


def test_the_regimes_at_three_steps_a_sample_are_those_whose_statistics_keep_every_measure_there():
    """:data:`REGIME_STEPS` is the rule's reading of the committed result files of the study at three steps a 1 µs
    sample (docs/figures/work_precision_statistics/three_steps/): the regimes whose row at 1e-6/3 s (asked as
    3.33334e-7 s) with the crossings averaged, fp32, growth every 5 µs where pads grow, keeps every measure (rule
    ¼ σ, criterion ``resolution``), the same seeds and references as their row at 2.5e-7 s beside it; the LF groups
    do not (their states keep :data:`PRESET_STEP`)."""
    from pathlib import Path

    from aca_warp.studies import work_precision_stats_rule as rule

    folder = Path(__file__).resolve().parent.parent / "docs" / "figures" / "work_precision_statistics" / "three_steps"
    preset_of = {"va": "varying_area", "va_equal": "varying_area_equal"}
    keep_all: dict[str, bool] = {}
    for sub in sorted(p for p in folder.iterdir() if p.is_dir() and p.name != "logs"):
        (path,) = sub.glob(f"wps_*_{sub.name}.json")
        regime = rule.load_results(path)["regimes"][sub.name]
        rows = {s["dt"]: s for s in regime["settings"]
                if s["role"] == "grid" and rule.usable(s) and s["precision"] == "fp32" and s["crossing"] == "mean"
                and not s["fast_math"] and s["growth_dt"] in (None, 5e-6)}  # fmt: skip
        three, four = rows[3.33334e-7], rows[2.5e-7]
        assert three["steps"] * 4 == four["steps"] * 3  # three steps where the default took four
        keep_all[preset_of.get(sub.name, sub.name)] = all(
            rule.kept(rule.verdict(regime, three, m, rule.DEFAULT_RULE)) for m in regime["measures"]
        )
    assert set(keep_all) == set(PRESETS) | {"ms_mid", "ms_app3"}
    assert {name for name, kept in keep_all.items() if kept} == set(REGIME_STEPS)
    assert all(step == THREE_STEP for step in REGIME_STEPS.values())
