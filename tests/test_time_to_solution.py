"""``aca_warp.studies.time_to_solution`` (``scripts/time_to_solution.py``): the μ error of a batch, the tolerance
ladder, the equations handed to diffrax against :class:`~aca_warp.hf.reference.ReferenceODE` (NumPy; diffrax
itself where importable), and the JSON → table → page path on a 9-patch pad (CPU)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from procs import nine_patch_scene

from aca_warp.hf.model import build_model
from aca_warp.hf.reference import ReferenceODE
from aca_warp.hf.state import initial_state
from aca_warp.scene import Scene
from aca_warp.studies import time_to_solution as tts


def tiny_scene(speed: float = 10.0) -> Scene:
    """9 HF1-size patches on a 1.5 mm grid at r = 0.13 m, perturbed from rest."""
    return nine_patch_scene("tiny", sample_dt=1e-6, duration=2e-5, angular_velocity=speed / 0.13)


def tiny_ode() -> tuple[ReferenceODE, np.ndarray, np.ndarray]:
    model = build_model([tiny_scene()], device="cpu", precision="fp64")
    u, v = (x.astype(np.float64) for x in initial_state(model).numpy())
    return ReferenceODE(model), u, v


def numpy_equations(ode: ReferenceODE):
    return tts.equations(tts.rhs_arrays(ode), np, lambda d, r, n: np.bincount(r, weights=d, minlength=n))


def test_equations_match_reference_ode():
    """The scaled right-hand side and μ written for diffrax equal ReferenceODE's at random states (NumPy)."""
    ode, _, _ = tiny_ode()
    rhs, mu = numpy_equations(ode)
    rng = np.random.default_rng(5)
    su, sv = ode.u_scale, ode.v_scale
    for _ in range(3):
        u, v = su * rng.standard_normal(ode.n), ode.vd + 0.02 * rng.standard_normal(ode.n)
        z = np.concatenate([u / su, v / sv])
        want = ode.rhs(0.0, np.concatenate([u, v]))
        got = rhs(0.0, z, None) * np.concatenate([su, sv])
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())
        assert mu(0.0, z, None) == pytest.approx(ode.globals(u[None], v[None])["mu"][0], rel=1e-13)
    # the coupling enters: without it the accelerations differ
    a = tts.rhs_arrays(ode)
    off = a["rows"] != a["cols"]
    assert off.any()
    a["vals"] = np.where(off, 0.0, a["vals"])
    bare, _ = tts.equations(a, np, lambda d, r, n: np.bincount(r, weights=d, minlength=n))
    z = np.concatenate([su * rng.standard_normal(ode.n) / su, ode.vd / sv])
    assert np.max(np.abs(bare(0.0, z, None) - rhs(0.0, z, None))) > 1e-3


def test_diffrax_solver_follows_the_reference():
    """diffrax Dopri8 (where JAX and diffrax import) reaches the DOP853 μ to its tolerance; vmapped pads each theirs."""
    pytest.importorskip("diffrax")
    ode, u, v = tiny_ode()
    times = np.arange(21) * 1e-6
    ref = ode.globals(*(lambda s: (s.u, s.v))(ode.solve(times, rtol=1e-11, u0=u, v0=v)))["mu"]
    one = tts.diffrax_solver(ode, times, batched=False)
    mu, acc, rej = one.fn(u, v, 1e-9)
    assert np.max(np.abs(np.asarray(mu) - ref)) < 1e-8 and int(acc) > 0
    both = tts.diffrax_solver(ode, times, batched=True)
    v2 = v + 0.01
    ref2 = ode.globals(*(lambda s: (s.u, s.v))(ode.solve(times, rtol=1e-11, u0=u, v0=v2)))["mu"]
    mus, _, _ = both.fn(np.stack([u, u]), np.stack([v, v2]), 1e-9)
    mus = np.asarray(mus)
    assert mus.shape == (2, len(times))
    assert np.max(np.abs(mus[0] - ref)) < 1e-8 and np.max(np.abs(mus[1] - ref2)) < 1e-8
    assert np.max(np.abs(ref2 - ref)) > 1e-5  # the two pads differ


def test_problem_error_over_checked_pads():
    """The μ error of a batch is the largest over its checked pads, each against its own reference."""
    prob = tts.Problem(tiny_scene(), pads=5, checked=3, duration=1e-5, log=lambda m: None)
    assert prob.checked == [0, 2, 4] and tts.check_pads(64, 4) == [0, 21, 42, 63]
    mu = np.stack([prob.ref[p] if p in prob.ref else np.zeros_like(prob.ref[0]) for p in range(5)], axis=1)
    assert prob.error(mu) == 0.0  # pads 1 and 3 are not checked
    mu[3, 2] += 4e-7
    mu[7, 4] -= 2e-7
    assert prob.error(mu) == pytest.approx(4e-7, rel=1e-12)
    assert np.max(np.abs(prob.ref[0] - prob.ref[4])) > 1e-6  # the pads' perturbations differ
    single = tts.Problem(tiny_scene(), pads=1, checked=4, duration=1e-5, log=lambda m: None)
    assert single.error(single.ref[0] + 3e-9) == pytest.approx(3e-9, rel=1e-6)


def test_ladder_stops_at_the_first_setting_that_reaches():
    """Settings are tried loosest first until one reaches the target; a failure ends the ladder and is marked;
    short runs are timed by the fastest of three."""
    errors = {1e-3: 5e-6, 1e-4: 3e-7, 1e-5: 4e-8, 1e-6: 1e-9}
    tried = []

    def fn(s):
        tried.append(s)
        return {"error": errors[s], "time_s": 1.0 / s}

    tries = tts.ladder(tuple(errors), fn, 1e-7, lambda m: None, "x")
    assert tried == [1e-3, 1e-4, 1e-5] and [t["reached"] for t in tries] == [False, False, True]
    assert tts.chosen(tries)["setting"] == 1e-5

    def boom(s):
        if s < 1e-3:
            raise RuntimeError("run stopped: fault\nmore")
        return fn(s)

    tries = tts.ladder(tuple(errors), boom, 1e-7, lambda m: None, "x")
    assert len(tries) == 2 and tries[1]["failed"] == "RuntimeError: run stopped: fault"
    assert tts.chosen(tries)["setting"] == 1e-3 and not tts.chosen(tries)["reached"]
    assert tts.chosen([{"setting": 1.0, "failed": "ImportError: x"}]) is None
    # a short run is repeated and timed by its fastest run
    clock = iter([0.3, 0.1, 0.2, 0.05])
    tries = tts.ladder((1e-3,), lambda s: {"error": 1e-8, "time_s": next(clock)}, 1e-7, lambda m: None, "x")
    assert tries[0]["times_s"] == [0.3, 0.1, 0.2] and tries[0]["time_s"] == 0.1


def test_json_table_and_page(tmp_path, monkeypatch):
    """A run of the benchmark on the tiny pad (SciPy and ours, diffrax off) writes the JSON; its table names the
    reached settings, and --report writes it into the page between the markers, keeping the text around."""
    monkeypatch.setattr(tts, "make_scene", lambda name: tiny_scene().replace(name=name))
    monkeypatch.setattr(tts, "STEPS", (1e-8,))
    monkeypatch.setattr(tts, "REPEATS", 1)  # one timed run per setting (the repeats have their own test)
    argv = ["--scenes", "hf1", "--duration", "1e-5", "--target", "1e-9", "--no-diffrax", "--out", str(tmp_path)]
    assert tts.main(argv) == 0
    doc = json.loads((tmp_path / "tts_cpu.json").read_text())
    rows = {r["solver"]: r for r in doc["rows"]}
    assert set(rows) >= {"reference: SciPy DOP853", "ours: adaptive (DP5)", "ours: strang 1e-8 s", "SciPy DOP853"}
    ad = tts.chosen(rows["ours: adaptive (DP5)"]["tries"])
    assert ad["reached"] and ad["error"] <= 1e-9 and ad["time_s"] > 0
    assert all(not t["reached"] for t in rows["ours: adaptive (DP5)"]["tries"][:-1])
    sp = tts.chosen(rows["SciPy DOP853"]["tries"])
    assert sp["reached"] and sp["setting"] < 1e-5
    text = "\n".join(tts.table(doc))
    assert f"| tol {ad['setting']:g} | {ad['error']:.1e} |" in text
    page = tmp_path / "page.md"
    page.write_text(f"# T\n\nmethod text\n\n{tts.BEGIN}\nOLD-GENERATED-TEXT\n{tts.END}\n\nGPU rows below\n")
    assert tts.main(["--report", str(tmp_path / "tts_cpu.json"), "--page", str(page)]) == 0
    out = page.read_text()
    assert "method text" in out and "GPU rows below" in out and "OLD-GENERATED-TEXT" not in out
    assert f"| tol {ad['setting']:g} | {ad['error']:.1e} |" in out and not math.isnan(doc["total_wall_s"])
