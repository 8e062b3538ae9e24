"""scripts/bench_patch_generator.py: one checkout's timings and layout hashes, and its refusal of bad input."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from scriptload import load_script

ROOT = str(Path(__file__).resolve().parents[1])  # this checkout


def test_one_checkout(tmp_path):
    assert load_script("bench_patch_generator").main([ROOT, "--seeds", "1", "--out", str(tmp_path)]) == 0
    doc = json.loads((tmp_path / "patch_generator.json").read_text())
    (rows,) = doc["runs"]
    assert [r["case"][0] for r in rows] == ["hf1", "hf2", "varying_area", "hf3"] and doc["identical"] is None
    assert all(len(r["sha256"]) == 64 and r["wall_s"] > 0 for r in rows)


def test_bad_checkout_is_one_line_exit_2(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        load_script("bench_patch_generator").main([str(tmp_path), "--out", str(tmp_path / "o")])
    assert e.value.code == 2
    assert "not a checkout of aca_warp" in capsys.readouterr().err
