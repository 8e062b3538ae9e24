"""Patch heights: the generator's height laws, the paper presets' load criteria and patches out of contact.

Heights are h_i = height + height_spread·z_i, z_i a standard normal truncated at ±height_truncation or uniform in
[−1, 1], drawn from a stream separate from positions and areas (``PatchGenerator.heights``). The presets
``hf1``…``hf4`` put the paper's clamp force 10 % above the load that brings every patch into contact, with the
matrix free (paper §3.1); ``varying_area`` (hf1's heights) starts matrix-dominated and ends with every patch in
contact and the matrix free (§3.2). References: SciPy's truncated normal, exact load sums, the closed form of
Eq. 10's growth.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from aca_warp.common.errors import SceneError
from aca_warp.hf.contact import load_window, scene_elements, solve_scene_contact
from aca_warp.scene import Friction, Material, Pad, Patches, PatchGenerator, Record, Scene, preset, scene_from_dict

N_STATS = 200_000  # heights drawn for the statistics (no placement: heights() only)


def law(**kw) -> PatchGenerator:
    """A generator of N_STATS patches with mean height 3 µm and the given height keys."""
    return PatchGenerator(**{"count": N_STATS, "height": 3.0e-6, "seed": 5, **kw})


# ------------------------------------------------------------------------------------------ the laws


@pytest.mark.parametrize("cut", [1.0, 2.0, 3.5])
def test_truncated_normal_statistics(cut):
    """Normal law: mean h_0, the truncated normal's standard deviation, bounds h_0 ± c s, and SciPy's CDF (KS)."""
    s = 0.4e-6
    h = law(height_spread=s, height_truncation=cut).heights()
    ref = stats.truncnorm(-cut, cut, loc=3.0e-6, scale=s)
    assert h.shape == (N_STATS,)
    assert h.min() >= 3.0e-6 - cut * s and h.max() <= 3.0e-6 + cut * s
    # the sample reaches close to both cuts (expected gap to the bound ~ 1/(n × density there))
    assert h.min() < 3.0e-6 - (cut - 0.01) * s and h.max() > 3.0e-6 + (cut - 0.01) * s
    se = ref.std() / math.sqrt(N_STATS)
    assert abs(h.mean() - 3.0e-6) < 5 * se
    assert h.std() == pytest.approx(ref.std(), rel=5 / math.sqrt(2 * N_STATS) * 1.5)
    assert stats.kstest(h, ref.cdf).pvalue > 1e-3


def test_uniform_statistics():
    """Uniform law: mean h_0, standard deviation s/√3, bounds h_0 ± s, and the uniform CDF (KS)."""
    s = 0.5e-6
    h = law(height_spread=s, height_law="uniform").heights()
    assert h.min() >= 2.5e-6 and h.max() <= 3.5e-6
    assert h.min() < 2.5e-6 + 1e-3 * s and h.max() > 3.5e-6 - 1e-3 * s
    assert abs(h.mean() - 3.0e-6) < 5 * s / math.sqrt(3 * N_STATS)
    assert h.std() == pytest.approx(s / math.sqrt(3), rel=0.01)
    assert stats.kstest(h, stats.uniform(2.5e-6, 1.0e-6).cdf).pvalue > 1e-3


def test_zero_spread_gives_equal_heights_and_ignores_the_law():
    """height_spread = 0: every height is exactly ``height`` whatever the law."""
    for name in ("normal", "uniform"):
        np.testing.assert_array_equal(law(height_law=name).heights(), 3.0e-6)


def test_heights_are_seeded_and_reproducible():
    """Same seed: the same bits; another seed: other heights; a larger count extends the same stream."""
    a = law(height_spread=0.3e-6).heights()
    np.testing.assert_array_equal(a, law(height_spread=0.3e-6).heights())
    b = law(height_spread=0.3e-6, seed=6).heights()
    assert not np.array_equal(a, b)
    np.testing.assert_array_equal(a[:1000], law(count=1000, height_spread=0.3e-6).heights())
    # the spread scales z: (h - h0) / s is the same draw for every spread
    c = law(height_spread=0.6e-6).heights()
    np.testing.assert_allclose((c - 3.0e-6) / 0.6e-6, (a - 3.0e-6) / 0.3e-6, rtol=0, atol=1e-9)


def test_heights_leave_positions_and_areas_unchanged():
    """A height law draws from its own stream: positions and areas are those of equal heights, bit for bit."""
    pad = Pad()
    flat = PatchGenerator(count=300, seed=3).generate(pad)
    for kw in ({"height_spread": 0.5e-6}, {"height_spread": 1e-6, "height_law": "uniform", "height": 2e-6}):
        p = PatchGenerator(count=300, seed=3, **kw).generate(pad)
        for k in ("x", "y", "area"):
            np.testing.assert_array_equal(getattr(p, k), getattr(flat, k))
        assert np.ptp(p.height) > 0
    # the paper presets keep the positions and areas of their equal-height variants
    for name in ("hf1", "hf2", "varying_area"):
        a, b = preset(name).patches, preset(f"{name}_equal").patches
        for k in ("x", "y", "area"):
            np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
        np.testing.assert_array_equal(b.height, 3.0e-6)


def test_heights_do_not_depend_on_position_or_area():
    """Heights are drawn independently of placement: no correlation with area or radius over a full preset."""
    p = preset("hf1").patches
    n = p.count
    for other in (p.area, p.friction_radius):
        r = np.corrcoef(p.height, other)[0, 1]
        assert abs(r) < 4 / math.sqrt(n)


@pytest.mark.parametrize(
    "kw, match",
    [
        ({"height_spread": -1e-7}, r"patches\.height_spread must be >= 0"),
        ({"height_spread": math.nan}, r"patches\.height_spread must be finite"),
        ({"height_spread": 1e-7, "height_law": "lognormal"}, r"patches\.height_law must be one of normal, uniform"),
        ({"height_spread": 1e-7, "height_truncation": 0.0}, r"patches\.height_truncation must be > 0"),
        ({"height_spread": 2e-6}, r"lowest patch would lie below the matrix"),  # 3 µm − 2 × 2 µm < 0
        ({"height_spread": 3.1e-6, "height_law": "uniform"}, r"lowest patch would lie below the matrix"),
    ],
)
def test_bad_height_laws_are_rejected(kw, match):
    """Invalid height keys are SceneErrors naming the key; a law reaching below the matrix is refused."""
    with pytest.raises(SceneError, match=match):
        PatchGenerator(count=5, height=3e-6, **kw)


def test_height_keys_in_toml_documents():
    """``[patches] height_spread/height_law/height_truncation`` are read; the source names the law."""
    doc = {
        "load": {"normal_force": 10.0},
        "patches": {"count": 30, "height": 2e-6, "height_spread": 0.5e-6, "height_law": "uniform", "seed": 4},
        "record": {"sample_dt": 1e-7},
        "run": {"duration": 1e-5},
    }
    s = scene_from_dict(doc)
    assert s.patches.height.min() >= 1.5e-6 and s.patches.height.max() <= 2.5e-6
    assert "law=uniform" in s.patches.source and "height_spread=5e-07" in s.patches.source
    doc["patches"]["height_spread"] = 0.0
    assert "law" not in scene_from_dict(doc).patches.source  # equal heights: the source reads as before


# ------------------------------------------------------------------------------------------ load criteria


def grown_sqrt_area(scene: Scene) -> np.ndarray:
    """√A after the run's growth (Eq. 10, A ← A + c√A each event): √A + c/2 per event to O(c²/√A) [m]."""
    events = int(scene.duration / scene.growth.interval)
    return np.sqrt(scene.patches.area) + 0.5 * scene.growth.increment * events


def gap_and_forces(scene: Scene, sqrt_area: np.ndarray | None = None) -> tuple[float, np.ndarray, float]:
    """Reference contact with every patch in contact: g = (Σk h − F_N)/Σk (matrix at 0 not reached), forces."""
    sq = np.sqrt(scene.patches.area) if sqrt_area is None else sqrt_area
    k = scene.material.K_N * sq
    h = scene.patches.height
    g = (np.sum(k * h) - scene.normal_force) / k.sum()
    return g, k * (h - g), float(np.sum(k * (h - h.min())))


@pytest.mark.parametrize("name", ["hf1", "hf2", "hf3", "hf4"])
def test_paper_presets_have_every_patch_in_contact_and_the_matrix_free(name):
    """§3.1: every patch touches, the matrix carries nothing; F_N is 10–11 % above the all-in-contact load."""
    s = preset(name)
    g, f_ref, f_all = gap_and_forces(s)
    sol = solve_scene_contact(s)
    assert np.all(sol.patch_force > 0.0)
    assert sol.matrix_force.sum() == 0.0 and sol.patch_share == 1.0
    assert 0.0 <= sol.gap <= s.patches.height.min()
    assert sol.gap == pytest.approx(g, rel=1e-12)
    np.testing.assert_allclose(sol.patch_force, f_ref, rtol=1e-9)
    win = load_window(s)
    assert win.all_in_contact == pytest.approx(f_all, rel=1e-12)
    assert win.holds(s.normal_force)
    assert 0.10 <= win.margin(s.normal_force) <= 0.11
    # the heights do spread: without the 10 % margin some patches would lose contact
    low = solve_scene_contact(s.replace(normal_force=0.95 * win.all_in_contact))
    assert 0 < np.count_nonzero(low.patch_force == 0.0) < s.patches.count


def test_varying_area_starts_matrix_dominated_and_ends_on_the_patches():
    """§3.2: HF1 patches (hf1's heights) under the HF2 load: matrix share > 1/2 at the start, every patch in
    contact throughout; at the end of the growth (HF2-size areas) all of the load on the patches."""
    s = preset("varying_area")
    np.testing.assert_array_equal(s.patches.height, preset("hf1").patches.height)
    sol = solve_scene_contact(s)
    assert np.all(sol.patch_force > 0.0)
    assert 0.5 < 1.0 - sol.patch_share < 0.6
    sq = grown_sqrt_area(s)
    assert (sq**2).mean() == pytest.approx(1.25e-6, rel=0.03)  # HF2's mean area
    end = solve_scene_contact(s, area=sq**2)
    g, f_ref, f_all = gap_and_forces(s, sq)
    assert np.all(end.patch_force > 0.0) and end.matrix_force.sum() == 0.0
    assert end.gap == pytest.approx(g, rel=1e-12)
    np.testing.assert_allclose(end.patch_force, f_ref, rtol=1e-9)
    assert load_window(s, area=sq**2).holds(s.normal_force)


def test_preset_stats_script_matches_the_references():
    """scripts/preset_stats.py: the grown areas follow Eq. 10's closed form, the stats match the reference contact,
    and --derive gives back the presets' spreads."""
    from scriptload import load_script

    ps = load_script("preset_stats")
    s = preset("varying_area").replace(duration=2.02e-7 * 5000)
    a = ps.grown_area(s)
    # √(s² + c s) = s √(1 + c/s) lies in [s + c/2 − c²/(8s), s + c/2]: the closed form bounds n events from above
    c, sq0 = s.growth.increment, np.sqrt(s.patches.area)
    assert np.all(np.sqrt(a) <= grown_sqrt_area(s) * (1 + 1e-15))
    assert np.all(np.sqrt(a) >= grown_sqrt_area(s) - 5000 * c**2 / (8 * sq0) * (1 + 1e-9))
    assert np.all(grown_sqrt_area(s) - np.sqrt(a) > 0.5 * 5000 * c**2 / (8 * np.sqrt(a)))  # and the bound is tight
    h1 = preset("hf1")
    st = ps.preset_stats(h1)
    g, f, f_all = gap_and_forces(h1)
    assert st["in_contact"] == 1758 and st["matrix_share"] == 0.0
    assert st["gap"] == pytest.approx(g, rel=1e-12)
    assert st["all_in_contact_ratio"] == pytest.approx(h1.normal_force / f_all, rel=1e-12)
    p = f / h1.patches.area
    assert st["pressure"] == pytest.approx((p.min(), np.median(p), p.max()), rel=1e-9)
    for name in ("hf1", "hf2"):
        s = preset(name)
        assert ps.derive_spread(s, 0.10) == s.origin["patches"]["height_spread"]


# ------------------------------------------------------------------------------------------ out of contact


def test_friction_derivative_matches_finite_differences():
    """Friction.derivative is the slope of the signed Eq. 4 (central differences), negative at 10 m/s."""
    f = Friction(M=0.8)
    v = np.array([-12.0, -0.3, -1e-3, 1e-4, 0.02, 1.0, 10.0, 40.0])
    eps = 1e-7 * np.maximum(np.abs(v), 1e-3)
    fd = (f.coefficient(v + eps) - f.coefficient(v - eps)) / (2 * eps)
    np.testing.assert_allclose(f.derivative(v), fd, rtol=1e-6)
    assert f.derivative(0.0) == pytest.approx(f.max_slope(), rel=1e-15)
    assert f.derivative(10.0) < 0.0


def uncoupled_scene(load: float) -> Scene:
    """20 uncoupled patches in a row, heights 3.0–3.95 µm, so a small load leaves the low ones out of contact."""
    n = 20
    p = Patches(
        x=np.linspace(-0.02, 0.02, n), y=np.full(n, 0.13), area=np.full(n, 5e-8), height=3e-6 + 5e-8 * np.arange(n)
    )
    return Scene(
        name="steps",
        pad=Pad(),
        patches=p,
        normal_force=load,
        material=Material(coupling_radius=0.0),
        record=Record(sample_dt=1e-7),
        duration=2e-6,
    )


@pytest.mark.parametrize("integrator", ["symplectic-euler", "implicit-friction", "strang", "adaptive"])
def test_patches_out_of_contact_feel_no_friction(integrator):
    """F_N,i = 0 patches: finite mass and stiffness, zero friction force, so from rest they stay exactly at rest while
    the patches in contact are pushed along the disc; μ counts only the loaded patches."""
    from aca_warp.hf.loop import run_hf
    from aca_warp.hf.model import build_model
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.state import initial_state

    s = uncoupled_scene(load=0.5)
    sol = solve_scene_contact(s)
    out = sol.patch_force == 0.0
    assert 3 <= np.count_nonzero(~out) < s.patches.count - 3
    model = build_model([s], device="cpu", precision="fp64")
    np.testing.assert_array_equal(model.host("normal_force"), sol.patch_force)
    assert np.all(np.isfinite(model.host("inv_mass"))) and np.all(model.host("k_t") > 0)
    state = initial_state(model)
    res = run_hf(model, state, RunOptions(duration=s.duration, integrator=integrator, dt=1e-8))
    assert res.complete
    u, v = state.numpy()
    assert np.all(u[out] == 0.0) and np.all(v[out] == 0.0)
    assert np.all(u[~out] > 0.0)
    mu = np.concatenate([c.globals for c in res.chunks])[:, 0, 0]
    f_disc = s.friction.coefficient(s.angular_velocity * s.patches.friction_radius)
    # at the first sample the loaded patches still slide at ≈ ω r: μ ≈ Σ F_N,i f(ω r_i) / F_N
    assert mu[0] == pytest.approx(np.sum(sol.patch_force * f_disc) / s.normal_force, rel=1e-3)


def test_device_contact_resolve_with_spread_heights():
    """The growth events' device re-solve (kernels/hf.py contact_flat, CPU) equals the host's exact solve for spread
    heights at loads that leave many patches out of contact, bring all in, or reach the matrix, from warm starts
    on either side of the root; patches out of contact get exactly 0."""
    import warp as wp
    from aca_warp.kernels.hf import contact_flat
    from aca_warp.kernels.hf_types import HFModel

    from aca_warp.hf.model import build_model

    s = preset("varying_area")
    model = build_model([s], device="cpu", precision="fp64")
    m = model.arrays
    k, h = scene_elements(s)
    win = load_window(s)
    for load in (1e-3, 2.0, 0.3 * win.all_in_contact, 1.02 * win.all_in_contact, 0.5 * win.matrix_contact, 3e4):
        for warm in (-5e-6, 3.4e-6, 10e-6):  # left of every root, inside the heights, right of every root
            m["pad_load"].assign(np.array([load]))
            gap = wp.array([warm], dtype=wp.float64, device="cpu")
            fn = wp.zeros_like(m["normal_force"])
            mf = wp.zeros_like(m["pad_matrix_force"])
            mr = wp.zeros_like(m["pad_matrix_radius"])
            km = HFModel.of(
                wp.float64, {**m, "pad_gap": gap, "normal_force": fn, "pad_matrix_force": mf, "pad_matrix_radius": mr}
            )
            wp.launch_tiled(
                contact_flat,
                dim=[1],
                block_dim=1,
                device="cpu",
                inputs=[km, wp.zeros(1, dtype=wp.int64, device="cpu"), 1, 1],
            )
            ref = solve_scene_contact(s.replace(normal_force=load))
            assert gap.numpy()[0] == pytest.approx(ref.gap, rel=1e-12, abs=1e-20)
            np.testing.assert_allclose(fn.numpy(), ref.patch_force, rtol=1e-9, atol=1e-12 * load)
            np.testing.assert_array_equal(fn.numpy() == 0.0, ref.patch_force == 0.0)
            assert mf.numpy()[0] == pytest.approx(ref.matrix_force.sum(), rel=1e-9, abs=1e-12 * load)
            assert fn.numpy().sum() + mf.numpy()[0] == pytest.approx(load, rel=1e-12)
    assert np.ptp(h[: s.patches.count]) > 0 and k.size == s.patches.count + 1


def test_growth_moves_the_contact_in_both_engines():
    """hf1 under 300 N (below its all-in-contact load 442 N) with fast growth: stiffer patches lift the disc, so the
    growth events' re-solves take the lowest patches out of contact; the forces balance the load and equal the
    host's exact solve at the grown areas; the on-chip engine gives the general engine's bits (CPU)."""
    from aca_warp.hf.loop import run_hf
    from aca_warp.hf.model import build_model
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.state import initial_state
    from aca_warp.scene import Growth

    s = preset("hf1").replace(
        normal_force=300.0, record=Record(sample_dt=1e-7), growth=Growth(increment=1e-6, interval=2e-7)
    )
    start = solve_scene_contact(s)
    touching0 = np.count_nonzero(start.patch_force > 0)
    out = []
    for engine in ("general", "onchip"):
        model = build_model([s], device="cpu", precision="fp64")
        state = initial_state(model)
        assert run_hf(model, state, RunOptions(integrator="strang", duration=1e-6, dt=1e-8, engine=engine)).complete
        f = model.host("normal_force")
        ref = solve_scene_contact(s, area=model.host("area"))
        np.testing.assert_allclose(f, ref.patch_force, rtol=1e-9, atol=1e-12 * s.normal_force)
        np.testing.assert_array_equal(f == 0.0, ref.patch_force == 0.0)
        assert f.sum() + model.host("pad_matrix_force")[0] == pytest.approx(300.0, rel=1e-12)
        assert 0 < np.count_nonzero(f > 0) < touching0 < s.patches.count
        assert model.host("pad_gap")[0] == pytest.approx(ref.gap, rel=1e-12) and ref.gap > start.gap
        out.append((f, *state.numpy()))
    for a, b in zip(*out, strict=True):
        np.testing.assert_array_equal(a, b)
