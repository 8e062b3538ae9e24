"""Initial states (aca_warp.hf.state.initial_state): rest or static equilibrium, plus seeded perturbations.

``[initial] state`` is ``rest`` (u = u̇ = 0) or ``equilibrium`` ((diag k_T + L) u = F_N,i f(ω r_i), u̇ = 0);
``perturbation`` [m/s] and ``displacement_perturbation`` [m] add N(0, σ²) draws per patch from two seeded
streams. References: the balance written out from the CSR links, NumPy's generators, sample statistics.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from aca_warp.common.errors import SceneError
from aca_warp.hf.model import build_model
from aca_warp.hf.state import initial_state, perturbations
from aca_warp.scene import Initial, preset, scene_from_dict


@pytest.fixture(scope="module")
def hf1():
    """The hf1 preset (1758 patches, spread heights)."""
    return preset("hf1")


def start(scene, precision="fp64", **initial):
    """(u, v) of the initial state of ``scene`` with ``[initial]`` keys ``initial``."""
    s = scene.replace(initial=Initial(**initial))
    model = build_model([s], device="cpu", precision=precision)
    return initial_state(model).numpy()


def static_residual(scene, u: np.ndarray) -> tuple[np.ndarray, float]:
    """k_T,i u_i + Σ_j k_ij (u_i − u_j) − F_N,i f(ω r_i) per patch [N], and the scale of the forces [N]."""
    model = build_model([scene], device="cpu", precision="fp64")
    start_, index, k_ij = (model.host(k) for k in ("nbr_start", "nbr_index", "nbr_stiffness"))
    e = np.arange(model.nnz)
    row = np.searchsorted(start_, e, side="right") - 1
    spring = model.host("k_t") * u
    np.add.at(spring, row, k_ij[e] * (u[row] - u[index[e]]))
    fric = model.host("normal_force") * scene.friction.coefficient(scene.angular_velocity * model.host("radius"))
    return spring - fric, float(np.abs(fric).max() + np.abs(spring).max())


def test_rest_is_zero(hf1):
    """rest without perturbations: u = u̇ = 0 exactly."""
    u, v = start(hf1)
    assert not u.any() and not v.any()


@pytest.mark.parametrize("load", [None, 150.0])
def test_equilibrium_satisfies_the_static_balance(hf1, load):
    """equilibrium: spring forces balance the steady friction F_N,i f(ω r_i) to rounding, u̇ = 0; also with a load
    that leaves patches out of contact (F_N,i = 0: those are held by their neighbours only)."""
    s = hf1 if load is None else hf1.replace(normal_force=load)
    u, v = start(s, state="equilibrium")
    assert not v.any()
    res, scale = static_residual(s, u)
    assert np.abs(res).max() < 1e-12 * scale
    assert np.all(u > 0)  # friction drags every patch along +disc direction, coupled ones too
    if load is not None:
        assert np.count_nonzero(build_model([s], device="cpu").host("normal_force") == 0.0) > 10


def test_same_seed_same_bits_other_seed_other_draws(hf1):
    """Perturbations are reproducible by seed, bit for bit, and change with it."""
    kw = {"perturbation": 1e-3, "displacement_perturbation": 2e-9}
    a = start(hf1, seed=7, **kw)
    b = start(hf1, seed=7, **kw)
    c = start(hf1, seed=8, **kw)
    for x, y, z in zip(a, b, c, strict=True):
        np.testing.assert_array_equal(x, y)
        assert not np.any(x == z)


def test_streams_are_independent_and_velocity_draws_unchanged(hf1):
    """Velocities are ``default_rng(seed).normal(0, σ, n)`` (as before displacements existed) whether displacements
    are perturbed or not, and displacements do not depend on the velocity setting."""
    n = hf1.patches.count
    u0, v0 = start(hf1, seed=3, perturbation=0.02)
    u1, v1 = start(hf1, seed=3, perturbation=0.02, displacement_perturbation=1e-8)
    u2, v2 = start(hf1, seed=3, displacement_perturbation=1e-8)
    np.testing.assert_array_equal(v0, np.random.default_rng(3).normal(0.0, 0.02, n))
    np.testing.assert_array_equal(v0, v1)
    np.testing.assert_array_equal(u1, u2)
    assert not u0.any() and not v2.any()
    assert not np.allclose(u1 / 1e-8, v1 / 0.02)  # two streams, not one draw scaled twice


@pytest.mark.parametrize("state", ["rest", "equilibrium"])
def test_perturbation_amplitudes(hf1, state):
    """The added draws have mean 0 and the asked standard deviations (5 standard errors over 1758 patches), on top
    of the base state exactly (fp64)."""
    n = hf1.patches.count
    su, sv = 3e-9, 5e-3
    u_base, _ = start(hf1, state=state)
    u, v = start(hf1, state=state, seed=11, perturbation=sv, displacement_perturbation=su)
    du, dv = perturbations(Initial(perturbation=sv, displacement_perturbation=su, seed=11), n)
    np.testing.assert_array_equal(u, u_base + du)
    np.testing.assert_array_equal(v, dv)
    for x, sd in ((u - u_base, su), (v, sv)):
        assert abs(x.mean()) < 5 * sd / math.sqrt(n)
        assert x.std() == pytest.approx(sd, rel=5 / math.sqrt(2 * n))


def test_equilibrium_plus_perturbation_in_fp32(hf1):
    """fp32 models: the same draws rounded once; the equilibrium solved from the fp32 model's constants."""
    u64, v64 = start(hf1, state="equilibrium", seed=2, perturbation=1e-3, displacement_perturbation=1e-9)
    u32, v32 = start(hf1, "fp32", state="equilibrium", seed=2, perturbation=1e-3, displacement_perturbation=1e-9)
    assert u32.dtype == np.float32
    np.testing.assert_array_equal(v32, v64.astype(np.float32))
    np.testing.assert_allclose(u32, u64, rtol=1e-6)


def test_batched_pads_draw_their_own_seeds(hf1):
    """In a batch every pad draws from its own scene's seed and amplitudes (the same seed gives the same draws)."""
    a = hf1.replace(initial=Initial(seed=1, perturbation=1e-3, displacement_perturbation=1e-9))
    b = hf1.replace(initial=Initial(seed=2, perturbation=2e-3))
    model = build_model([a, b, a], device="cpu", precision="fp64")
    u, v = initial_state(model).numpy()
    n = hf1.patches.count
    du, dv = perturbations(a.initial, n)
    np.testing.assert_array_equal(v[:n], dv)
    np.testing.assert_array_equal(v[2 * n :], dv)
    np.testing.assert_array_equal(u[2 * n :], du)
    np.testing.assert_array_equal(v[n : 2 * n], np.random.default_rng(2).normal(0.0, 2e-3, n))
    assert not u[n : 2 * n].any()


def test_initial_keys_in_toml_documents():
    """``[initial]`` reads state, perturbation, displacement_perturbation and seed; bad values are refused."""
    doc = {
        "load": {"normal_force": 10.0},
        "patches": {"count": 20, "seed": 4},
        "initial": {"state": "equilibrium", "perturbation": 1e-3, "displacement_perturbation": 1e-9, "seed": 7},
        "record": {"sample_dt": 1e-7},
        "run": {"duration": 1e-5},
    }
    s = scene_from_dict(doc)
    assert s.initial == Initial(state="equilibrium", perturbation=1e-3, displacement_perturbation=1e-9, seed=7)
    for bad, match in ((-1e-9, "must be >= 0"), (math.inf, "must be finite"), ("1e-9", "must be a number")):
        doc["initial"]["displacement_perturbation"] = bad
        with pytest.raises(SceneError, match=rf"initial\.displacement_perturbation {match}"):
            scene_from_dict(doc)
