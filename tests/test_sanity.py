"""Physical sanity (aca_warp/hf/sanity.py): a contact solution that does not carry the load is refused before a
file exists (exit 3); a μ beyond what Eq. 4 allows stops the run (exit 3); each is a warning when forced. And the
held case: every patch held by static friction (M = 100), where strang's step is far beyond the friction rate."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import h5py
import numpy as np
import pytest
from procs import small_scene_toml

from aca_warp.cli import main
from aca_warp.common.errors import PhysicsError
from aca_warp.hf import sanity
from aca_warp.hf.loop import run_hf
from aca_warp.hf.model import build_model
from aca_warp.hf.options import RunOptions
from aca_warp.hf.state import initial_state
from aca_warp.scene import PRESETS, Friction, load_scene, preset


def scene_file(tmp_path: Path, extra: str = "", height: float = 3.0e-6) -> Path:
    """40 HF1-size patches of ``height`` [m], perturbed, over 2 µs; ``extra``: TOML text appended."""
    p = tmp_path / "s.toml"
    p.write_text(
        small_scene_toml("sane", count=40, perturbation=1.0e-3, tables={"patches": {"height": height}}) + extra
    )
    return p


def run_cli(capsys, argv: list[str]) -> tuple[int, list[str]]:
    capsys.readouterr()
    code = main(argv)
    return code, [line for line in capsys.readouterr().err.splitlines() if line.strip()]


@pytest.mark.parametrize(
    ("extra", "height", "message"),
    [
        ("[material]\nK_N = 1e308\n", 3.0e-6, "the normal forces sum to 0 N for a clamp force of 20 N"),
        ("[material]\nK_N = 1e20\n", 3.0e-6, "relative error 1.2e-05 > 1e-06"),
        ("", 1.0e6, "heights up to 1e+06 m are beyond what float64 resolves"),
    ],
    ids=["K_N-1e308", "K_N-1e20", "heights-1e6"],
)
def test_contact_that_loses_the_load_is_refused(tmp_path, capsys, extra, height, message) -> None:
    """Stiffnesses or heights beyond float64: refused as implausible values (exit 2); allowed, the contact check
    refuses them in fp64: exit 3, one line, no file; --accept-unphysical runs with a warning. In fp32 (strang's
    default) a stiffness beyond what single precision holds is refused before, exit 2, one line naming fp64."""
    s = scene_file(tmp_path, extra, height)
    out = tmp_path / "run.h5"
    code, err = run_cli(capsys, ["hf", str(s), "-o", str(out), "--no-progress"])
    assert code == 2 and len(err) == 1 and "allow_implausible" in err[0], err
    code, err = run_cli(capsys, ["hf", str(s), "-o", str(out), "--no-progress", "--allow-implausible"])
    if "1e308" in extra:
        assert code == 2 and len(err) == 1 and "k_n (from material.K_N)" in err[0] and "--precision fp64" in err[0], err
    else:
        assert code == 3 and len(err) == 1 and message in err[0], err
    fp64 = ["hf", str(s), "-o", str(out), "--no-progress", "--precision", "fp64"]
    code, err = run_cli(capsys, [*fp64, "--allow-implausible"])
    assert code == 3 and len(err) == 1 and message in err[0] and "--accept-unphysical" in err[0], err
    assert not out.exists() and not (tmp_path / "run.h5.partial").exists() and not (tmp_path / "run.h5.lock").exists()
    if "1e20" in extra:  # runs in both precisions when accepted, with the warning
        for precision in ("fp64", "fp32"):
            sanity._WARNED.clear()  # each warning is printed once per process
            argv = ["hf", str(s), "-o", str(out), "--no-progress", "--precision", precision, "--overwrite"]
            code, err = run_cli(capsys, [*argv, "--accept-unphysical", "--allow-implausible"])
            assert code == 0 and len(err) == 1 and err[0].startswith("aca-warp: warning:") and message in err[0], err
            with h5py.File(out, "r") as f:
                assert f.attrs["complete"] and '"accept_unphysical": true' in f.attrs["run_options"]
                assert f.attrs["precision"] == precision


def test_presets_carry_their_load() -> None:
    """Every preset's contact solution sums to the clamp force far inside the tolerance (float64: ~1e-13)."""
    for name in PRESETS:
        s = preset(name)
        model = build_model([s])
        c = model.contacts[0]
        total = float(np.sum(c.patch_force) + np.sum(c.matrix_force))
        assert abs(total - s.normal_force) < 1e-3 * sanity.CONTACT_RTOL * s.normal_force, name
        assert sanity.contact_problem(model) is None


def test_mu_bound_stops_a_run_whose_forces_are_wrong(tmp_path) -> None:
    """Normal forces tripled on the device after the contact solve (a state no physics allows, still finite): the
    first chunk's μ exceeds (M Σ F_N,i + μ_pad F_m)/F_N, the run stops with a fault before that sample; accepted,
    it runs to the end with one warning. Unchanged forces never come near the bound."""
    s = load_scene(scene_file(tmp_path))
    bound = None
    for factor, accept in ((1.0, False), (3.0, False), (3.0, True)):
        model = build_model([s])
        model.normal_force.assign(model.host("normal_force") * factor)
        bound = sanity.mu_bounds(model)[0]
        res = run_hf(model, initial_state(model), RunOptions(accept_unphysical=accept))
        mu = res.collect().globals[:, 0, 0]
        if factor == 1.0:
            assert res.complete and np.max(np.abs(mu)) < 0.9 * bound
        elif not accept:
            assert not res.complete and "unphysical friction coefficient" in str(res.fault)
            kept = res.collect().time
            assert np.all(np.abs(mu) <= bound) and res.sim_time == (kept[-1] if len(kept) else 0.0)
        else:
            assert res.complete and np.max(np.abs(mu)) > bound
    f = Friction()
    assert bound == pytest.approx((f.M * 1.0 + f.mu_pad * 0.0) * (1 + sanity.MU_SLACK), rel=1e-6)  # all on patches


def test_mu_fault_unit() -> None:
    t = np.arange(4) * 1e-7
    mu = np.array([[0.1, 0.2], [0.3, -0.95], [0.2, 2.0], [np.nan, 0.1]])
    f = sanity.mu_fault(t, mu, np.array([1.0, 1.0]))
    assert f is not None and f.pad == 1 and f.time == t[2]
    assert sanity.mu_fault(t[:1], mu[:1], np.array([1.0, 1.0])) is None
    assert sanity.mu_fault(t[3:], mu[3:], np.array([1.0, np.inf])).pad == 0  # NaN beyond a finite bound


def test_m100_held_case(tmp_path, capsys) -> None:
    """The held case: M = 100 (40 patches, 20 N, 20 µs), every patch held by static friction. strang at 1e-8 s has
    h γ = 46 at zero slip; with the spring force inside its damped-midpoint solve it runs without a warning and,
    its samples reading the friction each step applies, gives mean μ 55.19, within 0.1 % of implicit-friction's
    (backward Euler) 55.24 (55.41 when a sample was the closing half sub-step: the NumPy prototype's forced damped
    midpoint, 55.414, docs/friction_step.md), and 55.24 at 1e-9 s and 2.5e-10 s. The
    implicit-midpoint strang with the spring kicks outside its solve gave −0.17 at 1e-8 s and 51.1 at 1e-9 s: its
    recorded velocity of a held patch was off by h F_s/(2m)."""
    s = scene_file(tmp_path, "[friction]\nM = 100.0\n")  # beyond any real friction coefficient: a stress test
    common = ["--no-progress", "--duration", "2e-5", "--sample-dt", "1e-7", "--allow-implausible"]

    def mu(tag: str, *extra: str) -> float:
        out = tmp_path / f"{tag}.h5"
        code, err = run_cli(capsys, ["hf", str(s), "-o", str(out), *common, *extra])
        assert code == 0 and not err, err
        with h5py.File(out, "r") as f:
            return float(np.mean(f["global/mu"][()]))

    reference = mu("implicit", "--integrator", "implicit-friction")
    assert reference == pytest.approx(55.24, abs=0.05)
    assert mu("strang", "--integrator", "strang", "--dt", "1e-8") == pytest.approx(55.19, abs=0.01)
    for tag, dt in (("tenth", "1e-9"), ("fine", "2.5e-10")):
        assert mu(tag, "--integrator", "strang", "--dt", dt) == pytest.approx(reference, rel=1e-3), tag


def test_strang_bound_is_the_springs_and_contact_check() -> None:
    """At M = 100 (h γ = 4 at 1/20 of the spring bound) strang's only bound is the springs', as implicit-friction's;
    a contact solution that does not carry the load raises PhysicsError."""
    s = preset("hf1")
    s = s.replace(friction=dataclasses.replace(s.friction, M=100.0), allow_implausible=True)
    model = build_model([s])
    from aca_warp.hf.solver import stable_step

    est = stable_step(model)
    assert 2.0 * est.friction < est.spring / 20
    assert est.limit("strang") == est.spring == est.limit("implicit-friction")
    assert "sticking" not in est.as_dict()
    with pytest.raises(PhysicsError):
        bad = build_model([s.replace(material=dataclasses.replace(s.material, K_N=1e308), allow_implausible=True)])
        sanity.check_contact(bad, accept=False)


def test_options_that_would_do_nothing_or_harm_say_so(tmp_path, capsys) -> None:
    """--tolerance with a fixed-step integrator is refused (exit 2, nothing written: it has no tolerance); a
    forced explicit step beyond its stable-step estimate runs with one warning naming the bound."""
    s = scene_file(tmp_path)
    common = ["--no-progress", "--duration", "2e-6", "--sample-dt", "2e-7"]
    out = tmp_path / "tol.h5"
    code, err = run_cli(
        capsys, ["hf", str(s), "-o", str(out), *common, "--integrator", "strang", "--tolerance", "1e-6"]
    )
    assert code == 2 and len(err) == 1 and "--tolerance applies to --integrator adaptive or auto only" in err[0], err
    assert not out.exists()
    out = tmp_path / "forced.h5"
    argv = ["hf", str(s), "-o", str(out), *common, "--integrator", "symplectic-euler", "--dt", "2e-7", "--force"]
    code, err = run_cli(capsys, argv)
    assert code == 0 and len(err) == 1, err
    assert "exceeds the stable-step estimate" in err[0] and "of symplectic-euler" in err[0]
    assert err[0].startswith("aca-warp: warning:") and "running as forced" in err[0]


def test_fp32_check_refuses_finite_values_beyond_single_precision_only() -> None:
    """The fp32 check refuses a finite value beyond 3.4e38 of either sign (naming the array and its setting) and lets
    through what fp32 holds, infinities, NaN and empty arrays, whether it decides from the extremes alone or looks at
    every value."""
    from aca_warp.common.errors import SceneError
    from aca_warp.hf.model import _check_fp32

    top = float(np.finfo(np.float32).max)
    for fine in ([1.0, -top, top], [np.inf, 1.0], [-np.inf, np.nan, 2.0], [], [0.0]):
        _check_fp32({"k_t": np.array(fine, dtype=np.float64)})
    for bad, shown in (([1.0, 3.5e38], "3.5e+38"), ([-3.5e38, 0.0], "3.5e+38"), ([np.inf, -1e300, np.nan], "1e+300")):
        with pytest.raises(SceneError, match=rf"k_n \(from material.K_N\) reaches {re.escape(shown)}, beyond"):
            _check_fp32({"k_t": np.ones(3), "k_n": np.array(bad)})
