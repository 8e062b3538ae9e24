"""Tests of the HashGrid neighbour search (kernels/neighbours.py) and the coupling springs of a model.

Reference: brute force over all pairs of the same pad with centre distance D0 ≤ coupling radius
(docs/model.md §2.5, paper Eq. 3 and "coupling neglected if D0 exceeds 5 mm").
"""

from __future__ import annotations

import numpy as np
import pytest
from aca_warp.kernels.neighbours import build_neighbours

from aca_warp.hf.model import build_model, coupling_matrix
from aca_warp.scene import Material, Pad, Patches, PatchGenerator, Scene


def brute_force(x, y, pad, radius):
    """{(i, j): 1/D0_ij} for all ordered pairs i ≠ j of the same pad within that pad's radius."""
    x, y, pad = np.asarray(x), np.asarray(y), np.asarray(pad)
    d = np.hypot(x[:, None] - x[None, :], y[:, None] - y[None, :])
    same = pad[:, None] == pad[None, :]
    r = np.asarray(radius)[pad][:, None]
    i, j = np.nonzero(same & (d <= r) & ~np.eye(len(x), dtype=bool))
    return {(int(a), int(b)): 1.0 / d[a, b] for a, b in zip(i, j, strict=True)}


def csr_pairs(start, index, inv_d):
    """{(i, j): 1/D0} from a CSR list; also checks the CSR shape invariants."""
    start = np.asarray(start)
    assert start[0] == 0 and np.all(np.diff(start) >= 0)
    assert start[-1] == len(index) == len(inv_d)
    rows = np.repeat(np.arange(len(start) - 1), np.diff(start))
    out = {(int(a), int(b)): float(v) for a, b, v in zip(rows, index, inv_d, strict=True)}
    assert len(out) == len(index), "a pair is listed twice"
    return out


def assert_same(got, want):
    """Same pair sets, and 1/D0 equal to ~1e-12 (coordinates are shifted once before the search)."""
    assert set(got) == set(want), (sorted(set(got) - set(want))[:5], sorted(set(want) - set(got))[:5])
    if want:
        keys = sorted(want)
        np.testing.assert_allclose([got[k] for k in keys], [want[k] for k in keys], rtol=1e-12)


def random_points(rng, n, span, x0=0.0, y0=0.13):
    """n uniform random points in a square of side ``span`` [m] centred at (x0, y0)."""
    return x0 + rng.uniform(-span / 2, span / 2, n), y0 + rng.uniform(-span / 2, span / 2, n)


@pytest.mark.parametrize(
    "seed, n, span, radius", [(0, 200, 0.02, 5e-3), (1, 500, 0.06, 5e-3), (2, 300, 0.01, 1e-3), (3, 50, 0.003, 5e-3)]
)
def test_one_pad_matches_brute_force(device, seed, n, span, radius):
    """All pairs within the radius, nothing else, with the right 1/D0, on random point sets of one pad."""
    rng = np.random.default_rng(seed)
    x, y = random_points(rng, n, span)
    pad = np.zeros(n, np.int32)
    got = csr_pairs(*build_neighbours(x, y, pad, np.array([radius]), device))
    want = brute_force(x, y, pad, [radius])
    assert len(want) > 0
    assert_same(got, want)


def test_symmetric_lists(device):
    """j is a neighbour of i exactly when i is a neighbour of j, with the same 1/D0 bit for bit."""
    rng = np.random.default_rng(5)
    x, y = random_points(rng, 300, 0.03)
    got = csr_pairs(*build_neighbours(x, y, np.zeros(300, np.int32), np.array([5e-3]), device))
    for (i, j), v in got.items():
        assert got[(j, i)] == pytest.approx(v, rel=1e-14)


def test_pads_sharing_coordinates_stay_apart(device):
    """Three pads of a batch with identical (and overlapping) coordinates: no link crosses pads."""
    rng = np.random.default_rng(7)
    x1, y1 = random_points(rng, 150, 0.02)
    x2, y2 = random_points(rng, 100, 0.02)
    x = np.concatenate([x1, x1, x2])
    y = np.concatenate([y1, y1, y2])
    pad = np.repeat(np.arange(3, dtype=np.int32), [150, 150, 100])
    radius = np.array([5e-3, 5e-3, 2e-3])  # pads may have different coupling radii
    got = csr_pairs(*build_neighbours(x, y, pad, radius, device))
    want = brute_force(x, y, pad, radius)
    assert_same(got, want)
    assert all(pad[i] == pad[j] for i, j in got)
    # pads 0 and 1 are the same point set: the same links, shifted by 150
    links0 = {(i, j) for i, j in got if pad[i] == 0}
    links1 = {(i - 150, j - 150) for i, j in got if pad[i] == 1}
    assert links0 == links1


def test_zero_radius_gives_no_neighbours(device):
    """A coupling radius of 0 means no coupling at all: an empty CSR with n + 1 zero offsets."""
    rng = np.random.default_rng(9)
    x, y = random_points(rng, 40, 0.01)
    start, index, inv_d = build_neighbours(x, y, np.zeros(40, np.int32), np.array([0.0]), device)
    assert start.shape == (41,) and np.all(start == 0)
    assert len(index) == 0 and len(inv_d) == 0


def test_single_patch(device):
    """One patch has no neighbours."""
    start, index, inv_d = build_neighbours(
        np.array([0.0]), np.array([0.13]), np.zeros(1, np.int32), np.array([5e-3]), device
    )
    assert start.tolist() == [0, 0]
    assert len(index) == 0 and len(inv_d) == 0


def test_isolated_patches(device):
    """Patches farther apart than the radius have no neighbours."""
    x = np.array([0.0, 0.01, 0.02, 0.03])
    y = np.full(4, 0.13)
    start, index, _ = build_neighbours(x, y, np.zeros(4, np.int32), np.array([5e-3]), device)
    assert np.all(start == 0) and len(index) == 0


def test_pair_exactly_at_the_radius_is_coupled(device):
    """D0 = coupling radius exactly counts as a neighbour (D0 ≤ 5 mm)."""
    x = np.array([0.0, 0.005, 0.0])
    y = np.array([0.13, 0.13, 0.120])
    got = csr_pairs(*build_neighbours(x, y, np.zeros(3, np.int32), np.array([0.005]), device))
    assert set(got) == {(0, 1), (1, 0)}
    assert got[(0, 1)] == pytest.approx(200.0, rel=1e-12)


def test_small_radius_on_a_wide_spread(device):
    """A radius tiny against the spread of the points (grid dimension capped, cells wrap) is still exact."""
    rng = np.random.default_rng(11)
    x, y = random_points(rng, 3000, 0.12)
    radius = np.array([1.5e-4])
    got = csr_pairs(*build_neighbours(x, y, np.zeros(3000, np.int32), radius, device))
    want = brute_force(x, y, np.zeros(3000, np.int32), radius)
    assert len(want) > 10
    assert_same(got, want)


def network_scene(seed=3, count=60) -> Scene:
    """A generated scene of ``count`` 0.02–0.08 mm² patches on a small pad, so that many pairs couple."""
    pad = Pad(r_inner=0.125, r_outer=0.135, span_deg=8.0)
    patches = PatchGenerator(count=count, seed=seed).generate(pad)
    return Scene(name=f"net{seed}", pad=pad, patches=patches, normal_force=5.0)


def test_coupling_matrix_of_a_model(device):
    """k_ij = K_C √(A_i A_j)/D0_ij for exactly the pairs with D0 ≤ coupling radius, and k_ij = k_ji."""
    s = network_scene()
    s = s.replace(material=Material(K_C=6.5e8, coupling_radius=4e-3))
    model = build_model([s], device=device, precision="fp64")
    start, index, kij = coupling_matrix(model)
    got = csr_pairs(start, index, kij)
    p = s.patches
    want_inv = brute_force(p.x, p.y, np.zeros(p.count, int), [4e-3])
    assert set(got) == set(want_inv) and len(got) > 100
    for (i, j), k in got.items():
        assert k == pytest.approx(6.5e8 * np.sqrt(p.area[i] * p.area[j]) * want_inv[(i, j)], rel=1e-12)
        assert got[(j, i)] == pytest.approx(k, rel=1e-14)
    assert model.has_coupling and model.nnz == len(got)


def test_coupling_matrix_of_a_batch(device):
    """In a batch of two pads, indices are global, no pair crosses pads, and each pad matches its brute force."""
    a, b = network_scene(3, 50), network_scene(4, 40)
    model = build_model([a, b], device=device, precision="fp64")
    start, index, kij = coupling_matrix(model)
    got = csr_pairs(start, index, kij)
    x = np.concatenate([a.patches.x, b.patches.x])
    y = np.concatenate([a.patches.y, b.patches.y])
    area = np.concatenate([a.patches.area, b.patches.area])
    pad = np.repeat([0, 1], [50, 40])
    want_inv = brute_force(x, y, pad, [5e-3, 5e-3])
    assert set(got) == set(want_inv)
    for (i, j), k in got.items():
        assert k == pytest.approx(7.96e8 * np.sqrt(area[i] * area[j]) * want_inv[(i, j)], rel=1e-12)


def test_model_without_coupling(device):
    """A coupling radius of 0 gives a model with no links (the coupling stage is skipped)."""
    s = network_scene().replace(material=Material(coupling_radius=0.0))
    model = build_model([s], device=device, precision="fp64")
    start, index, kij = coupling_matrix(model)
    assert np.all(start == 0)
    assert len(index) == 0 and len(kij) == 0
    assert model.nnz == 0
    assert not model.has_coupling


def test_scene_with_single_patch_model(device):
    """A one-patch scene builds a model with no links and the patch's own constants."""
    p = Patches(np.array([0.0]), np.array([0.13]), np.array([5e-8]), np.array([3e-6]))
    model = build_model([Scene(name="one", pad=Pad(), patches=p, normal_force=1.0)], device=device)
    assert model.patch_count == 1
    assert model.host("nbr_start").tolist() == [0, 0]
    assert model.host("k_t")[0] == pytest.approx(1.87e9 * np.sqrt(5e-8), rel=1e-12)
    assert 1.0 / model.host("inv_mass")[0] == pytest.approx(37.5 * 5e-8, rel=1e-12)


def unshared_coupling(scenes, device):
    """The batch's CSR, k_ij and Σ_j k_ij computed without sharing layouts: one search over every pad, k_ij per link,
    row sums over the whole batch (the arithmetic build_model must reproduce bit for bit)."""
    x = np.concatenate([s.patches.x for s in scenes])
    y = np.concatenate([s.patches.y for s in scenes])
    sq = np.sqrt(np.concatenate([s.patches.area for s in scenes]))
    pad = np.repeat(np.arange(len(scenes), dtype=np.int32), [s.patches.count for s in scenes])
    radius = np.array([s.material.coupling_radius for s in scenes])
    start, index, inv_d = build_neighbours(x, y, pad, radius, device)
    rows = np.repeat(np.arange(len(x)), np.diff(start))
    kc = np.array([s.material.K_C for s in scenes])[pad[rows]]
    k_ij = kc * sq[rows] * sq[index] * inv_d
    return start, index, inv_d, k_ij, np.bincount(rows, k_ij, minlength=len(x))


def test_shared_layouts_build_the_same_arrays(device):
    """Pads that share a layout (a sweep's pads differing in load, K_T, friction) share one neighbour search; the
    batch's lists, 1/D0, k_ij and k_diag equal those of a search over every pad, bit for bit, with pads of other
    coupling radii, K_C and patch counts mixed in (the largest radius sets the search's cells for all)."""
    a, b, c = network_scene(3, 60), network_scene(4, 45), network_scene(5, 60)
    wide = Material(coupling_radius=7e-3)
    scenes = [
        a,
        b,
        a.replace(normal_force=7.0),
        c.replace(material=wide),
        a.replace(material=Material(K_C=9e8)),
        b.replace(material=Material(K_T=2e9), normal_force=3.0),
        a,
        c,
    ]
    model = build_model(scenes, device=device, precision="fp64")
    start, index, inv_d, k_ij, k_sum = unshared_coupling(scenes, device)
    assert model.nnz == len(index) > 0
    for name, want in (("nbr_start", start), ("nbr_index", index), ("nbr_inv_dist", inv_d), ("nbr_stiffness", k_ij)):
        got = model.host(name)
        assert got.tobytes() == want.astype(got.dtype).tobytes(), name
    k_t = np.concatenate([s.material.K_T * np.sqrt(s.patches.area) for s in scenes])
    assert model.host("k_diag").tobytes() == (k_t + k_sum).tobytes()
