"""Extreme scenes (docs/stability.md): each runs bounded with finite outputs, or is refused before running with a
clear SceneError / StabilityError.

Runs use the default integrator and step (``strang``, 5e-8 s) for 250 µs from rest unless a case needs otherwise;
strang's step is bounded by the springs only, so the cases far beyond the friction rate (tiny patches, 100 kN, no
matrix) run unforced.
*Bounded* means: complete, every recorded value finite, |μ| ≤ max(M, μ_pad), and every patch velocity below

    B = max|ω r| + 3 max_i F_N,i M / √(k_T,i m_i) + 3 √(2E₀/m_min),

the disc speed plus three times the largest velocity amplitude a constant friction force F_N,i M excites in an
isolated patch started from rest (u_s ω = F/√(k m)), plus three times the energy bound of the initial
perturbation (zero unless a case sets one). Where symplectic Euler's estimate is below the default step, the
explicit scheme is refused at that step (StabilityError naming the friction slope) while ``strang`` runs.

``python tests/test_extreme.py`` prints the table of docs/stability.md from fresh runs.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest

from aca_warp.common.errors import SceneError, StabilityError
from aca_warp.hf.loop import EngineTuning, run_hf
from aca_warp.hf.model import PadModel, build_model, coupling_matrix
from aca_warp.hf.options import DEFAULT_DT, RunOptions, default_step
from aca_warp.hf.state import initial_state
from aca_warp.scene import Friction, Initial, Material, Matrix, Pad, Patches, Record, Scene

GRAPH_STEPS = 32  # short graphs: a CPU capture costs more per step the longer the graph (5000 steps of 30 patches
# sampled every 10 steps: 0.08 s of CPU in graphs of 32 steps, 0.38 s in graphs of 256)
DURATION = 2.5e-4  # s: 5000 default steps
RECORD = Record(sample_dt=1e-7, patches=("velocity",))
HF1_LOAD = 487.2  # N
R0 = 0.13  # m: friction radius of the test clusters
K_C = 7.96e8


# ------------------------------------------------------------------------------- geometry


def grid(n: int = 30, spacing: float = 1.2e-3, area: tuple[float, float] = (2e-8, 8e-8), height=3e-6, seed=1):
    """``n`` patches (areas uniform in ``area``, seeded) on a square grid of ``spacing`` around (0, R0)."""
    side = math.ceil(math.sqrt(n))
    ij = np.array([divmod(a, side) for a in range(n)], dtype=float)
    a = np.random.default_rng(seed).uniform(*area, n)
    h = np.broadcast_to(np.asarray(height, dtype=float), (n,)).copy()
    return Patches((ij[:, 1] - side / 2) * spacing, R0 + (ij[:, 0] - side / 2) * spacing, a, h)


def hexagonal(rings: int = 2, area: float = 5e-8, gap: float = 1e-9) -> Patches:
    """Equal patches on a hexagonal lattice (1 + 3 rings (rings + 1) of them), neighbours ``gap`` apart."""
    a = 2 * math.sqrt(area / math.pi) + gap
    pts = [(q, r) for q in range(-rings, rings + 1) for r in range(-rings, rings + 1) if abs(q + r) <= rings]
    x = np.array([a * (q + r / 2) for q, r in pts])
    y = R0 + np.array([a * r * math.sqrt(3) / 2 for q, r in pts])
    return Patches(x, y, np.full(len(pts), area), np.full(len(pts), 3e-6))


def in_disc(n: int = 40, diameter: float = 5e-3, seed: int = 2) -> Patches:
    """``n`` non-overlapping HF1-size patches with every centre inside one disc of ``diameter`` (all pairs coupled)."""
    rng = np.random.default_rng(seed)
    area = rng.uniform(2e-8, 8e-8, n)
    rad = np.sqrt(area / np.pi)
    xy: list[tuple[float, float]] = []
    for i in range(n):
        while True:
            p = rng.uniform(-diameter / 2, diameter / 2, 2)
            if np.hypot(*p) <= diameter / 2 and all(np.hypot(*(p - q)) >= rad[i] + rad[j] for j, q in enumerate(xy)):
                xy.append(p)
                break
    xy_a = np.array(xy)
    return Patches(xy_a[:, 0], R0 + xy_a[:, 1], area, np.full(n, 3e-6))


def row(areas: list[float], gap: float = 1e-4, height: float = 3e-6) -> Patches:
    """Patches of ``areas`` side by side along x at y = R0, ``gap`` between neighbouring edges."""
    rad = np.sqrt(np.asarray(areas) / np.pi)
    x = np.concatenate([[0.0], np.cumsum(rad[:-1] + rad[1:] + gap)])
    return Patches(x - x.mean(), np.full(len(areas), R0), np.asarray(areas, float), np.full(len(areas), height))


def scene(patches: Patches | None = None, **kw) -> Scene:
    """A scene on the default pad: 30-patch grid, HF1 load, 10 m/s at R0, M = 0.8, from rest."""
    kw.setdefault("normal_force", HF1_LOAD)
    kw.setdefault("angular_velocity", 10.0 / R0)
    return Scene(name="extreme", pad=Pad(), patches=patches if patches is not None else grid(), **kw)


def raised_matrix(patches: Patches, elevation: float) -> Matrix:
    """One matrix cell covering the free pad area, raised to ``elevation`` [m] (above the patch tops)."""
    pad = Pad()
    fresh = Matrix.fresh(pad, patches)
    return Matrix(fresh.area, fresh.radius, np.array([elevation]))


# ------------------------------------------------------------------------------- cases


@dataclass(frozen=True)
class Case:
    """One extreme case: how to build it, and what must happen.

    Attributes:
        name: Case id (pytest id and table row).
        what: One-line description for the table.
        build: Builds the scene (may raise SceneError: the case is refused at validation).
        refused: None when the case must run bounded, else (error type, regex the message must match).
        integrator: Integrator of the run.
        dt: Step [s] (None: the default).
    """

    name: str
    what: str
    build: Callable[[], Scene]
    refused: tuple[type, str] | None = None
    integrator: str = "strang"
    dt: float | None = None


TINY = grid(20, 1e-4, (1e-10, 1e-10))
CASES = [
    # areas
    Case("area-tiny", "20 patches of 1e-10 m² (11 µm), 0.1 mm grid", lambda: scene(TINY)),
    Case(
        "area-huge",
        "3 patches of 1e-4 m² (11.3 mm), coupled (coupling radius 25 mm)",
        lambda: scene(row([1e-4] * 3, 1e-3), material=Material(coupling_radius=0.025)),
    ),
    Case(
        "area-mixed",
        "1e-4 m² and 1e-10 m² patches alternating, 1 µm apart, coupled",
        lambda: scene(row([1e-4, 1e-10, 1e-4, 1e-10, 1e-10], 1e-6), material=Material(coupling_radius=0.025)),
    ),
    Case(
        "area-zero", "a patch of area 0", lambda: scene(row([5e-8, 0.0])), (SceneError, r"patch areas must be > 0 m²")
    ),
    Case(
        "area-outside",
        "a 1e-4 m² patch 1 mm from the outer edge",
        lambda: scene(Patches([0.0], [0.159], [1e-4], [3e-6])),
        (SceneError, r"1 patch\(es\) lie \(partly\) outside the pad, first is patch 0 at \(0, 0\.159\) m"),
    ),
    # loads
    Case("load-1mN", "1 mN on the 30-patch grid", lambda: scene(normal_force=1e-3)),
    Case("load-100kN", "100 kN on the 30-patch grid", lambda: scene(normal_force=1e5)),
    Case("load-100kN-tiny", "100 kN on the 1e-10 m² patches (stiffest case)", lambda: scene(TINY, normal_force=1e5)),
    Case(
        "load-negative", "F_N = -1 N", lambda: scene(normal_force=-1.0), (SceneError, r"load.normal_force must be >= 0")
    ),
    # friction factor
    Case("M-0", "M = 0 (patches frictionless, matrix Coulomb)", lambda: scene(friction=Friction(M=0.0))),
    Case("M-0.1", "M = 0.1", lambda: scene(friction=Friction(M=0.1))),
    Case("M-2", "M = 2", lambda: scene(friction=Friction(M=2.0))),
    # disc speed
    Case(
        "speed-0",
        "disc at rest, perturbed (σ = 1 mm/s)",
        lambda: scene(angular_velocity=0.0, initial=Initial(perturbation=1e-3, seed=1)),
    ),
    Case("speed-1e-4", "1e-4 m/s at R0 (stick-slip)", lambda: scene(angular_velocity=1e-4 / R0)),
    Case("speed-50", "50 m/s at R0", lambda: scene(angular_velocity=50.0 / R0)),
    Case("speed-negative", "-10 m/s at R0", lambda: scene(angular_velocity=-10.0 / R0)),
    Case(
        "speed-nan",
        "ω = NaN",
        lambda: scene(angular_velocity=math.nan),
        (SceneError, r"disc.angular_velocity must be finite"),
    ),
    # topology
    Case("single", "one HF1-size patch, 1 N", lambda: scene(row([5e-8]), normal_force=1.0)),
    Case("no-coupling", "coupling_radius = 0", lambda: scene(material=Material(coupling_radius=0.0))),
    Case("far-apart", "5 patches 20 mm apart (default coupling radius)", lambda: scene(row([5e-8] * 5, 2e-2))),
    Case("near-touching", "19 patches, hexagonal, edges 1e-9 m apart", lambda: scene(hexagonal())),
    Case(
        "overlap",
        "two patches overlapping by 1e-9 m",
        lambda: scene(row([5e-8, 5e-8], -1e-9)),
        (
            SceneError,
            r"1 pair\(s\) of patches overlap, first patches 0 and 1: centre distance 0.0002523 m < sum of radii "
            r"0.0002523 m \(overlap 1e-09 m\)",
        ),
    ),
    Case("one-disc", "40 patches inside one 5 mm disc (fully coupled)", lambda: scene(in_disc())),
    # contact
    Case(
        "one-patch-loaded",
        "1 mN, one patch 1 µm taller than the rest",
        lambda: scene(grid(height=np.r_[3e-6, np.full(29, 2e-6)]), normal_force=1e-3),
    ),
    Case("heights-0", "patch heights 0: patches and matrix share", lambda: scene(grid(height=0.0))),
    Case(
        "matrix-all",
        "matrix raised 10 µm: it carries the whole load",
        lambda: scene(matrix=raised_matrix(grid(), 1e-5)),
    ),
    Case(
        "matrix-none",
        "matrix of area 0: the patches carry the whole load",
        lambda: scene(matrix=Matrix(np.zeros(1), np.array([R0]), np.zeros(1))),
    ),
    # steps
    Case(
        "explicit-default-dt",
        "symplectic-euler at the default 1e-8 s, 100 kN on the grid",
        lambda: scene(normal_force=1e5),
        (
            StabilityError,
            r"dt = 1e-08 s exceeds the stable-step estimate 8.8\de-10 s of symplectic-euler \(springs 2.02e-06 s, "
            r"friction slope 8.8\de-10 s\); choose a smaller dt, an implicit-friction integrator "
            r"\(strang, implicit-friction\), or force=True$",
        ),
        integrator="symplectic-euler",
    ),
    Case(
        "strang-1e-5",
        "strang at dt = 1e-5 s (past the spring limit)",
        lambda: scene(),
        (
            StabilityError,
            r"dt = 1e-05 s exceeds the stable-step estimate 2.02e-06 s of strang \(springs 2.02e-06 s, .*\); "
            r"choose a smaller dt \(the springs bound every fixed-step scheme\), integrator='adaptive', or "
            r"force=True$",
        ),
        dt=1e-5,
    ),
]
RUNS = [c for c in CASES if c.refused is None]
REFUSALS = [c for c in CASES if c.refused is not None]


@dataclass
class Outcome:
    """What a case did: the model, the estimate, the run's result and recording, and the velocity bound."""

    scene: Scene
    model: PadModel
    result: object
    chunk: object
    bound: float


def velocity_bound(s: Scene, model: PadModel, v0: np.ndarray) -> float:
    """B of the module docstring [m/s]."""
    m = 1.0 / model.host("inv_mass").astype(np.float64)
    k = model.host("k_t").astype(np.float64)
    fn = model.host("normal_force").astype(np.float64)
    vd = np.abs(s.angular_velocity * model.host("radius").astype(np.float64))
    e0 = 0.5 * float(np.sum(m * v0**2))
    return float(vd.max() + 3.0 * np.max(fn * s.friction.M / np.sqrt(k * m)) + 3.0 * math.sqrt(2 * e0 / m.min()))


def attempt(case: Case, *, precision: str = "fp64", duration: float = DURATION, record: Record = RECORD) -> Outcome:
    """Build and run a case (exceptions propagate)."""
    s = case.build()
    model = build_model([s], precision=precision)
    state = initial_state(model)
    bound = velocity_bound(s, model, state.numpy()[1].astype(np.float64))
    opts = RunOptions(duration=duration, integrator=case.integrator, dt=case.dt)
    res = run_hf(model, state, opts, record=record, tuning=EngineTuning(max_graph_steps=GRAPH_STEPS))
    return Outcome(s, model, res, res.collect(), bound)


def mu_limit(s: Scene) -> float:
    """max(M, μ_pad): |μ| cannot exceed it (|f| ≤ M on the patches, Coulomb on the matrix)."""
    return max(s.friction.M, s.friction.mu_pad)


def assert_bounded(o: Outcome) -> None:
    """Complete, finite, |μ| ≤ max(M, μ_pad), |u̇| < B."""
    res, c = o.result, o.chunk
    assert res.complete and res.fault is None
    assert np.all(np.isfinite(c.globals)) and np.all(np.isfinite(c.velocity))
    assert np.max(np.abs(c.globals[:, 0, 0])) <= mu_limit(o.scene) * (1 + 1e-12)
    assert np.max(np.abs(c.velocity)) < o.bound


# ------------------------------------------------------------------------------- the table's tests


@pytest.fixture(scope="module")
def outcomes() -> dict[str, Outcome]:
    """Every running case, run once per module (several tests look at the same run)."""
    return {c.name: attempt(c) for c in RUNS}


@pytest.mark.parametrize("case", RUNS, ids=[c.name for c in RUNS])
def test_case_runs_bounded(case, outcomes):
    """The case runs 250 µs with strang at its default step (5e-8 s): complete, finite, |μ| ≤ max(M, μ_pad),
    |u̇| < B. Where the explicit estimate is below symplectic Euler's default step (1e-8 s), symplectic-euler is
    refused at that step with a message that names the friction slope (or springs) and suggests an implicit
    integrator; elsewhere it runs bounded too."""
    o = outcomes[case.name]
    assert_bounded(o)
    est = o.result.estimate
    assert est.spring > default_step("strang")  # within 1e-10..1e-4 m² strang's default is below the spring limit
    model = o.model
    if est.explicit < DEFAULT_DT:
        hint = r"exceeds the stable-step estimate .* an implicit-friction integrator \(strang, implicit-friction\)"
        with pytest.raises(StabilityError, match=hint):
            run_hf(model, initial_state(model), RunOptions(duration=DURATION, integrator="symplectic-euler"))
    else:
        explicit = attempt(Case(case.name, case.what, case.build, integrator="symplectic-euler"))
        assert_bounded(explicit)


def refusal_record(case: Case) -> Record:
    """The record of a case that is to be refused: samples at least its step apart, so that the step checked is the
    one asked for (a run shortens its step to fit a sample interval)."""
    return Record(sample_dt=max(RECORD.sample_dt, case.dt or default_step(case.integrator)), patches=("velocity",))


@pytest.mark.parametrize("case", REFUSALS, ids=[c.name for c in REFUSALS])
def test_case_refused_before_running(case):
    """The case is refused before any step, with the error type and message of the table."""
    kind, pattern = case.refused
    with pytest.raises(kind, match=pattern) as info:
        attempt(case, record=refusal_record(case))
    assert type(info.value) is kind
    assert "\n" not in str(info.value)  # one line, as the CLI prints it


# ------------------------------------------------------------------------------- case details


def test_tiny_and_huge_patch_estimates(outcomes):
    """Tiny patches are the stiff ones: ω ∝ A^(−1/4) and the friction time constant m/(F_N f′) ∝ A/F_N. An isolated
    1e-10 m² patch has 2/ω = 9.0e-7 s; coupling lowers the estimate: on the 0.1 mm grid the tiny patches couple
    to each other (k_ij up to 0.04 k_T), in the mixed row a tiny patch 1 µm from a huge one gets
    k_ij = K_C √(A_t A_h)/D ≈ 0.75 k_T,tiny per huge neighbour (the most a link can add: K_C √π / K_T = 0.755).
    Friction ≈ 1e-9 s under the HF1 load."""
    tiny = outcomes["area-tiny"].result.estimate
    huge = outcomes["area-huge"].result.estimate
    mixed = outcomes["area-mixed"]
    w_tiny = math.sqrt(1.87e9 * 1e-5 / (37.5 * 1e-10))
    assert 0.5 * (2 / w_tiny) < tiny.spring < 2 / w_tiny
    assert 0.5 * (2 / w_tiny) < mixed.result.estimate.spring < 2 / w_tiny
    assert huge.spring > 10 * tiny.spring
    assert tiny.friction < 1e-8 < huge.friction
    start, index, kij = coupling_matrix(mixed.model)
    k_t = mixed.model.host("k_t")
    link = start[1] + int(np.flatnonzero(index[start[1] : start[2]] == 0)[0])  # tiny patch 1 → huge patch 0
    assert kij[link] / k_t[1] == pytest.approx(0.75, abs=0.01)


def test_loads_span_eight_decades(outcomes):
    """1 mN sits on the patches alone; 100 kN mostly on the matrix (0.8 % on the patches, compressed 51 µm); μ
    varies by less than 0.1 over the run in both."""
    low = outcomes["load-1mN"].model.contacts[0]
    high = outcomes["load-100kN"].model.contacts[0]
    assert low.patch_share == 1.0 and low.total == pytest.approx(1e-3, rel=1e-12)
    assert 0.005 < high.patch_share < 0.02 and high.gap < -4e-5
    for name in ("load-1mN", "load-100kN"):
        c = outcomes[name].chunk
        assert np.ptp(c.globals[:, 0, 0]) < 0.1


def test_friction_factor_cases(outcomes):
    """M = 0: μ = μ_pad F_matrix/F_N exactly and the patches never move; M = 0.1 and 2 stay within their bounds."""
    o = outcomes["M-0"]
    share_m = 1.0 - o.model.contacts[0].patch_share
    np.testing.assert_allclose(o.chunk.globals[:, 0, 0], 0.3 * share_m, rtol=1e-12)
    assert np.all(o.chunk.velocity == 0.0)
    for name, m in (("M-0.1", 0.1), ("M-2", 2.0)):
        mu = outcomes[name].chunk.globals[:, 0, 0]
        assert np.all(mu > 0) and mu.max() <= max(m, 0.3)


def test_negative_speed_mirrors_positive():
    """ω < 0 from rest is the mirror image of ω > 0: μ and torque change sign, the friction radius does not."""
    pos = attempt(Case("speed+10", "", lambda: scene(angular_velocity=10.0 / R0)))
    neg = attempt(next(c for c in CASES if c.name == "speed-negative"))
    gp, gn = pos.chunk.globals[:, 0], neg.chunk.globals[:, 0]
    assert np.all(gp[1:, 0] > 0) and np.all(gn[1:, 0] < 0)
    np.testing.assert_allclose(gn[:, 0], -gp[:, 0], rtol=1e-12, atol=0)
    np.testing.assert_allclose(gn[:, 1], -gp[:, 1], rtol=1e-12, atol=0)
    np.testing.assert_allclose(gn[:, 2], gp[:, 2], rtol=1e-12)
    np.testing.assert_allclose(neg.chunk.velocity, -pos.chunk.velocity, rtol=1e-12, atol=0)


def test_speed_extremes(outcomes):
    """At rest the matrix has no friction (sign ω = 0), the perturbation dies out (friction only dissipates) and
    μ falls from its initial Σ F_N,i f(−u̇_i)/F_N to ~0; at 1e-4 m/s the
    patches stick (velocities ≈ the disc speed); at 50 m/s μ is below its 10 m/s value (Eq. 4 falls with speed)."""
    o = outcomes["speed-0"]
    rest = o.chunk
    assert np.max(np.abs(rest.velocity[-1])) < 1e-3 * np.max(np.abs(rest.velocity[0]))
    fn = o.model.host("normal_force")
    mu0 = np.sum(fn * o.scene.friction.coefficient(-rest.velocity[0])) / o.scene.normal_force
    assert rest.globals[0, 0, 0] == pytest.approx(mu0, rel=1e-12, abs=1e-15)
    assert abs(rest.globals[-1, 0, 0]) < 1e-3 * abs(mu0)
    slow = outcomes["speed-1e-4"]
    vd = 1e-4 / R0 * slow.model.host("radius")
    assert np.max(np.abs(slow.chunk.velocity[-100:] - vd)) < 1e-4
    fast = outcomes["speed-50"].chunk.globals[:, 0, 0]
    normal = outcomes["speed-negative"].chunk.globals[:, 0, 0]
    assert np.mean(fast) < -np.mean(normal)


def test_topology_cases(outcomes):
    """Single patch and uncoupled patches run without the coupling stage; near-touching patches have finite
    k_ij ≤ K_C √(A_i A_j)/(r_i + r_j) (for equal patches ≈ 0.38 k_T); the 5 mm cluster is fully coupled."""
    for name in ("single", "no-coupling", "far-apart"):
        o = outcomes[name]
        assert o.model.nnz == 0 and "no-coupling" in o.result.stages
    o = outcomes["near-touching"]
    start, index, kij = coupling_matrix(o.model)
    rows = np.repeat(np.arange(o.model.patch_count), np.diff(start))
    a = o.scene.patches.area
    touching = np.isclose(1.0 / kij * K_C * np.sqrt(a[rows] * a[index]), 2 * np.sqrt(a[0] / np.pi) + 1e-9, rtol=1e-9)
    assert touching.sum() == 2 * 42  # 42 touching pairs in a 19-patch hexagon
    assert np.all(np.isfinite(kij)) and kij.max() < 0.4 * o.model.host("k_t").min()
    o = outcomes["one-disc"]
    n = o.model.patch_count
    assert o.model.nnz == n * (n - 1)


def test_contact_cases(outcomes):
    """1 mN on patches of unequal height loads only the tallest; heights 0 share by stiffness; a raised matrix
    carries everything (μ = μ_pad exactly, patches at rest); a matrix of area 0 leaves everything to the patches."""
    fn = outcomes["one-patch-loaded"].model.contacts[0].patch_force
    assert fn[0] == pytest.approx(1e-3, rel=1e-12) and np.all(fn[1:] == 0.0)
    o = outcomes["heights-0"]
    kn = 2.39e9 * np.sqrt(o.scene.patches.area)
    km = 1.85e11 * o.scene.matrix.area[0]
    assert o.model.contacts[0].patch_share == pytest.approx(kn.sum() / (kn.sum() + km), rel=1e-12)
    o = outcomes["matrix-all"]
    assert o.model.contacts[0].patch_share == 0.0
    np.testing.assert_allclose(o.chunk.globals[:, 0, 0], 0.3, rtol=1e-12)
    assert np.all(o.chunk.velocity == 0.0)
    o = outcomes["matrix-none"]
    assert o.model.contacts[0].patch_share == 1.0
    assert np.all(np.isfinite(o.chunk.globals[:, 0, 1:3]))
    r = o.model.host("radius")
    assert r.min() <= o.chunk.globals[-1, 0, 2] <= r.max()


def test_fp32_matches_fp64_on_the_stiffest_case():
    """100 kN on 1e-10 m² patches (friction time constant ≈ 3e-11 s, 300× below the step), 2 µs:

    * strang (default step), every 10th step sampled: μ within 1e-6, torque and Σ|u̇| within 1e-5 relative,
      u and u̇ within 1e-5 and 1e-4 of their maxima;
    * implicit-friction, every step sampled: u̇ within 1e-5 of its maximum.

    (Sampled every step, strang's sticking patches ring from step to step, ±5 % at this γh; the ringing is the
    scheme's, both precisions show it, and single samples of it may differ between them.)"""
    case = next(c for c in CASES if c.name == "load-100kN-tiny")
    for integrator, sample, tol_v in (("strang", 1e-7, 1e-4), ("implicit-friction", 1e-8, 1e-5)):
        runs = {}
        for precision in ("fp64", "fp32"):
            c = Case(case.name, case.what, case.build, integrator=integrator)
            rec = Record(sample_dt=sample, patches=("velocity", "displacement"))
            runs[precision] = attempt(c, precision=precision, duration=2e-6, record=rec).chunk
        a, b = runs["fp64"], runs["fp32"]
        assert b.velocity.dtype == np.float32 and a.velocity.dtype == np.float64
        assert np.max(np.abs(a.globals[:, 0, 0] - b.globals[:, 0, 0])) < 1e-6
        for k in (1, 4):
            assert np.max(np.abs(a.globals[:, 0, k] - b.globals[:, 0, k])) < 1e-5 * np.max(np.abs(a.globals[:, 0, k]))
        assert np.max(np.abs(a.displacement - b.displacement)) < 1e-5 * np.max(np.abs(a.displacement))
        assert np.max(np.abs(a.velocity - b.velocity)) < tol_v * np.max(np.abs(a.velocity))


# ------------------------------------------------------------------------------- table for docs/stability.md


def table_row(case: Case) -> str:
    """One markdown row: case, what, outcome, estimate, observed values."""
    try:
        o = attempt(case, record=refusal_record(case)) if case.refused else attempt(case)
    except (SceneError, StabilityError) as e:
        msg = re.sub(r"\|", "/", str(e))
        return f"| `{case.name}` | {case.what} | refused: {type(e).__name__} | | | “{msg}” |"
    res, c = o.result, o.chunk
    est = res.estimate
    mu = c.globals[:, 0, 0]
    explicit = "refused" if est.explicit < DEFAULT_DT else "runs"
    return (
        f"| `{case.name}` | {case.what} | ran bounded ({case.integrator}, {res.dt:.0e} s) | "
        f"{est.spring:.2g} / {est.friction:.2g} / {est.explicit:.2g} s, explicit at 1e-8 s {explicit} | "
        f"{o.model.contacts[0].patch_share:.3g} | μ ∈ [{mu.min():.4g}, {mu.max():.4g}], "
        f"max\\|u̇\\| = {np.max(np.abs(c.velocity)):.3g} m/s = {np.max(np.abs(c.velocity)) / o.bound:.2g} B |"
    )


if __name__ == "__main__":
    import warp as wp

    wp.config.log_level = getattr(wp, "LOG_WARNING", 0)
    print("| case | scene | outcome | estimate spring / friction / explicit | patch share | observed |")
    print("|---|---|---|---|---|---|")
    for case in CASES:
        print(table_row(case))
