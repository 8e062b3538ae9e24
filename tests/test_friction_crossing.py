"""The zero-slip crossing treatment of the prototype (``thmean`` in aca_warp.studies.friction_schemes) and the
measures and tables of aca_warp.studies.friction_crossing: G = ∫ f in closed form against quadrature, ``thmean``
equal to ``thmid`` where no step crosses zero slip and solving the segment-averaged midpoint where one does, Φ and
f1 of a known set of patch signals, result files joined over seeds; the prototype's three readings of μ and its
dispersion-corrected stiffness."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.integrate

from aca_warp.studies import friction_crossing as fc
from aca_warp.studies import friction_schemes as fs


def one_patch(M: float = 0.8, slope: float = 200.0, decay: float = 0.25) -> fs.Pads:
    """One hf1-like patch (mass, damping, normal force, disc speed, k_T of an hf1 patch) with Eq. 4's law."""
    a = lambda x: np.array([x], dtype=np.float64)  # noqa: E731
    import scipy.sparse as sp

    return fs.Pads(
        m=a(1.86e-6), c=a(2.0e-2), fn=a(0.27), vd=a(10.0), kt=a(4.2e5), K=sp.csr_matrix(a(4.2e5)[:, None]),
        start=np.array([0, 1]), M=M, slope=slope, decay=decay, load=a(0.27), coulomb=a(0.0), u0=a(0.0), v0=a(0.0),
    )  # fmt: skip


@pytest.mark.parametrize(("M", "slope", "decay"), [(0.8, 200.0, 0.25), (0.4, 200.0, 0.25), (0.8, 50.0, 0.0)])
def test_friction_integral_is_the_integral_of_eq4(M: float, slope: float, decay: float) -> None:
    p = one_patch(M, slope, decay)
    s = np.array([-3.0, -0.3, -4e-3, 0.0, 1e-6, 1e-3, 0.17, 1.0, 2.7, 12.0, 30.0])
    g = fs.friction_integral(p, s)
    for x, gx in zip(s, g, strict=True):
        f = lambda y: float(fs.friction(p, np.array([y]))[0])  # noqa: E731
        ref = 0.0 if x == 0 else scipy.integrate.quad(f, 0.0, x, points=[0.0], limit=400, epsabs=1e-14, epsrel=1e-13)[0]
        assert gx == pytest.approx(ref, abs=2e-8), x
    assert np.array_equal(fs.friction_integral(p, -s), g)  # even


def test_thmean_is_thmid_where_no_step_crosses_zero_slip() -> None:
    p = one_patch()
    v = np.array([8.0])  # slip 2 m/s, a force that keeps it sliding over the step
    for h in (1e-7, 5e-7, 1e-6):
        a = fs.substep(p, "thmid", v, h, np.array([0.05]), np.zeros(1))
        b = fs.substep(p, "thmean", v, h, np.array([0.05]), np.zeros(1))
        assert (p.vd - a)[0] > 0.0
        assert np.array_equal(a, b)


def test_thmean_averages_the_friction_along_a_crossing_step() -> None:
    """A patch 0.3 m/s below the disc speed pushed across it within one step: thmean's result satisfies the
    midpoint with f replaced by its mean over the slip segment, m (v₁ − v₀)/h = F − c (v₀ + v₁)/2 + F_N Ḡ; thmid's
    does not, and the two differ by much more than the solve's tolerance."""
    p = one_patch()
    v0, h, force = np.array([9.7]), 5e-7, np.array([3.0])  # F ≫ F_N μ: it passes v_d
    mid = fs.substep(p, "thmid", v0, h, force, np.zeros(1))
    mean = fs.substep(p, "thmean", v0, h, force, np.zeros(1))
    s0, s1 = p.vd - v0, p.vd - mean
    assert s0[0] > 0.0 > s1[0] and (p.vd - mid)[0] < 0.0  # both cross
    gbar = (fs.friction_integral(p, s1) - fs.friction_integral(p, s0)) / (s1 - s0)
    lhs = p.m * (mean - v0) / h
    rhs = force - p.c * 0.5 * (v0 + mean) + p.fn * gbar
    assert lhs[0] == pytest.approx(rhs[0], rel=1e-9)
    assert abs(mean[0] - mid[0]) > 1e-3


def test_thmean_treats_each_patch_of_a_batch_as_alone() -> None:
    """Three patches at once (one crossing, one sliding, one held at hγ ≫ 6, where θ > 1/2): each result equals the
    same patch's alone; only the crossing one differs from thmid."""
    p1 = one_patch()
    p = fs.Pads(**{k: (np.repeat(v, 3) if isinstance(v, np.ndarray) and v.size == 1 else v)
                   for k, v in vars(p1).items() if k not in ("K", "start", "load", "coulomb", "names")},
                K=p1.K, start=np.array([0, 3]), load=p1.load, coulomb=p1.coulomb)  # fmt: skip
    v0 = np.array([9.7, 8.0, p1.vd[0] - 1e-4])
    force = np.array([3.0, 0.05, p1.c[0] * p1.vd[0]])
    h = 5e-7
    both = fs.substep(p, "thmean", v0, h, force, np.zeros(3))
    mid = fs.substep(p, "thmid", v0, h, force, np.zeros(3))
    for k in range(3):
        alone = fs.substep(p1, "thmean", v0[k : k + 1], h, force[k : k + 1], np.zeros(1))
        assert both[k] == pytest.approx(alone[0], rel=1e-13, abs=1e-13)
    assert abs(both[0] - mid[0]) > 1e-3 and both[1] == mid[1] and both[2] == mid[2]


def test_pad_measures_count_the_patches_above_a_tenth_of_the_largest() -> None:
    """Twenty patches with one signal (a 50 kHz line over broadband noise), three at amplitude 1, seventeen at 0.05:
    every bin has the same amplitude ratios, so Φ is 3 throughout the band; f1 is the line."""
    dt = 3e-6
    t = np.arange(4000) * dt
    x = np.sin(2 * math.pi * 50e3 * t) + 0.01 * np.random.default_rng(1).standard_normal(t.size)
    amps = np.r_[np.ones(3), np.full(17, 0.05)]
    vel = x[:, None] * amps[None, :]
    mu = 0.5 + 0.01 * np.sin(2 * math.pi * 7e3 * t)
    m = fc.pad_measures(t, mu, np.abs(vel).sum(axis=1), t, vel, fc.Window(0.0, dt))
    assert m["phi"] == pytest.approx(3.0)
    assert m["f1"] == pytest.approx(50e3, rel=0.01)
    assert m["mu_mean"] == pytest.approx(mu.mean()) and m["mu_std"] == pytest.approx(mu.std())
    assert m["floor"] > 0.0


def _doc(seeds: list[int], shift: float) -> dict:
    pad = lambda s, d: {k: float(s) + d for k in fc.MEASURES}  # noqa: E731
    run = lambda kind, method, dt, wall, d: {  # noqa: E731
        "kind": kind, "method": method, "dt": dt, "wall_s": wall, "steps": 1, "pads": [pad(s, d) for s in seeds]
    }  # fmt: skip
    runs = [run("reference", "strang", 5e-8, 10.0, 0.0), run("prototype", "thmean", 5e-7, 2.0, shift)]
    return {"seeds": seeds, "runs": runs, "duration_s": 0.045, "window_start_s": 0.025, "patch_dt_s": 3e-6}


def test_result_files_join_over_seeds_and_tabulate_the_paired_differences() -> None:
    doc = fc.joined([_doc([1, 2], 1.0), _doc([3], 1.0)])
    assert doc["seeds"] == [1, 2, 3]
    assert [len(r["pads"]) for r in doc["runs"]] == [3, 3]
    assert doc["runs"][0]["wall_s"] == 20.0
    lines = fc.table(doc)
    assert lines[2].startswith("| reference: strang (package) | 5e-08 | 20 |")
    assert lines[3].startswith("| forced-thmean (prototype) | 5e-07 | 4 | +1 ± 0 ")
    other = _doc([4], 1.0)
    other["runs"][1]["dt"] = 1e-6
    with pytest.raises(ValueError, match="different runs"):
        fc.joined([_doc([1], 1.0), other])
    shorter = _doc([5], 1.0)
    shorter["window_start_s"] = 0.03
    with pytest.raises(ValueError, match="different windows"):
        fc.joined([_doc([1], 1.0), shorter])


def test_step_errors_vanish_for_a_step_the_fine_steps_resolve() -> None:
    """On a 40-patch hf1 sector from its start state: one step of 2 ns against two of 1 ns errs by far less than a
    step of 0.5 µs against 50 of 10 ns; the counts and the lines add up."""
    from aca_warp.studies.friction_stats import sector_scenes

    pads = fs.load_pads(sector_scenes(1, 40))
    quiet = lambda _m: None  # noqa: E731
    fine = fc.step_errors(pads, 2e-9, 2, 1e-6, 3, 5e-6, quiet)
    coarse = fc.step_errors(pads, 5e-7, 50, 1e-6, 3, 5e-6, quiet)
    assert fine["patch_steps"] == coarse["patch_steps"] == 3 * pads.n
    assert fine["thmid_other_rms"] < 1e-3 * coarse["thmid_other_rms"]
    doc = dict(coarse, seed=1)
    lines = fc.step_error_lines(doc)
    assert lines[0].startswith("hf1 seed 1, one step of 5e-07 s against 50 steps of thmid, 3 instants 5 µs apart")
    assert lines[-1].startswith("| thmean |")


def test_the_readings_of_mu_agree_on_a_steadily_sliding_patch() -> None:
    """One patch released at its sliding equilibrium (the spring balances F_N f(v_d), no velocity): it stays there,
    so the point reading, the segment and instant readings (nothing crosses) and the applied friction of the
    momentum balance are the same μ, f(v_d), at every sample."""
    p = one_patch()
    f = float(fs.friction(p, p.vd)[0])
    p.u0 = np.array([p.fn[0] * f / p.kt[0]])
    r = fs.run_fixed(p, fs.Scheme.parse("forced-thmean"), 2.5e-7, 1e-5, 1e-6, readings=True)
    rec = r["record"]
    for reading in (rec.mu[1:], rec.mu_segment[1:], rec.mu_instant[1:], rec.mu_applied[1:]):
        assert np.allclose(reading, f, rtol=1e-9, atol=0.0)
    plain = fs.run_fixed(p, fs.Scheme.parse("forced-thmean"), 2.5e-7, 1e-5, 1e-6)["record"]  # not asked: not taken
    assert plain.mu_segment is None and plain.mu_instant is None and plain.mu_applied is None
    assert np.array_equal(plain.mu, rec.mu)


def test_the_segment_and_instant_readings_change_only_the_crossing_patches() -> None:
    """Two patches, one whose slip changes sign between its staggered and synchronous velocity and one that does not:
    the segment reading takes the crossing one's mean of f over its slip segment (quadrature), the instant reading
    f at the fraction τ of that segment, and both the other's f at its velocity."""
    p1 = one_patch()
    p = fs.Pads(**{k: (np.repeat(v, 2) if isinstance(v, np.ndarray) and v.size == 1 else v)
                   for k, v in vars(p1).items() if k not in ("K", "start", "load", "coulomb", "names")},
                K=p1.K, start=np.array([0, 2]), load=2 * p1.load, coulomb=p1.coulomb)  # fmt: skip
    w, v = np.array([9.9, 8.0]), np.array([10.2, 8.1])
    g = fs.pad_globals(p, v, w, np.array([0.25, 0.9]))
    law = lambda y: float(fs.friction(p1, np.array([y]))[0])  # noqa: E731
    s0, s1 = p1.vd[0] - w[0], p1.vd[0] - v[0]
    mean = scipy.integrate.quad(law, s1, s0, points=[0.0], epsabs=1e-13)[0] / (s0 - s1)
    expect = p1.fn[0] * (mean + law(p1.vd[0] - v[1])) / (2 * p1.load[0])
    assert g["mu_segment"][0] == pytest.approx(expect, rel=1e-7)
    point = p1.fn[0] * (law(s1) + law(p1.vd[0] - v[1])) / (2 * p1.load[0])
    assert g["mu"][0] == pytest.approx(point, rel=1e-12) and abs(g["mu"][0] - g["mu_segment"][0]) > 1e-3
    instant = p1.fn[0] * (law(s0 + 0.25 * (s1 - s0)) + law(p1.vd[0] - v[1])) / (2 * p1.load[0])
    assert g["mu_instant"][0] == pytest.approx(instant, rel=1e-12)
    assert law(s0 + 0.25 * (s1 - s0)) > 0.0 > law(s1)  # τ = 0.25 lies before the crossing, on the start's side


def test_the_instant_reading_is_reproducible_and_averages_to_the_segment_reading() -> None:
    """A record's instants come from a generator seeded by the sample: the same sample gives the same μ in another
    record, other samples other instants, and over many samples a crossing patch's instant reading averages to its
    segment reading."""
    p1 = one_patch()
    w, v = np.array([9.9]), np.array([10.2])
    rec, again = fs.Record.empty(3001, p1, 1e-6, readings=True), fs.Record.empty(3001, p1, 1e-6, readings=True)
    for k in range(1, 3001):
        rec.put(k, p1, v, w)
    again.put(7, p1, v, w)
    inst = rec.mu_instant[1:, 0]
    assert again.mu_instant[7, 0] == inst[6]
    assert np.unique(np.sign(inst - rec.mu_segment[1, 0])).size == 2  # both sides of the crossing are read
    assert inst.mean() == pytest.approx(rec.mu_segment[1, 0], abs=3 * inst.std() / math.sqrt(inst.size))


def test_the_applied_reading_is_the_friction_and_damping_over_each_interval() -> None:
    """One patch released from a stretched spring (it oscillates while sliding): the applied reading of each
    sample interval, run at 1 ns, equals the mean of F_N f(v_d − u̇) − c u̇ over the span its sub-steps cover, taken
    from the point reading and the velocity of a run that samples every step (linear between steps). The sub-steps
    lag the samples by half a step, and the opening interval's first one spans half a step: [0, t₁ − h/2], then
    [t_{k−1} − h/2, t_k − h/2]."""
    p = one_patch()
    p.u0 = np.array([1e-5])  # m: velocity swings of ≈ ±4.7 m/s, slip 5–15 m/s (no crossing)
    h, every, duration = 1e-9, 1e-7, 4e-6
    coarse = fs.run_fixed(p, fs.Scheme.parse("forced-thmid"), h, duration, every, readings=True)["record"]
    fine = fs.run_fixed(p, fs.Scheme.parse("forced-thmid"), h, duration, h)["record"]
    force = fine.mu[:, 0] * p.load[0] - p.coulomb[0] - p.c[0] * fine.sum_velocity[:, 0]  # N, at every step
    per = round(every / h)
    half = lambda j: h / 8 * (3 * force[j] + force[j - 1])  # noqa: E731  (∫ over [t_j − h/2, t_j], linear)
    for k in range(1, round(duration / every) + 1):
        j0, j1 = (k - 1) * per, k * per
        seg = force[j0 : j1 + 1]
        integral = h * (seg.sum() - 0.5 * (seg[0] + seg[-1])) - half(j1) + (half(j0) if k > 1 else 0.0)
        mean = integral / (per * h - (0.0 if k > 1 else h / 2))
        applied = coarse.mu_applied[k, 0] * p.load[0] - p.coulomb[0]
        assert applied == pytest.approx(mean, rel=2e-6), k
    assert np.ptp(force) > 0.05  # the friction force swings by far more than the tolerance


def test_the_corrected_stiffness_gives_the_leapfrog_the_true_frequencies() -> None:
    """A 40-patch hf1 sector: with K_c = K − (h²/12) K M⁻¹ K the leapfrog's frequency of every spring mode,
    (2/h) arcsin(ω_c h/2), is ω to within (ωh)⁴/100 relative, where with K it is off by about (ωh)²/24."""
    from aca_warp.studies.friction_stats import sector_scenes

    pads = fs.load_pads(sector_scenes(1, 40))
    h = 5e-7
    lam = lambda k: np.sort(np.linalg.eigvals(np.diag(1 / pads.m) @ k.toarray()).real)  # noqa: E731
    omega, omega_c = np.sqrt(lam(pads.K)), np.sqrt(lam(pads.dispersion_corrected(h).K))
    leap = lambda w: 2.0 / h * np.arcsin(w * h / 2.0)  # noqa: E731
    x = omega * h
    assert np.all(np.abs(leap(omega_c) / omega - 1.0) < x**4 / 100)
    assert np.all(np.abs(leap(omega) / omega - 1.0 - x**2 / 24) < x**4 / 100)
    assert x.max() > 0.3  # the largest mode is far enough from ωh → 0 for the test to tell the two apart


def test_the_readings_table_lists_the_prototype_runs_that_recorded_them() -> None:
    doc = _doc([1, 2, 3], 1.0)
    for run in doc["runs"]:
        for p in run["pads"]:
            p |= {"mu_segment_mean": p["mu_mean"] - 0.5, "mu_segment_std": p["mu_std"], "mu_applied_mean": p["mu_mean"]}
    lines = fc.readings_table(doc)  # files without the instant reading: its columns left out
    assert len(lines) == 3 and lines[2].startswith("| forced-thmean (prototype) | 5e-07 | +1 ± 0 ")
    assert "+0.5 ± 0" in lines[2] and "instant" not in lines[0] and lines[2].count("|") == 8
    for run in doc["runs"]:
        for p in run["pads"]:
            p |= {"mu_instant_mean": p["mu_mean"] + 2.0, "mu_instant_std": p["mu_std"]}
    lines = fc.readings_table(doc)
    assert "μ mean, instant" in lines[0] and "μ std, instant" in lines[0] and "+3 ± 0" in lines[2]
    assert fc.readings_table(_doc([1], 1.0)) == []
