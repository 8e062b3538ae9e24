"""``scripts/profile_shard_turn.py``: each path times the phases it names, shard by shard, and writes them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from scriptload import load_script

PHASES = {
    "prepared": ["upload", "setup", "run"],
    "built": ["build", "setup", "run"],
    "host": ["build", "upload", "setup", "run"],
}


@pytest.mark.parametrize("path", sorted(PHASES))
def test_paths_time_their_phases(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, path: str) -> None:
    """Two shards of two hf1 pads on the CPU: per shard the phases of its path (in their order, each > 0 s), the
    shard's steps and engine, and a profile of its build and set-up (the set-up's ``_Run`` among its functions)."""
    script = load_script("profile_shard_turn")
    out = tmp_path / "turn.json"
    argv = ["x", "--device", "cpu", "--shards", "2", "--shard-size", "2", "--duration", "2e-6", "--dt", "1e-7"]
    monkeypatch.setattr("sys.argv", [*argv, "--path", path, "--top", "40", "--json", str(out)])
    assert script.main() == 0
    doc = json.loads(out.read_text())
    assert doc["path"] == path and [s["index"] for s in doc["shards"]] == [0, 1]
    for s in doc["shards"]:
        assert list(s["phases_s"]) == PHASES[path] and all(v > 0 for v in s["phases_s"].values())
        assert s["pads"] == 2 and s["steps"] == 20 and s["engine"]
        assert any("(__init__)" in r["function"] and "loop.py" in r["function"] for r in s["profile_top"])


@pytest.mark.parametrize("option", ["--shards", "--shard-size", "--top"])
def test_counts_below_one_are_one_line(monkeypatch: pytest.MonkeyPatch, capsys, option: str) -> None:
    """``--shards 0`` (or ``--shard-size``, ``--top`` of 0) is argparse's one line and exit 2, before Warp starts."""
    script = load_script("profile_shard_turn")
    monkeypatch.setattr("sys.argv", ["x", "--device", "cpu", option, "0"])
    with pytest.raises(SystemExit) as e:
        script.main()
    err = capsys.readouterr().err.strip().splitlines()
    assert e.value.code == 2 and f"argument {option}: must be >= 1, got '0'" in err[-1], err
