"""Saturation in every run's analysis: σ_i in the run file at creation, ``/analysis/saturation`` and its summary.

A 6-patch hf1 sector with equal heights and equal areas (hf1's patch density and pressure), started from its
static equilibrium plus 1 mm/s per patch, integrated with the adaptive integrator on the CPU: its Σ|u̇| grows at
the median isolated σ_i (the rates of its patches differ by the friction radius alone, ±8 %).
"""

from __future__ import annotations

import shutil

import h5py
import numpy as np
import pytest

from aca_warp.analysis.report import analyze_run, read_group, saturation_summary
from aca_warp.analysis.saturation import friction_slope
from aca_warp.hf.options import RunOptions
from aca_warp.hf.runner import run_scene
from aca_warp.scene import Initial, Pad, PatchGenerator, preset

GROWTH_TOLERANCE = 0.03
"""Measured growth rate of Σ|u̇| against the predicted median σ_i (relative; docs/analysis.md)."""


def small_equal_pad(count: int = 6):
    """hf1 at its patch density and pressure on a small sector, equal heights and areas, equilibrium + 1 mm/s."""
    base = preset("hf1")
    density = 1758 / base.pad.area
    ri, ro = 0.12, 0.14
    pad = Pad(r_inner=ri, r_outer=ro, span_deg=float(np.degrees(2 * count / density / (ro**2 - ri**2))))
    patches = PatchGenerator(count=count, seed=1, area_min=5e-8, area_max=5e-8).generate(pad)
    initial = Initial(state="equilibrium", perturbation=1e-3, seed=1)
    return base.replace(pad=pad, patches=patches, normal_force=base.normal_force * count / 1758, initial=initial)


def run(path, duration: float):
    run_scene(small_equal_pad(), path, RunOptions(duration=duration, integrator="adaptive"))
    return path


@pytest.fixture(scope="module")
def growing(tmp_path_factory):
    """8 ms: about 5 e-folds of growth, far from saturation."""
    return run(tmp_path_factory.mktemp("sat") / "growing.h5", 8e-3)


@pytest.fixture(scope="module")
def saturating(tmp_path_factory):
    """25 ms: grows for ~15 ms, then saturates."""
    return run(tmp_path_factory.mktemp("sat") / "saturating.h5", 25e-3)


def test_run_file_holds_the_predicted_rates(growing):
    """σ_i = p_i |f′(ω r_i)| / (2 ρ_A) − ζ ω_0,i (the underdamped closed form), and its min / median / max."""
    s = small_equal_pad()
    with h5py.File(growing) as f:
        sigma = f["patches/predicted_growth_rate"][()]
        assert f["patches/predicted_growth_rate"].attrs["unit"] == "s-1"
        fn, a = f["patches/normal_force"][()], f["patches/area"][()]
        stats = [f.attrs[f"predicted_growth_rate_{k}"] for k in ("min", "median", "max")]
    m = s.material
    slope = friction_slope(s.angular_velocity * s.patches.friction_radius, s.friction.M)
    omega0 = np.sqrt(m.K_T * np.sqrt(a) / (m.mass_per_area * a))
    expected = fn / a * np.abs(slope) / (2 * m.mass_per_area) - m.damping_ratio * omega0
    np.testing.assert_allclose(sigma, expected, rtol=1e-9)
    np.testing.assert_allclose(stats, [sigma.min(), np.median(sigma), sigma.max()], rtol=1e-12)
    assert sigma.size == 6 and np.all(sigma > 0)


def test_growth_rate_agrees_with_the_prediction_and_the_growing_record_is_not_saturated(growing):
    g = analyze_run(growing)["saturation"]
    a = g.attrs
    assert a["status"] == "not saturated" and a["t_start"] is None
    assert a["growth_rate"] == pytest.approx(a["predicted_growth_rate_median"], rel=GROWTH_TOLERANCE)
    assert a["growth_rate_ratio"] == pytest.approx(a["growth_rate"] / a["predicted_growth_rate_median"])
    assert a["predicted_growth_rate_min"] <= a["predicted_growth_rate_q25"] <= a["predicted_growth_rate_median"]
    assert saturation_summary(g).startswith("not saturated")
    with h5py.File(growing) as f:  # what the file holds reads back to the same summary
        assert saturation_summary(read_group(f["analysis/saturation"])) == saturation_summary(g)
        assert (
            f["analysis/saturation/sum_abs_velocity_envelope"].shape
            == f["analysis/saturation/sum_abs_velocity_time"].shape
        )


def test_a_saturating_record_says_from_when(saturating):
    g = analyze_run(saturating)["saturation"]
    a = g.attrs
    assert a["status"] == "saturated"
    assert 12e-3 < a["t_start"] < 22e-3 and a["t_start"] == max(a["t_s_sum_abs_velocity"], a["t_s_mu"])
    assert a["growth_rate"] == pytest.approx(a["predicted_growth_rate_median"], rel=GROWTH_TOLERANCE)
    assert saturation_summary(g).startswith(f"saturated from {a['t_start'] * 1e3:.4g} ms")


def test_a_file_without_predicted_rates_still_analyses(growing, tmp_path):
    old = shutil.copy(growing, tmp_path / "old.h5")
    with h5py.File(old, "r+") as f:  # as written by earlier versions
        del f["patches/predicted_growth_rate"]
        for k in ("min", "median", "max"):
            del f.attrs[f"predicted_growth_rate_{k}"]
        if "analysis" in f:
            del f["analysis"]
    a = analyze_run(old)["saturation"].attrs
    assert a["status"] == "not saturated" and a["growth_rate"] > 0
    assert "predicted_growth_rate_median" not in a and a["growth_rate_ratio"] is None
    assert "no predicted σ" in saturation_summary(analyze_run(old)["saturation"])


def test_a_record_too_short_is_not_analysed(tmp_path):
    path = run(tmp_path / "short.h5", 40e-6)  # 41 samples: fewer than the detector's 64
    g = analyze_run(path)["saturation"]
    assert g.attrs["status"] == "not analysed" and "too short" in g.attrs["reason"]
    assert saturation_summary(g).startswith("saturation not analysed")


def test_a_record_shorter_than_one_predicted_e_fold_is_too_short_to_tell():
    """No growth phase in a record of σ_pred·T < 1 e-fold (a 1 ms hf1 record, σ median 590 s^-1): the summary says
    the record is too short to tell, not that Σ|u̇| settled without growing; from one e-fold on it says settled."""
    from aca_warp.analysis.report import Group

    attrs = {
        "status": "no growth phase",
        "t_s_sum_abs_velocity": 7.956e-4,
        "growth_rate": "none",
        "predicted_growth_rate_median": 590.1,
        "predicted_growth_rate_q25": 413.3,
        "record_length": 1.0e-3,
    }
    line = saturation_summary(Group(attrs=attrs))
    assert line.startswith("no growth phase: record too short to tell (σ_pred·T = 0.59 e-folds)")
    assert "settled" not in line
    long = saturation_summary(Group(attrs={**attrs, "record_length": 3.0e-3}))
    assert long.startswith("no growth phase (Σ|u̇| settled from 0.7956 ms without growing)")
    old = {k: v for k, v in attrs.items() if k != "record_length"}  # an analysis written before record_length
    assert saturation_summary(Group(attrs=old)).startswith("no growth phase (Σ|u̇| settled")
    stable = {**attrs, "predicted_growth_rate_median": -3000.0}  # σ_pred < 0: a stable pad settles, as said
    assert saturation_summary(Group(attrs=stable)).startswith("no growth phase (Σ|u̇| settled")
