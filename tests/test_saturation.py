"""Saturation detector and linear growth rate (aca_warp/analysis/saturation.py).

Synthetic records with a known envelope check the detector; an isolated patch integrated with SciPy checks
the predicted growth rate against the detector's fit; a small coupled pad checks what the isolated-patch
rates say about the coupled, nonlinear pad.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from aca_warp.analysis.saturation import (
    common_start,
    coupled_growth_rates,
    dominant_frequency,
    friction_slope,
    growth_rate_summary,
    predicted_growth_rate,
    record_saturation,
    saturation,
)
from aca_warp.scene import Friction, Pad, PatchGenerator, preset

F0, DT, SIGMA = 1000.0, 5.0e-5, 10.0  # carrier [Hz], sampling [s], growth rate [1/s]: 1 % growth per period, as HF1


def landau(t: np.ndarray, a0: float, a_s: float = 1.0, sigma: float = SIGMA) -> np.ndarray:
    """Amplitude of ȧ = σ a (1 − a²/a_s²) from a(0) = a0 (exponential growth, then saturation at a_s)."""
    return a_s / np.sqrt(1.0 + (a_s**2 / a0**2 - 1.0) * np.exp(-2.0 * sigma * t))


def record(amplitude, duration=3.0, noise=0.0, seed=0):
    """(t, a(t)·sin(2π F0 t) + white noise of standard deviation ``noise``)."""
    t = np.arange(round(duration / DT)) * DT
    rng = np.random.default_rng(seed)
    return t, amplitude(t) * np.sin(2 * np.pi * F0 * t + 0.3) + noise * rng.standard_normal(t.size)


def test_growth_then_saturation_of_a_landau_envelope():
    a0 = 1e-3
    t, x = record(lambda t: landau(t, a0))
    r = saturation(t, x)
    assert r.window == 640  # 32 periods of F0
    assert r.saturated and r.start_index == round(r.t_s / DT)
    assert r.growth_rate == pytest.approx(SIGMA, rel=0.02)
    assert r.growth_r2 > 0.999
    # the local log-slope σ(1 − a²/a_s²) falls to growth_fraction·σ = 0.2σ where a² = 0.8 a_s²
    t_star = np.log(4.0 * (1.0 / a0**2 - 1.0)) / (2.0 * SIGMA)
    assert abs(r.t_s - t_star) <= 2 * r.window_duration
    assert r.level == pytest.approx(1.0 / np.sqrt(2.0), rel=0.01)  # std of a unit sinusoid
    assert r.level_spread < 0.01
    assert "saturated from t_s" in r.verdict and "growth phase" in r.verdict


@pytest.mark.parametrize(("noise", "tolerance"), [(1e-3, 0.03), (1e-2, 0.06)])
def test_noise_floor_is_excluded_from_the_growth_fit(noise, tolerance):
    """Growth from 1e-5 under a noise floor; the fit window starts above it.

    The signal rises 6.6 (4.3) e-folds above the floor. The fit keeps 1 e-fold clear of floor and saturated
    level, where the local log-slope is still 0.865 σ at either end, so the fitted rate is 1.7 % (5 %) low.
    """
    t, x = record(lambda t: landau(t, 1e-5), noise=noise)
    r = saturation(t, x)
    assert r.saturated
    assert r.growth_rate == pytest.approx(SIGMA, rel=tolerance)
    floor_reached = np.log(noise / 1e-5) / SIGMA  # the signal crosses the floor
    assert r.growth_window[0] > floor_reached


def test_record_saturated_from_the_start():
    t, x = record(lambda t: 1.0 + 0.02 * np.sin(2 * np.pi * 1.3 * t), noise=0.05, seed=2)
    r = saturation(t, x)
    assert r.t_s == t[0] and r.start_index == 0
    assert r.growth_rate is None and r.growth_window is None
    assert r.level == pytest.approx(np.sqrt(0.5 + 0.05**2), rel=0.02)
    assert r.verdict.startswith("saturated from the start")


def test_pure_growth_never_saturates():
    t, x = record(lambda t: 1e-4 * np.exp(SIGMA * t), duration=1.0)
    r = saturation(t, x)
    assert r.t_s is None and r.start_index is None and r.level is None
    assert r.growth_rate == pytest.approx(SIGMA, rel=0.005)
    assert r.final_log_slope == pytest.approx(SIGMA, rel=0.02)
    assert r.verdict.startswith("not saturated: the envelope still changes")


def test_slower_second_growth_is_not_saturation():
    # growth at σ to 0.1 (at t = 0.46 s), then on at 0.3 σ: each window changes by only 1 %, yet it grows
    t_knee = np.log(100.0) / SIGMA

    def amp(t):
        return 1e-3 * np.exp(SIGMA * np.minimum(t, t_knee) + 0.3 * SIGMA * np.maximum(t - t_knee, 0.0))

    t, x = record(amp, duration=2.0)
    r = saturation(t, x, window=60, fit_window=(0.05, 0.4))  # the automatic fit would span both rates
    assert r.growth_rate == pytest.approx(SIGMA, rel=0.01)
    assert r.t_s is None
    assert "0.30 of the growth rate" in r.verdict


def test_overshoot_counts_as_saturated_only_after_it_decays():
    # grows, overshoots to 1.5 and relaxes to 1 with time constant 0.1 s from t = 1 s
    def amp(t):
        return np.where(t < 1.0, 1.5 * np.exp(SIGMA * (t - 1.0)), 1.0 + 0.5 * np.exp(-(t - 1.0) / 0.1))

    t, x = record(amp)
    r = saturation(t, x)
    assert r.saturated
    # a − 1 = 0.5 exp(−(t − 1)/0.1) falls below band = 10 % of the level at t = 1 + 0.1 ln 5 = 1.16 s
    assert 1.15 < r.t_s < 1.3
    assert r.level == pytest.approx(1.0 / np.sqrt(2.0), rel=0.02)


def test_slow_ramp_is_not_saturated_over_its_whole_length():
    t, x = record(lambda t: 1.0 + t / 3.0)  # envelope doubles linearly: < 1 e-fold, no growth phase
    r = saturation(t, x)
    assert r.growth_rate is None
    assert r.t_s is None or r.t_s > 2.0  # only a short tail lies within band = 10 % of the final level
    if r.t_s is not None:
        assert r.level_spread / r.level < 0.05


def test_batched_columns_match_single_calls():
    t, a = record(lambda t: landau(t, 1e-3))
    _, b = record(lambda t: 0.5 + 0 * t, noise=0.01, seed=4)
    _, c = record(lambda t: 1e-4 * np.exp(SIGMA * t / 4))
    batch = saturation(t, np.column_stack([a, b, c]), window=400)
    assert isinstance(batch, list) and len(batch) == 3
    for col, res in zip((a, b, c), batch, strict=True):
        one = saturation(t, col, window=400)
        assert res.t_s == one.t_s and res.verdict == one.verdict
        assert (res.growth_rate is None) == (one.growth_rate is None)
        if one.growth_rate is not None:
            assert res.growth_rate == pytest.approx(one.growth_rate, rel=1e-12)
        np.testing.assert_allclose(res.envelope, one.envelope, rtol=1e-14)
    assert batch[0].saturated and batch[1].start_index == 0 and batch[2].t_s is None
    assert common_start(batch) is None
    assert common_start(batch[:2]) == batch[0].start_index


def test_statistics_and_default_window():
    t, x = record(lambda t: landau(t, 1e-3), duration=1.5)
    assert dominant_frequency(t, x) == pytest.approx(F0, rel=0.01)
    assert saturation(t, x).window == t.size // 64  # 32 periods would give fewer than 64 windows
    level = saturation(t, np.abs(x), statistic="mean")  # mean of |a sin|: 2a/π
    assert level.level == pytest.approx(2.0 / np.pi, rel=0.02)  # the tail includes the last 1-2 % of the approach
    assert level.growth_rate == pytest.approx(SIGMA, rel=0.03)
    rms = saturation(t, 3.0 + np.sin(2 * np.pi * F0 * t), statistic="rms")
    assert rms.start_index == 0 and rms.level == pytest.approx(np.sqrt(9.5), rel=1e-3)
    hidden = saturation(t, x + 3.0, statistic="rms")  # an offset hides the growth from the rms (use "std")
    assert hidden.growth_rate is None


def test_fit_window_override():
    t, x = record(lambda t: landau(t, 1e-3))
    r = saturation(t, x, window=200, fit_window=(0.1, 0.4))
    assert r.growth_window == pytest.approx((0.1, 0.4))
    assert r.growth_rate == pytest.approx(SIGMA, rel=0.01)
    with pytest.raises(ValueError, match="fit_window"):
        saturation(t, x, window=200, fit_window=(0.1, 0.115))


def test_bad_input_raises_one_clear_line():
    t, x = record(lambda t: landau(t, 1e-3))
    x2 = np.column_stack([x, x])
    x2[5, 1] = np.nan
    with pytest.raises(ValueError, match="non-finite value at sample 5, column 1"):
        saturation(t, x2)
    wide = np.tile(x[:, None], (1, 70)).astype(np.float32)  # two column blocks, float32 kept
    wide[-1, 66] = np.inf
    with pytest.raises(ValueError, match=f"non-finite value at sample {t.size - 1}, column 66"):
        saturation(t, wide, window=400)
    with pytest.raises(ValueError, match="non-finite value at sample 7$|sample 7;"):
        saturation(t, np.where(np.arange(t.size) == 7, np.nan, x))
    with pytest.raises(ValueError, match="shapes|must be"):
        saturation(t[:-1], x)
    with pytest.raises(ValueError, match="too short"):
        saturation(t[:40], x[:40])
    with pytest.raises(ValueError, match="strictly increasing"):
        saturation(t[::-1], x)
    with pytest.raises(ValueError, match="statistic"):
        saturation(t, x, statistic="max")
    with pytest.raises(ValueError, match="windows"):
        saturation(t, x, window=t.size // 4)
    zero = saturation(t, np.zeros_like(t))
    assert zero.t_s is None and "constant" in zero.verdict
    for bad in (1.5, -0.1):
        with pytest.raises(ValueError, match="min_r2"):
            saturation(t, x, min_r2=bad)


def test_a_rise_that_is_not_exponential_is_no_growth_phase_under_min_r2():
    """A fast release (a few windows), then a slow drift: the max-rise run spans both, its fit is a poor line of a
    few 1/s whose fraction no settled window's slope stays under; ``min_r2`` rejects that fit and the record
    settles by its level. A Landau envelope's fit (R² > 0.999) stays a growth phase."""
    t = np.arange(0.0, 0.12, 1e-6)
    level = (
        (1 - 0.95 * np.exp(-t / 2.5e-3)) * (1 + 0.06 * (1 - np.exp(-t / 30e-3))) * (1 + 0.01 * np.sin(90 * np.pi * t))
    )
    x = 100 * level * np.abs(np.sin(2 * np.pi * 70e3 * t))
    drift = saturation(t, x, statistic="mean")
    assert not drift.saturated and drift.growth_r2 < 0.5 and drift.growth_rate < 5.0
    released = saturation(t, x, statistic="mean", min_r2=0.9)
    assert released.saturated and released.t_s < 20e-3 and released.growth_rate is None
    assert released.growth_r2 == pytest.approx(drift.growth_r2)
    assert "no exponential growth phase" in released.verdict and f"R² = {drift.growth_r2:.3f}" in released.verdict
    tl, xl = record(lambda t: landau(t, 1e-3))
    assert saturation(tl, xl, min_r2=0.9).growth_rate == pytest.approx(saturation(tl, xl).growth_rate)
    chosen = saturation(t, x, statistic="mean", min_r2=0.9, fit_window=(0.0, 0.05))  # the caller's span: kept
    assert chosen.growth_rate is not None and chosen.growth_r2 < 0.9
    mu = 0.5 + 0.01 * (1 - 0.97 * np.exp(-t / 8e-3)) * (1 + 0.1 * (1 - np.exp(-t / 40e-3))) * np.sin(1.4e5 * np.pi * t)
    rec = record_saturation(t, mu, x, min_growth_r2=0.9)  # Σ|u̇| only: μ keeps its poor fit
    assert rec.sum_abs_velocity.growth_rate is None and rec.mu.growth_rate is not None and rec.mu.growth_r2 < 0.9


# --------------------------------------------------------------------------------------- linear growth rate


def test_friction_slope_is_the_derivative_of_eq4():
    fr = Friction(M=0.8)
    v = np.array([-12.0, -1.0, -3e-3, 0.0, 1e-3, 0.5, 7.7, 10.0, 12.3])
    h = 1e-7
    fd = (fr.coefficient(v + h) - fr.coefficient(v - h)) / (2 * h)
    np.testing.assert_allclose(friction_slope(v, 0.8), fd, rtol=1e-6, atol=1e-9)
    assert friction_slope(0.0, 0.8) == pytest.approx(fr.max_slope())


def test_predicted_rate_is_the_real_part_of_the_2x2_eigenvalues():
    rng = np.random.default_rng(7)
    n = 40
    area = rng.uniform(2e-8, 2e-6, n)
    radius = rng.uniform(1e-5, 0.16, n)  # below ~1 mm (ω r < 0.08 m/s) Eq. 4 rises: damped patches
    fn = np.exp(rng.uniform(np.log(0.05), np.log(5e3), n))  # up to overdamped effective damping
    zeta, M, omega = 1e-3, 0.8, 10.0 / 0.13
    k = 1.87e9 * np.sqrt(area)
    sigma = predicted_growth_rate(fn, area, radius, omega, M, zeta=zeta)
    m = 37.5 * area
    c_eff = 2 * zeta * np.sqrt(k * m) + fn * friction_slope(omega * radius, M)
    overdamped = c_eff**2 > 4 * m * k
    assert overdamped.any() and (~overdamped).any()
    for i in range(n):
        jac = np.array([[0.0, 1.0], [-k[i] / m[i], -c_eff[i] / m[i]]])
        assert sigma[i] == pytest.approx(np.linalg.eigvals(jac).real.max(), rel=1e-9)
    # the underdamped closed form p|f'|/(2 ρ_A) − ζ ω_0
    p, w0 = fn / area, np.sqrt(k / m)
    closed = p * np.abs(friction_slope(omega * radius, M)) / (2 * 37.5) - zeta * w0
    np.testing.assert_allclose(sigma[~overdamped], closed[~overdamped], rtol=1e-9)


def test_isolated_patch_growth_rate_and_saturation():
    """One HF1-size patch from its equilibrium plus 1 mm/s, integrated with SciPy (no coupling)."""
    area, r, omega, M, fn = 5e-8, 0.13, 10.0 / 0.13, 0.8, 1.0
    m, k = 37.5 * area, 1.87e9 * np.sqrt(area)
    c = 2e-6 * np.sqrt(k * m)
    fr = Friction(M=M)
    vd = omega * r
    sigma = float(predicted_growth_rate(fn, area, r, omega, M))

    def rhs(_t, y):
        return [y[1], (-k * y[0] - c * y[1] + fn * fr.coefficient(vd - y[1])) / m]

    def jac(_t, y):
        return [[0.0, 1.0], [-k / m, (-c - fn * friction_slope(vd - y[1], M)) / m]]

    period = 2 * np.pi * np.sqrt(m / k)
    t = np.arange(0.0, 15.0 / sigma, period / 20)
    y0 = [fn * fr.coefficient(vd) / k, 1e-3]
    sol = solve_ivp(rhs, (0, t[-1]), y0, method="LSODA", jac=jac, rtol=1e-9, atol=[1e-15, 1e-9], t_eval=t)
    assert sol.success
    v = sol.y[1]
    res = saturation(t, v, unit="m/s")
    assert res.growth_rate == pytest.approx(sigma, rel=0.02)
    assert res.saturated
    # saturated: the patch reaches the disc speed (sticks) once per cycle, no faster
    assert v[res.start_index :].max() == pytest.approx(vd, rel=0.03)
    # the saturated part on its own (a run started from the saturated state) is saturated from its start
    tail = saturation(t[res.start_index :], v[res.start_index :], window=res.window)
    assert tail.start_index == 0 and tail.growth_rate is None
    assert tail.level == pytest.approx(res.level, rel=0.01)


def test_coupled_rates_lie_between_the_isolated_rates():
    """Re λ = −x*C x/(2 x*M x) for every underdamped mode: a weighted mean of −c_i/(2 m_i)."""
    rng = np.random.default_rng(3)
    n = 30
    m = rng.uniform(1e-6, 3e-6, n)
    kc = np.triu(rng.uniform(0, 2e5, (n, n)) * (rng.random((n, n)) < 0.3), 1)
    kc = kc + kc.T
    kmat = np.diag(rng.uniform(3e5, 6e5, n) + kc.sum(1)) - kc
    c_eff = rng.uniform(-4e-3, 1e-3, n)
    rates, freqs = coupled_growth_rates(m, c_eff, kmat)
    iso = -c_eff / (2 * m)
    assert np.all(freqs > 0)  # all underdamped here
    assert rates.max() <= iso.max() * (1 + 1e-9) and rates.min() >= iso.min() * (1 + 1e-9)
    assert rates[0] < iso.max()  # coupling spreads the fastest patch's energy: strictly below here


def test_growth_rate_summary_per_pad():
    s = growth_rate_summary(np.array([1.0, 5.0, 3.0, 10.0, 20.0]), np.array([0, 0, 0, 1, 1]))
    np.testing.assert_array_equal(s["min"], [1.0, 10.0])
    np.testing.assert_array_equal(s["median"], [3.0, 15.0])
    np.testing.assert_array_equal(s["max"], [5.0, 20.0])


def small_hf1_pad(count: int, seed: int):
    """hf1 at its patch density and pressure on a small annular sector (count patches, ~11 neighbours each)."""
    base = preset("hf1")
    density = 1758 / base.pad.area
    ri, ro = 0.12, 0.14
    span = np.degrees(2 * count / density / (ro**2 - ri**2))
    pad = Pad(r_inner=ri, r_outer=ro, span_deg=span)
    patches = PatchGenerator(count=count, seed=seed).generate(pad)
    return base.replace(pad=pad, patches=patches, normal_force=base.normal_force * count / 1758)


def test_coupled_pad_growth_of_sum_abs_velocity():
    """100 coupled hf1 patches from rest, nonlinear (ReferenceODE) and linearised, 3 ms of growth.

    Σ|u̇| grows at the rate of the bulk of the patches early on (0.7 % above the median isolated σ_i here),
    well below the fastest patch (σ_max = 1.66 median), whose localised mode has not yet taken over. The
    fastest coupled mode lies between median and maximum, as Re λ is a weighted mean of the isolated rates.
    """
    from aca_warp.hf.model import build_model
    from aca_warp.hf.reference import ReferenceODE

    scene = small_hf1_pad(100, seed=1)
    ref = ReferenceODE(build_model([scene]))
    area = scene.patches.area
    sigma = predicted_growth_rate(ref.fn, area, ref.r, ref.omega, scene.friction.M, k_t=1.87e9 * np.sqrt(area))
    c_eff = ref.c + ref.fn * friction_slope(ref.vd, scene.friction.M)
    rates, _ = coupled_growth_rates(ref.m, c_eff, ref.K)
    assert np.median(sigma) < rates[0] <= sigma.max() * (1 + 1e-9)

    t = np.arange(0.0, 3e-3, 1e-6)
    nonlinear = ref.solve(t, rtol=1e-7).v
    n = ref.n
    u_eq = np.linalg.solve(ref.K.toarray(), ref.fn * ref.friction(ref.vd))

    def linear(_t, y):
        return np.concatenate([y[n:], (-(ref.K @ (y[:n] - u_eq)) - c_eff * y[n:]) / ref.m])

    lin = solve_ivp(linear, (0, t[-1]), np.zeros(2 * n), method="DOP853", rtol=1e-7, atol=1e-13, t_eval=t)
    fit = {"statistic": "mean", "window": 150, "fit_window": (0.5e-3, 3e-3)}
    measured = saturation(t, np.abs(nonlinear).sum(axis=1), **fit).growth_rate
    linearised = saturation(t, np.abs(lin.y[n:]).sum(axis=0), **fit).growth_rate
    assert measured == pytest.approx(linearised, rel=0.02)  # |u̇| < 3 m/s < 0.3 ω r: still nearly linear
    assert sigma.min() < measured < sigma.max()
    assert measured == pytest.approx(np.median(sigma), rel=0.1)
