"""A device the machine lacks (``--device cuda:99``) is a bad argument: one line naming the devices there are, exit
code 2, nothing written; never a traceback (the package's ``get_device`` and the study and benchmark scripts that
take ``--device``, those with a ``main(argv)`` and those that read ``sys.argv``). The same for the scripts' other
mistyped arguments: an unknown preset, a zero or negative count, step or duration."""

from __future__ import annotations

from pathlib import Path

import pytest
from scriptload import exit_code, load_script

from aca_warp.common.devices import get_device
from aca_warp.common.errors import SceneError

ABSENT = "cuda:99"


def test_get_device_names_the_devices_there_are(capfd):
    assert str(get_device("cpu")) == "cpu"
    with pytest.raises(SceneError, match=r"'cuda:99' is not available here.*this machine has: cpu"):
        get_device(ABSENT)
    import warp as wp

    if not wp.is_cuda_available():  # "cuda" without a usable GPU: the one error, no native CUDA messages before it
        capfd.readouterr()
        with pytest.raises(SceneError, match=r"^device 'cuda' is not available here: no usable CUDA GPU"):
            get_device("cuda")
        assert capfd.readouterr().err == ""


def test_validation_refuses_an_absent_device_before_writing(tmp_path: Path, capsys):
    from aca_warp.studies.validation import cli

    out = tmp_path / "v"
    assert cli.main(["--device", ABSENT, "--quick", "--out", str(out), "--only", "hf1"]) == 2
    assert "not available here" in capsys.readouterr().err
    assert not out.exists()  # no log, no results file


def test_validation_dry_run_that_must_make_lf_runs_on_an_absent_device_says_how(tmp_path: Path, capsys):
    from aca_warp.studies.validation import cli

    argv = ["--device", ABSENT, "--quick", "--out", str(tmp_path / "v"), "--only", "ms_fast", "--dry-run"]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert "not available here" in err and "--device cpu" in err and "--lf-dir" in err


@pytest.mark.parametrize(
    ("name", "argv"),
    [
        ("work_precision_stats", ["--quick"]),
        ("lf_reproducible", ["--seeds", "1"]),
        ("bench_cluster_barrier", []),
    ],
)
def test_scripts_refuse_an_absent_device(name: str, argv: list[str], tmp_path: Path, capsys):
    extra = ["--out", str(tmp_path / "out")] if name != "bench_cluster_barrier" else []
    with pytest.raises(SystemExit) as stop:
        load_script(name).main(["--device", ABSENT, *argv, *extra])
    assert stop.value.code == 2
    assert "not available here" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


BENCH_ONCHIP = ["--json", "{tmp}/b.json"]  # its output, which a refused call must not write


@pytest.mark.parametrize(
    ("name", "argv", "says"),
    [
        ("bench_lf", ["--device", ABSENT, "--json", "{tmp}/out"], "not available here"),
        ("onchip_gpu_check", ["--device", ABSENT, "--out", "{tmp}/out"], "not available here"),
        ("bench_onchip", [*BENCH_ONCHIP, "--device", "cpu", "--duration", "1e-7"], "at least one 1 µs sample"),
        ("bench_onchip", [*BENCH_ONCHIP, "--device", "cpu", "--scene", "nope"], "unknown preset 'nope'"),
        ("bench_onchip", [*BENCH_ONCHIP, "--device", "cpu", "--pads", "0"], "--pads must be ≥ 1"),
        ("bench_onchip", [*BENCH_ONCHIP, "--device", ABSENT], "not available here"),
        ("adaptive_growth", ["--device", ABSENT], "not available here"),
        ("adaptive_growth", ["--duration", "0"], "--duration: must be positive"),
        ("adaptive_growth", ["--dt", "-1"], "--dt: must be positive"),
        ("adaptive_growth", ["--tols", "0"], "--tols: must be positive"),
        ("architecture_figure", ["--dpi", "0"], "--dpi: must be >= 1"),
        ("capture_cost", ["--scene", "nope"], "unknown preset 'nope'"),
        ("capture_cost", ["--repeat", "0"], "--repeat must be at least 1"),
        ("launch_cost", ["--scene", "nope"], "unknown preset 'nope'"),
        ("profile_onchip", ["--device", ABSENT], "not available here"),
        ("profile_onchip", ["--device", "cpu", "--window", "0"], "--window: must be positive"),
        ("profile_onchip", ["--device", "cpu", "--growth-dt", "1e-6"], "--growth-dt needs --growth"),
        ("profile_onchip", ["--device", "cpu", "--growth", "--saturate", "1e-5"], "--saturate profiles a batch"),
        ("profile_onchip_adaptive", ["--device", ABSENT], "not available here"),
        ("profile_onchip_adaptive", ["--device", "cpu", "--pads", "0"], "--pads: must be >= 1"),
        ("profile_onchip_adaptive", ["--device", "cpu", "--tolerance", "0"], "--tolerance: must be positive"),
        ("profile_onchip_adaptive", ["--device", "cpu", "--repeats", "0"], "--repeats: must be >= 1"),
        ("recorder_flush_cost", ["--device", ABSENT], "not available here"),
        ("bench_lf", ["--scene", "nope"], "LF scene 'nope' is neither a preset"),
        ("bench_lf", ["--duration", "0"], "--duration: must be positive"),
        ("bench_lf", ["--compare", "{tmp}/absent.h5"], "--compare: no run file"),
        ("bench_lf", ["--save", "{tmp}/absent/lf.h5"], "output folder"),
        ("checkpoint_cost", ["--scene", "nope"], "unknown preset 'nope'"),
        ("checkpoint_cost", ["--pads", "0"], "--pads: must be >= 1"),
        ("checkpoint_cost", ["--hf-duration", "0"], "--hf-duration: must be positive"),
        ("checkpoint_cost", ["--wall", "0"], "--wall: must be positive"),
        ("checkpoint_cost", ["--device", ABSENT], "not available here"),
        ("checkpoint_cost", ["--json", "{tmp}/absent/c.json"], "output folder"),
    ],
)
def test_scripts_refuse_bad_arguments(
    name: str, argv: list[str], says: str, tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch
):
    """A mistyped argument: one line (after any usage) and exit code 2, before the first compile and with nothing
    written (``main()`` reads ``sys.argv``; ``main(argv)``, given none, does too)."""
    monkeypatch.chdir(tmp_path)
    assert exit_code(name, [a.format(tmp=tmp_path) for a in argv]) == 2
    err = capsys.readouterr().err
    assert says in err and "Traceback" not in err
    assert not any(tmp_path.iterdir())
