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
    row = next(ln for ln in text.split(MODULE.BEGIN, 1)[1].splitlines() if ln.startswith("| 64 saturated hf1 pads"))
    cell = row.split(" | ")[1]  # the measured value, as generated
    changed = row.replace(f" | {cell} | ", f" | 9{cell} | ", 1)
    page.write_text(text.replace(row, changed))
    assert MODULE.main(["--check", "--status", str(page)]) == 1
    out = capsys.readouterr().out
    assert f"-{changed}" in out and f"+{row}" in out
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


def _sweep_run(code: str, mode: str, units: int, run: int, wall: float, command: float, fraction: float) -> dict:
    return {"code": code, "mode": mode, "units": units, "run": run, "wall_s": wall, "command_wall_s": command,
            "wall_over_in_shard": fraction}  # fmt: skip


def test_sweep_readers_take_the_default_path_of_this_code(tmp_path: Path) -> None:
    """The sweep rows read the overlapped runs of the code measured, paired run by run, among decoys: the
    baseline's, the kept pool's and the sequential path's runs."""
    runs = [
        _sweep_run("new", "overlapped", 1, 1, 4.0, 8.0, 0.60),
        _sweep_run("new", "overlapped", 2, 1, 2.0, 5.0, 0.55),
        _sweep_run("new", "overlapped", 1, 2, 3.0, 7.0, 0.70),
        _sweep_run("new", "overlapped", 2, 2, 2.5, 6.0, 0.50),
        _sweep_run("baseline", "overlapped", 1, 1, 1.0, 1.0, 0.99),
        _sweep_run("new", "kept", 2, 1, 0.1, 0.1, 0.99),
        _sweep_run("new", "sequential", 1, 1, 9.0, 0.0, 0.10),
    ]
    path = tmp_path / "sweep.json"
    path.write_text(MODULE.json.dumps({"machine": {"device_name": "GPU", "host": "CPU, 8 cores"}, "runs": runs}))
    assert MODULE.sweep_wall_fraction([path]).values == pytest.approx((60.0, 70.0))
    two = MODULE.sweep_two_over_one([path])
    assert two.values == pytest.approx((2.0, 1.2)) and two.machine == "2 × GPU, CPU, 8 cores"
    assert two.note == "the whole command, cluster start included, 1.17–1.60×"


def _tts_row(solver: str, where: str, tries: list[tuple[float, float, bool]]) -> dict:
    return {"scene": "hf1", "solver": solver, "pads": 1, "where": where,
            "tries": [{"error": e, "time_s": t, "reached": r, "setting": 0} for e, t, r in tries]}  # fmt: skip


def test_time_to_solution_ratio_takes_the_try_that_reached_and_says_when_none_did(tmp_path: Path) -> None:
    """A solver's time is its first try that reached the error (not its last, nor another engine's row); where the
    other solver never reaches it, its finest try bounds the ratio and the note says so; where ours does not, too."""
    rows = [
        _tts_row("ours", "gpu", [(1e-6, 0.1, False), (5e-8, 0.2, True), (1e-8, 0.9, True)]),
        _tts_row("ours", "cpu", [(5e-8, 5.0, True)]),
        _tts_row("other", "", [(1e-5, 0.3, False), (2e-6, 0.5, False)]),
        _tts_row("third", "", [(5e-8, 0.05, True)]),
        _tts_row("late", "", [(1e-6, 0.4, False)]),
    ]
    path = tmp_path / "tts.json"
    path.write_text(MODULE.json.dumps({"machine": {"device": "cpu", "host": "CPU, 2 cores"}, "rows": rows}))
    slow = MODULE.tts_ratio("hf1", ("ours", "gpu"), ("other", ""), speedup=False)([path])
    assert slow.values == pytest.approx((0.4,)) and "at most this ratio at equal error" in slow.note
    fast = MODULE.tts_ratio("hf1", ("third", ""), ("ours", "gpu"), speedup=True)([path])
    assert fast.values == pytest.approx((4.0,)) and fast.note == "0.0500 s against 0.200 s"
    short = MODULE.tts_ratio("hf1", ("late", ""), ("third", ""), speedup=False)([path])
    assert "ours at 1.0e-6, short of the error" in short.note
    gpu = tmp_path / "tts_gpu.json"
    gpu.write_text(MODULE.json.dumps({"machine": {"device": "cuda:0", "device_name": "NVIDIA H200"}, "rows": rows}))
    both = MODULE.tts_ratio("hf1", ("third", ""), ("ours", "gpu"), speedup=True)([path, gpu])
    assert both.note == "CPU, 2 cores: (0.0500 s against 0.200 s); H200: (0.0500 s against 0.200 s)"
    twice = MODULE.tts_ratio("hf1", ("third", ""), ("ours", "gpu"), speedup=True)([gpu, gpu])
    assert twice.note == "H200 run 1: (0.0500 s against 0.200 s); H200 run 2: (0.0500 s against 0.200 s)"
    assert MODULE.tts_ratio("hf1", ("third", ""), ("ours", "gpu"), speedup=True)([path, gpu, path]).note == ""


def test_a_markdown_profile_names_its_device(tmp_path: Path) -> None:
    md = tmp_path / "p.md"
    md.write_text("On-chip ablation profile: hf1, 1 pad(s), dt 1e-08 s; NVIDIA H200, Warp 1.19.0 (scripts/x.py)\n")
    assert MODULE.profile_md_machine(md) == "NVIDIA H200"
    md.write_text("a profile without a device\n")
    with pytest.raises(ValueError, match="names no device"):
        MODULE.profile_md_machine(md)


def test_values_by_machine_only_where_the_files_ran_on_several() -> None:
    fmt = "{:.2f}".format
    names = ["NVIDIA H100 80GB HBM3", "NVIDIA H100 80GB HBM3", "NVIDIA H200", "NVIDIA H200", "NVIDIA H200"]
    assert MODULE.per_machine([1.78, 1.72, 2.0, 1.99, 2.0], names, fmt) == "H100 80GB HBM3 1.72–1.78; H200 1.99–2.00"
    assert MODULE.per_machine([1.78, 1.72], names[:2], fmt) == ""
    assert MODULE.per_machine([3.5, 2.0], ["NVIDIA H100", "AMD EPYC"], fmt) == "H100 3.50; AMD EPYC 2.00"


def test_entry_without_files_is_not_in_data() -> None:
    target = MODULE.Target("x", "x ≤ 1 s", 1.0, "≤", "s", (), None, "[status.md](status.md)")
    row = MODULE.measure(target)
    assert row["value"] == MODULE.NOT_IN_DATA and row["verdict"] == "–"
    assert MODULE.measured_cell(row) == MODULE.NOT_IN_DATA


def test_validation_stepping_is_one_value_per_results_file() -> None:
    """Each results file is a run of the whole validation: its batches' stepping summed over the calls that made it
    (the two eight-seed runs on one code, one call each; the 32-seed file, joined from several calls)."""
    twice = MODULE.DOCS / "validation" / "rerun_twice"
    got = MODULE.validation_stepping([twice / "results.json", twice / "results_b.json.gz"])
    assert [round(v, 1) for v in got.values] == [91.9, 90.3] and got.note == "1 call each"
    assert got.machine == "NVIDIA H200"
    joined = MODULE.validation_stepping([MODULE.DOCS / "validation" / "seeds32" / "results.json.gz"])
    assert len(joined.values) == 1 and joined.note.endswith(" calls") and joined.note != "1 calls"
