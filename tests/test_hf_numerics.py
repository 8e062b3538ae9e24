"""Numerical tests of the HF engine (aca_warp.hf) against independent references (docs/model.md §2).

* a single undamped, frictionless patch against the analytic oscillator u = (v0/ω) sin ωt;
* a small coupled, loaded, sliding network against SciPy's DOP853 solution of the equation of motion
  written out here from docs/model.md (masses, k_T, k_ij, damping, contact forces, signed Eq. 4, μ, torque);
* the isolated-patch frequencies √(k_T/m)/2π of docs/model.md §2.2 (75.2 kHz at 0.05 mm², 33.6 kHz at 1.25 mm²);
* the stable-step estimate, StabilityError and fault reporting.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import warp as wp
from aca_warp.kernels.physics import friction_substep
from procs import cpu_fibers, nine_patch_scene
from scipy.integrate import solve_ivp

from aca_warp.common.errors import SceneError, SimulationFault, StabilityError
from aca_warp.hf.loop import EngineTuning, run_hf
from aca_warp.hf.model import build_model
from aca_warp.hf.options import INTEGRATORS, RunOptions
from aca_warp.hf.solver import stable_step
from aca_warp.hf.state import initial_state
from aca_warp.scene import Friction, Initial, Material, Pad, Patches, Record, Scene

FIXED_STEP = [i for i in INTEGRATORS if i != "adaptive"]
K_T, K_N, K_C, RHO_A = 1.87e9, 2.39e9, 7.96e8, 37.5  # docs/model.md §2.1
K_M, MU_PAD = 1.85e11, 0.3


def one_patch(area=5.0e-8, r=0.13, height=3.0e-6) -> Patches:
    """A single patch on +y at friction radius ``r``."""
    return Patches(np.array([0.0]), np.array([r]), np.array([area]), np.array([height]))


# Short graphs: on the CPU, capturing a graph costs far more than replaying it, and more per step the longer the
# graph (5000 steps of 30 patches sampled every 10 steps: 0.08 s of CPU in graphs of 32 steps, 0.38 s in graphs of 256).
GRAPH_STEPS = 32


def run(scene, *, integrator, dt=None, precision="fp64", device="cpu", duration=None, **kw):
    """Build, initialise and run a one-scene model; returns (result, collected chunk, initial u, initial v)."""
    model = build_model([scene], device=device, precision=precision)
    state = initial_state(model)
    u0, v0 = (a.astype(np.float64).copy() for a in state.numpy())
    tuning = EngineTuning(max_graph_steps=kw.pop("max_graph_steps", GRAPH_STEPS))
    options = RunOptions(duration=duration or scene.duration, integrator=integrator, dt=dt, engine="general", **kw)
    res = run_hf(model, state, options, tuning=tuning)
    return res, res.collect(), u0, v0


# ------------------------------------------------------------------------------- a. analytic oscillator


def oscillator_scene(v_pert=0.05, seed=5, area=5.0e-8, sample_dt=None, periods=3.0) -> Scene:
    """One undamped patch, M = 0 (no friction force), started by a seeded velocity perturbation."""
    omega = math.sqrt(K_T * math.sqrt(area) / (RHO_A * area))
    period = 2 * math.pi / omega
    sample_dt = sample_dt or period / 100
    return Scene(
        name="oscillator",
        pad=Pad(),
        patches=one_patch(area),
        material=Material(damping_ratio=0.0),
        friction=Friction(M=0.0),
        normal_force=1.0,
        initial=Initial(perturbation=v_pert, seed=seed),
        record=Record(sample_dt=sample_dt, patches=("velocity", "displacement")),
        duration=round(periods * 100) * sample_dt,
    )


def oscillator_error(integrator, steps_per_sample, device="cpu", **kw):
    """Max errors of u and u̇ relative to their amplitudes, against u = (v0/ω) sin ωt, u̇ = v0 cos ωt."""
    s = oscillator_scene()
    res, c, _, v0 = run(s, integrator=integrator, dt=s.record.sample_dt / steps_per_sample, device=device, **kw)
    assert res.complete and res.fault is None
    omega = math.sqrt(K_T * math.sqrt(5e-8) / (RHO_A * 5e-8))
    t = c.patch_time
    assert len(t) == round(s.duration / s.record.sample_dt) + 1
    amp_v = abs(v0[0])
    u_ref = v0[0] / omega * np.sin(omega * t)
    v_ref = v0[0] * np.cos(omega * t)
    eu = np.max(np.abs(c.displacement[:, 0] - u_ref)) / (amp_v / omega)
    ev = np.max(np.abs(c.velocity[:, 0] - v_ref)) / amp_v
    return eu, ev


def test_oscillator_initial_perturbation_is_seeded():
    """The initial velocity is N(0, σ²) from the scene's seed (numpy PCG64), u = 0."""
    s = oscillator_scene()
    model = build_model([s])
    u, v = initial_state(model).numpy()
    assert u.tolist() == [0.0]
    assert v[0] == np.random.default_rng(5).normal(0.0, 0.05, 1)[0]


def test_oscillator_strang(device):
    """Strang (velocity Verlet without friction) at dt = T/2000: error < 1e-5 of the amplitude, second order."""
    eu, ev = oscillator_error("strang", 20, device)
    assert eu < 1e-5 and ev < 1e-5
    eu2, ev2 = oscillator_error("strang", 10, device)
    assert 3.5 < eu2 / eu < 4.5 and 3.5 < ev2 / ev < 4.5


@pytest.mark.parametrize("integrator", ["symplectic-euler", "implicit-friction"])
def test_oscillator_first_order_schemes(integrator, device):
    """Symplectic and IMEX Euler at dt = T/2000: error within the O(ωdt) bound, halving with the step."""
    omega_dt = 2 * math.pi / 2000
    eu, ev = oscillator_error(integrator, 20, device)
    assert eu < omega_dt and ev < omega_dt
    eu2, ev2 = oscillator_error(integrator, 10, device)
    assert 1.7 < ev2 / ev < 2.3


def test_oscillator_adaptive(device):
    """The adaptive scheme at a tight tolerance follows the analytic oscillator closely (its strang fall-back at
    T/1e5, never cheaper than DP5 here)."""
    eu, ev = oscillator_error("adaptive", 1000, device, tolerance=1e-9)
    assert eu < 1e-5 and ev < 1e-5


def test_oscillator_energy_is_conserved_by_strang():
    """Undamped and frictionless, Strang (symplectic) keeps ½ m v² + ½ k u² to O(dt²) over 20 periods."""
    s = oscillator_scene(periods=20.0)
    res, c, _, v0 = run(s, integrator="strang", dt=s.record.sample_dt / 10)
    m, k = RHO_A * 5e-8, K_T * math.sqrt(5e-8)
    e = 0.5 * m * c.velocity[:, 0] ** 2 + 0.5 * k * c.displacement[:, 0] ** 2
    e0 = 0.5 * m * v0[0] ** 2
    assert np.max(np.abs(e / e0 - 1)) < 1e-3  # (ω dt)²/4 ≈ 1e-4 oscillation, no drift
    assert abs(e[-100:].mean() / e[:100].mean() - 1) < 1e-6


# ------------------------------------------------------------------------------- b. coupled network


NET_LOAD = 20.0  # N: ≈ 12.8 N on 9 HF1-size patches at full height, the rest on the matrix


def network_scene(load=NET_LOAD, perturbation=0.05, sample_dt=1e-7, duration=2e-5) -> Scene:
    """9 HF1-size patches on a 1.5 mm grid near r = 0.13 m (one 4.5 mm off, coupled to only some), M = 0.8."""
    return nine_patch_scene(
        "network",
        sample_dt=sample_dt,
        duration=duration,
        patches=("velocity", "displacement"),
        centre_off=True,
        normal_force=load,
        initial=Initial(perturbation=perturbation, seed=3),
    )


def friction_eq4(v, M=0.8):
    """Signed Eq. 4: f(v) = (M/π) atan(200 v) (1/(0.25|v| + 1) + 1)."""
    return M / np.pi * np.arctan(200.0 * v) * (1.0 / (0.25 * np.abs(v) + 1.0) + 1.0)


def network_reference(scene: Scene, v0: np.ndarray, times: np.ndarray) -> dict:
    """Independent solution of m ü + c u̇ + k_T u + Σ k_ij (u_i − u_j) = F_N,i f(ω r_i − u̇_i) (DOP853, rtol 1e-12).

    Every constant is computed here from docs/model.md and the patch geometry (not from the model's arrays).
    """
    p = scene.patches
    n = p.count
    A = p.area
    m = RHO_A * A
    kt = K_T * np.sqrt(A)
    c = 2 * 1e-6 * np.sqrt(kt * m)
    d = np.hypot(p.x[:, None] - p.x[None, :], p.y[:, None] - p.y[None, :])
    kij = np.where((d > 0) & (d <= 5e-3), K_C * np.sqrt(A[:, None] * A[None, :]) / np.where(d > 0, d, 1.0), 0.0)
    stiff = np.diag(kt + kij.sum(axis=1)) - kij
    # contact: equal free heights h on every patch, one flat matrix cell (uncovered pad area) at elevation 0
    h = 3e-6
    kn = K_N * np.sqrt(A)
    pad = scene.pad
    a_free = math.radians(pad.span_deg) / 2 * (pad.r_outer**2 - pad.r_inner**2) - A.sum()
    km = K_M * a_free
    gap = h - scene.normal_force / kn.sum()
    if gap < 0:  # the matrix takes part of the load
        gap = (kn.sum() * h - scene.normal_force) / (kn.sum() + km)
    fn = kn * (h - gap)
    f_matrix = km * max(-gap, 0.0)
    assert fn.sum() + f_matrix == pytest.approx(scene.normal_force, rel=1e-12)
    # matrix friction radius: centroid of the uncovered area
    moment = math.radians(pad.span_deg) / 2 * 2 / 3 * (pad.r_outer**3 - pad.r_inner**3)
    r = np.hypot(p.x, p.y)
    r_m = (moment - np.sum(A * r)) / a_free
    vd = scene.angular_velocity * r

    def rhs(_t, y):
        u, v = y[:n], y[n:]
        return np.concatenate([v, (-stiff @ u - c * v + fn * friction_eq4(vd - v)) / m])

    y0 = np.concatenate([np.zeros(n), v0])
    atol = np.concatenate([np.full(n, 1e-18), np.full(n, 1e-12)])
    sol = solve_ivp(rhs, (0.0, times[-1]), y0, method="DOP853", rtol=1e-12, atol=atol, t_eval=times)
    assert sol.success
    u, v = sol.y[:n].T, sol.y[n:].T
    f = fn * friction_eq4(vd[None, :] - v)
    ftot = f.sum(axis=1) + MU_PAD * f_matrix
    torque = (f * r).sum(axis=1) + MU_PAD * f_matrix * r_m
    return {
        "u": u,
        "v": v,
        "mu": ftot / scene.normal_force,
        "torque": torque,
        "radius": torque / ftot,
        "sum_v": v.sum(axis=1),
        "sum_abs_v": np.abs(v).sum(axis=1),
        "centroid": np.hypot(f @ p.x, f @ p.y) / np.abs(f.sum(axis=1)),  # patch friction only
        "fn": fn,
        "f_matrix": f_matrix,
    }


@pytest.fixture(scope="module")
def net_ref():
    """The network scene, its seeded initial velocities and the SciPy reference at the sample times."""
    s = network_scene()
    v0 = np.random.default_rng(3).normal(0.0, 0.05, s.patches.count)
    times = np.arange(round(s.duration / s.record.sample_dt) + 1) * s.record.sample_dt
    return s, v0, times, network_reference(s, v0, times)


def net_errors(c, ref):
    """Errors of a run against the reference: μ (relative), u̇ and u (relative to their max)."""
    return {
        "mu": np.max(np.abs(c.globals[:, 0, 0] - ref["mu"]) / np.abs(ref["mu"])),
        "v": np.max(np.abs(c.velocity - ref["v"])) / np.max(np.abs(ref["v"])),
        "u": np.max(np.abs(c.displacement - ref["u"])) / np.max(np.abs(ref["u"])),
    }


def test_network_setup_matches_model(net_ref):
    """The model's normal forces, matrix force and initial velocities are those of the reference."""
    s, v0, _, ref = net_ref
    model = build_model([s])
    np.testing.assert_allclose(model.contacts[0].patch_force, ref["fn"], rtol=1e-12)
    assert model.contacts[0].matrix_force.sum() == pytest.approx(ref["f_matrix"], rel=1e-10)
    assert 0.2 < ref["f_matrix"] / s.normal_force < 0.5  # both μ terms matter
    np.testing.assert_array_equal(initial_state(model).numpy()[1], v0)


def test_network_strang_fp64_matches_reference(net_ref, device):
    """Strang fp64 at dt = 1e-9 s: μ(t) within 1e-6 relative of DOP853 over 20 µs; all globals agree."""
    s, _, times, ref = net_ref
    res, c, _, _ = run(s, integrator="strang", dt=1e-9, device=device)
    assert res.complete and res.steps == 20000
    np.testing.assert_allclose(c.time, times, rtol=1e-12)
    e = net_errors(c, ref)
    assert e["mu"] < 1e-6, e
    assert e["v"] < 1e-6 and e["u"] < 1e-6, e
    g = c.globals[:, 0]
    np.testing.assert_allclose(g[:, 1], ref["torque"], rtol=1e-6)
    np.testing.assert_allclose(g[:, 2], ref["radius"], rtol=1e-6)
    np.testing.assert_allclose(g[:, 3], ref["sum_v"], atol=1e-5 * np.abs(ref["v"]).max())
    np.testing.assert_allclose(g[:, 4], ref["sum_abs_v"], atol=1e-5 * np.abs(ref["v"]).max())
    np.testing.assert_allclose(g[:, 5], ref["centroid"], rtol=1e-6)
    assert np.all(g[:, 5] < g[:, 2])  # the centroid of forces along an arc lies inside it
    # the dynamic part of μ, not only its mean, is resolved
    dmu = g[:, 0] - g[0, 0]
    assert np.max(np.abs(dmu - (ref["mu"] - ref["mu"][0]))) < 1e-6 * np.ptp(ref["mu"])


def test_network_strang_is_second_order(net_ref):
    """With friction and coupling, ten times the step gives about a hundred times the error."""
    s, _, _, ref = net_ref
    e_fine = net_errors(run(s, integrator="strang", dt=1e-9)[1], ref)["v"]
    e_coarse = net_errors(run(s, integrator="strang", dt=1e-8)[1], ref)["v"]
    assert 40 < e_coarse / e_fine < 250


@pytest.mark.parametrize("integrator", ["symplectic-euler", "implicit-friction"])
def test_network_first_order_schemes(net_ref, integrator):
    """The first-order schemes at dt = 1e-9 s: μ within 1e-6, u̇ within 1e-4 of the reference."""
    s, _, _, ref = net_ref
    res, c, _, _ = run(s, integrator=integrator, dt=1e-9)
    e = net_errors(c, ref)
    assert e["mu"] < 1e-6 and e["v"] < 1e-4, e


def test_network_adaptive_matches_reference(net_ref):
    """The adaptive scheme at tolerance 1e-7 lands on every sample time and agrees with the reference."""
    s, _, times, ref = net_ref
    res, c, _, _ = run(s, integrator="adaptive", tolerance=1e-7)
    assert res.complete
    np.testing.assert_allclose(c.time, times, rtol=1e-12)
    e = net_errors(c, ref)
    assert e["mu"] < 1e-6 and e["v"] < 1e-5, e


def test_network_block_lanes_agree_with_one_lane(net_ref):
    """The lane-parallel paths that CUDA takes (a stage evaluation's links read by 32 lanes of a block, a sample's
    global sums by 256), run on Warp's CPU fibers, agree with the one-lane CPU path to rounding, and the run with
    them still matches the reference."""
    s, _, _, ref = net_ref
    out = []
    for fibers in (False, True):
        with cpu_fibers(fibers):
            res, c, _, _ = run(s, integrator="adaptive", tolerance=1e-7)
        assert res.complete
        out.append(c)
    one, lanes = out
    np.testing.assert_allclose(lanes.globals, one.globals, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(lanes.velocity, one.velocity, rtol=0, atol=1e-12 * np.abs(one.velocity).max())
    e = net_errors(lanes, ref)
    assert e["mu"] < 1e-6 and e["v"] < 1e-5, e


def test_eval_lanes_rule():
    """Stage evaluations use 32 lanes per patch on CUDA for small batches only, one lane on the CPU."""
    from types import SimpleNamespace

    from aca_warp.hf.adaptive import eval_lanes

    h200 = SimpleNamespace(is_cuda=True, sm_count=132)
    assert eval_lanes(h200, 1758) == 32 and eval_lanes(h200, 4224) == 32
    assert eval_lanes(h200, 4225) == 1 and eval_lanes(h200, 64 * 1758) == 1
    assert eval_lanes(wp.get_device("cpu"), 1758) == (32 if wp.config.enable_cpu_blocks else 1)


def test_network_symplectic_euler_fp32(net_ref):
    """fp32 state with the explicit scheme agrees with the fp64 reference to ~1e-4 of the velocity scale."""
    s, _, _, ref = net_ref
    res, c, _, _ = run(s, integrator="symplectic-euler", dt=1e-9, precision="fp32")
    assert c.velocity.dtype == np.float32
    e = net_errors(c, ref)
    assert e["mu"] < 1e-5 and e["v"] < 1e-3, e


@pytest.mark.parametrize("integrator", ["strang", "implicit-friction"])
def test_network_implicit_schemes_fp32(net_ref, integrator):
    """fp32 with the implicit friction solve agrees with the fp64 reference as well as the explicit scheme does."""
    s, _, _, ref = net_ref
    res, c, _, _ = run(s, integrator=integrator, dt=1e-9, precision="fp32")
    e = net_errors(c, ref)
    assert e["mu"] < 1e-5 and e["v"] < 1e-3, e


def test_friction_solve_fp32_residual():
    """The fp32 implicit-midpoint friction increment equals the fp64 one to ~1e-3 relative (a few ulps of u̇)."""
    v = np.linspace(-0.6, 0.6, 25)
    inc = {}
    for T, np_t, tol in ((wp.float32, np.float32, 1e-6), (wp.float64, np.float64, 1e-12)):
        out = wp.zeros(len(v), dtype=T, device="cpu")
        wp.launch(
            _midpoint_kernel[T],
            dim=len(v),
            inputs=[wp.array(v.astype(np_t), dtype=T), T(1e-10), T(tol)],
            outputs=[out],
            device="cpu",
        )
        inc[T] = out.numpy().astype(np.float64) - v.astype(np_t).astype(np.float64)
    exact = inc[wp.float64]
    assert np.all(exact > 1e-5)  # the friction increment over 1e-10 s is ≈ 2.7e-5 m/s
    np.testing.assert_allclose(inc[wp.float32], exact, rtol=1e-2)


def _midpoint_kernel_for(T):
    """A kernel applying kernels.physics.friction_substep to 0.05 mm² patches with F_N = 1 N at 10 m/s."""

    @wp.kernel(enable_backward=False, module="unique")
    def kernel(v_in: wp.array(dtype=T), dt: T, tol: T, v_out: wp.array(dtype=T)):
        i = wp.tid()
        v_out[i] = friction_substep(
            v_in[i], dt, T(37.5 * 5e-8), T(0.0), T(1.0), T(0.0), T(10.0), T(0.8 / 3.141592653589793), T(200.0),
            T(0.25), tol, 0,
        )  # fmt: skip

    return kernel


_midpoint_kernel = {T: _midpoint_kernel_for(T) for T in (wp.float32, wp.float64)}


@wp.kernel(enable_backward=False, module="unique")
def _substep_kernel(
    v_in: wp.array(dtype=wp.float64),
    dt: wp.array(dtype=wp.float64),
    m: wp.array(dtype=wp.float64),
    c: wp.array(dtype=wp.float64),
    fn: wp.array(dtype=wp.float64),
    force: wp.array(dtype=wp.float64),
    vd: wp.array(dtype=wp.float64),
    mu_scale: wp.float64,
    v_out: wp.array(dtype=wp.float64),
):
    i = wp.tid()
    # M/π comes in as an argument: a float literal in a kernel is rounded to fp32 first
    v_out[i] = friction_substep(
        v_in[i], dt[i], m[i], c[i], fn[i], force[i], vd[i], mu_scale, wp.float64(200.0), wp.float64(0.25),
        wp.float64(1e-12), 0,
    )  # fmt: skip


def friction_slope_eq4(v, M=0.8, a=200.0, b=0.25):
    """df/dv of Eq. 4 [s/m] (the paper's constants)."""
    q = 1.0 / (b * abs(v) + 1.0)
    return M / math.pi * (a / (1.0 + (a * v) ** 2) * (q + 1.0) - math.atan(a * v) * b * math.copysign(1.0, v) * q * q)


def test_friction_substep_solves_the_damped_midpoint_equation():
    """friction_substep returns v + (V − v)/θ where V solves m (V − v) = θ dt (F + F_N f(v_d − V) − c V) with the
    spring force F frozen, found here by SciPy's brentq on the same equation; θ = 1/2 while dt γ ≤ 6 at the
    patch's own friction rate γ = (c + F_N f′(v_d − v))/m, else (1 − 1.5/(dt γ))/1.5. From sliding to sticking and
    from small steps to steps 1000× the friction relaxation time m / (F_N max|f′|) (where the solve must bisect)."""
    from scipy.optimize import brentq

    rng = np.random.default_rng(3)
    n = 200
    m = 37.5 * rng.uniform(2e-8, 8e-8, n)  # kg: 2-8e-8 m² at 37.5 kg/m²
    fn = rng.uniform(0.1, 5.0, n)
    relax = m / (fn * 0.8 / np.pi * 200.0 * 2.0)  # m / (F_N max|f'|), f'(0) = 2 (M/π) a
    dt = relax * 10.0 ** rng.uniform(-3, 3, n)
    c = rng.uniform(0.0, 1e-3, n)
    vd = rng.uniform(0.0, 20.0, n)
    v = vd + rng.uniform(-0.05, 0.05, n) * np.where(rng.uniform(size=n) < 0.5, 1.0, 100.0)
    force = fn * 0.8 * rng.uniform(-1.5, 1.5, n)  # spring forces up to 1.5 F_N M: held and slipping patches
    arrays = [wp.array(a, dtype=wp.float64, device="cpu") for a in (v, dt, m, c, fn, force, vd)]
    out = wp.zeros(n, dtype=wp.float64, device="cpu")
    wp.launch(_substep_kernel, dim=n, inputs=[*arrays, 0.8 / math.pi], outputs=[out], device="cpu")
    got = out.numpy()
    damped = 0
    for i in range(n):
        x = dt[i] * (c[i] + fn[i] * friction_slope_eq4(vd[i] - v[i])) / m[i]
        theta = 0.5 if x <= 6.0 else min((1.0 - 1.5 / x) / 1.5, 1.0)
        damped += theta > 0.5
        h = theta * dt[i]

        def g(vm, i=i, h=h):
            return m[i] * (vm - v[i]) - h * (force[i] + fn[i] * friction_eq4(vd[i] - vm) - c[i] * vm)

        bound = (abs(v[i]) + h * (fn[i] * 0.8 + abs(force[i])) / m[i] + 1.0) * 2.0
        vm = brentq(g, -bound, bound, xtol=1e-15, rtol=1e-15)
        want = v[i] + (vm - v[i]) / theta
        # the solve's own scale: its tolerance 1e-12 is relative to (|r| + θh F_N f_max)/a (r the residual at v),
        # which a frozen force nearly balancing friction makes far larger than the increment
        a = m[i] + h * c[i]
        scale = (abs(h * (force[i] - c[i] * v[i])) + h * fn[i] * 0.8) / a / theta
        floor = 8.0 * np.finfo(float).eps * abs(v[i]) / theta  # the rounding of V = v + δ and of the update
        assert abs(got[i] - want) <= 1e-10 * scale + floor, (i, got[i], want, scale)
    assert 10 < damped < n - 10  # both branches of θ are exercised


def test_equilibrium_start_stays_at_rest():
    """From the 'equilibrium' state (springs balance friction, u̇ = 0) the network does not move."""
    s = network_scene(perturbation=0.0, duration=5e-6).replace(initial=Initial(state="equilibrium"))
    res, c, u0, v0 = run(s, integrator="strang", dt=1e-9)
    assert np.all(v0 == 0.0) and np.all(u0 > 0)
    assert np.max(np.abs(c.velocity)) < 1e-8
    np.testing.assert_allclose(c.displacement[-1], u0, rtol=1e-8)


def test_equilibrium_matches_hand_solve(net_ref):
    """The equilibrium displacement solves (diag k_T + L) u = F_N f(ω r) with the reference's constants."""
    s, _, _, ref = net_ref
    model = build_model([s.replace(initial=Initial(state="equilibrium"))])
    u = initial_state(model).numpy()[0]
    p = s.patches
    A = p.area
    d = np.hypot(p.x[:, None] - p.x[None, :], p.y[:, None] - p.y[None, :])
    kij = np.where((d > 0) & (d <= 5e-3), K_C * np.sqrt(A[:, None] * A[None, :]) / np.where(d > 0, d, 1.0), 0.0)
    stiff = np.diag(K_T * np.sqrt(A) + kij.sum(axis=1)) - kij
    rhs = ref["fn"] * friction_eq4(s.angular_velocity * np.hypot(p.x, p.y))
    np.testing.assert_allclose(u, np.linalg.solve(stiff, rhs), rtol=1e-10)


def test_equilibrium_of_a_single_patch():
    """A single patch starts at u = F_N f(ω r)/k_T in the 'equilibrium' state."""
    s = Scene(name="eq1", pad=Pad(), patches=one_patch(), normal_force=1.0, initial=Initial(state="equilibrium"))
    u = initial_state(build_model([s])).numpy()[0]
    assert u[0] == pytest.approx(friction_eq4(10.0) / (K_T * math.sqrt(5e-8)), rel=1e-12)


# ------------------------------------------------------------------------------- c. isolated frequencies


def spectrum_peak(x, dt, pad_factor=16):
    """Frequency [Hz] of the largest peak of the Hann-windowed amplitude spectrum (mean removed, zero-padded)."""
    x = np.asarray(x, float) - np.mean(x)
    n = len(x)
    spec = np.abs(np.fft.rfft(x * np.hanning(n), n * pad_factor))
    freq = np.fft.rfftfreq(n * pad_factor, dt)
    k = int(np.argmax(spec[1:])) + 1
    a, b, c = np.log(spec[k - 1 : k + 2])
    return freq[k] + 0.5 * (a - c) / (a - 2 * b + c) * (freq[1] - freq[0])


def test_isolated_patch_frequencies():
    """Single sliding patches of 0.05 and 1.25 mm² (friction-excited from rest) ring at 75.2 and 33.6 kHz (±1 %)."""
    scenes = []
    for area, load in ((5.0e-8, 1.0), (1.25e-6, 5.0)):
        scenes.append(
            Scene(
                name=f"iso{area:g}",
                pad=Pad(),
                patches=one_patch(area),
                normal_force=load,
                record=Record(sample_dt=1e-7),
                duration=5e-4,
            )
        )
    model = build_model(scenes)  # one batch of two pads
    res = run_hf(
        model,
        initial_state(model),
        RunOptions(duration=5e-4, integrator="strang", dt=1e-8),
        tuning=EngineTuning(max_graph_steps=GRAPH_STEPS),
    )
    assert res.complete
    c = res.collect()
    f_small = spectrum_peak(c.globals[:, 0, 3], 1e-7)
    f_large = spectrum_peak(c.globals[:, 1, 3], 1e-7)
    analytic = [math.sqrt(K_T * math.sqrt(a) / (RHO_A * a)) / (2 * math.pi) for a in (5e-8, 1.25e-6)]
    assert analytic == pytest.approx([75.2e3, 33.6e3], rel=1e-3)  # docs/model.md §2.2: √(k_T/m)/2π
    assert f_small == pytest.approx(75.2e3, rel=0.01)
    assert f_large == pytest.approx(33.6e3, rel=0.01)
    assert f_small == pytest.approx(analytic[0], rel=2e-3)
    assert f_large == pytest.approx(analytic[1], rel=2e-3)
    assert f_small / f_large == pytest.approx(25.0**0.25, rel=0.01)  # f ∝ A^(−1/4)
    # friction really excites the patch: it swings about its static deflection F_N f(ωr)/k_T
    assert np.ptp(c.globals[:, 0, 3]) > 0.1


# ------------------------------------------------------------------------------- d. stability, faults


def test_stable_step_estimate_fields():
    """All three bounds are positive and finite; the combined explicit bound is below both parts."""
    est = stable_step(build_model([network_scene()]))
    for v in (est.spring, est.friction, est.explicit):
        assert 0 < v < 1e-3 and math.isfinite(v)
    assert est.explicit <= min(est.spring, est.friction) * (1 + 1e-12)
    assert est.limit("symplectic-euler") == est.explicit
    assert est.limit("implicit-friction") == est.limit("strang") == est.spring
    # a single frictionless patch: spring bound 2/ω exactly, no friction bound
    est1 = stable_step(build_model([oscillator_scene()]))
    omega = math.sqrt(K_T * math.sqrt(5e-8) / (RHO_A * 5e-8))
    assert est1.spring == pytest.approx(2 / omega, rel=1e-12)
    assert est1.friction == math.inf


def test_explicit_step_beyond_estimate_is_refused():
    """symplectic-euler above estimate.explicit raises StabilityError; implicit schemes accept that step."""
    s = network_scene(load=200.0, sample_dt=1e-6, duration=2e-6)
    est = stable_step(build_model([s]))
    assert est.explicit < est.spring
    dt = 0.5 * (est.explicit + min(est.spring, 1e-6))
    model = build_model([s])
    with pytest.raises(StabilityError, match="exceeds the stable-step estimate"):
        run_hf(model, initial_state(model), RunOptions(duration=2e-6, integrator="symplectic-euler", dt=dt))
    res = run_hf(
        model,
        initial_state(model),
        RunOptions(duration=2e-6, integrator="implicit-friction", dt=dt),
        tuning=EngineTuning(max_graph_steps=GRAPH_STEPS),
    )
    assert res.complete
    # strang beyond the springs' bound (a sample interval long enough that the step is not fitted below it)
    wide = build_model([network_scene(load=200.0, sample_dt=1e-5, duration=2e-5)])
    with pytest.raises(StabilityError, match="exceeds the stable-step estimate"):
        run_hf(wide, initial_state(wide), RunOptions(duration=2e-5, integrator="strang", dt=1.5 * est.spring))


def test_forced_unstable_run_reports_a_fault():
    """Forced far beyond the spring limit, the run stops with a SimulationFault; samples before it are finite."""
    s = network_scene(sample_dt=2e-5, duration=2e-2)
    model = build_model([s])
    est = stable_step(model)
    dt = 5.0 * est.spring
    assert dt < 2e-5
    with pytest.raises(StabilityError):
        run_hf(model, initial_state(model), RunOptions(duration=2e-2, integrator="symplectic-euler", dt=dt))
    res = run_hf(
        model,
        initial_state(model),
        RunOptions(duration=2e-2, integrator="symplectic-euler", dt=dt, force=True),
        tuning=EngineTuning(max_graph_steps=GRAPH_STEPS),
    )
    assert not res.complete
    f = res.fault
    assert isinstance(f, SimulationFault)
    assert f.pad == 0 and 0 <= f.patch < s.patches.count
    assert 0 < f.time < 2e-2
    assert "beyond the stable estimate" in f.cause
    c = res.collect()
    assert len(c.time) > 0 and np.all(c.time < f.time)
    # the result describes the samples kept, not the chunk in which the fault was found
    assert res.sim_time == c.time[-1] and res.steps == round(c.time[-1] / s.record.sample_dt) * round(2e-5 / res.dt)
    assert np.all(np.isfinite(c.globals))
    assert np.all(np.isfinite(c.velocity)) and np.all(np.isfinite(c.displacement))


def test_forced_explicit_friction_beyond_its_limit():
    """Stiff friction (disc at rest, so sliding speeds cross 0) with symplectic Euler forced past the friction
    limit: the run either faults cleanly or stays finite (the saturating friction bounds the chatter)."""
    s = network_scene(load=200.0, sample_dt=1e-7, duration=2e-6).replace(angular_velocity=0.0)
    model = build_model([s])
    est = stable_step(model)
    dt = min(3.0 * est.explicit, 0.5 * est.spring, 1e-7)
    assert dt > est.explicit
    res = run_hf(
        model,
        initial_state(model),
        RunOptions(duration=2e-6, integrator="symplectic-euler", dt=dt, force=True),
        tuning=EngineTuning(max_graph_steps=GRAPH_STEPS),
    )
    c = res.collect()
    if res.fault is not None:
        assert res.fault.patch >= 0 and res.fault.time > 0
        assert np.all(c.time < res.fault.time)
    assert np.all(np.isfinite(c.globals))


def test_run_argument_errors():
    """Unknown integrators, bad durations/steps/tolerances are SceneErrors before anything runs."""
    s = network_scene(duration=2e-6)
    model = build_model([s])
    st = initial_state(model)
    with pytest.raises(SceneError, match="unknown integrator 'rk4'"):
        run_hf(model, st, RunOptions(duration=1e-6, integrator="rk4"))
    with pytest.raises(SceneError, match="duration must be a positive number"):
        run_hf(model, st, RunOptions(duration=-1e-6))
    with pytest.raises(SceneError, match="duration must be a positive number"):
        run_hf(model, st, RunOptions(duration=math.nan))
    with pytest.raises(SceneError, match="sample interval .* exceeds the duration"):
        run_hf(model, st, RunOptions(duration=1e-8))
    with pytest.raises(SceneError, match="dt must be a positive number"):
        run_hf(model, st, RunOptions(duration=1e-6, integrator="strang", dt=-1e-9))
    with pytest.raises(SceneError, match="tolerance must be a positive number"):
        run_hf(model, st, RunOptions(duration=1e-6, integrator="adaptive", tolerance=0.0))
    with pytest.raises(SceneError, match="precision must be one of"):
        build_model([s], precision="fp16")
    with pytest.raises(SceneError, match="at least one scene"):
        build_model([])


def test_no_load_gives_zero_mu():
    """Without load there is no contact: μ = 0 by convention, torque 0, patches at rest stay at rest."""
    s = network_scene(load=0.0, perturbation=0.0, duration=2e-6)
    res, c, _, _ = run(s, integrator="strang", dt=1e-8)
    assert res.complete
    assert np.all(c.globals[:, 0, :] == 0.0)


def test_patch_history_window_and_decimation():
    """Per-patch rows are exactly the samples in the window, every n-th; they equal a full recording's rows."""
    s = network_scene(duration=5e-6)
    full = run(s, integrator="strang", dt=1e-8)[1]
    rec = Record(sample_dt=1e-7, patches=("velocity",), window=(1.05e-6, 3e-6), decimation=3)
    part = run(s.replace(record=rec), integrator="strang", dt=1e-8)[1]
    k = np.arange(11, 31, 3)  # first sample at or after 1.05 µs is 11; last in the window is 30
    np.testing.assert_allclose(part.patch_time, k * 1e-7, rtol=1e-12)
    assert part.displacement is None
    np.testing.assert_array_equal(part.velocity, full.velocity[k])
    np.testing.assert_array_equal(part.globals, full.globals)  # global outputs are recorded at every sample
    assert len(part.time) == 51


def test_dp5_stability_function():
    """R(z) of the adaptive pair agrees with e^z to 5th order (the local error shrinks 64× when z halves), and its
    stability interval on the negative real axis is DOPRI5's [−3.31, 0] (Hairer & Wanner); on the imaginary axis
    |R| stays ≤ 1 up to about 1 only."""
    from aca_warp.hf.adaptive import stability_bounds, stability_function

    e1 = abs(stability_function(0.1) - np.exp(0.1))
    e2 = abs(stability_function(0.05) - np.exp(0.05))
    assert 55 < e1 / e2 < 72
    x, y = stability_bounds()
    assert 3.30 < x < 3.31 and 0.99 < y < 1.0
    assert abs(stability_function(-3.4)) > 1 and abs(stability_function(2.0j)) > 1
