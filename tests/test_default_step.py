"""The step a fixed-step run takes when none is asked for: strang's is the step at which the saturated statistics
were shown to hold (5e-8 s, one value for every pad, so that a pad's run does not depend on its batch); the other
fixed-step integrators keep 1e-8 s."""

from __future__ import annotations

import pytest

from aca_warp.hf.loop import run_hf
from aca_warp.hf.model import build_model
from aca_warp.hf.options import DEFAULT_DT, STATISTICS_STEP, RunOptions, default_step
from aca_warp.hf.runner import plan_run
from aca_warp.hf.state import initial_state
from aca_warp.scene import Record, load_scene, preset
from tests.test_small_defects import tiny_scene


def test_default_steps_by_integrator():
    assert default_step("strang") == STATISTICS_STEP == 5e-8
    assert default_step("implicit-friction") == default_step("symplectic-euler") == DEFAULT_DT == 1e-8


def test_a_run_without_dt_takes_the_default_step():
    """run_hf, the plan a command announces, and a scene whose friction relaxes fastest of the presets
    (varying_area, friction step 1.34e-8 s) all take strang's default: the step is not set per batch."""
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
    assert plan_run(va, RunOptions(duration=1e-3)).step == STATISTICS_STEP
    assert load_scene("hf1").record.sample_dt >= STATISTICS_STEP  # the presets' sample intervals hold whole steps


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
    directory begun when the default was 1e-8 s is then another sweep, not continued at another step)."""
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
