"""The friction sub-step of the kernels (kernels/physics.py, docs/friction_step.md §6): the per-patch solve's
step-halving safeguard, the damped midpoint on a held patch, and strang bounded at 0.95 × the exact spring bound of
an hf1 sector. The held case (M = 100) is in tests/test_sanity.py, the sub-step's equation against brentq and the
second order of strang in tests/test_hf_numerics.py, general against on-chip in tests/test_onchip.py."""

from __future__ import annotations

import math

import numpy as np
import pytest
import warp as wp
from aca_warp.kernels.physics import (
    friction_coefficient,
    friction_pair,
    friction_substep,
    solve_velocity,
    strang_sample_velocity,
)
from scipy.optimize import brentq

from aca_warp.hf.loop import EngineTuning, run_hf
from aca_warp.hf.options import RunOptions
from aca_warp.scene import Record
from aca_warp.studies import friction_schemes as fs

# hf1's Eq. 4 (M, slope a, decay b)
M, SLOPE, DECAY = 0.8, 200.0, 0.25


def eq4(s: float) -> float:
    return M / math.pi * math.atan(SLOPE * s) * (1.0 / (DECAY * abs(s) + 1.0) + 1.0)


@wp.kernel(enable_backward=False, module="unique")
def _solve_kernel(p: wp.array(dtype=wp.float64), mu_scale: wp.float64, out: wp.array(dtype=wp.float64)):
    out[0] = solve_velocity(
        p[0],
        p[1],
        p[2],
        p[3],
        p[4],
        mu_scale,
        wp.float64(SLOPE),
        wp.float64(DECAY),
        wp.float64(1e-9),
        0,
        wp.float64(0.0),
        wp.float64(0.0),
        0,  # no pair known at the guess: the solve evaluates its own
        wp.float64(0.0),
        wp.float64(0.0),
    )


def test_solve_breaks_the_newton_two_cycle() -> None:
    """On CYCLE_CASE (a solve of a saturated hf1 sector at 1e-6 s) Newton without the step-halving rule alternates
    between slips +0.053 and −0.0996 m/s inside its bracket for all 60 iterations and returns an iterate far from
    the root; solve_velocity with the rule returns the root."""
    c = fs.CYCLE_CASE
    r = c["b"] - c["a"] * c["guess"]  # solve_velocity takes b − a·guess
    p = wp.array([c["a"], r, c["hfn"], c["vd"], c["guess"]], dtype=wp.float64, device="cpu")
    out = wp.zeros(1, dtype=wp.float64, device="cpu")
    wp.launch(_solve_kernel, dim=1, inputs=[p, M / math.pi], outputs=[out], device="cpu")

    def g(v: float) -> float:
        return c["a"] * v - c["hfn"] * eq4(c["vd"] - v) - c["b"]

    root = brentq(g, c["vd"] - 1.0, c["vd"] + 1.0, xtol=1e-15, rtol=1e-15)
    scale = c["hfn"] * M / c["a"]  # the bracket's half width [m/s]
    assert abs(float(out.numpy()[0]) - root) < 1e-8 * scale


@wp.kernel(enable_backward=False, module="unique")
def _hold_kernel(v: wp.array(dtype=wp.float64), h: wp.float64, p: wp.array(dtype=wp.float64), mu_scale: wp.float64):
    for k in range(v.shape[0] - 1):
        v[k + 1] = friction_substep(
            v[k], h, p[0], p[1], p[2], p[3], p[4], mu_scale, wp.float64(SLOPE), wp.float64(DECAY), wp.float64(1e-12), 0
        )


def test_held_patch_chatter_halves_every_step() -> None:
    """A patch held under a frozen spring force −F_N M/2 (its static slip s*, where F + F_N f(s*) − c v = 0), started
    1 mm/s off s*: at h γ = 1000 the damped midpoint multiplies the deviation by −1/2 every step (the implicit
    midpoint: by ≈ −1, chatter without decay); at h γ = 1 it converges monotonically, as the midpoint does."""
    m, c, fn, vd = 37.5 * 5e-8, 1e-4, 1.0, 10.0
    force = -0.5 * fn * M
    static = brentq(lambda s: force + fn * eq4(s) - c * (vd - s), -0.1, 0.1, xtol=1e-16)
    gamma = (c + fn * 2.0 * M / math.pi * SLOPE) / m
    params = wp.array([m, c, fn, force, vd], dtype=wp.float64, device="cpu")
    for hg, lo, hi in ((1000.0, -0.6, -0.4), (1.0, 0.0, 1.0)):
        v = wp.array(np.full(8, vd - static - 1e-3), dtype=wp.float64, device="cpu")
        wp.launch(_hold_kernel, dim=1, inputs=[v, hg / gamma, params, M / math.pi], device="cpu")
        dev = (vd - v.numpy()) - static
        ratio = dev[1:] / dev[:-1]
        assert np.all((ratio > lo) & (ratio < hi)), (hg, ratio)


@pytest.fixture(scope="module")
def sector():
    """One 60-patch hf1 sector (the validation's reduced pad, seed 1) at equilibrium + 0.01 m/s, and its exact
    spring bound 2/ω_max [s] (largest eigenvalue of M⁻¹ᐟ² K M⁻¹ᐟ²)."""
    from aca_warp.studies.friction_stats import sector_scenes

    scenes = sector_scenes(1, 60)
    return scenes[0], 2.0 / fs.load_pads(scenes).omega_max()


def test_strang_bounded_at_the_spring_bound(sector) -> None:
    """strang at 0.95 × the exact spring bound (h γ up to ≈ 100 at zero slip, forced past the Gershgorin estimate)
    runs 3 ms of an hf1 sector bounded: no fault, |μ| ≤ M, every patch velocity within ±(v_d + 20 m/s)."""
    from aca_warp.studies.runs import batch_at_start

    scene, bound = sector
    model, state = batch_at_start([scene], "cpu", "fp64")
    h = 0.95 * bound
    rec = Record(sample_dt=100 * h, patches=("velocity",))
    opts = RunOptions(duration=1200 * h, integrator="strang", dt=h, force=True, engine="general")
    res = run_hf(model, state, opts, record=rec, tuning=EngineTuning(max_graph_steps=32))
    assert res.complete and res.fault is None
    out = res.collect()
    assert np.all(np.abs(out.globals[:, 0, 0]) <= M)
    vd = scene.angular_velocity * np.hypot(scene.patches.x, scene.patches.y)
    assert np.all(np.abs(out.velocity) < vd.max() + 20.0)


def _substep_kernel(T: type) -> wp.Kernel:
    @wp.kernel(enable_backward=False, module="unique")
    def k(
        v: wp.array(dtype=T), m: wp.array(dtype=T), c: wp.array(dtype=T), fn: wp.array(dtype=T),
        force: wp.array(dtype=T), vd: wp.array(dtype=T), h: T, tol: T, out: wp.array(dtype=T),
    ):  # fmt: skip
        i = wp.tid()
        out[i] = friction_substep(
            v[i], h, m[i], c[i], fn[i], force[i], vd[i], T(M / math.pi), T(SLOPE), T(DECAY), tol, 0
        )

    return k


def test_fp32_substep_keeps_the_damping() -> None:
    """The sub-step forms its solve's right-hand side by its terms, θh (F − c v): in fp32 at 5e-8 s, where θh c is
    below half an ulp of an hf1-like patch's mass, so that a = m + θh c rounds to m, the fp32 velocity increments
    still agree with fp64's on average to a small share of the damping's own increment θh c v/m (formed as b − a·v
    they were off by 0.8 of it: the damping lost)."""
    rng = np.random.default_rng(1)
    n = 20_000
    m = 37.5 * rng.uniform(2e-8, 8e-8, n)  # kg: hf1's mass per area [kg/m²] × patch areas [m²]
    c = 0.95 * m  # N s/m: hf1's c/m
    fn = rng.uniform(0.1, 0.5, n)  # N
    vd = np.full(n, 10.0)  # m/s
    v = vd - rng.uniform(0.02, 0.1, n)  # sliding a little slower than the disc
    force = -fn * M / math.pi * np.arctan(SLOPE * (vd - v)) * (1 / (DECAY * np.abs(vd - v) + 1) + 1) + c * v
    h = float(np.float32(5e-8))
    v, m, c, fn, force, vd = (x.astype(np.float32).astype(np.float64) for x in (v, m, c, fn, force, vd))
    assert np.all(np.float32(m) + np.float32(0.5 * h) * np.float32(c) == np.float32(m))  # a rounds to m in fp32
    increment = {}
    for T, npt, tol in ((wp.float32, np.float32, 1e-6), (wp.float64, np.float64, 1e-12)):
        arrays = [wp.array(x.astype(npt), dtype=T, device="cpu") for x in (v, m, c, fn, force, vd)]
        out = wp.zeros(n, dtype=T, device="cpu")
        wp.launch(_substep_kernel(T), dim=n, inputs=[*arrays, T(h), T(tol)], outputs=[out], device="cpu")
        increment[T] = out.numpy().astype(np.float64) - v
    damping = np.mean(h * c * v / m)  # m/s: the damping's share of an increment
    assert abs(np.mean(increment[wp.float32] - increment[wp.float64])) < 0.05 * damping


@pytest.mark.parametrize("crossing", [0, 1])
def test_a_sample_reads_the_friction_its_step_applies(crossing: int) -> None:
    """strang's sample (V, w⁺) from a staggered w: w⁺ is the merged sub-step's velocity (what the step drifts
    with), and its increment is the step's force at V, m (w⁺ − w) = h (F + F_N f(v_d − V) − c V), whatever θ:
    at small h γ (θ = 1/2) and on held patches far beyond it (θ → 1); with the crossing treatment the same where
    the slip keeps its sign."""

    @wp.kernel(enable_backward=False, module="unique")
    def sample(p: wp.array2d(dtype=wp.float64), h: wp.float64, out: wp.array2d(dtype=wp.float64)):
        i = wp.tid()
        w, m, c, fn, force, vd = p[i, 0], p[i, 1], p[i, 2], p[i, 3], p[i, 4], p[i, 5]
        mu_scale, slope, decay, tol = wp.float64(M / math.pi), wp.float64(SLOPE), wp.float64(DECAY), wp.float64(1e-13)
        im = wp.float64(1.0) / m
        v, w1 = strang_sample_velocity(w, force, h, im, c, fn, vd, mu_scale, slope, decay, tol, crossing)
        out[i, 0] = v
        out[i, 1] = w1
        # the merged step's sub-step (strang_velocity: the mass as 1/(1/m))
        out[i, 2] = friction_substep(
            w, h, wp.float64(1.0) / im, c, fn, force, vd, mu_scale, slope, decay, tol, crossing
        )
        out[i, 3] = friction_coefficient(vd - v, mu_scale, slope, decay)
        out[i, 4] = friction_substep(w, h, wp.float64(1.0) / im, c, fn, force, vd, mu_scale, slope, decay, tol, 0)

    rng = np.random.default_rng(7)
    n = 4000
    m = 37.5 * rng.uniform(2e-8, 8e-8, n)  # kg
    c = 0.95 * m
    fn = rng.uniform(0.1, 0.5, n)  # N
    vd = np.full(n, 10.0)
    w = vd - rng.choice([1e-4, 1e-2, 0.5], n) * rng.uniform(0.5, 1.0, n)  # slips of one sign: no crossing
    force = rng.uniform(-0.3, 0.3, n)  # N
    out = wp.zeros((n, 5), dtype=wp.float64, device="cpu")
    p = wp.array(np.stack([w, m, c, fn, force, vd], axis=1), dtype=wp.float64, device="cpu")
    thetas = []
    for h in (1e-9, 2.5e-7):
        wp.launch(sample, dim=n, inputs=[p, h], outputs=[out], device="cpu")
        v, w1, step, f, w1_point = out.numpy().T
        np.testing.assert_array_equal(w1, step)  # the very velocity the step drifts with
        keep = ((vd - w) * (vd - w1) > 0.0) & ((vd - w) * (vd - w1_point) > 0.0)  # no segment mean taken
        impulse = m * (w1 - w) - h * (force + fn * f - c * v)
        assert np.all(np.abs(impulse[keep]) <= 1e-9 * h * fn[keep] * M), np.abs(impulse[keep]).max()
        moved = keep & (np.abs(w1 - w) > 1e-9)
        thetas.append(((v - w)[moved] / (w1 - w)[moved]).max())  # V = w + θ (w⁺ − w)
    assert abs(thetas[0] - 0.5) < 1e-6 and thetas[1] > 0.55  # the midpoint, and the held patches' larger θ


@pytest.mark.parametrize("dtype", [wp.float32, wp.float64])
def test_a_known_pair_at_the_guess_gives_the_same_solve(dtype) -> None:
    """solve_velocity with the law's pair at the guess handed in (``known``, as the CPU build's friction sub-step
    does) returns the bits it returns evaluating the pair itself: over random patches, sliding and near sticking,
    with and without zero in the bracket (a large force puts the first iterate at a bracket end)."""

    @wp.kernel(enable_backward=False, module="unique")
    def solve_both(p: wp.array2d(dtype=dtype), out: wp.array2d(dtype=dtype)):
        i = wp.tid()
        a, r, hfn, vd, guess = p[i, 0], p[i, 1], p[i, 2], p[i, 3], p[i, 4]
        mu_scale, slope, decay, tol = dtype(0.8 / 3.141592653589793), dtype(SLOPE), dtype(DECAY), dtype(1e-6)
        zero = dtype(0.0)
        f, df = friction_pair(vd - guess, mu_scale, slope, decay)
        for known in range(2):
            out[i, known] = solve_velocity(
                a, r, hfn, vd, guess, mu_scale, slope, decay, tol, 0, vd - guess, zero, known, f, df
            )

    rng = np.random.default_rng(7)
    n = 20_000
    m = rng.uniform(1e-6, 3e-6, n)
    h = rng.choice([1e-8, 1e-7, 5e-7], n)
    fn = rng.uniform(0.1, 2.0, n)
    guess = rng.choice([0.0, 9.99, 10.0], n) + rng.normal(0.0, 0.05, n)
    force = rng.normal(0.0, 1.0, n) * rng.choice([1e-3, 1.0, 1e3], n)  # 1e3 N: 0 outside the bracket
    p = np.stack([m, h * force, h * fn, np.full(n, 10.0), guess], axis=1)
    host = np.float32 if dtype is wp.float32 else np.float64
    out = wp.zeros((n, 2), dtype=dtype, device="cpu")
    wp.launch(solve_both, n, [wp.array(p.astype(host), dtype=dtype, device="cpu"), out], device="cpu")
    got = out.numpy()
    assert np.all(np.isfinite(got))
    np.testing.assert_array_equal(got[:, 1], got[:, 0])
