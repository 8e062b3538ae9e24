"""``aca_warp.studies.work_precision`` (``scripts/work_precision.py``) and ``aca_warp.hf.reference``: the statistics
of saturated windows, the SciPy reference against the HF engine, start states made once and cached, and the
measure → report pipeline end to end on a 9-patch scene (CPU)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from procs import nine_patch_scene

from aca_warp.analysis.spectra import amplitude_spectrum
from aca_warp.hf.loop import run_hf
from aca_warp.hf.model import build_model
from aca_warp.hf.options import RunOptions
from aca_warp.hf.reference import ReferenceODE
from aca_warp.hf.state import initial_state
from aca_warp.scene import Initial, Record, Scene
from aca_warp.studies import work_precision as wp_study
from aca_warp.studies import work_precision_report as wp_report
from aca_warp.studies import work_precision_states as wp_states


def tiny_scene(speed=10.0, load=20.0) -> Scene:
    """9 HF1-size patches on a 1.5 mm grid at r = 0.13 m, sharing ``load`` with the matrix, perturbed."""
    return nine_patch_scene("tiny", sample_dt=1e-6, duration=2e-5, normal_force=load, angular_velocity=speed / 0.13)


def test_statistics_errors():
    """Identical records give zero errors; a record whose oscillation is ×2 gives std error 1 and a spectrum error
    of ln 2 (the mean stays); sticking counts |ωr − u̇| below the threshold."""
    t = np.arange(1001) * 1e-6
    rng = np.random.default_rng(0)
    osc = 0.01 * np.sin(2 * np.pi * 50e3 * t) + 0.003 * rng.standard_normal(len(t))
    v = 1e-3 * rng.standard_normal((len(t), 20))
    slip = np.full(20, 2e-3)
    a = wp_study.statistics(0.5 + osc, v, slip, 5e3)
    b = wp_study.statistics(0.5 + 2 * osc, v, slip, 5e3)
    zero = wp_study.stat_errors(a, a)
    assert all(v == 0.0 for k, v in zero.items() if k != "stick")
    e = wp_study.stat_errors(b, a)
    assert e["std"] == pytest.approx(1.0, rel=1e-12)
    assert e["spectrum"] == pytest.approx(math.log(2.0), rel=1e-3)  # spectra normalised by the mean of μ
    assert e["mean"] < 1e-3 and e["peak_f"] < 1e-3
    # |2e-3 − v| < 1e-3 ⇔ 1e-3 < v < 3e-3: the normal tail above 1σ (15.87 %) minus above 3σ (0.13 %)
    assert a["stick"] == pytest.approx(0.1574, abs=0.01)
    f, amp = amplitude_spectrum(0.5 + osc, 1e-6)
    assert a["bands"].max() <= amp[f >= 5e3].max()


def test_reference_jacobian_and_agreement():
    """The analytic sparse Jacobian matches finite differences; strang fp64 converges to DOP853 (order 2)."""
    scene = tiny_scene(speed=0.5)  # slow disc: friction slope large and sign-changing
    model = build_model([scene])
    ode = ReferenceODE(model)
    v0 = initial_state(model).numpy()[1]
    y = np.concatenate([np.random.default_rng(0).normal(0, 1e-7, ode.n), v0])
    jac = ode.jac(0.0, y).toarray()
    eps = 1e-9
    fd = np.stack([(ode.rhs(0, y + eps * e) - ode.rhs(0, y - eps * e)) / (2 * eps) for e in np.eye(2 * ode.n)], 1)
    np.testing.assert_allclose(jac, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())
    assert ode.jac_sparsity().nnz >= np.count_nonzero(jac)
    times = np.arange(21) * 1e-6
    ref = ode.solve(times, method="DOP853", rtol=1e-11, v0=v0)
    mu_ref = ode.globals(ref.u, ref.v)["mu"]
    err = []
    for dt in (1e-9, 5e-10):  # the sticking transient: strang converges to DOP853 at second order
        state = initial_state(model)
        res = run_hf(
            model, state, RunOptions(duration=2e-5, integrator="strang", dt=dt), record=Record(1e-6, ("velocity",))
        )
        c = res.collect()
        err.append(np.max(np.abs(c.globals[:, 0, 0] - mu_ref)))
    assert err[0] < 2e-4 and 3.2 < err[0] / err[1] < 4.8
    assert np.max(np.abs(c.velocity - ref.v)) < 1e-3 * np.max(np.abs(ref.v))
    radau = ode.solve(times, method="Radau", rtol=1e-8, v0=v0)
    assert np.max(np.abs(ode.globals(radau.u, radau.v)["mu"] - mu_ref)) < 1e-5


def test_deadline_stops_a_slow_solve():
    """Past its deadline the right-hand side raises Overrun (the SciPy solve stops); afterwards the ODE is as before."""
    ode = ReferenceODE(build_model([tiny_scene()]))
    times = np.arange(11) * 1e-6
    with pytest.raises(wp_study.Overrun), wp_study.deadline(ode, 0.0):
        ode.solve(times, method="DOP853", rtol=1e-8)
    assert "rhs" not in vars(ode)
    with wp_study.deadline(ode, 60.0):
        sol = ode.solve(times, method="DOP853", rtol=1e-8)
    assert sol.nfev > 0 and "rhs" not in vars(ode)


@pytest.fixture
def tiny_study(monkeypatch):
    """The study's scenes replaced by the tiny pad (hf1_sat: from equilibrium + perturbation, 0.3 ms spin-up)."""
    base = tiny_scene()
    real = wp_states.make_scene

    def scene(name, patches=None):
        s = base.replace(name=name)
        if name in wp_states.SPIN:
            return s.replace(initial=Initial(state="equilibrium", perturbation=0.05, seed=1))
        return s

    monkeypatch.setattr(wp_states, "make_scene", scene)
    monkeypatch.setattr(wp_states, "SPIN", {"hf1_sat": ("hf1", 3e-4)})
    return real


def test_measure_and_report_end_to_end(tmp_path, tiny_study):
    """A tiny study (a sliding scene named stickslip and a saturated scene with its statistics window; adaptive,
    strang, DOP853) and a page merged from two JSONs; the start state is made once and read back."""
    args = ["--quick", "--scenes", "stickslip", "hf1_sat", "--tolerances", "1e-2", "1e-5", "--steps", "1e-7", "2e-8"]
    args += ["--scipy-methods", "DOP853", "--scipy-rtols", "1e-6", "1e-9"]
    args += ["--window", "2e-5", "--long-window", "5e-5", "--out", str(tmp_path)]
    assert wp_study.main(args) == 0
    path = tmp_path / "wp_cpu_quick_stickslip-hf1_sat.json"
    doc = json.loads(path.read_text())
    st, sat = doc["scenes"]
    rows = {(r["method"], r.get("dt_requested", r.get("tolerance", r.get("rtol")))): r for r in st["rows"]}
    assert len(rows) == 2 + 2 + 2
    assert st["reference"]["check_mu"] < 1e-8
    s1, s2 = rows[("strang", 1e-7)]["window"], rows[("strang", 2e-8)]["window"]
    assert s2["state"] < s1["state"] / 10 and s2["mu"] < s1["mu"] / 10  # second order: 25× expected
    a1, a2 = rows[("adaptive", 1e-2)]["window"], rows[("adaptive", 1e-5)]["window"]
    assert a2["mu"] < a1["mu"] / 30 and a2["mu"] < 1e-6 and a2["steps"] > a1["steps"]
    assert rows[("scipy-DOP853", 1e-6)]["window"]["mu"] < 1e-5
    assert {"peak_f", "sync"} <= set(s1)
    # the saturated scene: start state from a run, statistics window with its floor
    assert sat["start"]["how"].startswith("equilibrium") and (tmp_path / "state_hf1_sat_9.npz").exists()
    lr = sat["long_reference"]
    assert lr["vs_reference_mu"] < 1e-6 and set(lr["floor"]) == {"mean", "std", "spectrum", "peak_f", "sync", "stick"}
    long_rows = [r for r in sat["rows"] if "long" in r]
    assert {r["method"] for r in long_rows} == {"adaptive", "strang", "scipy-DOP853"}
    fine = next(r for r in long_rows if r["method"] == "scipy-DOP853")["long"]
    assert fine["spectrum"] < 1e-3 and fine["std"] < 1e-3
    # the cached start state is read back, not made again
    start = wp_states.start_state("hf1_sat", wp_study.build_parser().parse_args(["--out", str(tmp_path)]), print)
    assert start.info.get("cached", "").endswith("state_hf1_sat_9.npz")
    u0 = np.load(tmp_path / "state_hf1_sat_9.npz")["u"]
    np.testing.assert_array_equal(start.u, u0)
    # report: a second "device" (its stickslip scene only: one figure fewer to draw) merged into one page that keeps
    # the hand-written text
    other = json.loads(path.read_text())
    other["machine"]["device"], other["machine"]["device_name"] = "cuda:0", "Fake GPU"
    other["scenes"] = [sc for sc in other["scenes"] if sc["scene"] == "stickslip"]
    p2 = tmp_path / "gpu.json"
    p2.write_text(json.dumps(other))
    page = tmp_path / "page.md"
    page.write_text(f"# Title\n\nhand-written\n\n{wp_report.BEGIN}\nOLD-GENERATED-TEXT\n{wp_report.END}\n\nafter\n")
    wp_study.main(["--report", str(path), str(p2), "--page", str(page), "--figures", str(tmp_path / "fig")])
    text = page.read_text()
    assert "hand-written" in text and "after" in text and "OLD-GENERATED-TEXT" not in text
    assert text.count("### stickslip on") == 2 and "Fake GPU" in text and "floor (twin reference)" in text
    assert "Cheapest setting that reaches a μ error" in text and "at the floor or within" in text
    assert (tmp_path / "fig" / "wp_hf1_sat_cpu_quick.png").exists()
    assert (tmp_path / "fig" / "wp_stickslip_cuda0_quick.pdf").exists()
    assert sorted(f.stem for f in (tmp_path / "fig").glob("*.png")) == [
        "wp_hf1_sat_cpu_quick", "wp_stickslip_cpu_quick", "wp_stickslip_cuda0_quick"
    ]  # fmt: skip


def test_summary_picks_the_cheapest_that_reaches():
    """The summary's cell is the cheapest row of a method within the target, and ``at_floor`` needs every
    statistic with a floor within the factor."""
    rows = [
        {"method": "adaptive", "precision": "fp64", "tolerance": 1e-3, "window": {"mu": 2e-6, "wall_s": 1.0}},
        {"method": "adaptive", "precision": "fp64", "tolerance": 1e-5, "window": {"mu": 5e-8, "wall_s": 3.0}},
        {"method": "adaptive", "precision": "fp64", "tolerance": 1e-6, "window": {"mu": 4e-9, "wall_s": 9.0}},
        {"method": "adaptive", "precision": "fp32", "tolerance": 1e-4, "window": {"mu": 1e-8, "wall_s": 0.1}},
    ]
    sc = {"rows": rows}
    assert wp_report.cheapest(sc, "adaptive", lambda b: b["mu"] <= 1e-5)["tolerance"] == 1e-3
    assert wp_report.cheapest(sc, "adaptive", lambda b: b["mu"] <= 1e-7)["tolerance"] == 1e-5
    assert wp_report.cheapest(sc, "adaptive", lambda b: b["mu"] <= 1e-10) is None
    floor = {"std": 0.01, "spectrum": 0.1, "sync": 0.02, "stick": None}
    assert wp_report.at_floor({"std": 0.015, "spectrum": 0.2, "sync": 0.01, "stick": 5.0}, floor)
    assert not wp_report.at_floor({"std": 0.015, "spectrum": 0.21, "sync": 0.01}, floor)
    tiny = {"std": 1e-10, "spectrum": 1e-10, "sync": 0.0, "stick": 0.0}  # a twin that has not parted
    assert wp_report.at_floor({"std": 0.009, "spectrum": 0.009, "sync": 0.005, "stick": 0.05}, tiny)
    assert not wp_report.at_floor({"std": 0.009, "spectrum": 0.011, "sync": 0.005, "stick": 0.05}, tiny)
