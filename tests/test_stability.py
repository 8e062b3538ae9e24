"""Stability of the HF integrators against the stable-step estimate, and energy audits (docs/stability.md).

* The estimate (``aca_warp.hf.solver.stable_step``) against the exact spectrum of the spring network.
* Explicit symplectic Euler at 0.9× ``estimate.explicit`` stays bounded over 1e5 steps, both where the
  friction slope limits the step and where the springs do; at 3× it is refused, and, forced, it is unstable.
* ``implicit-friction`` and ``strang`` are limited by ``estimate.spring`` only: bounded at 0.9×, refused and
  unstable at 3×; ``implicit-friction`` stays bounded 10–50× past the friction limit.
* Energy: without friction and damping E = Σ ½ m u̇² + ½ k_T u² + ½ Σ_{i<j} k_ij (u_i − u_j)² is conserved up
  to a bounded oscillation (symplectic schemes); with friction and damping E(t) − E(0) = W_friction − W_damping,
  with a residual of the scheme's order.

Scenes: 30 HF1-size patches (0.02–0.08 mm²) on a 1.2 mm grid at r = 0.13 m, all coupled (24 links each on
average), so 1e5 steps take well under a second on the CPU.

*Velocity bound.* With the disc at rest (ω = 0) friction only dissipates (f(−u̇)u̇ ≤ 0), and so do the schemes'
friction updates (implicit ones exactly; explicit ones below the friction limit); the spring part of
symplectic Euler / Verlet conserves a modified energy that, from u = 0, bounds the velocities by
|u̇_i| ≤ √(2E₀/m_min) / √(1 − (h ω_max/2)²). At h ≤ 0.9 × the (conservative) spring estimate this gives the
scene-derived bound B = √(2E₀/m_min) / √(1 − 0.9²) ≈ 2.3 √(2E₀/m_min).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from aca_warp.common.errors import SimulationFault, StabilityError
from aca_warp.hf.loop import EngineTuning, run_hf
from aca_warp.hf.model import PadModel, build_model, coupling_matrix
from aca_warp.hf.options import RunOptions
from aca_warp.hf.solver import stable_step
from aca_warp.hf.state import initial_state
from aca_warp.scene import Friction, Initial, Material, Pad, Patches, Record, Scene

GRAPH_STEPS = 32  # short graphs: a CPU capture costs more per step the longer the graph (5000 steps of 30 patches
# sampled every 10 steps: 0.08 s of CPU in graphs of 32 steps, 0.38 s in graphs of 256)
STEPS = 100_000
SAMPLE_EVERY = 100  # steps per recorded sample in the long runs


def grid_patches(n: int = 30, spacing: float = 1.2e-3, seed: int = 1) -> Patches:
    """``n`` patches of 0.02–0.08 mm² (seeded) on a square grid of ``spacing`` around (0, 0.13 m)."""
    side = math.ceil(math.sqrt(n))
    ij = np.array([divmod(a, side) for a in range(n)], dtype=float)
    area = np.random.default_rng(seed).uniform(2e-8, 8e-8, n)
    return Patches((ij[:, 1] - side / 2) * spacing, 0.13 + (ij[:, 0] - side / 2) * spacing, area, np.full(n, 3e-6))


def friction_scene(**kw) -> Scene:
    """Disc at rest, 200 N (49 N on the patches): the friction slope at zero sliding speed limits explicit steps
    (estimate.friction ≈ 1.5e-8 s ≪ estimate.spring ≈ 2.0e-6 s). Started from u = 0, u̇ ~ N(0, (0.1 mm/s)²)."""
    kw.setdefault("initial", Initial(perturbation=1e-4, seed=1))
    return Scene(
        name="friction-limited",
        pad=Pad(),
        patches=grid_patches(),
        normal_force=200.0,
        angular_velocity=0.0,
        record=Record(sample_dt=1e-6),
        **kw,
    )


def spring_scene(**kw) -> Scene:
    """The same patches without friction (M = 0): only the spring network limits the step."""
    return friction_scene(friction=Friction(M=0.0), **kw)


def masses(model: PadModel) -> np.ndarray:
    """Patch masses [kg]."""
    return 1.0 / model.host("inv_mass").astype(np.float64)


def velocity_bound(model: PadModel, v0: np.ndarray) -> float:
    """B = √(2E₀/m_min)/√(1 − 0.9²) [m/s] for a start from u = 0 with velocities v0 (see the module docstring)."""
    m = masses(model)
    e0 = 0.5 * float(np.sum(m * v0**2))
    return math.sqrt(2.0 * e0 / m.min()) / math.sqrt(1.0 - 0.9**2)


def long_run(scene: Scene, integrator: str, dt: float, *, steps: int = STEPS, force: bool = False):
    """Run ``steps`` steps of ``dt`` recording u̇ every SAMPLE_EVERY steps; returns (result, chunk, bound)."""
    model = build_model([scene])
    state = initial_state(model)
    bound = velocity_bound(model, state.numpy()[1].astype(np.float64))
    rec = Record(sample_dt=SAMPLE_EVERY * dt, patches=("velocity",))
    res = run_hf(
        model,
        state,
        RunOptions(duration=steps * dt, integrator=integrator, dt=dt, force=force),
        record=rec,
        tuning=EngineTuning(max_graph_steps=GRAPH_STEPS),
    )
    return res, res.collect(), bound


def assert_bounded(res, c, bound: float, steps: int = STEPS) -> None:
    """Complete, every recorded value finite, max |u̇| below the bound."""
    assert res.complete and res.fault is None and res.steps == steps
    assert np.all(np.isfinite(c.globals)) and np.all(np.isfinite(c.velocity))
    assert np.max(np.abs(c.velocity)) < bound


def assert_unstable(res, c, bound: float) -> str:
    """A fault (non-finite state) or velocities beyond the bound; returns which."""
    if res.fault is not None:
        assert isinstance(res.fault, SimulationFault) and not res.complete
        assert "beyond the stable estimate" in res.fault.cause
        assert np.all(np.isfinite(c.velocity))  # what was kept is from before the fault
        return "fault"
    assert np.max(np.abs(c.velocity)) > 5.0 * bound
    return "growth"


def spring_spectrum(model: PadModel) -> float:
    """Exact ω_max [rad/s] of M^-1/2 K M^-1/2 (dense eigen-solve; small models only)."""
    start, index, kij = coupling_matrix(model)
    n = model.patch_count
    rows = np.repeat(np.arange(n), np.diff(start))
    k = np.zeros((n, n))
    np.add.at(k, (rows, index), -kij)
    k += np.diag(model.host("k_t").astype(np.float64) + np.bincount(rows, kij, minlength=n))
    m = masses(model)
    return math.sqrt(np.linalg.eigvalsh(k / np.sqrt(np.outer(m, m))).max())


# ------------------------------------------------------------------------------- the estimate


def test_estimate_formulas_and_exact_spectrum():
    """The estimate's three numbers from their formulas; the Gershgorin spring bound is conservative but close
    (0.86 of the exact 2/ω_max here), and the explicit bound is the exact symplectic-Euler condition."""
    model = build_model([friction_scene()])
    est = stable_step(model)
    m = masses(model)
    fn = model.host("normal_force")
    c = model.host("damping")
    gamma = (c + fn * 2 * 200.0 * 0.8 / math.pi) / m  # f'(0) = 2·slope·M/π
    assert est.friction == pytest.approx(2.0 / gamma.max(), rel=1e-12)
    w_exact = spring_spectrum(model)
    assert 0.8 * (2.0 / w_exact) < est.spring <= 2.0 / w_exact
    assert est.explicit <= min(est.spring, est.friction)
    # on each patch h = est.explicit solves h²ω_i² = 4 − 2hγ_i for the patch that limits it
    start, _, kij = coupling_matrix(model)
    rows = np.repeat(np.arange(model.patch_count), np.diff(start))
    w2 = (model.host("k_t") + np.bincount(rows, kij, minlength=model.patch_count)) / m
    w2 += np.bincount(rows, kij / np.sqrt(m[rows] * m[coupling_matrix(model)[1]]), minlength=model.patch_count)
    h = est.explicit
    assert np.min(4 - 2 * h * gamma - h**2 * w2) == pytest.approx(0.0, abs=1e-9)
    # friction dominates this scene by two orders of magnitude; without friction the springs limit
    assert est.spring / est.friction > 100
    est0 = stable_step(build_model([spring_scene()]))
    assert est0.spring == est.spring and est0.explicit == pytest.approx(est0.spring, rel=1e-5)


def test_spring_estimate_brackets_the_true_limit():
    """Strang (Verlet springs) forced just past the exact limit 2/ω_max (1.05×) diverges; at 0.97× it is bounded.

    The estimate sits below both: the refusal threshold is conservative by the Gershgorin margin only."""
    scene = spring_scene()
    model = build_model([scene])
    limit = 2.0 / spring_spectrum(model)
    assert stable_step(model).spring < 0.97 * limit
    res, c, bound = long_run(scene, "strang", 0.97 * limit, steps=20_000, force=True)
    assert_bounded(res, c, bound, steps=20_000)
    res, c, bound = long_run(scene, "strang", 1.05 * limit, steps=20_000, force=True)
    assert assert_unstable(res, c, bound) == "fault"


# ------------------------------------------------------------------------------- explicit Euler


@pytest.mark.parametrize("make", [friction_scene, spring_scene], ids=["friction-limited", "spring-limited"])
def test_symplectic_euler_bounded_at_0_9_estimate(make):
    """symplectic-euler at 0.9 × estimate.explicit: 1e5 steps, all finite, max |u̇| below B."""
    scene = make()
    est = stable_step(build_model([scene]))
    res, c, bound = long_run(scene, "symplectic-euler", 0.9 * est.explicit)
    assert_bounded(res, c, bound)


@pytest.mark.parametrize(
    ("make", "expect"),
    [(friction_scene, "growth"), (spring_scene, "fault")],
    ids=["friction-limited", "spring-limited"],
)
def test_symplectic_euler_refused_and_unstable_at_3x_estimate(make, expect):
    """At 3 × estimate.explicit the step is refused before running; forced, the run is unstable.

    Past the friction limit the explicit friction term overshoots zero sliding speed every step; the saturating
    friction law (|f| ≤ M) caps this at a period-2 chatter of ≈ 3M/f'(0) ≈ 0.02 m/s, far beyond B (growth).
    Past the spring limit the amplitude grows exponentially until the state is non-finite (fault)."""
    scene = make()
    model = build_model([scene])
    dt = 3.0 * stable_step(model).explicit
    with pytest.raises(StabilityError, match=r"exceeds the stable-step estimate .* of symplectic-euler"):
        opts = RunOptions(duration=100 * dt, integrator="symplectic-euler", dt=dt)
        run_hf(model, initial_state(model), opts, record=Record(sample_dt=10 * dt))  # (dt is the step taken)
    res, c, bound = long_run(scene, "symplectic-euler", dt, force=True)
    assert assert_unstable(res, c, bound) == expect


# ------------------------------------------------------------------------------- implicit friction


@pytest.mark.parametrize("integrator", ["implicit-friction", "strang"])
def test_implicit_schemes_spring_limit(integrator):
    """implicit-friction and strang: bounded 1e5 steps at 0.9 × estimate.spring; refused at 3×, and forced they
    diverge to a fault (springs alone, M = 0: strong implicit friction would damp the spring instability)."""
    scene = spring_scene()
    model = build_model([scene])
    est = stable_step(model)
    assert est.limit(integrator) == est.spring
    res, c, bound = long_run(scene, integrator, 0.9 * est.spring)
    assert_bounded(res, c, bound)
    with pytest.raises(StabilityError, match=f"of {integrator}"):
        opts = RunOptions(duration=300 * est.spring, integrator=integrator, dt=3 * est.spring)
        run_hf(model, initial_state(model), opts, record=Record(sample_dt=30 * est.spring))
    res, c, bound = long_run(scene, integrator, 3.0 * est.spring, force=True)
    assert assert_unstable(res, c, bound) == "fault"


@pytest.mark.parametrize("factor", [10.0, 50.0])
def test_implicit_friction_far_past_the_friction_limit(factor):
    """At 10× and 50× estimate.friction (still < 0.9 × estimate.spring) implicit-friction and strang are accepted
    and stay bounded for 1e5 steps, where symplectic-euler is refused and, forced, chatters far beyond the bound."""
    scene = friction_scene()
    model = build_model([scene])
    est = stable_step(model)
    dt = factor * est.friction
    assert dt < 0.9 * est.spring
    for integrator in ("implicit-friction", "strang"):
        res, c, bound = long_run(scene, integrator, dt)
        assert_bounded(res, c, bound)
    with pytest.raises(StabilityError, match="friction slope"):
        run_hf(model, initial_state(model), RunOptions(duration=100 * dt, integrator="symplectic-euler", dt=dt))
    res, c, bound = long_run(scene, "symplectic-euler", dt, steps=10_000, force=True)
    assert assert_unstable(res, c, bound) == "growth"


# ------------------------------------------------------------------------------- energy


def energy(model: PadModel, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """E = Σ ½ m u̇² + ½ k_T u² + ½ Σ_{i<j} k_ij (u_i − u_j)² [J] per row of (samples, patches) u, v."""
    start, index, kij = coupling_matrix(model)
    rows = np.repeat(np.arange(model.patch_count), np.diff(start))
    once = rows < index  # the CSR lists every pair twice (k_ij = k_ji): each pair once
    stretch = u[:, rows[once]] - u[:, index[once]]
    stretch *= stretch
    e = 0.5 * (v**2) @ masses(model) + 0.5 * (u**2) @ model.host("k_t").astype(np.float64)
    return e + 0.5 * stretch @ kij[once]


def recorded_run(scene: Scene, integrator: str, dt: float, steps: int, every: int = 1):
    """Run and return (model, times, u, u̇) sampled every ``every`` steps (float64 copies)."""
    model = build_model([scene])
    res = run_hf(
        model,
        initial_state(model),
        RunOptions(duration=steps * dt, integrator=integrator, dt=dt),
        record=Record(sample_dt=every * dt, patches=("velocity", "displacement")),
        tuning=EngineTuning(max_graph_steps=GRAPH_STEPS),
    )
    assert res.complete
    c = res.collect()
    return model, c.patch_time, c.displacement.astype(np.float64), c.velocity.astype(np.float64)


@pytest.mark.parametrize(
    ("integrator", "osc_bound", "drift_bound"), [("symplectic-euler", 1e-2, 1e-4), ("strang", 1e-4, 1e-7)]
)
def test_energy_conserved_without_friction_and_damping(integrator, osc_bound, drift_bound):
    """M = 0, ζ = 0: over 1e5 steps of 1e-8 s (≈ 75 periods of the slowest patch) the energy oscillates by
    O(hω) (Euler, hω_max ≈ 0.01) or O((hω)²) (Strang) and does not drift (first and last tenth agree)."""
    scene = spring_scene(material=Material(damping_ratio=0.0), initial=Initial(perturbation=0.05, seed=1))
    model, _, u, v = recorded_run(scene, integrator, 1e-8, STEPS, every=10)
    e = energy(model, u, v)
    assert u[0].tolist() == [0.0] * model.patch_count and e[0] > 0
    tenth = len(e) // 10
    assert np.ptp(e) / e[0] < osc_bound
    assert abs(e[-tenth:].mean() / e[:tenth].mean() - 1.0) < drift_bound


def balance_residual(scene: Scene, integrator: str, dt: float, duration: float = 2e-5):
    """Energy balance from per-step u, u̇: returns (max_t |E − E₀ − W_f + W_d|, W_f(T), W_d(T)) [J].

    W_f = ∫ Σ F_N,i f(ω r_i − u̇_i) u̇_i dt and W_d = ∫ Σ c_i u̇_i² dt by the trapezoid rule."""
    model, t, u, v = recorded_run(scene, integrator, dt, round(duration / dt))
    fn = model.host("normal_force").astype(np.float64)
    r = model.host("radius").astype(np.float64)
    c = model.host("damping").astype(np.float64)
    power_f = (fn * scene.friction.coefficient(scene.angular_velocity * r - v) * v).sum(axis=1)
    power_d = (c * v**2).sum(axis=1)

    def integral(p: np.ndarray) -> np.ndarray:
        return np.concatenate([[0.0], np.cumsum(0.5 * (p[1:] + p[:-1]) * np.diff(t))])

    w_f, w_d = integral(power_f), integral(power_d)
    e = energy(model, u, v)
    return float(np.max(np.abs(e - e[0] - w_f + w_d))), float(w_f[-1]), float(w_d[-1])


@pytest.mark.parametrize(
    ("speed", "integrator", "order", "rel_bound", "duration"),
    [
        (10.0, "strang", 2, 1e-6, 1e-5),
        (10.0, "symplectic-euler", 1, 1e-3, 1e-5),
        (0.01, "strang", 2, 1e-2, 2e-5),
        (0.01, "implicit-friction", 1, 2e-3, 2e-5),
    ],
    ids=["sliding-strang", "sliding-euler", "stick-slip-strang", "stick-slip-imex"],
)
def test_energy_balance_closes(speed, integrator, order, rel_bound, duration):
    """With friction (M = 0.8) and damping (ζ = 0.02), E(t) − E(0) = W_friction − W_damping over 10 or 20 µs: the
    residual (max over time) is small against the friction work and falls as dt^order from 2 ns to 1 ns.

    ``sliding``: disc at 10 m/s (no zero crossing of the sliding speed), 10 µs (its largest residual comes within
    them: the ratios are those of 20 µs); ``stick-slip``: 1 cm/s disc with 0.05 m/s velocity perturbations, so the
    sliding speed crosses zero where friction is stiffest, 20 µs (the friction work of a shorter run is too small
    for the bound)."""
    scene = friction_scene(
        material=Material(damping_ratio=0.02),
        initial=Initial(perturbation=0.05, seed=1),
    ).replace(angular_velocity=speed / 0.13)
    r_coarse, w_f, w_d = balance_residual(scene, integrator, 2e-9, duration)
    r_fine, w_f2, _ = balance_residual(scene, integrator, 1e-9, duration)
    assert w_f > 0 and w_d > 0 and w_f2 == pytest.approx(w_f, rel=1e-2)
    assert r_coarse / abs(w_f) < rel_bound
    ratio = r_coarse / r_fine
    assert 2**order * 0.8 < ratio < 2**order * 1.2, ratio


def test_spring_row_sums_are_numpys_bit_for_bit():
    """The estimate's row sums Σ_j k_ij and Σ_j k_ij / √(m_i m_j), summed natively, equal NumPy's ``bincount`` of the
    same terms bit for bit: on a batch of generated hf1 pads (each a layout of its own, fp32 springs), on random
    graphs with empty rows and on a model without links."""
    from aca_warp.kernels.step_bound import spring_row_sums

    from aca_warp.sweep import load_spec

    def numpy_sums(
        start: np.ndarray, index: np.ndarray, kij: np.ndarray, m: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        n = len(m)
        deg = np.diff(start)
        rows = np.repeat(np.arange(n), deg)
        ksum = np.bincount(rows, kij, minlength=n)
        off = np.bincount(rows, kij / np.sqrt(np.repeat(m, deg) * m[index]), minlength=n) if len(kij) else np.zeros(n)
        return ksum, off

    spec = load_spec({"sweep": {"name": "seeds", "base": "hf1"}, "parameters": {"patches.seed": [1, 2, 3]}})
    model = build_model(spec.scenes(spec.shard_pads(0)), precision="fp32")
    start, index, kij = coupling_matrix(model)
    m = masses(model)
    got, want = spring_row_sums(start, index, kij, m), numpy_sums(start, index, kij, m)
    assert len(kij) > 1000 and all(np.array_equal(a, b) for a, b in zip(got, want, strict=True))
    rng = np.random.default_rng(7)
    for n in (1, 5, 300):
        deg = rng.integers(0, 9, n) * (rng.random(n) < 0.7)  # about a third of the rows empty
        start = np.concatenate([[0], np.cumsum(deg)]).astype(np.int32)
        index = rng.integers(0, n, int(start[-1])).astype(np.int32)
        kij = rng.lognormal(8.0, 2.0, len(index))
        m = rng.lognormal(-12.0, 1.0, n)
        got, want = spring_row_sums(start, index, kij, m), numpy_sums(start, index, kij, m)
        assert all(np.array_equal(a, b) for a, b in zip(got, want, strict=True)), n
    zero = spring_row_sums(np.zeros(4, np.int32), np.zeros(0, np.int32), np.zeros(0), np.ones(3))
    assert all(np.array_equal(a, np.zeros(3)) for a in zero)
    start, index, kij, m = np.array([0, 1, 2]), np.array([1, 0]), np.ones(2), np.ones(2)
    for bad in (
        (start[:2], index, kij, m),  # offsets for one row fewer
        (start, index[:1], kij, m),  # fewer indices than links
        (start, index, kij[:1], m),  # fewer stiffnesses than links
        (start, np.array([1, 2]), kij, m),  # an index past the last row
        (np.array([0, 2, 1]), index, kij, m),  # decreasing offsets
    ):
        with pytest.raises(ValueError, match="spring_row_sums"):
            spring_row_sums(*bad)
