"""scripts/targets_table.py: the targets table of docs/status.md and its figure's data are what the committed data
files give (the docs cannot drift from the data), a changed number fails the check, and the verdicts."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from scriptload import load_script

MODULE = load_script("targets_table")


def test_check_passes_on_the_committed_docs(capsys: pytest.CaptureFixture[str]) -> None:
    assert MODULE.main(["--check"]) == 0, capsys.readouterr().out


def test_check_fails_on_a_changed_number(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A copy of status.md with one number of the generated block changed: --check exits 1 and shows the line."""
    page = tmp_path / "status.md"
    shutil.copy(MODULE.STATUS, page)
    text = page.read_text()
    block = text.split(MODULE.BEGIN, 1)[1].split(MODULE.END, 1)[0]
    assert "| 1.58–1.59 s (2 runs) |" in block
    page.write_text(text.replace("| 1.58–1.59 s (2 runs) |", "| 1.48–1.59 s (2 runs) |"))
    assert MODULE.main(["--check", "--status", str(page)]) == 1
    out = capsys.readouterr().out
    assert "-| 64 saturated hf1 pads" in out and "1.48–1.59 s" in out
    page.write_text(text)
    assert MODULE.main(["--check", "--status", str(page)]) == 0


def test_check_fails_without_the_markers(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A page whose block was replaced by a hand-written table under the heading: the check shows the block it would
    put there, in place of that table."""
    page = tmp_path / "status.md"
    text = MODULE.STATUS.read_text()
    head, rest = text.split(MODULE.BEGIN, 1)
    page.write_text(head + "| target | measured |\n|---|---|\n| a | b |" + rest.split(MODULE.END, 1)[1])
    assert MODULE.main(["--check", "--status", str(page)]) == 1
    out = capsys.readouterr().out
    assert "-| a | b |" in out and f"+{MODULE.BEGIN}" in out


@pytest.mark.parametrize(
    ("values", "goal", "direction", "want"),
    [
        ([107.1], 120.0, "≤", "met"),
        ([1.58, 1.59], 0.5, "≤", "missed 3.2×"),
        ([1.72, 1.78], 1.5, "≤", "missed 1.1–1.2×"),
        ([2645.0, 2881.0], 2000.0, "≥", "met"),
        ([4.33], 10.0, "≥", "missed 2.3×"),
        ([87.2], 90.0, "≥", "missed 1.03×"),
        ([0.9, 1.2], 1.0, "≤", "met in 1 of 2 runs"),
        ([1.0], 1.0, "≥", "met"),
    ],
)
def test_verdict(values: list[float], goal: float, direction: str, want: str) -> None:
    assert MODULE.verdict(values, goal, direction) == want


def test_ratio_is_below_one_when_met_in_both_directions() -> None:
    assert MODULE.ratios([0.25, 1.0], 0.5, "≤") == [0.5, 2.0]
    assert MODULE.ratios([200.0, 50.0], 100.0, "≥") == [0.5, 2.0]
    with pytest.raises(ValueError):
        MODULE.ratios([1.0], 1.0, "<")


def test_entry_without_files_is_not_in_data() -> None:
    target = MODULE.Target("x", "x ≤ 1 s", 1.0, "≤", "s", (), None, "[status.md](status.md)")
    row = MODULE.measure(target)
    assert row["value"] == MODULE.NOT_IN_DATA and row["verdict"] == "–"
    assert MODULE.measured_cell(row) == MODULE.NOT_IN_DATA
