"""The ``aca-warp hf`` command and the run files it writes: exit codes, units, atomic output."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
from procs import small_scene_toml

from aca_warp.cli import main
from aca_warp.hf import runner
from aca_warp.hf.runfile import read_run
from aca_warp.scene import load_scene

SCENE = small_scene_toml()


@pytest.fixture
def scene_file(tmp_path):
    p = tmp_path / "small.toml"
    p.write_text(SCENE)
    return p


def _datasets(path):
    out = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda n, o: out.__setitem__(n, dict(o.attrs)) if isinstance(o, h5py.Dataset) else None)
    return out


def test_hf_writes_a_complete_run_file(scene_file, tmp_path, capsys):
    """A TOML scene runs to completion; every dataset has a unit; provenance attributes are present."""
    out = tmp_path / "run.h5"
    assert main(["hf", str(scene_file), "-o", str(out), "--no-progress", "--record-patches", "velocity"]) == 0
    assert "samples over" in capsys.readouterr().out
    r = read_run(out)
    assert r["attrs"]["complete"] and r["attrs"]["status"] == "complete"
    assert len(r["global/time"]) == 21 and np.allclose(r["global/time"], np.arange(21) * 1e-7)
    assert r["patches/velocity"].shape == (21, 60)
    for name, attrs in _datasets(out).items():
        assert "unit" in attrs, name
    for key in ("scene", "integrator", "run_options", "precision", "device", "versions", "stages", "stable_step"):
        assert key in r["attrs"], key
    assert "record:patches" in r["attrs"]["stages"]
    assert r["attrs"]["scene"]["load"]["normal_force"] == 20.0
    assert not (tmp_path / "run.h5.partial").exists()
    mu = r["global/mu"]
    assert np.all(np.isfinite(mu)) and 0.3 < mu[-1] < 0.8


def test_the_precision_follows_the_integrator(scene_file, tmp_path, capsys):
    """Without --precision, strang runs in fp32 (its statistics' choice) and adaptive in fp64; the file and the
    summary line say which; --precision overrides it."""
    for integrator, extra, precision in (
        ("strang", [], "fp32"),
        ("adaptive", [], "fp64"),
        ("strang", ["--precision", "fp64"], "fp64"),
    ):
        out = tmp_path / f"{integrator}-{precision}.h5"
        assert main(["hf", str(scene_file), "-o", str(out), "--no-progress", "--integrator", integrator, *extra]) == 0
        assert f"{integrator}, {precision})" in capsys.readouterr().out
        with h5py.File(out, "r") as f:
            assert f.attrs["precision"] == precision


def test_the_crossing_treatment_is_a_run_option(scene_file, tmp_path, capsys):
    """``--crossing mean`` is said in the summary line and stored with the run options, so ``rerun`` repeats it."""
    out = tmp_path / "mean.h5"
    assert main(["hf", str(scene_file), "-o", str(out), "--no-progress", "--crossing", "mean"]) == 0
    assert "crossings averaged" in capsys.readouterr().out
    assert read_run(out)["attrs"]["run_options"]["crossing"] == "mean"


def test_the_solve_tolerance_is_a_run_option(scene_file, tmp_path, capsys):
    """``--solve-tol`` is said in the summary line and stored with the run options, and ``rerun`` repeats it (the
    same samples); ``--resume`` takes the stored one and refuses the option; a value outside (0, 1), or one with
    ``--crossing mean``, exits 2 before anything is written."""
    out = tmp_path / "tight.h5"
    assert main(["hf", str(scene_file), "-o", str(out), "--no-progress", "--solve-tol", "1e-7"]) == 0
    assert ", solve tol 1e-07" in capsys.readouterr().out
    assert read_run(out)["attrs"]["run_options"]["solve_tol"] == 1e-7
    again = tmp_path / "again.h5"
    assert main(["rerun", str(out), "-o", str(again), "--no-progress"]) == 0
    assert read_run(again)["attrs"]["run_options"]["solve_tol"] == 1e-7
    assert np.array_equal(read_run(again)["global/mu"], read_run(out)["global/mu"])
    assert main(["hf", "--resume", str(out), "--solve-tol", "1e-7"]) == 2
    assert "--solve-tol" in capsys.readouterr().err
    for extra in (["--solve-tol", "1"], ["--solve-tol", "1e-7", "--crossing", "mean"]):
        bad = tmp_path / "bad.h5"
        assert main(["hf", str(scene_file), "-o", str(bad), "--no-progress", *extra]) == 2
        assert "solve_tol" in capsys.readouterr().err
        assert not bad.exists() and not list(tmp_path.glob("bad.h5*"))


def test_only_what_is_asked_is_recorded(scene_file, tmp_path):
    """Without --record-patches no per-patch history (and no per-patch stage) exists."""
    out = tmp_path / "run.h5"
    assert main(["hf", str(scene_file), "-o", str(out), "--no-progress"]) == 0
    r = read_run(out)
    assert not any(k.startswith("patches/velocity") or k == "patches/time" for k in r)
    assert "record:patches" not in r["attrs"]["stages"]


def test_record_patches_none_turns_a_scenes_record_off(scene_file, tmp_path):
    """``--record-patches none`` leaves out the per-patch histories a scene records itself."""
    scene = tmp_path / "patches.toml"
    scene.write_text(scene_file.read_text().replace("[record]\n", '[record]\npatches = ["velocity"]\n'))
    on, off = tmp_path / "on.h5", tmp_path / "off.h5"
    assert main(["hf", str(scene), "-o", str(on), "--no-progress"]) == 0
    assert main(["hf", str(scene), "-o", str(off), "--no-progress", "--record-patches", "none"]) == 0
    assert "patches/velocity" in read_run(on)
    assert not any(k.startswith("patches/velocity") for k in read_run(off))


@pytest.mark.parametrize(
    "argv, message",
    [
        (["hf", "nope", "-o", "{out}"], "neither a preset"),
        (["hf", "multiscale", "-o", "{out}"], "is an LF scene: run it with 'aca-warp lf multiscale -o LF.h5'"),
        (["lf", "hf1", "-o", "{out}"], "is an HF scene: run it with 'aca-warp hf hf1 -o RUN.h5'"),
        (
            ["hf", "{scene}", "-o", "{out}", "--integrator", "symplectic-euler", "--dt", "1e-6", "--sample-dt", "1e-6"],
            "stable-step",
        ),
        (["hf", "{scene}", "-o", "{out}", "--dt", "1e-6"], "shorter than the step"),
        (["hf", "{scene}", "-o", "{out}", "--sample-dt", "1e-3"], "(--sample-dt) exceeds the duration"),
        (["hf", "{scene}", "-o", "{out}", "--duration", "5e-8"], "(the scene's record.sample_dt) exceeds the duration"),
        (["hf", "{scene}", "-o", "{out}", "--record-patches", "pressure"], "unknown variable"),
        (["hf", "{scene}", "-o", "{out}", "--record-patches", " , "], "or none for no per-patch histories"),
        (["hf", "{scene}", "-o", "{out}", "--record-patches", "none,velocity"], "none stands alone"),
        (["hf", "{scene}", "-o", "{out}", "--device", "cuda:7"], "device"),
        (["hf", "{scene}", "-o", "/no/such/dir/run.h5"], "does not exist"),
        (["hf", "{scene}", "-o", "{out}", "--integrator", "adaptive", "--crossing", "mean"], "treatment of strang"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(argv, message, scene_file, tmp_path, capsys):
    """Bad input: exit code 2, one line on stderr naming the problem, and no file written."""
    out = tmp_path / "run.h5"
    args = [a.format(out=out, scene=scene_file) for a in argv]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and err[0].startswith("aca-warp: error:")
    assert not out.exists() and not (tmp_path / "run.h5.partial").exists()


@pytest.mark.parametrize("spelling", [["--duration", "-1e-4"], ["--duration=-1e-4"], ["--dt", "-.5"]])
def test_negative_numbers_are_values_refused_as_not_positive(spelling, scene_file, tmp_path, capsys):
    """A negative number in any notation is read as the option's value, in both spellings, and refused by the
    option's own check (not "expected one argument"): exit 2, nothing written."""
    out = tmp_path / "run.h5"
    with pytest.raises(SystemExit) as e:
        main(["hf", str(scene_file), "-o", str(out), *spelling])
    assert e.value.code == 2
    err = capsys.readouterr().err
    value = spelling[-1].split("=")[-1]
    assert f"must be positive (> 0), got {value!r}" in err and "expected one argument" not in err
    assert not out.exists()


def test_existing_output_needs_overwrite(scene_file, tmp_path, capsys):
    """An existing file is never replaced without --overwrite."""
    out = tmp_path / "run.h5"
    out.write_bytes(b"precious")
    assert main(["hf", str(scene_file), "-o", str(out), "--no-progress"]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert out.read_bytes() == b"precious"
    assert main(["hf", str(scene_file), "-o", str(out), "--no-progress", "--overwrite"]) == 0
    assert read_run(out)["attrs"]["complete"]


def test_fault_stops_with_exit_3_and_an_incomplete_file(scene_file, tmp_path, capsys):
    """A forced explicit step far beyond the estimate blows up: exit 3, time/patch/cause reported, file kept."""
    out = tmp_path / "run.h5"
    code = main(
        [
            "hf",
            str(scene_file),
            "-o",
            str(out),
            "--no-progress",
            "--integrator",
            "symplectic-euler",
            "--dt",
            "5e-6",
            "--sample-dt",
            "1e-5",
            "--duration",
            "2e-3",
            "--force",
        ]
    )
    assert code == 3
    captured = capsys.readouterr()
    err = captured.err
    assert "non-finite" in err and "patch" in err and "likely cause" in err
    # the summary gives the time the run stopped at, not the 2 ms asked for
    stopped = float(captured.out.split("stopped at t = ")[1].split(" s")[0])
    assert "of the requested 0.002 s (incomplete)" in captured.out and 0 < stopped < 2e-3
    r = read_run(out)
    assert r["attrs"]["complete"] is False or not r["attrs"]["complete"]
    assert "stopped" in r["attrs"]["status"]
    assert np.all(np.isfinite(r["global/mu"]))  # only the samples before the fault
    assert r["global/time"][-1] == pytest.approx(stopped)


def test_interrupt_leaves_a_marked_file(scene_file, tmp_path, monkeypatch):
    """Ctrl-C during a run: the file holds the samples so far and says it was interrupted."""
    real = runner.run_hf

    def interrupted(*args, sink, **kw):
        calls = []

        def once(chunk):
            sink(chunk)
            calls.append(1)
            raise KeyboardInterrupt

        return real(*args, sink=once, **kw)

    monkeypatch.setattr(runner, "run_hf", interrupted)
    out = tmp_path / "run.h5"
    assert main(["hf", str(scene_file), "-o", str(out), "--no-progress"]) == 130
    r = read_run(out)
    assert not r["attrs"]["complete"] and "interrupted" in r["attrs"]["status"]
    assert len(r["global/mu"]) >= 1
    assert not (tmp_path / "run.h5.partial").exists()


def test_run_file_scene_reloads(scene_file, tmp_path):
    """The scene stored in a run file describes the run (seeded generator, constants, record)."""
    out = tmp_path / "run.h5"
    assert main(["hf", str(scene_file), "-o", str(out), "--no-progress"]) == 0
    stored = read_run(out)["attrs"]["scene"]
    orig = load_scene(scene_file)
    assert stored["patches"]["seed"] == 4 and stored["patches"]["count"] == 60
    assert stored["disc"]["angular_velocity"] == pytest.approx(orig.angular_velocity)
    assert stored["material"]["K_T"] == orig.material.K_T


def test_help_explains(capsys):
    """--help exits 0 and describes units and exit codes."""
    with pytest.raises(SystemExit) as e:
        main(["hf", "--help"])
    assert e.value.code == 0
    text = capsys.readouterr().out
    assert "--record-patches" in text and "Exit codes" in text and "[s]" in text


def _cli(*args: str, cwd=None, env=None):
    """``aca-warp ARGS`` in a subprocess (stdout, stderr and stdin not a terminal); returns the completed process."""
    import os
    import subprocess
    import sys

    code = "import sys; from aca_warp.cli import main; sys.exit(main(sys.argv[1:]))"
    return subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=cwd, env={**os.environ, **(env or {})}
    )


def test_version_and_quiet_start(scene_file, tmp_path):
    """--version answers; a run into a log writes no Warp banner, no CUDA-driver warning, no module-load lines, no
    plan line and no progress bar: stderr is empty (but for the first-run compile note), stdout the summary line."""
    from aca_warp import __version__

    done = _cli("--version")
    assert done.returncode == 0 and done.stdout.strip() == f"aca-warp {__version__}"
    out = tmp_path / "run.h5"
    done = _cli("hf", str(scene_file), "-o", str(out))
    assert done.returncode == 0, done.stderr
    err = [line for line in done.stderr.splitlines() if not line.startswith("compiling kernels (once per")]
    assert err == [], done.stderr
    assert "%|" not in done.stderr and "Module" not in done.stderr and "CUDA" not in done.stderr
    assert len(done.stdout.strip().splitlines()) == 1 and "samples over" in done.stdout


def test_only_simulations_start_warp(tmp_path, monkeypatch, capsys):
    """analyze and plot read and write files only: the command line starts no Warp for them (≈ 0.3 s of CPU per
    process); hf does, before its handler (even one that is refused)."""
    from aca_warp.common import devices

    started = []
    monkeypatch.setattr(devices, "init_warp", lambda: started.append(True))
    missing = str(tmp_path / "missing.h5")
    assert main(["analyze", missing]) == 2 and main(["plot", missing, "-o", str(tmp_path / "figs")]) == 2
    assert started == []
    assert main(["hf", "--resume", missing]) == 2 and started == [True]
    capsys.readouterr()


def test_absurd_runs_are_refused_before_anything_is_written(scene_file, tmp_path, capsys):
    """A duration typed in the wrong unit, a step of 1e-20 s or an output of terabytes: one line, exit 2, no file,
    first as implausible values (the unit named), and with --allow-implausible by the size limits; --force lifts the
    limits (checked with the step count only: the plan passes). The step count is a fixed-step integrator's."""
    out = tmp_path / "run.h5"
    strang = ["--integrator", "strang"]
    for extra, message, limit in (
        (["--duration", "1e3"], "did you mean µs? (1000 µs = 0.001 s)", "more than a run records"),
        (
            ["--duration", "50", "--dt", "1e-10", *strang],
            "run.duration = 50 s — beyond 1 s",
            "5e+11 steps, more than 1e+10",
        ),
        (["--dt", "1e-20", *strang], "dt = 1e-20 s — below 1e-13 s", "steps, more than 1e+10"),
        (["--duration", "1e1", "--sample-dt", "5e-8", "--record-patches", "velocity"], "beyond 1 s", "more than 50 GB"),
    ):
        for allow, expected in (([], message), (["--allow-implausible"], limit)):
            assert main(["hf", str(scene_file), "-o", str(out), *extra, *allow]) == 2
            err = capsys.readouterr().err.strip().splitlines()
            assert len(err) == 1 and expected in err[0], err
            assert not out.exists() and not out.with_name("run.h5.partial").exists()
    scene = load_scene(str(scene_file), allow_implausible=True)
    plan = runner.plan_run(scene, runner.RunOptions(duration=50.0, integrator="strang", dt=1e-10, force=True))
    assert plan.steps == 500_000_000_000 and plan.samples == 500_000_001
    assert plan.describe() == "5e+11 steps of 1e-10 s, 5e+08 samples, about 28 GB to record"


@pytest.mark.parametrize(
    "argv, message",
    [
        (["hf", "{scene}", "-o", "{out}", "--duration", "1ms"], "not a number: '1ms' (a plain number in SI units"),
        (["hf", "{scene}", "-o", "{out}", "--bogus"], "unrecognized arguments: --bogus"),
        (["hf", "{scene}", "-o", "{out}", "--integrator", "rk4"], "invalid choice: 'rk4'"),
    ],
)
def test_a_mistyped_command_line_is_one_line(argv, message, scene_file, tmp_path, capsys):
    """What argparse refuses is one line too (no usage block), naming the --help that lists the options; exit 2."""
    out = tmp_path / "run.h5"
    with pytest.raises(SystemExit) as e:
        main([a.format(out=out, scene=scene_file) for a in argv])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and err[0].endswith("--help"), err
    assert not out.exists()


def test_a_large_run_says_what_it_will_record_in_a_log_too(capsys):
    """Off a terminal (a log, a pipe) the plan's line is printed for a run that records 1 GB or more, even with
    --no-progress; a smaller run stays quiet there."""
    from aca_warp.hf.commands import LARGE_OUTPUT_BYTES, _announce
    from aca_warp.hf.runner import RunPlan

    def plan(size: float) -> RunPlan:
        return RunPlan(steps=10, step=5e-8, samples=11, patch_rows=11, output_bytes=int(size), file_bytes=int(size))

    for progress in (True, False):
        _announce("big.h5", progress, lambda plan: [])(plan(LARGE_OUTPUT_BYTES))
        assert capsys.readouterr().err == "aca-warp: big.h5: 10 steps of 5e-08 s, 11 samples, about 1 GB to record\n"
        _announce("small.h5", progress, lambda plan: [])(plan(LARGE_OUTPUT_BYTES / 10))
        assert capsys.readouterr().err == ""


def test_a_file_of_the_other_kind_says_which_command_takes_it(tmp_path, capsys):
    """An HDF5 file where a TOML scene is asked for, an LF scene file or preset given to hf or bench, --snapshot
    with a preset, an LF run given to hf --resume: one line each, exit 2, naming the command that takes it."""
    h5 = tmp_path / "run.h5"
    with h5py.File(h5, "w") as f:
        f.attrs["kind"] = "lf"
    lf_toml = tmp_path / "lf.toml"
    lf_toml.write_text("[lf]\ndt = 0.01\n")
    sched = tmp_path / "sched.toml"  # an LF scene of the defaults but its schedule
    sched.write_text('[[schedule]]\nkind = "application"\nduration = 1.0\nnormal_force = 400.0\nsliding_speed = 10.0\n')
    out = str(tmp_path / "x.h5")
    for argv, said in (
        (["lf", str(h5), "-o", out], f"{h5} is an HDF5 file, not a TOML LF scene file"),
        (["bench", "--scene", str(h5), "--device", "cpu"], "is an HDF5 file, not a TOML scene file"),
        (
            ["hf", str(lf_toml), "-o", out],
            f"{lf_toml} is an LF scene file (it has [lf]): run it with 'aca-warp lf",
        ),
        (["hf", str(sched), "-o", out], f"{sched} is an LF scene file (it has [schedule]): run it with 'aca-warp lf"),
        (
            ["bench", "--scene", "multiscale", "--device", "cpu"],
            "'multiscale' is an LF scene: run it with 'aca-warp lf",
        ),
        (["hf", "hf1", "--snapshot", "app1_start", "-o", out], "--snapshot takes a pad from an LF run file"),
        (["hf", "--resume", str(h5)], f"{h5} is an LF run: continue it with 'aca-warp lf --resume {h5}'"),
    ):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and said in err[0], (argv, err)


def test_a_misspelled_preset_gets_a_suggestion(tmp_path, capsys):
    """A preset name off by its case or a few letters: the one line also names the nearest preset."""
    for argv, near in ((["hf", "HF1"], "'hf1'"), (["hf", "varying"], "'varying_area'"), (["lf", "multiscal"], None)):
        assert main([*argv, "-o", str(tmp_path / "x.h5")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].endswith(f"(did you mean {near or repr('multiscale')}?)"), err
    assert main(["hf", "zzz", "-o", str(tmp_path / "x.h5")]) == 2
    assert "did you mean" not in capsys.readouterr().err


def test_the_help_names_every_preset():
    from aca_warp.hf.commands import run_epilog
    from aca_warp.scene.files import PRESETS

    text = run_epilog("aca-warp hf --resume RUN.h5")
    for name in PRESETS:
        base = name.removesuffix("_equal")
        assert base in text and (name == base or "NAME_equal" in text), name


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["hf", "hf1", "--duraton", "1e-4", "-o", "x.h5"], "(did you mean --duration?); see aca-warp hf --help"),
        (["hf", "hf1", "--sampledt=1e-6", "-o", "x.h5"], "(did you mean --sample-dt?); see aca-warp hf --help"),
        (["analyze", "x.h5", "--no-snyc"], "(did you mean --no-sync?); see aca-warp analyze --help"),
        (["hf", "hf1", "--zzz", "-o", "x.h5"], "unrecognized arguments: --zzz; see aca-warp hf --help"),
        (["hf", "hf1", "--verbose", "-o", "x.h5"], "--verbose is an option of aca-warp itself: give it before the"),
    ],
)
def test_a_mistyped_option_is_refused_by_its_command_with_the_nearest(argv, said, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as e:
        main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert e.value.code == 2 and len(err) == 1 and said in err[0], err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    ("extra", "said"),
    [
        (["--record-patches", "velocty"], "--record-patches: unknown variable 'velocty'; choose from velocity,"),
        (["--record-patches", "velocity", "--patch-window", "1e-4", "0"], "--patch-window: the end T1 must exceed"),
    ],
)
def test_a_bad_record_option_is_named_as_typed(extra, said, capsys, tmp_path):
    out = tmp_path / "e.h5"
    assert main(["hf", "hf1", "--duration", "1e-4", *extra, "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and said in err[0], err
    assert not list(tmp_path.iterdir())


def test_analyse_is_analyze():
    """The British spelling of the command the help text uses runs the same command."""
    from aca_warp.analysis.commands import cmd_analyze
    from aca_warp.cli import build_parser

    for spelling in ("analyze", "analyse"):
        args = build_parser().parse_args([spelling, "run.h5", "--no-sync"])
        assert args.command == "analyze" and args.handler is cmd_analyze and args.run == "run.h5"
