"""The error-controlled integrators on the general engine (CPU): ``controlled`` (strang's step with a per-pad step
from its error estimate) and ``auto`` (the DP5 pair while a pad slides, the split step once a patch sticks)."""

from __future__ import annotations

import numpy as np
import pytest
from aca_warp.kernels import hf_adaptive as KA
from procs import nine_patch_scene

from aca_warp.common.checkpoint import Checkpoint
from aca_warp.common.errors import SceneError
from aca_warp.hf.engine import EngineSetup, EngineTuning
from aca_warp.hf.general import GeneralEngine
from aca_warp.hf.loop import RunResult, run_hf
from aca_warp.hf.model import build_model
from aca_warp.hf.onchip_layout import choose_engine
from aca_warp.hf.options import RunOptions
from aca_warp.hf.state import initial_state
from aca_warp.scene import Scene

SAMPLE_DT = 1.0e-6  # s
STICK_OMEGA = 0.5  # rad/s: v_d = 0.065 m/s at r = 0.13 m, below the static slip: the patches stick and slip


def sliding(duration: float = 2.0e-5) -> Scene:
    """The 9-patch scene sliding at 10 m/s (no patch comes near the static branch)."""
    return nine_patch_scene(sample_dt=SAMPLE_DT, duration=duration)


def sticking(duration: float = 2.0e-5) -> Scene:
    """The 9-patch scene at v_d ≈ 0.065 m/s from a 0.05 m/s perturbation: patches stick."""
    return nine_patch_scene(sample_dt=SAMPLE_DT, duration=duration, angular_velocity=STICK_OMEGA)


def run(scene: Scene, **options) -> tuple[RunResult, np.ndarray]:
    """A run on the CPU (general engine, fp64): the result and μ at every sample."""
    model = build_model([scene], device="cpu", precision="fp64")
    res = run_hf(model, initial_state(model), RunOptions(engine="general", **options))
    assert res.complete
    return res, res.collect().globals[:, 0, 0]


def test_lands_on_samples_in_equal_steps():
    """Every accepted step divides the rest of its interval evenly (h = rest/⌈rest/want⌉), each interval ends on
    its sample time exactly, and once the step has settled the steps of an interval are equal (samples every 5 µs,
    several spring-bound steps each)."""
    dt = 5.0e-6
    scene = nine_patch_scene(sample_dt=dt, duration=15 * dt)
    model = build_model([scene], device="cpu", precision="fp64")
    state = initial_state(model)
    setup = EngineSetup(model, state, RunOptions(integrator="controlled"), scene.record, 15, EngineTuning(False))
    engine = GeneralEngine(setup)
    engine.begin(None)
    stepper = engine.stepper
    steps: dict[int, list[float]] = {}
    for _ in range(2000):
        before = stepper.ctl.numpy()[0].copy()
        stepper.body()
        after = stepper.ctl.numpy()[0]
        if after[KA.C_T] != before[KA.C_T]:  # accepted
            h = before[KA.C_TRIAL]
            rest = before[KA.C_TARGET] - before[KA.C_T]
            assert abs(rest / h - round(rest / h)) < 1e-6
            assert after[KA.C_T] == pytest.approx(before[KA.C_T] + h, rel=1e-12)
            k = round(before[KA.C_TARGET] / dt)
            steps.setdefault(k, []).append(h)
            if stepper.mode.numpy()[0, KA.M_LANDED]:
                assert after[KA.C_T] == before[KA.C_TARGET]
        if stepper.done.numpy()[0]:
            break
    assert sorted(steps) == list(range(1, 16))
    settled = [k for k in steps if k > 3]
    assert all(max(steps[k]) == pytest.approx(min(steps[k]), rel=1e-9) for k in settled)
    assert sum(len(steps[k]) for k in settled) > len(settled)  # more than one step in some: a real test of equality


def test_steps_grow_in_sliding_and_shrink_when_patches_stick():
    """In sliding the step grows to the largest allowed (min(sample interval, 0.9 × the spring bound)); where
    patches stick the friction part of the error makes it about half as long (measured: 3.5e-7 against 6.8e-7 s
    on average, the start from 1e-9 s included)."""
    slide, _ = run(sliding(), integrator="controlled")
    stick, _ = run(sticking(), integrator="controlled")
    h_max = min(SAMPLE_DT, 0.9 * slide.estimate.spring)
    assert slide.dt > 0.6 * h_max
    assert stick.dt < 0.6 * slide.dt
    assert stick.steps > 1.6 * slide.steps


def test_agrees_with_strang_at_a_fine_step():
    """At a tight split tolerance controlled converges to strang's solution (both the forced damped midpoint).

    Bound: a step's scaled error is an rms over the pad's n patches, so a patch's velocity error per step is at
    most tol V √n (V = 10 m/s, the disc speed, every patch's velocity scale here); after N steps at most N tol V √n.
    μ = Σ F_N,i f(s_i) / F_N moves by at most max|f′(s)| per m/s of the patches' slip, where the slips stay within
    0.5 m/s of v_d = 10 m/s (the start is perturbed by 0.05 m/s); add strang's own error at 1e-9 s (≈ 1e-8 in μ)."""
    tol = 1.0e-6
    scene = sliding()
    res, mu = run(scene, integrator="controlled", split_tolerance=tol)
    _, mu_ref = run(scene, integrator="strang", dt=1.0e-9)
    v_scale, n = 10.0, scene.patches.count
    s = np.linspace(v_scale - 0.5, v_scale + 0.5, 1001)
    slope = np.max(np.abs(np.gradient(scene.friction.coefficient(s), s)))
    bound = slope * res.steps * tol * v_scale * np.sqrt(n) + 1e-7
    err = np.max(np.abs(mu - mu_ref))
    assert err < bound  # measured 2.4e-6 in 271 steps
    loose, mu_loose = run(scene, integrator="controlled")  # the default tolerance is visibly coarser (2.8e-4)
    assert np.max(np.abs(mu_loose - mu_ref)) > 10 * err
    assert loose.steps < res.steps


@pytest.mark.parametrize(
    "options",
    [{"split_tolerance": 0.0}, {"split_tolerance": -1e-2}, {"split_tolerance": float("nan")}, {"tolerance": 0.0}],
)
def test_bad_tolerance_is_refused(options):
    with pytest.raises(SceneError, match="tolerance must be a positive number"):
        RunOptions(integrator="controlled", **options)


@pytest.mark.parametrize(
    ("integrator", "flag"),
    [("strang", "--split-tolerance"), ("controlled", "--tolerance"), ("adaptive", "--split-tolerance")],
)
def test_cli_refuses_a_tolerance_the_integrator_has_not(integrator, flag, tmp_path, capsys):
    from aca_warp.cli import main

    out = tmp_path / "r.h5"
    assert main(["hf", "hf1", "-o", str(out), "--integrator", integrator, flag, "1e-3", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and flag in err[0]
    assert not out.exists()


def test_auto_is_adaptive_while_sliding():
    """No patch reaches the static branch: auto steps every pad with the pair, sample for sample as adaptive."""
    a, mu_a = run(sliding(), integrator="adaptive")
    b, mu_b = run(sliding(), integrator="auto")
    np.testing.assert_array_equal(mu_a, mu_b)
    assert (a.steps, a.rejected) == (b.steps, b.rejected)


def test_auto_switches_to_the_split_step_once_patches_stick():
    """With sticking patches auto moves the pad to the split step (the mode flag of its checkpoint), takes far
    fewer steps than the pair alone, and its μ follows controlled's within the split tolerance's reach."""
    ckpts: list[Checkpoint] = []
    model = build_model([sticking()], device="cpu", precision="fp64")
    opts = RunOptions(engine="general", integrator="auto", checkpoint_interval=1e-5)
    res = run_hf(model, initial_state(model), opts, on_checkpoint=ckpts.append)
    assert res.complete and ckpts
    assert ckpts[0].arrays["adaptive/mode"][0, KA.M_SPLIT] == 1
    pair, _ = run(sticking(), integrator="adaptive")
    assert res.steps + res.rejected < 0.5 * (pair.steps + pair.rejected)


@pytest.mark.parametrize("integrator", ["controlled", "auto"])
@pytest.mark.parametrize("scene", ["sticking", "growing"])
def test_checkpoint_resume_bit_identical(integrator, scene):
    """Resuming from a checkpoint (clocks, the controller's step history, the spring forces of the last two steps,
    the mode and calm count) gives the uninterrupted run's samples, counters and final state bit for bit; on a
    growing scene too (the spring forces re-evaluated at every event)."""
    if scene == "growing":
        s = nine_patch_scene(increment=1e-6, interval=7e-7, sample_dt=SAMPLE_DT, duration=1e-5)
    else:
        s = sticking(1e-5)
    opts = RunOptions(engine="general", integrator=integrator, checkpoint_interval=3e-6)
    model = build_model([s], device="cpu", precision="fp64")
    state = initial_state(model)
    ckpts: list[Checkpoint] = []
    full = run_hf(model, state, opts, on_checkpoint=ckpts.append)
    assert full.complete and len(ckpts) == 3
    ck = ckpts[1]
    assert "adaptive/force_prev" in ck.arrays
    again = build_model([s], device="cpu", precision="fp64")
    state2 = initial_state(again)
    rest = run_hf(again, state2, opts, resume=ck)
    a, b = full.collect(), rest.collect()
    k = len(a.time) - len(b.time)
    np.testing.assert_array_equal(a.globals[k:], b.globals)
    np.testing.assert_array_equal(state.u.numpy(), state2.u.numpy())
    np.testing.assert_array_equal(state.v.numpy(), state2.v.numpy())
    assert (full.steps, full.rejected) == (rest.steps, rest.rejected)


@pytest.mark.parametrize("integrator", ["controlled", "auto"])
def test_general_engine_only(integrator):
    """The on-chip engine implements neither: auto picks the general engine, onchip is refused in one line."""
    model = build_model([sliding()], device="cpu", precision="fp64")
    assert choose_engine(model, "auto", integrator) == "general"
    with pytest.raises(SceneError, match="strang and adaptive integrators only"):
        choose_engine(model, "onchip", integrator)


def test_auto_on_hf1_is_adaptive_pointwise():
    """hf1 from its default start slides: auto's μ(t) is adaptive's, sample for sample (the README's main job)."""
    from aca_warp.scene.files import preset

    scene = preset("hf1")
    a, mu_a = run(scene, integrator="adaptive", duration=5e-5)
    b, mu_b = run(scene, integrator="auto", duration=5e-5)
    np.testing.assert_array_equal(mu_a, mu_b)
    assert a.steps == b.steps
