"""``scripts/friction_step_sector.py`` on a tiny sector: the engine is a setting of the study, recorded and reported,
and both engines give the same statistics (the same bits)."""

from __future__ import annotations

import json
from pathlib import Path

from scriptload import load_script

from aca_warp.studies.friction_sector import report


def test_the_engine_is_recorded_and_both_give_the_same_statistics(tmp_path: Path) -> None:
    docs = {}
    for engine in ("general", "auto"):
        out = tmp_path / f"{engine}.json"
        argv = ["--patches", "20", "--duration", "1e-3", "--window", "5e-4", "--reference", "strang:2e-8"]
        assert (
            load_script("friction_step_sector").main([*argv, "--runs", "strang", "--engine", engine, "--out", str(out)])
            == 0
        )
        docs[engine] = json.loads(out.read_text())
        assert docs[engine]["setup"]["engine"] == engine
    for a, b in zip(docs["general"]["runs"], docs["auto"]["runs"], strict=True):
        assert (a["run"], a["steps"], a["stats"]) == (b["run"], b["steps"], b["stats"])
    assert "`auto`'s engine (on chip for strang) on the CPU" in report(docs["auto"])[0]
    assert "general engine on the CPU" in report(docs["general"])[0]


def test_an_integrator_the_on_chip_engine_lacks_is_refused_before_anything_runs(tmp_path: Path, capsys) -> None:
    """``--engine onchip`` with a run the on-chip engine does not implement: exit code 2 and one line, before the
    reference runs and before anything is written."""
    out = tmp_path / "x.json"
    argv = ["--patches", "20", "--runs", "strang", "controlled:tol=3e-3", "--engine", "onchip", "--out", str(out)]
    assert load_script("friction_step_sector").main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'controlled:tol=3e-3'" in err[0] and not out.exists()


def test_a_run_may_name_its_precision(tmp_path: Path) -> None:
    """``strang@fp32`` runs in fp32 beside an fp64 reference (the defaults against the reference in one file): its
    statistics differ from the same run's in fp64 by less than 0.1 %, and the report says which runs differ."""
    from aca_warp.studies.friction_sector import parse_run

    assert parse_run("strang:5e-8@fp32") == {"integrator": "strang", "dt": 5e-8, "precision": "fp32"}
    assert parse_run("auto:tol=3e-3") == {"integrator": "auto", "split_tolerance": 3e-3}
    out = tmp_path / "p.json"
    argv = ["--patches", "20", "--duration", "1e-3", "--window", "5e-4", "--reference", "strang:2e-8"]
    assert load_script("friction_step_sector").main([*argv, "--runs", "strang", "strang@fp32", "--out", str(out)]) == 0
    doc = json.loads(out.read_text())
    fp64, fp32 = doc["runs"][1]["stats"], doc["runs"][2]["stats"]
    assert fp64 != fp32 and all(abs(fp32[k][0] - fp64[k][0]) <= 1e-3 * abs(fp64[k][0]) for k in fp64), (fp64, fp32)
    assert "fp64 (a run ending in @fp32 or @fp64: that precision)" in report(doc)[0]


def test_a_run_may_name_its_engine(tmp_path: Path) -> None:
    """``/ENGINE`` after a run: that run on its own engine, the others on ``--engine``, so that the default on chip
    and the reference on the general engine compare within one call; the engines give the same statistics."""
    from aca_warp.studies.friction_sector import parse_run

    assert parse_run("strang:1e-8@fp64/general") == {
        "integrator": "strang",
        "dt": 1e-8,
        "precision": "fp64",
        "engine": "general",
    }
    assert parse_run("strang/auto") == {"integrator": "strang", "engine": "auto"}
    out = tmp_path / "e.json"
    argv = ["--patches", "20", "--duration", "1e-3", "--window", "5e-4", "--engine", "auto"]
    argv += ["--reference", "strang:2e-8/general", "--runs", "strang:2e-8", "--out", str(out)]
    assert load_script("friction_step_sector").main(argv) == 0
    ref, run = json.loads(out.read_text())["runs"]
    assert ref["run"] == "strang:2e-8/general" and (ref["steps"], ref["stats"]) == (run["steps"], run["stats"])


def test_an_unknown_engine_of_a_run_is_refused(tmp_path: Path, capsys) -> None:
    argv = ["--patches", "20", "--runs", "strang/gpu", "--out", str(tmp_path / "x.json")]
    assert load_script("friction_step_sector").main(argv) == 2
    assert "unknown engine 'gpu' in 'strang/gpu'" in capsys.readouterr().err
    argv = ["--patches", "20", "--runs", "controlled/onchip", "--out", str(tmp_path / "x.json")]
    assert load_script("friction_step_sector").main(argv) == 2
    assert "the on-chip engine runs" in capsys.readouterr().err
