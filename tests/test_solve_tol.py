"""The friction solve's tolerance as a run option (``RunOptions.solve_tol``, ``aca-warp hf --solve-tol``, a study
setting's ``:solve_tol=V``): the precision's default when not given (the same bits), another value reaches the
kernels on both engines (other bits, the same within the solve's tolerance), bad values refused with a clear
message, and the study names and pairs it."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from aca_warp.common.errors import SceneError
from aca_warp.hf.loop import run_hf
from aca_warp.hf.options import NEWTON_TOL, RunOptions
from aca_warp.hf.solver import HFSolver
from aca_warp.scene import Record
from aca_warp.studies.friction_stats import sector_scenes
from aca_warp.studies.runs import batch_at_start
from aca_warp.studies.work_precision_stats import parse_setting
from aca_warp.studies.work_precision_stats_report import setting_family
from aca_warp.studies.work_precision_stats_rule import twin_of

DT = 5e-8  # s
DURATION = 2e-5  # s: 400 steps, the patches sliding from equilibrium


@pytest.fixture(scope="module")
def scenes() -> list:
    return sector_scenes(1, 40)


def _run(scenes: list, engine: str, solve_tol: float | None) -> tuple[np.ndarray, np.ndarray]:
    model, state = batch_at_start(scenes, "cpu", "fp32")
    options = RunOptions(duration=DURATION, dt=DT, engine=engine, solve_tol=solve_tol)
    res = run_hf(model, state, options, record=Record(sample_dt=1e-6))
    assert res.complete
    return res.collect().globals, state.numpy()[1]


@pytest.mark.parametrize("engine", ["general", "onchip"])
def test_solve_tol_reaches_the_kernels(scenes, engine):
    default_mu, default_v = _run(scenes, engine, None)
    same_mu, same_v = _run(scenes, engine, NEWTON_TOL["fp32"])
    assert np.array_equal(default_mu, same_mu) and np.array_equal(default_v, same_v)  # None is the default
    tight_mu, tight_v = _run(scenes, engine, 1e-9)
    assert not np.array_equal(default_v, tight_v)  # another tolerance, other bits
    np.testing.assert_allclose(tight_v, default_v, rtol=0, atol=1e-4)  # m/s, within the fp32 solve's reach


def test_solver_takes_the_tolerance_and_the_precisions_default(scenes):
    model, _ = batch_at_start(scenes, "cpu", "fp64")
    assert float(HFSolver(model, "strang", DT).newton_tol) == NEWTON_TOL["fp64"]
    assert math.isclose(float(HFSolver(model, "strang", DT, solve_tol=3e-7).newton_tol), 3e-7)


@pytest.mark.parametrize("bad", [0.0, 1.0, -1e-6, 2.0, math.nan, "1e-7", True])
def test_bad_solve_tol_is_refused(bad):
    with pytest.raises(SceneError, match="solve_tol must be a number between 0 and 1"):
        RunOptions(solve_tol=bad)


def test_solve_tol_is_refused_with_the_mean_crossing_treatment(scenes):
    """The ``mean`` treatment's short-segment threshold is 1e3 × the solve's tolerance: a tolerance of its own would
    move it too, so the two are not combined (options, solver, study setting)."""
    with pytest.raises(SceneError, match="solve_tol with crossing 'mean'"):
        RunOptions(solve_tol=1e-7, crossing="mean")
    model, _ = batch_at_start(scenes, "cpu", "fp32")
    with pytest.raises(SceneError, match="solve_tol with crossing 'mean'"):
        HFSolver(model, "strang", DT, crossing="mean", solve_tol=1e-7)
    with pytest.raises(ValueError, match="solve_tol with crossing 'mean'"):
        parse_setting("strang@fp32:dt=1e-8:solve_tol=1e-7:mean")


def test_solve_tol_on_a_preset_asks_for_the_point_treatment(tmp_path, capsys):
    """A preset's physics averages the crossings by default, so a tolerance of its own is refused there until the
    point treatment is asked for; the message names that option as the interface spells it."""
    from aca_warp.cli import main
    from aca_warp.hf.model import build_model
    from aca_warp.scene import preset

    model = build_model([preset("hf1")], device="cpu", precision="fp32")
    with pytest.raises(SceneError, match=r"or add crossing='point'"):
        HFSolver(model, "strang", DT, solve_tol=1e-7)
    assert float(HFSolver(model, "strang", DT, solve_tol=1e-7, crossing="point").newton_tol) == pytest.approx(1e-7)
    out = tmp_path / "r.h5"
    assert main(["hf", "hf1", "--duration", "1e-6", "--solve-tol", "1e-7", "-o", str(out), "--no-progress"]) == 2
    assert "or add --crossing point" in capsys.readouterr().err and not out.exists()


def test_the_study_runs_a_setting_at_its_solve_tolerance(scenes, monkeypatch):
    """A study setting's ``:solve_tol=V`` reaches the run's options (``run_setting`` → ``run_engine`` →
    ``run_hf``), not only its label."""
    from types import SimpleNamespace

    from aca_warp.studies import runs
    from aca_warp.studies import work_precision_stats as wps

    seen = []

    class Stop(Exception):
        pass

    def capture(model, state, options, **kwargs):
        seen.append(options)
        raise Stop

    monkeypatch.setattr(runs, "run_hf", capture)
    plan = SimpleNamespace(duration=DURATION, record=lambda cfg: Record(sample_dt=1e-6))
    prep = SimpleNamespace(scenes=scenes, exp=SimpleNamespace(name="sector"), plan=plan)
    cfg = SimpleNamespace(device="cpu", engine="auto")
    (setting,) = parse_setting("strang@fp32:dt=5e-8:solve_tol=3e-7")
    with pytest.raises(Stop):
        wps.run_setting(prep, cfg, setting, "grid", [], lambda line: None)
    assert [o.solve_tol for o in seen] == [3e-7]


def test_stored_options_keep_the_tolerance_and_old_files_take_the_default():
    assert RunOptions.from_dict({"solve_tol": 1e-7}).solve_tol == 1e-7
    assert RunOptions.from_dict({}).solve_tol is None
    assert RunOptions.from_dict(json.loads(RunOptions(solve_tol=2e-7).to_json())).solve_tol == 2e-7


def test_study_settings_name_and_pair_the_tolerance():
    (s,) = parse_setting("strang@fp32:dt=1e-8:solve_tol=1e-7")
    assert s.solve_tol == 1e-7 and s.label == "strang@fp32:dt=1e-08:solve_tol=1e-07"
    assert parse_setting(s.label) == [s]
    assert [x.solve_tol for x in parse_setting("strang@fp64:dt=1e-8:solve_tol=1e-6,1e-9")] == [1e-6, 1e-9]
    for bad in ("strang@fp32:solve_tol=1", "strang@fp32:solve_tol=0", "strang@fp32:solve_tol="):
        with pytest.raises(ValueError):
            parse_setting(bad)
    row = {"integrator": "strang", "precision": "fp64", "solve_tol": 1e-6}
    assert setting_family(row) == "strang@fp64 solve tol 1e-06"
    assert setting_family({"integrator": "strang", "precision": "fp64"}) == "strang@fp64"
    ref = {"role": "reference", "integrator": "strang", "precision": "fp64", "dt": 1e-8, "tolerance": None}
    loose = {**ref, "role": "grid", "precision": "fp32", "solve_tol": 1e-7, "complete": True, "values": {"x": [1]}}
    twin = {**loose, "solve_tol": None}
    assert twin_of({"settings": [ref, loose]}) is None  # another tolerance is no twin
    assert twin_of({"settings": [ref, loose, twin]}) is twin
