"""strang's treatment of the steps that cross zero slip (``RunOptions.crossing``): "mean" is the prototype's ``thmean``
in the kernels (the friction averaged along a crossing step's slip segment), its samples read a crossing patch's
friction at a reproducible random instant of the sub-step the sample reads, the on-chip engine gives the same bits as
the general one, a pad's reading does not depend on its batch, "point" stays the package's strang, and the option is
refused where it does not apply."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import warp as wp
from aca_warp.kernels.physics import INSTANT_SEED, friction_integral, friction_pair, segment_pair
from procs import cpu_fibers
from scipy.integrate import quad

from aca_warp.common.errors import SceneError
from aca_warp.hf.loop import EngineTuning, run_hf
from aca_warp.hf.options import RunOptions
from aca_warp.scene import Record
from aca_warp.studies import friction_schemes as fs
from aca_warp.studies.friction_stats import sector_scenes
from aca_warp.studies.runs import batch_at_start

DT = 2.5e-7  # s
DURATION = 2e-5  # s
SAMPLE_DT = 1e-6  # s
SPREAD = 0.3  # m/s: start velocities about the disc speed, so that slips change sign from the first steps on


@pytest.fixture(scope="module")
def scenes() -> list:
    return sector_scenes(2, 40)


def _start(scenes: list) -> tuple[fs.Pads, np.ndarray]:
    pads = fs.load_pads(scenes)
    v0 = pads.vd + SPREAD * np.random.default_rng(5).standard_normal(pads.n)
    return dataclasses.replace(pads, v0=v0), v0


def _package(
    scenes: list, v0: np.ndarray, crossing: str, engine: str = "general", precision: str = "fp64", block: int = 0
):
    """The package's strang run from velocities ``v0``: its globals and final state; ``block`` > 0: the on-chip
    kernel with blocks of that many cooperative CPU threads (Warp's CPU fibers)."""
    model, state = batch_at_start(scenes, "cpu", precision)
    state.v.assign(v0.astype(state.v.numpy().dtype))
    options = RunOptions(integrator="strang", duration=DURATION, dt=DT, force=True, engine=engine, crossing=crossing)
    tuning = None
    if engine == "onchip":
        tuning = EngineTuning(samples_per_launch=3, **({"block_dim": block} if block else {}))
    with cpu_fibers(block > 0):
        res = run_hf(model, state, options, record=Record(sample_dt=SAMPLE_DT), tuning=tuning)
    assert res.complete
    return res.collect().globals, state.numpy()


@wp.kernel
def _draw(out: wp.array2d(dtype=wp.float32)):
    k, i = wp.tid()
    state = wp.rand_init(INSTANT_SEED + k, i)
    out[k, i] = wp.randf(state)


def _instants(samples: int, patches: int) -> np.ndarray:
    """τ of sample k and in-pad patch index i, as the recorder draws them."""
    out = wp.zeros((samples, patches), dtype=wp.float32, device="cpu")
    wp.launch(_draw, dim=(samples, patches), inputs=[out], device="cpu")
    return out.numpy().astype(np.float64)


def test_mean_is_the_prototype_thmean_read_at_the_drawn_instants(scenes):
    """The dynamics are the prototype's ``forced-thmean`` (Σ|u̇| and Σu̇ to rounding), and μ of each sample is
    Eq. 4 at the sample's velocities (the θ-point V of the merged sub-step from w to w⁺ that the next step opens
    with) except at the patches whose slip changes sign along that sub-step, which read it at w + τ (w⁺ − w) with τ
    from ``wp.rand_init(INSTANT_SEED + k, i)``."""
    pads, v0 = _start(scenes)
    g, _ = _package(scenes, v0, "mean")
    st = fs.SplitStepper(pads, fs.Scheme.parse("forced-thmean"))
    per, h = fs.fixed_step(DT, SAMPLE_DT)
    samples = round(DURATION / SAMPLE_DT)
    sizes = np.diff(pads.start)
    tau = _instants(samples + 1, int(sizes.max()))
    local = np.arange(pads.n) - np.repeat(pads.start[:-1], sizes)
    crossings = 0
    for k in range(1, samples + 1):
        for _ in range(per):
            st.step(np.full(pads.n, h))
        (v, w1), w = st.sample_velocity(), st.w
        glob = fs.pad_globals(pads, v)
        np.testing.assert_allclose(g[k, :, 4], glob["sum_abs_velocity"], rtol=1e-12, atol=1e-10)
        np.testing.assert_allclose(g[k, :, 3], glob["sum_velocity"], rtol=0, atol=1e-10)
        cross = (pads.vd - w) * (pads.vd - w1) < 0.0
        crossings += int(cross.sum())
        vf = np.where(cross, w + tau[k, local] * (w1 - w), v)
        f = pads.fn * fs.friction(pads, pads.vd - vf)
        mu = (np.add.reduceat(f, pads.start[:-1]) + pads.coulomb) / pads.load
        np.testing.assert_allclose(g[k, :, 0], mu, rtol=0, atol=1e-12)
    assert crossings >= 5  # the instant reading was exercised (8 patch-samples in this run)


def test_point_stays_the_package_strang_on_crossing_steps(scenes):
    """``point`` (the default outside the measured regimes) on the same crossing-rich start is the prototype's
    ``forced-thmid``: the option leaves that path as it was, and ``mean`` does change the run."""
    pads, v0 = _start(scenes)
    g, _ = _package(scenes, v0, "point")
    r = fs.run_fixed(pads, fs.Scheme.parse("forced-thmid"), DT, DURATION, SAMPLE_DT, sample="step")
    np.testing.assert_allclose(g[:, :, 0], r["record"].mu, rtol=0, atol=1e-12)
    np.testing.assert_allclose(g[:, :, 4], r["record"].sum_abs_velocity, rtol=1e-12, atol=1e-10)
    gm, _ = _package(scenes, v0, "mean")
    assert np.abs(gm[:, :, 4] - g[:, :, 4]).max() > 1e-6


def test_onchip_matches_general_with_mean(scenes):
    """On the CPU the on-chip kernel (its CROSSING variant) does what the general kernels do, bit for bit; with
    blocks of 32 cooperative threads the states stay bit-identical (every barrier reached by all threads)."""
    _, v0 = _start(scenes)
    g, (u, v) = _package(scenes, v0, "mean")
    go, (uo, vo) = _package(scenes, v0, "mean", engine="onchip")
    np.testing.assert_array_equal(go, g)
    np.testing.assert_array_equal(uo, u)
    np.testing.assert_array_equal(vo, v)
    gf, (uf, vf) = _package(scenes, v0, "mean", engine="onchip", block=32)  # 32 fiber threads per block
    np.testing.assert_array_equal(uf, u)
    np.testing.assert_array_equal(vf, v)
    np.testing.assert_allclose(gf, g, rtol=1e-12, atol=0)  # the block's tree sums in float64


def test_a_pads_reading_does_not_depend_on_its_batch(scenes):
    """τ is drawn from the sample index and the patch's index within its pad: pad 1 alone reads what it reads
    beside pad 0."""
    _, v0 = _start(scenes)
    both, _ = _package(scenes, v0, "mean")
    n0 = scenes[0].patches.count
    alone, _ = _package(scenes[1:], v0[n0:], "mean")
    np.testing.assert_array_equal(alone[:, 0], both[:, 1])


@wp.kernel
def _integral(s: wp.array(dtype=wp.float64), law: wp.vec3d, out: wp.array(dtype=wp.float64)):
    i = wp.tid()
    out[i] = friction_integral(s[i], law[0], law[1], law[2])


def test_friction_integral_is_the_prototypes_and_its_derivative_is_eq4(scenes):
    """The kernels' closed-form G = ∫ f agrees with the prototype's, with quadrature of Eq. 4 to its stated
    O(decay²/slope³) (≈ 4e-9 m/s), and its central differences give Eq. 4."""
    pads = fs.load_pads(scenes[:1])
    s = np.concatenate([np.linspace(-12.0, 12.0, 2401), [-1e-5, 0.0, 3e-4, 1e-3, 4.0e-3]])
    law = wp.vec3d(pads.M / np.pi, pads.slope, pads.decay)
    out = wp.zeros(s.size, dtype=wp.float64, device="cpu")
    wp.launch(_integral, dim=s.size, inputs=[wp.array(s, dtype=wp.float64, device="cpu"), law, out], device="cpu")
    np.testing.assert_allclose(out.numpy(), fs.friction_integral(pads, s), rtol=1e-12, atol=1e-15)
    e = 1e-6
    g = lambda x: fs.friction_integral(pads, x)  # noqa: E731
    x = np.linspace(-5.0, 5.0, 101)
    np.testing.assert_allclose((g(x + e) - g(x - e)) / (2 * e), fs.friction(pads, x), rtol=0, atol=1e-7)
    ends = np.array([-7.0, -0.3, 0.004, 0.05, 2.0, 12.0])
    g_end = wp.zeros(ends.size, dtype=wp.float64, device="cpu")
    wp.launch(_integral, dim=ends.size, inputs=[wp.array(ends, dtype=wp.float64, device="cpu"), law, g_end],
              device="cpu")  # fmt: skip
    f = lambda x: float(fs.friction(pads, np.array([x]))[0])  # noqa: E731
    exact = [quad(f, 0.0, end, points=[0.0], limit=200)[0] for end in ends]
    np.testing.assert_allclose(g_end.numpy(), exact, rtol=0, atol=1e-8)


@wp.kernel
def _segment(vp: wp.array(dtype=wp.float64), s0: wp.float64, law: wp.vec3d, tol: wp.float64,
             out: wp.array2d(dtype=wp.float64)):  # fmt: skip
    i = wp.tid()
    g0 = friction_integral(s0, law[0], law[1], law[2])
    f, df = segment_pair(vp[i], s0, g0, law[0], law[1], law[2], tol)
    p, dp = friction_pair(vp[i], law[0], law[1], law[2])
    out[i, 0] = f
    out[i, 1] = df
    out[i, 2] = p


def test_segment_law_and_its_short_segment_fallback(scenes):
    """The segment law is the mean of Eq. 4 over [s0, 2 vp − s0] with its derivative in vp; a segment shorter than
    10³ × the solve's tolerance takes Eq. 4 at the midpoint instead."""
    pads = fs.load_pads(scenes[:1])
    s0, tol = -0.01, 1e-9  # fp64: segments below 1e-6 m/s fall back
    vp = np.array([s0 + 0.02, s0 + 0.2, s0 + 1e-3, s0 + 4e-7, s0 - 2e-7])
    law = wp.vec3d(pads.M / np.pi, pads.slope, pads.decay)
    out = wp.zeros((vp.size, 3), dtype=wp.float64, device="cpu")
    wp.launch(_segment, dim=vp.size, inputs=[wp.array(vp, dtype=wp.float64, device="cpu"), s0, law, tol, out],
              device="cpu")  # fmt: skip
    r = out.numpy()
    f = lambda x: float(fs.friction(pads, np.array([x]))[0])  # noqa: E731
    for k in range(3):
        s1 = 2 * vp[k] - s0
        mean = quad(f, s0, s1, points=[0.0], limit=200)[0] / (s1 - s0)
        assert r[k, 0] == pytest.approx(mean, abs=1e-7)
        assert r[k, 1] == pytest.approx(2 * (f(s1) - r[k, 0]) / (s1 - s0), rel=1e-9)
    np.testing.assert_array_equal(r[3:, 0], r[3:, 2])  # |Δs| = 8e-7 and 4e-7 m/s: the midpoint value


def test_mean_in_fp32_follows_fp64(scenes):
    """The fp32 kernels take the same treatment: over 20 µs of crossing-rich motion their Σ|u̇| and μ stay within
    fp32's reach of the fp64 run's."""
    _, v0 = _start(scenes)
    g64, _ = _package(scenes, v0, "mean")
    g32, _ = _package(scenes, v0, "mean", precision="fp32")
    np.testing.assert_allclose(g32[:, :, 4], g64[:, :, 4], rtol=1e-4)
    np.testing.assert_allclose(g32[:, :, 0], g64[:, :, 0], rtol=0, atol=1e-4)


def test_crossing_refused_where_it_does_not_apply():
    with pytest.raises(SceneError, match="crossing 'mean' is a treatment of strang"):
        RunOptions(integrator="adaptive", crossing="mean")
    with pytest.raises(SceneError, match="unknown crossing treatment"):
        RunOptions(crossing="segment")
    assert RunOptions.from_dict({"integrator": "strang"}).crossing is None  # the batch's default, resolved later
