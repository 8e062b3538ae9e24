"""scripts/sweep_compiles.py: the tiles of a sweep's shards (no sweep run here) and its refusal of bad input."""

from __future__ import annotations

import json

import pytest
from scriptload import load_script


def test_tiles_of_the_shards(tmp_path):
    argv = ["--tiles", "1", "--shards", "2", "--pads", "1", "--out", str(tmp_path)]
    assert load_script("sweep_compiles").main(argv) == 0
    doc = json.loads((tmp_path / "sweep_tiles.json").read_text())
    assert [r["shard"] for r in doc["rows"]] == [0, 1]
    for r in doc["rows"]:  # an hf1 pad: 1758 patches, 1760 to whole warps, 1792 in its bucket
        assert r["exact"][0] == 1760 and r["bucketed"][0] == 1792 and r["bucketed"][1] >= r["exact"][1]
    assert "| shard | exact | bucketed |" in (tmp_path / "sweep_tiles.md").read_text()


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["{tmp}"], "not a checkout of aca_warp"),
        ([], "give one or two checkouts"),
        (["{tmp}", "--tiles", "640"], "give no CHECKOUT"),
        (["--tiles", "2048"], "THREADS (1-1024)"),
    ],
)
def test_bad_input_is_one_line_exit_2(tmp_path, capsys, argv, said):
    with pytest.raises(SystemExit) as e:
        load_script("sweep_compiles").main([a.format(tmp=tmp_path) for a in argv] + ["--out", str(tmp_path / "o")])
    assert e.value.code == 2
    assert said in capsys.readouterr().err
