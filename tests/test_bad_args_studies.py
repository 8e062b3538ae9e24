"""The study scripts refuse a mistyped argument in one line on stderr with exit code 2, before any simulation starts
and with nothing written: an absent device, a zero or negative step, duration, count or tolerance, an unknown
integrator or scene, a result file that is not there, an output in a missing folder."""

from __future__ import annotations

from pathlib import Path

import pytest
from scriptload import exit_code

ABSENT = "cuda:99"
HF_STUDY = ["--quick", "--outdir", "{tmp}/out"]
MULTISCALE = ["--quick", "--outdir", "{tmp}/out"]
TTS = ["--scenes", "stickslip", "--out", "{tmp}/out", "--page", "{tmp}/page.md"]
SECTOR = ["--quick", "--out", "{tmp}/out/sector.json"]
SCHEMES = ["--quick", "--parts", "single", "--out", "{tmp}/out"]
VA = ["--quick", "--out", "{tmp}/out", "--page", "{tmp}/page.md", "--figures", "{tmp}/figures"]
WP = ["--quick", "--scenes", "stickslip", "--out", "{tmp}/out", "--page", "{tmp}/page.md"]
WPS = ["--quick", "--out", "{tmp}/out"]
VALIDATION = ["--quick", "--device", "cpu", "--only", "hf1", "--out", "{tmp}/out"]


@pytest.mark.parametrize(
    ("name", "argv", "says"),
    [
        ("hf_study", [*HF_STUDY, "--device", ABSENT], "not available here"),
        ("hf_study", [*HF_STUDY, "--dt", "0"], "--dt: must be positive"),
        ("hf_study", [*HF_STUDY, "--sample-dt", "0"], "--sample-dt: must be positive"),
        ("hf_study", [*HF_STUDY, "--decimation", "0"], "--decimation: must be >= 1"),
        ("hf_study", [*HF_STUDY, "--integrator", "nope"], "invalid choice: 'nope'"),
        ("hf_study", [*HF_STUDY, "--phi-min", "-1"], "--phi-min: must be >= 0"),
        ("hf_study", [*HF_STUDY, "--sweep-M", "0"], "--sweep-M: must be positive"),
        ("hf_study", [*HF_STUDY, "--sweep-speed", "-1"], "--sweep-speed: must be positive"),
        ("hf_study", [*HF_STUDY, "--seed", "-1"], "--seed: must be >= 0"),
        ("multiscale_study", [*MULTISCALE, "--scene", "nope"], "LF scene 'nope' is neither a preset"),
        ("multiscale_study", [*MULTISCALE, "--device", ABSENT], "not available here"),
        ("multiscale_study", [*MULTISCALE, "--hf-sample-dt", "0"], "--hf-sample-dt: must be positive"),
        ("multiscale_study", [*MULTISCALE, "--hf-duration", "0"], "--hf-duration: must be positive"),
        ("multiscale_study", [*MULTISCALE, "--docs", "{tmp}/absent/page.md"], "output folder"),
        ("time_to_solution", [*TTS, "--device", ABSENT], "not available here"),
        ("time_to_solution", [*TTS, "--report", "{tmp}/absent.json"], "--report: no result file"),
        ("time_to_solution", [*TTS, "--target", "0"], "--target: must be positive"),
        ("time_to_solution", [*TTS, "--duration", "0"], "--duration: must be positive"),
        ("time_to_solution", [*TTS, "--pads", "-1"], "--pads: must be >= 0"),
        ("friction_step_sector", ["--report", "{tmp}/absent.json"], "--report: no result file"),
        ("friction_step_sector", [*SECTOR, "--seeds", "0"], "--seeds: must be >= 1"),
        ("friction_step_sector", [*SECTOR, "--runs", "strang@fp16"], "unknown precision 'fp16'"),
        ("friction_schemes", [*SCHEMES, "--ref-dt", "0"], "--ref-dt: must be positive"),
        ("friction_schemes", [*SCHEMES, "--tol-e", "0"], "--tol-e: must be positive"),
        ("friction_schemes", [*SCHEMES, "--speed", "-1"], "--speed: must be positive"),
        ("friction_schemes", ["--out", "{tmp}/out", "--report"], "no folder of results"),
        ("time_varying_area", ["--device", ABSENT, "--steps", "1e-6", "--out", "{tmp}/out"], "not available here"),
        ("varying_area", [*VA, "--device", ABSENT], "not available here"),
        ("varying_area", [*VA, "--speedup", "0"], "--speedup: must be positive"),
        ("varying_area", [*VA, "--chunk", "0"], "--chunk: must be positive"),
        ("varying_area", [*VA, "--resume", "{tmp}/absent.npz"], "--resume: no file"),
        ("varying_area", [*VA, "--report-only", "{tmp}/absent.h5"], "--report-only: no file"),
        ("varying_area", [*VA, "--growth-dt", "0"], "--growth-dt: must be positive"),
        ("varying_area", [*VA, "--growth-dt", "3e-6", "--dt", "1e-8"], "does not divide --chunk"),
        ("work_precision", [*WP, "--patches", "0"], "--patches: must be >= 1"),
        ("work_precision", [*WP, "--window", "0"], "--window: must be positive"),
        ("work_precision", [*WP, "--device", ABSENT], "not available here"),
        ("work_precision", [*WP, "--report", "{tmp}/absent.json"], "--report: no result file"),
        ("work_precision_stats", [*WPS, "--window", "0"], "--window: must be positive"),
        ("work_precision_stats", [*WPS, "--duration", "0"], "--duration: must be positive"),
        ("work_precision_stats", [*WPS, "--max-wall", "-1"], "--max-wall: must be >= 0"),
        ("work_precision_stats", [*WPS, "--rule", "0"], "--rule: must be positive"),
        ("work_precision_stats", [*WPS, "--first-seed", "-1"], "--first-seed: must be >= 0"),
        ("warp_cpu_threads", ["--seconds", "nan"], "--seconds: must be finite"),
        ("warp_cpu_threads", ["--md", "{tmp}/absent/threads.md"], "output folder"),
        ("validation", [*VALIDATION, "--seeds", "0"], "--seeds: must be >= 1"),
        ("validation", [*VALIDATION, "--window", "0"], "--window: must be positive"),
        ("validation", [*VALIDATION, "--dt", "0"], "--dt: must be positive"),
        ("validation", [*VALIDATION, "--workers", "0"], "--workers: must be >= 1"),
        ("validation", [*VALIDATION, "--max-wall", "-1"], "--max-wall: must be >= 0"),
        ("validation", [*VALIDATION, "--growth-speedup", "0"], "--growth-speedup: must be positive"),
        ("validation", [*VALIDATION, "--page", "{tmp}/absent/page.md"], "output folder"),
    ],
)
def test_study_scripts_refuse_bad_arguments(name: str, argv: list[str], says: str, tmp_path: Path, capsys):
    """One line (after any usage), exit code 2, no traceback, and nothing in the output's place."""
    assert exit_code(name, [a.format(tmp=tmp_path) for a in argv]) == 2
    err = capsys.readouterr().err
    assert says in err and "Traceback" not in err
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("content", ['{"x": 1}', "[1, 2]", "not json"])
@pytest.mark.parametrize(
    ("name", "argv"),
    [
        ("time_to_solution", ["--report", "{bad}", "--page", "{tmp}/page.md"]),
        ("work_precision", ["--report", "{bad}", "--page", "{tmp}/page.md"]),
        ("friction_step_sector", ["--report", "{bad}", "--page", "{tmp}/page.md"]),
        ("work_precision_stats", ["--report", "{bad}", "--page", "{tmp}/page.md", "--figures", "{tmp}/fig"]),
        ("work_precision_stats", ["--by-part", "{bad}"]),
        ("work_precision_stats", ["--steps", "{bad}", "--figures", "{tmp}/fig"]),
    ],
)
def test_study_reports_refuse_a_file_that_is_not_their_results(
    name: str, argv: list[str], content: str, tmp_path: Path, capsys
):
    """--report (and --by-part, --steps) of a JSON file of something else, or of no JSON: one line, exit code 2, no
    page."""
    bad = tmp_path / "bad.json"
    bad.write_text(content)
    code = exit_code(name, [a.format(tmp=tmp_path, bad=bad) for a in argv])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    assert "not a result file" in err or "not JSON" in err or "not a readable" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.json"]
