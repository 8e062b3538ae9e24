"""scripts/default_row_changes.py: the committed comparison of the default row before and after the samples read the
next step's solve is what the script prints from the committed result files; bad folders are refused."""

from __future__ import annotations

from pathlib import Path

import pytest
from scriptload import load_script

REPO = Path(__file__).resolve().parents[1]
FOLDER = REPO / "docs" / "figures" / "work_precision_statistics"


def test_the_committed_changes_are_the_scripts_output(capsys):
    script = load_script("default_row_changes")
    assert script.main([str(FOLDER / "fast_mean"), str(FOLDER / "step_sample")]) == 0
    printed = capsys.readouterr().out
    assert printed == (FOLDER / "step_sample" / "changes.txt").read_text()
    assert printed.count("(kept before, not after)") == 1  # ms_app3's Φ, at 0.256 σ
    assert "over 124 regime-measures" in printed


def test_folders_without_a_common_regime_are_refused(tmp_path, capsys):
    script = load_script("default_row_changes")
    (tmp_path / "a").mkdir()
    with pytest.raises(SystemExit) as e:
        script.main([str(tmp_path / "a"), str(FOLDER / "step_sample")])
    assert e.value.code == 2 and "no regime" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        script.main([str(tmp_path / "missing"), str(FOLDER / "step_sample")])
    assert e.value.code == 2 and "is not a folder" in capsys.readouterr().err
