"""scripts/sweep_compiles.py: the tiles of a sweep's shards (no sweep run here) and its refusal of bad input."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from scriptload import load_script

ROOT = str(Path(__file__).resolve().parents[1])  # this checkout


def test_tiles_of_the_shards(tmp_path, capsys):
    assert (
        load_script("sweep_compiles").main(
            [".", "--tiles", "1", "--shards", "2", "--pads", "1", "--out", str(tmp_path)]
        )
        == 0
    )
    doc = json.loads((tmp_path / "sweep_tiles.json").read_text())
    assert [r["shard"] for r in doc["rows"]] == [0, 1]
    for r in doc["rows"]:
        assert r["bucketed"][0] >= r["exact"][0] and r["bucketed"][1] >= r["exact"][1]
    assert "| shard | exact | bucketed |" in (tmp_path / "sweep_tiles.md").read_text()


def test_bad_checkout_is_one_line_exit_2(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        load_script("sweep_compiles").main([str(tmp_path), "--out", str(tmp_path / "o")])
    assert e.value.code == 2
    assert "is not a checkout of aca_warp" in capsys.readouterr().err
