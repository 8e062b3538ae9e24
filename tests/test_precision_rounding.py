"""scripts/precision_rounding.py: fp32 against fp64 over a few strang steps from one state."""

from __future__ import annotations

import json

from scriptload import exit_code, load_script


def test_fp32_and_fp64_steps_differ_by_rounding_and_a_lost_term_would_show(tmp_path, capsys, monkeypatch):
    """From a short hf1 run's state, one strang step in fp32 differs from fp64 by rounding: some patch by a part of
    an ulp, none by more than a few; the file holds each row, the machine and the command. With the fp32 run's state
    nudged by 1e-4 m/s before it steps (what a term lost in fp32 would do), the same comparison reads hundreds of
    ulps, its mean many standard errors from 0: the measure can tell a lost term from rounding."""
    argv = ["--scene", "hf1", "--settle", "2e-5", "--steps", "1", "2", "--out", str(tmp_path)]
    assert exit_code("precision_rounding", argv) == 0
    doc = json.loads((tmp_path / "precision_rounding_hf1.json").read_text())
    assert [r["steps"] for r in doc["rows"]] == [1, 2] and doc["patches"] > 1000
    assert max(r["dv_ulp10"]["max"] for r in doc["rows"]) < 4.0
    assert min(r["du_ulp"]["max"] for r in doc["rows"]) > 0.1  # fp32 differs: both sides in fp64 would give 0
    assert doc["command"].startswith("python3 scripts/precision_rounding.py --scene hf1") and doc["machine"]["host"]
    assert "| 1 |" in capsys.readouterr().out

    module = load_script("precision_rounding")
    run = module.run_steps

    def nudged(scene, precision, u, v, dt, n):
        return run(scene, precision, u, v + (1e-4 if precision == "fp32" else 0.0), dt, n)

    monkeypatch.setattr(module, "run_steps", nudged)
    assert module.main(argv) == 0
    doc = json.loads((tmp_path / "precision_rounding_hf1.json").read_text())
    assert min(r["dv_ulp10"]["q50"] for r in doc["rows"]) > 50.0
    assert all(abs(r["mean_signed_dv_m_s"]) > 100 * r["mean_signed_dv_se_m_s"] for r in doc["rows"])


def test_bad_input_exits_2(tmp_path, capsys):
    assert exit_code("precision_rounding", ["--scene", "hf1", "--dt", "-1", "--out", str(tmp_path)]) == 2
    assert "--dt" in capsys.readouterr().err
    assert exit_code("precision_rounding", ["--scene", "nope", "--out", str(tmp_path)]) == 2
    assert "neither a preset" in capsys.readouterr().err
    (tmp_path / "a_file").write_text("")
    assert exit_code("precision_rounding", ["--scene", "hf1", "--out", str(tmp_path / "a_file")]) == 2
    assert "precision_rounding:" in capsys.readouterr().err
