"""Small defects, each fixed with its test: checkpoints written once each, the stable step checked as the run takes
it, the pad count of a too-large sweep printed exactly. (The others of the list live with their topic: the
state after a fault in test_hf_numerics.py, a folder as patch file in test_limits.py, two sweeps into one folder
and a resume with HDF5 file locking off in test_output_lock.py.)"""

from __future__ import annotations

import numpy as np
import pytest

from aca_warp.common.errors import StabilityError
from aca_warp.hf.loop import run_hf
from aca_warp.hf.model import build_model
from aca_warp.hf.options import RunOptions
from aca_warp.hf.solver import fitted_step, stable_step
from aca_warp.hf.state import initial_state
from aca_warp.scene import Friction, PatchGenerator, Record, load_scene
from aca_warp.sweep import SweepError, load_spec


def tiny_scene(sample_dt: float):
    s = load_scene("hf1")
    return s.replace(
        patches=PatchGenerator(count=20, seed=3).generate(s.pad), record=Record(sample_dt=sample_dt), duration=1e-3
    )


@pytest.mark.parametrize(("interval", "sample_dt", "duration"), [(1e-4, 1e-6, 2e-3), (1e-6, 1e-7, 1e-5)])
def test_each_checkpoint_once(interval, sample_dt, duration) -> None:
    """One checkpoint per multiple of the interval before the end (was: 29 instead of 19 for 1e-4 over 2 ms, the
    time 9.999999999999999e-05 counting as below 1e-4 and the next one set to 1e-4 again)."""
    s = tiny_scene(sample_dt)
    model = build_model([s])
    seen: list[float] = []
    run_hf(
        model,
        initial_state(model),
        RunOptions(duration=duration, checkpoint_interval=interval),
        on_checkpoint=lambda c: seen.append(c.sim_time),
    )
    expected = np.arange(1, round(duration / interval)) * interval
    assert len(seen) == len(expected) and np.allclose(seen, expected, rtol=1e-9)


def test_stable_step_checked_as_taken() -> None:
    """A requested dt above the spring limit whose sample interval makes the run take a step below it runs (the
    step is shortened so that whole steps fit a sample interval); the same dt with a sample interval that keeps it
    is refused, naming the step taken."""
    s = tiny_scene(1e-7).replace(friction=Friction(M=0.0))
    model = build_model([s])
    spring = stable_step(model).spring
    dt = 1.5 * spring
    taken = fitted_step(dt, 0.5 * spring)
    assert taken == 0.5 * spring
    res = run_hf(
        model,
        initial_state(model),
        RunOptions(integrator="strang", duration=20 * spring, dt=dt),
        record=Record(0.5 * spring),
    )
    assert res.complete and res.dt == taken
    with pytest.raises(StabilityError, match=f"dt = {dt:.3g} s exceeds the stable-step estimate"):
        run_hf(
            model,
            initial_state(model),
            RunOptions(integrator="strang", duration=20 * dt, dt=dt),
            record=Record(sample_dt=2 * dt),
        )


def test_sweep_pad_count_printed_exactly() -> None:
    doc = {
        "sweep": {"base": "hf1"},
        "parameters": {"friction.M": {"linspace": [0.5, 0.9, 1001]}, "patches.seed": {"range": [0, 1000]}},
    }
    with pytest.raises(SweepError, match=r"combine into 1001000 pads, more than a sweep runs \(1000000\)"):
        load_spec(doc)
