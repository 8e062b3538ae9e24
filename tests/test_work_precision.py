"""``aca_warp.studies.work_precision`` (``scripts/work_precision.py``) and ``aca_warp.hf.reference``: Richardson
check, the SciPy reference against the HF engine, and the measure → report pipeline end to end on a 9-patch scene
(CPU)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from aca_warp.hf.loop import run_hf
from aca_warp.hf.model import build_model
from aca_warp.hf.options import RunOptions
from aca_warp.hf.reference import ReferenceODE
from aca_warp.hf.state import initial_state
from aca_warp.scene import Friction, Initial, Pad, Patches, Record, Scene
from aca_warp.studies import work_precision as wp_study


def tiny_scene(speed=10.0, load=20.0) -> Scene:
    """9 HF1-size patches on a 1.5 mm grid at r = 0.13 m, sharing ``load`` with the matrix, perturbed."""
    pos = [(i * 1.5e-3, 0.13 + j * 1.5e-3) for i in (-1, 0, 1) for j in (-1, 0, 1)]
    area = np.random.default_rng(2).uniform(2e-8, 8e-8, len(pos))
    p = Patches(np.array([q[0] for q in pos]), np.array([q[1] for q in pos]), area, np.full(len(pos), 3e-6))
    return Scene(
        name="tiny",
        pad=Pad(),
        patches=p,
        friction=Friction(M=0.8),
        normal_force=load,
        angular_velocity=speed / 0.13,
        initial=Initial(perturbation=0.05, seed=3),
        record=Record(sample_dt=1e-6),
        duration=2e-5,
    )


def test_richardson_recovers_order():
    """Three solutions exact + C hᵖ at h = 4, 2, 1: the order p and the finest error C are recovered."""
    x = np.linspace(0, 1, 50)
    exact, c = np.sin(x), 1e-3 * np.cos(3 * x)
    for p in (1.0, 2.0, 4.0):
        a, b, f = (exact + c * h**p for h in (4.0, 2.0, 1.0))
        r = wp_study.richardson(a, b, f)
        assert r["order"] == pytest.approx(p, abs=1e-9)
        assert r["error_estimate"] == pytest.approx(np.max(np.abs(c)), rel=1e-9)
    assert math.isnan(wp_study.richardson(exact, exact, exact)["order"])


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


def test_measure_and_report_end_to_end(tmp_path, monkeypatch):
    """A tiny study (one scene, strang + adaptive, fp64, DOP853 baseline) and a page merged from two JSONs."""
    base = tiny_scene()
    monkeypatch.setattr(wp_study, "make_scene", lambda name: base.replace(name=name))
    args = ["--quick", "--scenes", "stickslip", "--integrators", "strang", "adaptive", "--precisions", "fp64"]
    args += ["--scipy-methods", "DOP853", "--t-state", "1e-5", "--t-long", "4e-5", "--steps", "1e-7", "2e-8"]
    args += ["--ref-dt", "2.5e-9", "--out", str(tmp_path)]
    assert wp_study.main(args) == 0
    path = next(tmp_path.glob("wp_cpu_quick_stickslip.json"))
    doc = json.loads(path.read_text())
    sc = doc["scenes"][0]
    rows = {(r["method"], r.get("dt_requested", r.get("tolerance", r.get("rtol")))): r for r in sc["rows"]}
    assert len(rows) == 2 + 3 + 2
    assert 1.8 < sc["long_reference"]["richardson_mu"]["order"] < 2.2
    s1, s2 = rows[("strang", 1e-7)], rows[("strang", 2e-8)]
    assert s2["state"]["error"] < s1["state"]["error"] / 10  # second order: 25× expected
    assert s2["long"]["mu"] < s1["long"]["mu"] / 10
    assert rows[("scipy-DOP853", 1e-7)]["state"]["error"] < 1e-4
    # a second "device": the same results relabelled, merged into one page that keeps the hand-written text
    other = json.loads(path.read_text())
    other["machine"]["device"], other["machine"]["device_name"] = "cuda:0", "Fake GPU"
    p2 = tmp_path / "gpu.json"
    p2.write_text(json.dumps(other))
    page = tmp_path / "page.md"
    page.write_text(f"# Title\n\nhand-written\n\n{wp_study.BEGIN}\nold\n{wp_study.END}\n\nafter\n")
    wp_study.main(["--report", str(path), str(p2), "--page", str(page), "--figures", str(tmp_path / "fig")])
    text = page.read_text()
    assert "hand-written" in text and "after" in text and "old" not in text
    assert text.count("### stickslip on") == 2 and "Fake GPU" in text
    assert (tmp_path / "fig" / "wp_stickslip_cpu_quick.png").exists()
    assert (tmp_path / "fig" / "wp_stickslip_cuda0_quick.pdf").exists()
