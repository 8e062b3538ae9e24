"""Tests of the normal force distribution (aca_warp.hf.contact; docs/model.md §2.6).

Compression-only springs in parallel: F_i = k_i max(H_i − g, 0), Σ F_i = F_N. The exact piecewise-linear
solve is checked against force balance, a brute-force bisection on g, and the load-sharing statements of
docs/model.md §2.6 for the equal-height presets (HF1/HF2 loads on the patches only; HF1 patches under the HF2 load
share it with the matrix, about half), and the load window (all patches in contact, matrix free) against the solve.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aca_warp.common.errors import SceneError
from aca_warp.hf.contact import load_at_gap, load_window, solve_contact, solve_scene_contact
from aca_warp.scene import Matrix, Pad, Patches, Scene, preset


def bisection_gap(k, h, load, iters=200):
    """Reference: g with Σ k max(h − g, 0) = load by bisection on a bracket (monotone decreasing in g)."""
    k, h = np.asarray(k, float), np.asarray(h, float)
    total = lambda g: float(np.sum(k * np.maximum(h - g, 0.0)))  # noqa: E731
    hi = float(h[k > 0].max())
    lo = float(h[k > 0].min()) - 2.0 * load / k.sum() - 1e-9
    assert total(lo) > load >= total(hi)
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        if total(mid) > load:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def check_solution(k, h, load, sol, n_patches=None):
    """Force balance, non-negative forces, F_i = k_i max(h_i − g, 0), and g equal to the bisection's."""
    k, h = np.asarray(k, float), np.asarray(h, float)
    n = len(k) if n_patches is None else n_patches
    f = np.concatenate([sol.patch_force, sol.matrix_force])
    assert sol.patch_force.shape == (n,) and sol.matrix_force.shape == (len(k) - n,)
    assert np.all(f >= 0.0)
    assert f.sum() == pytest.approx(load, rel=1e-10)
    assert sol.total == pytest.approx(load, rel=1e-10)
    np.testing.assert_allclose(f, k * np.maximum(h - sol.gap, 0.0), rtol=1e-12, atol=1e-12 * load)
    g_ref = bisection_gap(k, h, load)
    scale = max(float(np.ptp(h)), load / k.sum(), 1e-12)
    assert sol.gap == pytest.approx(g_ref, abs=1e-9 * scale)
    # elements not in contact carry nothing, elements in contact are compressed
    assert np.all(f[h < sol.gap - 1e-9 * scale] == 0.0)
    assert np.all(f[(h > sol.gap + 1e-9 * scale) & (k > 0)] > 0.0)


@pytest.mark.parametrize("seed", range(8))
def test_random_sets_balance_and_match_bisection(seed):
    """Random stiffnesses and heights (with ties, zero stiffnesses, negative heights) and random loads."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 60))
    k = rng.uniform(1e4, 1e7, n)
    k[rng.random(n) < 0.2] = 0.0  # some zero-stiffness elements
    k[0] = max(k[0], 1e5)  # at least one carries load
    h = rng.choice(rng.uniform(-2e-6, 5e-6, max(1, n // 3)), n)  # many ties
    for load in (1e-6, 1.0, 50.0, 1e4):
        sol = solve_contact(k, h, load)
        check_solution(k, h, load, sol)


@settings(max_examples=150, deadline=None, database=None, derandomize=True)
@given(
    elems=st.lists(
        st.tuples(
            st.sampled_from([0.0, 1.0, 3.0e5, 2.0e6, 7.7e8]),
            st.sampled_from([-1.0e-6, 0.0, 1.0e-6, 3.0e-6, 3.0e-6 + 1e-12]),
        ),
        min_size=1,
        max_size=30,
    ),
    load=st.floats(1e-9, 1e5),
    matrix_cells=st.integers(0, 3),
)
def test_hypothesis_balance_and_bisection(elems, load, matrix_cells):
    """Property: for any element set with some stiffness, forces balance the load and match bisection."""
    k = np.array([e[0] for e in elems])
    h = np.array([e[1] for e in elems])
    if not np.any(k > 0):
        with pytest.raises(SceneError, match="no contact element has positive stiffness"):
            solve_contact(k, h, load)
        return
    n = max(0, len(k) - matrix_cells)
    sol = solve_contact(k, h, load, n_patches=n)
    check_solution(k, h, load, sol, n_patches=n)


def test_single_element_and_equal_heights():
    """One spring: g = h − F/k. Equal heights: forces in proportion to stiffness."""
    sol = solve_contact(np.array([2.0e6]), np.array([3.0e-6]), 1.0)
    assert sol.gap == pytest.approx(3.0e-6 - 0.5e-6, rel=1e-12)
    k = np.array([1.0e6, 2.0e6, 3.0e6, 0.0])
    sol = solve_contact(k, np.full(4, 1.0e-6), 3.0)
    np.testing.assert_allclose(sol.patch_force, [0.5, 1.0, 1.5, 0.0], rtol=1e-12)
    assert sol.patch_share == 1.0


def test_zero_load_means_no_contact():
    """Load 0: the disc is away (gap = +inf), every force is 0 and the patch share is 0."""
    sol = solve_contact(np.array([1e6, 2e6, 3e6]), np.array([1e-6, 2e-6, 0.0]), 0.0, n_patches=2)
    assert sol.gap == math.inf
    assert sol.patch_force.tolist() == [0.0, 0.0] and sol.matrix_force.tolist() == [0.0]
    assert sol.total == 0.0 and sol.patch_share == 0.0


@pytest.mark.parametrize("load", [-1.0, math.nan, math.inf])
def test_bad_loads_are_rejected(load):
    """A negative or non-finite load is a SceneError."""
    with pytest.raises(SceneError, match="normal force must be finite and >= 0"):
        solve_contact(np.array([1e6]), np.array([1e-6]), load)


def test_no_stiffness_cannot_carry_load():
    """All stiffnesses zero with a positive load is a SceneError."""
    with pytest.raises(SceneError, match="no contact element has positive stiffness"):
        solve_contact(np.zeros(3), np.ones(3) * 1e-6, 1.0)


def test_tiny_load_rests_on_the_highest_patch_only():
    """A load too small to close the 1 µm height difference rests on the highest patch alone."""
    p = Patches(
        x=np.array([-4e-3, 0.0, 4e-3, 8e-3]),
        y=np.full(4, 0.13),
        area=np.full(4, 5e-8),
        height=np.array([3e-6, 4e-6, 3e-6, 2e-6]),
    )
    s = Scene(name="tiny", pad=Pad(), patches=p, normal_force=0.1)
    sol = solve_scene_contact(s)
    k_n = 2.39e9 * math.sqrt(5e-8)
    assert sol.patch_force.tolist() == pytest.approx([0.0, 0.1, 0.0, 0.0], abs=1e-15)
    assert sol.gap == pytest.approx(4e-6 - 0.1 / k_n, rel=1e-12)
    assert sol.matrix_force.tolist() == [0.0]
    assert sol.patch_share == 1.0
    # enough load to close the 1 µm gap brings patches 0 and 2 in, but not patch 3
    s2 = s.replace(normal_force=k_n * 1.5e-6)
    sol2 = solve_scene_contact(s2)
    assert sol2.gap == pytest.approx(3e-6 - 0.5e-6 / 3, rel=1e-9)
    assert sol2.patch_force[3] == 0.0 and np.all(sol2.patch_force[:3] > 0)


def test_raised_matrix_carries_the_whole_load():
    """A matrix cell raised above every patch (e.g. thermal expansion) carries a small load alone."""
    p = Patches(x=np.array([0.0, 4e-3]), y=np.full(2, 0.13), area=np.full(2, 5e-8), height=np.full(2, 3e-6))
    pad = Pad()
    cells = Matrix(area=np.array([4e-3, 7e-3]), radius=np.array([0.12, 0.14]), height=np.array([5e-6, 1e-6]))
    s = Scene(name="raised", pad=pad, patches=p, normal_force=100.0, matrix=cells)
    sol = solve_scene_contact(s)
    k_m = 1.85e11 * 4e-3
    assert sol.patch_force.tolist() == [0.0, 0.0]
    assert sol.matrix_force[1] == 0.0
    assert sol.matrix_force[0] == pytest.approx(100.0, rel=1e-12)
    assert sol.gap == pytest.approx(5e-6 - 100.0 / k_m, rel=1e-12)
    assert sol.patch_share == 0.0


def test_patches_at_matrix_level_share_by_stiffness():
    """Patches of height 0 sit level with the fresh matrix: every element shares by stiffness."""
    p = Patches(x=np.array([0.0, 4e-3]), y=np.full(2, 0.13), area=np.full(2, 5e-8), height=np.zeros(2))
    s = Scene(name="flush", pad=Pad(), patches=p, normal_force=1000.0)
    sol = solve_scene_contact(s)
    k_p = 2.39e9 * math.sqrt(5e-8)
    k_m = 1.85e11 * s.matrix.area[0]
    assert sol.gap == pytest.approx(-1000.0 / (2 * k_p + k_m), rel=1e-12)
    assert sol.patch_share == pytest.approx(2 * k_p / (2 * k_p + k_m), rel=1e-10)


@pytest.fixture(scope="module")
def preset_contacts():
    """Contact solutions of the equal-height presets (each solved once; spread heights: tests/test_heights.py)."""
    scenes = {n: preset(f"{n}_equal") for n in ("hf1", "hf2", "varying_area")}
    return {n: (s, solve_scene_contact(s)) for n, s in scenes.items()}


def test_hf1_load_sits_on_the_patches(preset_contacts):
    """hf1_equal: all 487.2 N on the patches, each compressed ≈ 0.52 µm of its 3 µm height."""
    s, sol = preset_contacts["hf1"]
    check_solution(*_elements(s), s.normal_force, sol, s.patches.count)
    assert sol.patch_share == 1.0
    assert sol.matrix_force.sum() == 0.0
    assert np.all(sol.patch_force > 0)  # all patches in contact
    assert 3e-6 - sol.gap == pytest.approx(0.52e-6, abs=0.02e-6)
    assert sol.gap > 0.0


def test_hf2_load_sits_on_the_patches(preset_contacts):
    """hf2_equal: all 12.37 kN on the patches, compression 2.6–2.7 µm < 3 µm (matrix not touched)."""
    s, sol = preset_contacts["hf2"]
    check_solution(*_elements(s), s.normal_force, sol, s.patches.count)
    assert sol.patch_share == 1.0
    assert 2.6e-6 <= 3e-6 - sol.gap <= 2.7e-6
    assert np.all(sol.patch_force > 0)


def test_varying_area_start_shares_with_the_matrix(preset_contacts):
    """varying_area_equal start (HF1 patches, HF2 load): patches carry ≈ 0.47, compressed ≈ 6.2 µm; the matrix the
    rest."""
    s, sol = preset_contacts["varying_area"]
    check_solution(*_elements(s), s.normal_force, sol, s.patches.count)
    assert 0.45 <= sol.patch_share <= 0.49
    assert 3e-6 - sol.gap == pytest.approx(6.2e-6, abs=0.1e-6)
    assert sol.matrix_force[0] == pytest.approx(1.85e11 * s.matrix.area[0] * (-sol.gap), rel=1e-12)


def test_growing_areas_shift_the_load_to_the_patches(preset_contacts):
    """solve_scene_contact(area=...) with HF2-size areas puts (almost) all of the HF2 load on the patches."""
    s, sol0 = preset_contacts["varying_area"]
    sol = solve_scene_contact(s, area=s.patches.area * 25.0)
    assert sol.patch_share > sol0.patch_share
    assert sol.patch_share == 1.0


def _elements(s: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness and height of every element of a scene, patches first (written out from docs/model.md §2.6)."""
    k = np.concatenate([2.39e9 * np.sqrt(s.patches.area), 1.85e11 * s.matrix.area])
    h = np.concatenate([s.patches.height, s.matrix.height])
    return k, h


@pytest.mark.parametrize("seed", range(4))
def test_load_window_ends_are_where_the_solve_reaches_the_lowest_patch_and_the_matrix(seed):
    """At F_all the solved gap is the lowest patch height (every patch just touching); at F_mat it is the highest
    matrix cell; holds() and margin() follow; load_at_gap is the force sum of the solve at that gap."""
    rng = np.random.default_rng(seed)
    n = 12
    p = Patches(
        x=np.linspace(-0.03, 0.03, n),
        y=np.full(n, 0.13),
        area=rng.uniform(2e-8, 8e-8, n),
        height=rng.uniform(2e-6, 4e-6, n),
    )
    cells = Matrix(area=np.array([4e-3, 6e-3]), radius=np.array([0.12, 0.14]), height=np.array([0.5e-6, -0.2e-6]))
    s = Scene(name="window", pad=Pad(), patches=p, normal_force=1.0, matrix=cells)
    win = load_window(s)
    assert 0 < win.all_in_contact < win.matrix_contact
    at_all = solve_scene_contact(s.replace(normal_force=win.all_in_contact))
    assert at_all.gap == pytest.approx(p.height.min(), rel=1e-12)
    assert np.count_nonzero(at_all.patch_force > 0) == n - 1  # the lowest patch touches with zero force
    at_mat = solve_scene_contact(s.replace(normal_force=win.matrix_contact))
    assert at_mat.gap == pytest.approx(0.5e-6, rel=1e-9)
    assert at_mat.matrix_force.sum() < 1e-9 * win.matrix_contact and np.all(at_mat.patch_force > 0)
    k = np.concatenate([2.39e9 * np.sqrt(p.area), 1.85e11 * cells.area])
    h = np.concatenate([p.height, cells.height])
    assert load_at_gap(k, h, at_all.gap) == pytest.approx(win.all_in_contact, rel=1e-12)
    assert win.holds(win.all_in_contact) and win.holds(win.matrix_contact)
    assert not win.holds(0.99 * win.all_in_contact) and not win.holds(1.01 * win.matrix_contact)
    assert win.margin(1.1 * win.all_in_contact) == pytest.approx(0.1, rel=1e-12)
    assert solve_scene_contact(s.replace(normal_force=0.99 * win.all_in_contact)).patch_force.min() == 0.0
    over = solve_scene_contact(s.replace(normal_force=1.01 * win.matrix_contact))
    assert over.matrix_force[0] > 0 and over.matrix_force[1] == 0.0


def test_equal_heights_are_all_in_contact_under_any_load(preset_contacts):
    """Equal heights: the all-in-contact load is 0 (any load touches every patch), margin infinite."""
    s, _ = preset_contacts["hf1"]
    win = load_window(s)
    assert win.all_in_contact == 0.0 and win.margin(s.normal_force) == math.inf
    assert win.matrix_contact == pytest.approx(2.39e9 * np.sqrt(s.patches.area).sum() * 3e-6, rel=1e-12)
