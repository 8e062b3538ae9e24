"""The adaptive integrator on growing scenes (CPU): growth events at their simulated times j·interval, on which
every pad lands; the areas after the run, μ(t) against a piecewise SciPy reference and strang, the order of an
event and a sample at the same time, checkpoint and resume."""

from __future__ import annotations

import numpy as np
import pytest
from procs import nine_patch_scene

from aca_warp.common.checkpoint import Checkpoint
from aca_warp.hf.general import Growth
from aca_warp.hf.loop import EngineTuning, RunResult, run_hf
from aca_warp.hf.model import PadModel, build_model
from aca_warp.hf.onchip_layout import unsupported
from aca_warp.hf.options import RunOptions
from aca_warp.hf.reference import ReferenceODE
from aca_warp.hf.solver import GROWTH_MUTABLE
from aca_warp.hf.state import initial_state
from aca_warp.scene import Scene

SAMPLE_DT = 1.0e-6  # s
INCREMENT = 1.0e-6  # m: ΔA = 1e-6 m · √A per event, ≈ 0.5 % of an HF1 patch's area (1000× Eq. 10)


def growing_scene(interval: float, duration: float = 1.0e-5) -> Scene:
    """The 9-patch scene growing by INCREMENT · √A every ``interval`` [s], sampled every SAMPLE_DT."""
    return nine_patch_scene(increment=INCREMENT, interval=interval, sample_dt=SAMPLE_DT, duration=duration)


def run(scene: Scene, precision: str = "fp64", **options) -> tuple[RunResult, PadModel, np.ndarray]:
    """A run of ``scene`` on the CPU: the result, the model after it and μ at every sample."""
    model = build_model([scene], device="cpu", precision=precision)
    res = run_hf(model, initial_state(model), RunOptions(engine="general", **options))
    assert res.complete
    return res, model, res.collect().globals[:, 0, 0]


def eq10_areas(area: np.ndarray, events: int) -> np.ndarray:
    """The areas after ``events`` events of Eq. 10, A ← A + g √A [m²] (NumPy, float64)."""
    a = area.astype(np.float64)
    for _ in range(events):
        a = a + INCREMENT * np.sqrt(a)
    return a


def piecewise_reference(scene: Scene, duration: float) -> tuple[np.ndarray, np.ndarray]:
    """μ at every sample time from SciPy (DOP853, rtol 1e-12) integrated between the event times, each event
    applied by the model's growth launches; returns (μ after the events at a sample time, μ before them)."""
    grown = build_model([scene], device="cpu", precision="fp64")
    still = build_model([scene.replace(growth=None)], device="cpu", precision="fp64")
    event = Growth(grown, scene.growth.interval)  # a step of one interval: an event at every launch
    state = initial_state(grown)
    u, v = state.u.numpy().astype(np.float64), state.v.numpy().astype(np.float64)
    interval = scene.growth.interval
    marks = {k * SAMPLE_DT: {"sample"} for k in range(round(duration / SAMPLE_DT) + 1)}
    for j in range(1, int(duration / interval + 1e-9) + 1):
        te, ts = j * interval, round(j * interval / SAMPLE_DT) * SAMPLE_DT
        marks.setdefault(ts if abs(ts - te) <= 1e-9 * min(SAMPLE_DT, interval) else te, set()).add("event")
    after, before = [], []
    now = 0.0
    for t in sorted(marks):
        if t > now:
            sol = ReferenceODE(still).solve(np.array([t - now]), method="DOP853", rtol=1e-12, u0=u, v0=v)
            u, v, now = sol.u[-1], sol.v[-1], t
        mu_before = ReferenceODE(still).globals(u[None], v[None])["mu"][0]
        if "event" in marks[t]:
            event.launch()
            for name in GROWTH_MUTABLE:
                if name in still.arrays:  # (not the contact solve's warm start, pad_gap)
                    still.arrays[name].assign(grown.arrays[name])
        if "sample" in marks[t]:
            before.append(mu_before)
            after.append(ReferenceODE(still).globals(u[None], v[None])["mu"][0])
    return np.array(after), np.array(before)


@pytest.mark.parametrize("precision", ["fp64", "fp32"])
@pytest.mark.parametrize("interval", [2.0e-6, 2.5e-6, 3.3e-7])
def test_areas_follow_the_events(interval, precision):
    """Every event at j·interval up to the end (t = 10 µs included) adds g √A once (Eq. 10, unscaled): the areas
    equal the NumPy sum of the events and strang's areas at dt = 1e-8 s (a step that divides every interval here,
    so its events fall on the same times; the areas do not depend on the motion)."""
    s = growing_scene(interval)
    tol = 1e-9 if precision == "fp64" else 1e-5
    res, model, _ = run(s, precision, integrator="adaptive", tolerance=tol)
    events = int(1.0e-5 / interval + 1e-9)
    rtol = 1e-12 if precision == "fp64" else 1e-6
    np.testing.assert_allclose(model.host("area"), eq10_areas(s.patches.area, events), rtol=rtol)
    _, strang, _ = run(s, precision, integrator="strang", dt=1e-8)
    np.testing.assert_allclose(model.host("area"), strang.host("area"), rtol=rtol)
    np.testing.assert_allclose(model.host("normal_force"), strang.host("normal_force"), rtol=10 * rtol)
    # at least one trial per event interval and per sample interval
    assert res.steps >= events + 10


def test_mu_matches_piecewise_reference_and_strang():
    """μ(t) at tol 1e-9 against SciPy integrated between the events (interval 2.5 µs: events between samples and
    on them) and against strang at 1e-9 s; a sample at an event time sees the grown patches (the fixed-step order:
    growth after the step, the sample after it)."""
    s = growing_scene(2.5e-6)
    ref_after, ref_before = piecewise_reference(s, 1.0e-5)
    _, _, mu = run(s, integrator="adaptive", tolerance=1e-9)
    _, _, mu_strang = run(s, integrator="strang", dt=1e-9)
    assert mu.shape == ref_after.shape == (11,)
    np.testing.assert_allclose(mu, ref_after, rtol=0, atol=1e-10)  # measured 1.6e-12
    np.testing.assert_allclose(mu_strang, ref_after, rtol=0, atol=5e-8)  # strang: 1.2e-8 at 1e-9 s, 2.3e-8 at 2e-9 s
    # the events at 5 and 10 µs move μ by far more than the tolerance: the order is seen
    coincide = [5, 10]
    assert np.all(np.abs(ref_after[coincide] - ref_before[coincide]) > 1e-5)
    np.testing.assert_allclose(mu[coincide], ref_after[coincide], rtol=0, atol=1e-10)


@pytest.mark.parametrize("engine", ["general", "onchip"])
@pytest.mark.parametrize("precision", ["fp64", "fp32"])
def test_checkpoint_resume_bit_identical(precision, engine):
    """Resuming from a checkpoint between events (areas, stiffnesses, contact, clocks, event index and, on the
    general engine, flag) gives the uninterrupted run's samples and final areas bit for bit, on both engines."""
    s = growing_scene(7.0e-7)
    tol = 1e-8 if precision == "fp64" else 1e-5
    opts = RunOptions(engine=engine, integrator="adaptive", tolerance=tol, checkpoint_interval=3e-6)
    model = build_model([s], device="cpu", precision=precision)
    ckpts: list[Checkpoint] = []
    tuning = EngineTuning(samples_per_launch=2) if engine == "onchip" else EngineTuning()
    full = run_hf(model, initial_state(model), opts, on_checkpoint=ckpts.append, tuning=tuning)
    assert full.complete and len(ckpts) == 3
    ck = ckpts[1]
    assert "adaptive/mode" in ck.arrays and "model/area" in ck.arrays
    assert ("growth/event" in ck.arrays) == (engine == "general")
    again = build_model([s], device="cpu", precision=precision)
    rest = run_hf(again, initial_state(again), opts, resume=ck, tuning=tuning)
    a, b = full.collect(), rest.collect()
    k = len(a.time) - len(b.time)
    assert k == int(ck.counters["samples"]) + 1
    np.testing.assert_array_equal(a.time[k:], b.time)
    np.testing.assert_array_equal(a.globals[k:], b.globals)
    for name in ("area", "normal_force", "k_diag", "pad_gap"):
        np.testing.assert_array_equal(model.host(name), again.host(name))
    assert (full.steps, full.rejected) == (rest.steps, rest.rejected)


@pytest.mark.parametrize("engine", ["general", "onchip"])
def test_a_pause_at_an_event_changes_nothing(engine):
    """Checkpoints every 2 µs pause the run on samples that are also event times (every 0.5 µs): the run equals the
    one without pauses, bit for bit (the first stage after the event is evaluated with the grown model even when the
    pad waited at the pause, not kept from before it)."""
    s = growing_scene(5.0e-7)
    runs = []
    for interval in (0.0, 2.0e-6):
        model = build_model([s], device="cpu", precision="fp64")
        opts = RunOptions(engine=engine, integrator="adaptive", tolerance=1e-8, checkpoint_interval=interval)
        res = run_hf(model, initial_state(model), opts, on_checkpoint=lambda c: None)
        assert res.complete and res.checkpoints == (4 if interval else 0)
        runs.append(res.collect().globals)
    np.testing.assert_array_equal(runs[1], runs[0])


@pytest.mark.parametrize("precision", ["fp64", "fp32"])
@pytest.mark.parametrize(("interval", "sample_dt"), [(1.5e-6, 1e-6), (1e-6, 3e-6), (1e-6, 1e-6)])
def test_onchip_engine_grows_bit_identical_to_general(interval, sample_dt, precision):
    """The on-chip kernel lands on the growth events and grows its pad itself: on the CPU every sample, the grown
    model (areas, stiffnesses, normal forces, contact gap) and the step counts equal the general engine's, bit for
    bit, with events between samples, samples between events and both at once, across launches."""
    s = nine_patch_scene(increment=2e-5, interval=interval, sample_dt=sample_dt, duration=2e-5)
    runs = []
    for engine, tuning in (("general", EngineTuning()), ("onchip", EngineTuning(samples_per_launch=3))):
        model = build_model([s], device="cpu", precision=precision)
        assert unsupported(model, "adaptive") is None
        state = initial_state(model)
        opts = RunOptions(engine=engine, integrator="adaptive", tolerance=1e-5)
        res = run_hf(model, state, opts, tuning=tuning)
        assert res.complete and ("growth" in res.stages)
        runs.append((res, model, state))
    (rg, mg, sg), (ro, mo, so) = runs
    assert "step:adaptive:onchip" in ro.stages
    np.testing.assert_array_equal(ro.collect().globals, rg.collect().globals)
    for name in ("area", "sqrt_area", "k_t", "k_diag", "nbr_stiffness", "normal_force", "damping", "pad_gap"):
        np.testing.assert_array_equal(mo.host(name), mg.host(name), err_msg=name)
    np.testing.assert_array_equal(so.u.numpy(), sg.u.numpy())
    np.testing.assert_array_equal(so.v.numpy(), sg.v.numpy())
    assert (ro.steps, ro.rejected) == (rg.steps, rg.rejected)
    fresh = build_model([s], device="cpu", precision=precision)
    assert np.all(mo.host("area") > fresh.host("area") * 1.01)  # the events happened: not a comparison at rest
    assert np.any(mo.host("normal_force") != fresh.host("normal_force"))


def test_script_table(capsys):
    """``scripts/adaptive_growth.py`` on the varying_area preset's first 2 µs: one row per run, strang against
    itself 0, the tightest adaptive run against itself 0; adaptive lands on 9 events and 2 samples."""
    from scriptload import load_script

    assert load_script("adaptive_growth").main(["--duration", "2e-6", "--tols", "1e-5"]) == 0
    rows = [r.split("|")[1:-1] for r in capsys.readouterr().out.splitlines() if r.startswith("| ") and "run" not in r]
    assert [r[0].strip() for r in rows] == ["strang 1e-08 s", "adaptive tol 1e-05"]
    assert [r[1].strip() for r in rows] == ["onchip", "onchip"]  # auto on the CPU
    assert float(rows[0][8]) == 0.0 and float(rows[1][9]) == 0.0
    assert int(rows[1][3]) >= 11 and int(rows[1][3]) > int(rows[1][5])  # ≥ one trial per target; fewer without
