"""Mistyped arguments of the benchmark and tool scripts and of ``aca-warp sweep``: one line (after any usage) and exit
code 2, before the first run, compile or clone, with nothing written (no output file or folder, no scratch file); never
a traceback, a run of nothing that passes, or a folder made for an output that cannot be written."""

from __future__ import annotations

from pathlib import Path

import h5py
import pytest
import test_device_errors

from aca_warp.cli import main as aca_warp

REPO = str(Path(__file__).resolve().parent.parent)  # a checkout of aca_warp
SPEC = Path(REPO) / "aca_warp" / "data" / "sweep_hf1.toml"
ABSENT = "{tmp}/absent"  # a folder that does not exist


@pytest.mark.parametrize(
    ("name", "argv", "says"),
    [
        ("bench_analysis", ["--patches", "0"], "--patches: must be >= 1"),
        ("bench_analysis", ["--log2-samples", "-3"], "--log2-samples: must be >= 10"),
        ("bench_analysis", ["--dt", "0"], "--dt: must be positive"),
        ("bench_analysis", ["--file", f"{ABSENT}/s.h5"], "output folder"),
        ("bench_analysis", ["--json", f"{ABSENT}/a.json"], "output folder"),
        ("bench_sweep", ["--units", "0"], "--units: must be >= 1"),
        ("bench_sweep", ["--shard-size", "0"], "--shard-size: must be >= 1"),
        ("bench_sweep", ["--duration", "0"], "--duration: must be positive"),
        ("bench_sweep", ["--repeat", "0"], "--repeat: must be >= 1"),
        ("bench_sweep", ["--host-repeat", "-1"], "--host-repeat: must be >= 0"),
        ("bench_sweep", ["--prepare", "-1"], "--prepare: must be >= 0"),
        ("bench_sweep", ["--pads", "3"], "choose a power of two"),
        ("bench_sweep", ["--dt", "0"], "--dt: must be positive"),
        ("bench_sweep", ["--sweep", "grid"], "invalid choice: 'grid'"),
        ("bench_sweep", ["--host-only", "--host-repeat", "0"], "--host-only measures the host phases"),
        ("bench_sweep", ["--json", f"{ABSENT}/b.json"], "output folder"),
        ("compare_checkouts", [ABSENT, ABSENT, "--out", "{tmp}/cmp"], "not a checkout of aca_warp"),
        ("compare_batch_checkouts", [ABSENT, ABSENT, "--device", "cpu"], "not a checkout of aca_warp"),
        ("compare_cuda_code", [ABSENT, REPO], "not a checkout of aca_warp"),
        ("compare_cuda_code", [REPO, REPO, "--arch", "12"], "--arch 12: this Warp build compiles CUDA code for"),
        ("compare_cuda_code", [REPO, REPO, "--out", f"{ABSENT}/c.json"], "output folder"),
        ("compare_cuda_code", [REPO, REPO, "--groups", "all"], "invalid choice: 'all'"),
        ("compare_batch_checkouts", [REPO, REPO, "--pads", "0"], "--pads: must be >= 1"),
        ("compare_batch_checkouts", [REPO, REPO, "--dt", "0"], "--dt: must be positive"),
        ("compare_checkouts", [REPO, REPO, "--out", "{tmp}/cmp", "--jobs", "hf_lf_state", "lf_seed7"], "name lf_seed7"),
        ("compare_checkouts", [REPO, REPO, "--out", "{tmp}/cmp", "--jobs", "hf_lf_state"], "name lf_seed7"),
        ("corrupt_files", ["--commands", "nope"], "--commands: unknown 'nope'"),
        ("corrupt_files", ["--jobs", "0"], "--jobs: must be >= 1"),
        ("corrupt_files", ["--formats", "-1"], "--formats: must be >= 0"),
        ("corrupt_files", ["--flips", "0"], "--flips: must be >= 1"),
        ("corrupt_files", ["--json", f"{ABSENT}/c.json"], "output folder"),
        ("onchip_registers", ["--preset", "nope"], "unknown preset 'nope'"),
        ("onchip_registers", ["--clusters", "0"], "--clusters: must lie in [1, 16]"),
        ("onchip_registers", ["--blocks", "0"], "--blocks: must lie in [1, 1024]"),
        ("preset_stats", ["--derive", "-1"], "--derive: must be >= 0"),
        ("preset_stats", ["--out", f"{ABSENT}/t.md"], "output folder"),
        ("time_quickstart", ["--timeout", "0"], "--timeout: must be positive"),
        ("time_quickstart", ["--json", f"{ABSENT}/q.json"], "output folder"),
        ("time_tests", ["--timeout", "-1"], "--timeout: must be positive"),
        ("time_tests", ["--markdown", f"{ABSENT}/t.md"], "output folder"),
        ("bench_onchip", ["--device", "cpu", "--clusters", "-1"], "--clusters: must lie in [0, 16]"),
        ("bench_onchip", ["--device", "cpu", "--blocks", "-1"], "--blocks: must lie in [0, 1024]"),
        ("bench_onchip", ["--device", "cpu", "--json", f"{ABSENT}/b.json"], "output folder"),
        ("bench_spool", ["--pads", "0"], "--pads: must be >= 1"),
        ("bench_spool", ["--json", f"{ABSENT}/s.json"], "output folder"),
        ("fault_injection", ["--workloads", "nope"], "--workloads: unknown 'nope'"),
        ("fault_injection", ["--kills", "-1"], "--kills: must be >= 0"),
        ("fault_injection", ["--json", f"{ABSENT}/f.json"], "output folder"),
        ("onchip_gpu_check", ["--device", "cpu", "--pads", "0"], "--pads: must be >= 1"),
        ("onchip_gpu_check", ["--device", "cpu", "--budget", "0"], "--budget: must be positive"),
        ("time_tests", ["--durations", "-1"], "--durations: must be >= 0"),
        ("lf_reproducible", ["--out", "/dev/null/runs"], "/dev/null is not a folder"),
        ("launch_cost", ["--json", f"{ABSENT}/l.json"], "output folder"),
        ("bench_lf_batches", ["--device", "cpu", "--window", "0"], "--window must be > 0"),
        ("bench_lf_batches", ["--device", "cpu", "--json", f"{ABSENT}/b.json"], "output folder"),
        ("bench_lf_batches", ["--device", "cpu", "--cases", "ms_nope"], "unknown group(s) ms_nope"),
        ("bench_lf_batches", ["--device", "cpu", "--cases", "ms_fast@x"], "a case is GROUP[:STATE][@K]"),
        ("bench_lf_batches", ["--device", "cpu", "--state-patches", "0"], "--state-patches: must be >= 2"),
        ("bench_checkouts", [ABSENT, ABSENT, "--out", "{tmp}/b", "--dt", "0"], "--dt must be a step > 0"),
        ("bench_checkouts", [ABSENT, ABSENT, "--out", "{tmp}/b", "--growth-dt", "-1"], "--growth-dt must be a step"),
        ("bench_checkouts", [REPO, REPO, "--out", "{tmp}/b", "--growth-dt", "5e-6"], "scene 'hf1' does not grow"),
        ("bench_checkouts", [REPO, REPO, "--out", "{tmp}/b", "--scene", "nope"], "--scene: "),
        (
            "bench_checkouts",
            [REPO, REPO, "--out", "{tmp}/b", "--scene", "varying_area", "--growth-dt", "5e-6"]
            + ["--cases", "onchip_adaptive"],
            "none is asked for",
        ),
        ("validation_cost", [f"{ABSENT}/results.json"], "no results file"),
    ],
)
def test_scripts_refuse_bad_arguments(
    name: str, argv: list[str], says: str, tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch
):
    """As the study scripts' table (``main()`` reads ``sys.argv``; exit 2, the message, no traceback, the working
    folder left empty); bench_analysis's scratch file goes there too (its default lies outside it)."""
    extra = ["--file", "{tmp}/s.h5"] if name == "bench_analysis" and "--file" not in argv else []
    test_device_errors.test_scripts_refuse_bad_arguments(name, [*argv, *extra], says, tmp_path, capsys, monkeypatch)


def test_sweep_on_a_gpu_the_machine_lacks_is_refused_before_its_folder(tmp_path: Path, capsys):
    """``aca-warp sweep --device cuda:99``: one line naming the devices there are (before: a ValueError traceback from
    a Dask worker, exit 1, and the sweep folder made)."""
    out = tmp_path / "sweep"
    assert aca_warp(["sweep", str(SPEC), "-o", str(out), "--device", "cuda:99", "--quiet"]) == 2
    assert "'cuda:99' is not available here" in capsys.readouterr().err
    assert not out.exists()
    # without --quiet too: the one line on stderr, no sweep header on stdout before it
    assert aca_warp(["sweep", str(SPEC), "-o", str(out), "--device", "cuda:99"]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "'cuda:99' is not available here" in captured.err
    assert not out.exists()


def test_a_run_file_given_as_a_sweep_spec_is_named(tmp_path: Path, capsys):
    """An HDF5 file (a run file) given where a sweep spec is asked for: one line saying so, not a decoding error;
    a spec that is not UTF-8 says that in words."""
    run = tmp_path / "run.h5"
    with h5py.File(run, "w") as f:
        f.attrs["complete"] = True
    bad = tmp_path / "bad.toml"
    bad.write_bytes(b"\xff\xfe[sweep]\n")
    for spec, words in (
        (run, f"{run} is an HDF5 file, not a TOML sweep spec"),
        (bad, "a sweep spec is TOML text, and byte 0 is not UTF-8"),
    ):
        assert aca_warp(["sweep", str(spec), "-o", str(tmp_path / "sw"), "--quiet"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], err
        assert not (tmp_path / "sw").exists()
