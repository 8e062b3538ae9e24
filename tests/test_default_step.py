"""The step a fixed-step run takes when none is asked for: strang's is the step at which the saturated statistics
were shown to hold (5e-8 s, one value for every pad, so that a pad's run does not depend on its batch); the other
fixed-step integrators keep 1e-8 s."""

from __future__ import annotations

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
