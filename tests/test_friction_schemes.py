"""The friction sub-step prototype (aca_warp.studies.friction_schemes, friction_analysis, friction_control): the
L-stable sub-steps hold a sticking patch at hγ = 1000 where implicit midpoint chatters, the split schemes are of
second order on a smooth case, the closed-form stability functions match the nonlinear sub-steps in the linear
range, and the prototype's strang and DP5 reproduce the package's kernels."""

from __future__ import annotations

import numpy as np
import pytest

from aca_warp.studies import friction_analysis as fa
from aca_warp.studies import friction_schemes as fs


@pytest.fixture(scope="module")
def sector() -> fs.Pads:
    from aca_warp.studies.friction_stats import sector_scenes

    return fs.load_pads(sector_scenes(1, 40))


@pytest.fixture(scope="module")
def patch(sector: fs.Pads) -> fs.Pads:
    return fa.isolated(sector, int(np.argsort(sector.m)[sector.n // 2]))


@pytest.mark.parametrize("method", ["be", "sdirk2", "trbdf2", "sub4"])
def test_l_stable_substep_holds_a_sticking_patch(patch: fs.Pads, method: str) -> None:
    r = fa.hold(patch, method, 1000.0)
    dev = np.abs(np.array(r["slips"]) - r["static_slip"]) / r["static_slip"]
    assert dev[1:].max() < 1e-2, dev  # on the static slip from the second step on
    assert np.all(np.array(r["slips"]) > 0.0)  # the slip never changes sign


def test_midpoint_chatters_at_large_hgamma(patch: fs.Pads) -> None:
    r = fa.hold(patch, "mid", 1000.0)
    s = np.array(r["slips"])
    assert np.abs(s - r["static_slip"]).min() > 0.3 * r["static_slip"]  # never settles
    assert np.all(np.diff(np.sign(s - r["static_slip"])) != 0)  # alternates about it every step


@pytest.mark.parametrize("method", fs.METHODS)
def test_stability_function_matches_the_substep(patch: fs.Pads, method: str) -> None:
    """In the linear range of Eq. 4 (slip ≪ 1/slope) and with F = c v_d (static slip 0) one sub-step multiplies the
    slip by R(−hγ) of the closed form."""
    gamma = float(patch.gamma_max()[0])
    for hg in (0.5, 3.0, 30.0):
        h = hg / gamma
        v = patch.vd - 1e-7
        v1 = fs.substep(patch, method, v, h, patch.c * patch.vd, np.zeros(1))
        ratio = float((patch.vd - v1)[0] / 1e-7)
        assert ratio == pytest.approx(fs.stability_function(method, -hg).real, abs=2e-3), (hg, ratio)


@pytest.mark.parametrize(("name", "order"), [("forced-sdirk2", 2.0), ("forced-trbdf2", 2.0), ("strang-mid", 2.0),
                                             ("forced-be", 1.0)])  # fmt: skip
def test_order_on_a_smooth_case(patch: fs.Pads, name: str, order: float) -> None:
    """An isolated patch sliding at the disc speed (no sticking): the velocity error against Radau at rtol 1e-11
    falls by 2^order per halving of the step (forced-be tends to order 1 from above)."""
    p = fa.isolated(patch, 0)
    p.v0[:] = 0.0
    ref = fa.cycle_reference(p, 1e-5, 1e-6)
    errs = []
    for h in (5e-8, 2.5e-8, 1.25e-8):
        r = fa.limit_cycle(p, fs.Scheme.parse(name), h, 1e-5)
        errs.append(np.abs(r["v"][:: round(1e-6 / h)] - ref["v"]).max())
    observed = np.log2(errs[1] / errs[2])
    assert abs(observed - order) < 0.3 if order == 2.0 else observed < 1.6, (errs, observed)


@pytest.mark.parametrize("dt", [2e-8, 5e-7])
def test_prototype_forced_thmid_is_the_package_strang(dt: float) -> None:
    """The kernels' strang is the prototype's forced damped midpoint, at a small step (θ = 1/2 everywhere) and at
    5e-7 s (h γ up to ≈ 20: θ > 1/2 on the stiffest patches)."""
    from aca_warp.scene import Record
    from aca_warp.studies.friction_stats import sector_scenes
    from aca_warp.studies.runs import batch_at_start, run_general

    scenes = sector_scenes(2, 40)
    pads = fs.load_pads(scenes)
    r = fs.run_fixed(pads, fs.Scheme.parse("forced-thmid"), dt, 2e-5, 1e-6, sample="step")
    model, state = batch_at_start(scenes, "cpu", "fp64")
    res = run_general(model, state, duration=2e-5, integrator="strang", dt=dt, record=Record(sample_dt=1e-6))
    g = res.collect().globals
    assert np.abs(g[:, :, 0] - r["record"].mu).max() < 1e-12
    assert np.abs(g[:, :, 4] - r["record"].sum_abs_velocity).max() < 1e-10


def test_prototype_dp5_is_the_package_adaptive(sector: fs.Pads) -> None:
    from aca_warp.scene import Record
    from aca_warp.studies.friction_control import Composite
    from aca_warp.studies.friction_stats import sector_scenes
    from aca_warp.studies.runs import batch_at_start, run_general

    scenes = sector_scenes(1, 40)
    c = Composite(fs.load_pads(scenes), tol_e=1e-5, tol_i=1e-3, modes="E")
    rec = c.run(2e-5)
    model, state = batch_at_start(scenes, "cpu", "fp64")
    res = run_general(model, state, duration=2e-5, integrator="adaptive", tolerance=1e-5, record=Record(sample_dt=1e-6))
    assert c.counts.accepted["E"] == res.steps
    assert np.abs(res.collect().globals[:, 0, 0] - rec.mu[:, 0]).max() < 1e-12


def test_composite_switches_to_the_implicit_mode_when_patches_stick(sector: fs.Pads) -> None:
    """Patches started with the disc (on the static branch) make the pad leave the explicit pair at the first
    sample; it stays in the implicit mode while they hold."""
    from aca_warp.studies.friction_control import Composite

    p = fs.Pads(**{**sector.__dict__, "v0": sector.vd.copy()})
    c = Composite(p, tol_e=1e-5, tol_i=1e-3)
    c.run(3e-5)
    assert c.counts.switches >= 1 and c.counts.accepted["I"] > 0
    assert np.all(np.isfinite(c.counts.time["I"]))


def test_solve_breaks_the_newton_two_cycle(sector: fs.Pads) -> None:
    """On CYCLE_CASE the kernels' Newton (no step-halving rule) cycles inside its bracket for all 60 iterations;
    with the rule the solve converges to the root."""
    c = fs.CYCLE_CASE
    p = fs.Pads(**{**sector.__dict__, "vd": np.array([c["vd"]])})
    args = (np.array([c["a"]]), np.array([c["b"]]), np.array([c["hfn"]]), np.array([c["guess"]]))

    def residual(v: np.ndarray) -> float:
        return float(abs(c["a"] * v[0] - c["hfn"] * fs.friction(p, p.vd - v)[0] - c["b"]) / c["b"])

    ev = np.zeros(1)
    assert residual(fs.solve(p, *args, ev)) < 1e-12 and ev[0] < 20
    ev = np.zeros(1)
    assert residual(fs.solve(p, *args, ev, halving=False)) > 1e-3 and ev[0] == 60


def test_damped_midpoint(patch: fs.Pads) -> None:
    """thmid is the midpoint while hγ ≤ 6 and halves a held patch's deviation each step beyond (midpoint: ±0.8 s*)."""
    for hg in (1.0, 4.0):
        assert fa.hold(patch, "thmid", hg)["slips"] == pytest.approx(fa.hold(patch, "mid", hg)["slips"], rel=1e-12)
    for method, lo, hi in (("thmid", 0.4, 0.6), ("mid", 0.95, 1.01)):
        r = fa.hold(patch, method, 1000.0)
        dev = np.abs(np.array(r["slips"]) - r["static_slip"])
        assert np.all((dev[1:] / dev[:-1] > lo) & (dev[1:] / dev[:-1] < hi)), (method, dev)


def test_even_steps_land_on_the_sample() -> None:
    from aca_warp.studies.friction_control import even_step

    h = even_step(3e-7, 0.0, 1e-6)
    assert h == pytest.approx(2.5e-7) and even_step(1e-6, 2e-7, 1e-6) == pytest.approx(8e-7)
    assert even_step(5e-7, 0.0, 1e-6) == pytest.approx(5e-7)


def test_run_fixed_refuses_an_unknown_sample(sector: fs.Pads) -> None:
    """``run_fixed``'s ``sample`` is "close" or "step"; anything else is refused, not read as "close"."""
    with pytest.raises(ValueError, match="sample must be"):
        fs.run_fixed(sector, fs.Scheme.parse("forced-thmid"), 1e-7, 1e-6, 1e-6, sample="steps")
