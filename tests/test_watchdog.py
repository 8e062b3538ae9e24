"""The device watchdog of HF runs: non-finite values and runaway patch energies are flagged by the recording
kernel (inside the captured graph) and reported at chunk ends with time, pad, patch and likely cause."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from aca_warp.common.errors import SimulationFault
from aca_warp.hf.loop import EngineTuning, run_hf
from aca_warp.hf.model import build_model
from aca_warp.hf.options import WATCHDOG_FACTOR, RunOptions
from aca_warp.hf.recorder import watchdog_bound
from aca_warp.hf.solver import stable_step
from aca_warp.hf.state import initial_state
from aca_warp.scene import Friction, Initial, Pad, Patches, Record, Scene


def grid(n: int = 16, spacing: float = 1.2e-3) -> Patches:
    """``n`` patches of 0.02–0.08 mm² on a square grid around (0, 0.13 m), all coupled."""
    side = math.ceil(math.sqrt(n))
    ij = np.array([divmod(a, side) for a in range(n)], dtype=float)
    area = np.random.default_rng(1).uniform(2e-8, 8e-8, n)
    return Patches((ij[:, 1] - side / 2) * spacing, 0.13 + (ij[:, 0] - side / 2) * spacing, area, np.full(n, 3e-6))


def scene(**kw) -> Scene:
    kw.setdefault("initial", Initial(perturbation=1e-3, seed=3))
    return Scene(name="watch", pad=Pad(), patches=grid(), normal_force=50.0, record=Record(sample_dt=1e-7), **kw)


def test_bound_formula():
    """bound = 100 (max ω r + 3 max F_N M/√(k_T m) + 3 √(2E₀/m_min)) per pad, E₀ the initial kinetic and spring
    energy; a pad that nothing drives (no load, disc at rest, no initial energy) gets +inf."""
    s = scene()
    model = build_model([s, s.replace(normal_force=0.0, angular_velocity=0.0, initial=Initial())])
    state = initial_state(model)
    b = watchdog_bound(model, state)
    n = s.patches.count
    m = 1.0 / model.host("inv_mass")[:n]
    k = model.host("k_t")[:n]
    fn = model.host("normal_force")[:n]
    v0 = state.numpy()[1][:n]
    e0 = 0.5 * np.sum(m * v0**2)
    want = WATCHDOG_FACTOR * (
        np.max(s.angular_velocity * model.host("radius")[:n])
        + 3 * np.max(fn * s.friction.M / np.sqrt(k * m))
        + 3 * math.sqrt(2 * e0 / m.min())
    )
    assert b[0] == pytest.approx(want, rel=1e-12)
    assert b[1] == math.inf


def test_bounded_run_stays_far_below_the_bound():
    """A sliding pad in its limit cycle (strang, 20 µs) never comes near the bound: max |u̇| < bound/20."""
    s = scene()
    model = build_model([s])
    state = initial_state(model)
    bound = watchdog_bound(model, state)[0]
    res = run_hf(model, state, RunOptions(duration=2e-5), record=Record(sample_dt=1e-7, patches=("velocity",)))
    assert res.complete and res.fault is None
    assert np.max(np.abs(res.collect().velocity)) < bound / 20


def test_runaway_is_caught_before_it_turns_non_finite():
    """Strang forced to 3× the spring limit (M = 0: nothing damps the spring instability): the watchdog stops the
    run on a finite but diverging state, earlier than the non-finite check alone, naming time, pad, patch, the
    energy speed against the bound and the step against the estimate; the kept samples are all finite."""
    s = scene(friction=Friction(M=0.0))
    model = build_model([s])
    dt = 3.0 * stable_step(model).spring
    rec = Record(sample_dt=10 * dt, patches=("velocity",))
    options = RunOptions(duration=20000 * dt, integrator="strang", dt=dt, force=True)
    kw = dict(record=rec, tuning=EngineTuning(max_graph_steps=32))
    res = run_hf(model, initial_state(model), options, **kw)
    f = res.fault
    assert isinstance(f, SimulationFault) and not res.complete
    assert str(f).startswith("diverging state (patch energy speed")
    assert "beyond the watchdog bound" in str(f) and "beyond the stable estimate" in f.cause
    assert f.pad == 0 and 0 <= f.patch < s.patches.count and 0 < f.time < 20000 * dt
    c = res.collect()
    assert np.all(np.isfinite(c.globals)) and np.all(np.isfinite(c.velocity)) and np.all(c.time < f.time)
    late = run_hf(model, initial_state(model), dataclasses.replace(options, watchdog_factor=None), **kw)
    assert late.fault is not None and str(late.fault).startswith("non-finite state")
    assert late.fault.time > f.time
