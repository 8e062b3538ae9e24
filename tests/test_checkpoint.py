"""Checkpoint and resume of HF runs: a run killed with SIGKILL (or stopped by Ctrl-C) and resumed from its last
checkpoint ends in a file whose every dataset equals an uninterrupted run's, bit for bit (CPU, same precision)."""

from __future__ import annotations

from pathlib import Path

import h5py
import pytest
from procs import assert_refused, assert_same_run_file, interrupted_at_second_checkpoint, small_scene_toml
from sigkill import AUTO_AT_ONCE, kill_after_first_checkpoint

from aca_warp.cli import main
from aca_warp.common import checkpoint
from aca_warp.common.checkpoint import has_checkpoint
from aca_warp.hf import runner
from aca_warp.hf.runfile import RunWriter

SCENE = small_scene_toml("ckpt", count=40, duration=2.0e-5, perturbation=1.0e-3)

GROWTH = """
[growth]
increment = 1.0e-7
interval = 3.0e-7
"""


def assert_same_file(a: Path, b: Path) -> None:
    """Same dataset names, shapes, dtypes and bits; both complete; the same step counts (run_options differ: the
    checkpoint interval)."""
    assert_same_run_file(a, b, ("steps", "rejected_steps", "sim_time", "scene", "stages", "dt"))


@pytest.fixture
def scene_file(tmp_path: Path) -> Path:
    p = tmp_path / "ckpt.toml"
    p.write_text(SCENE)
    return p


def test_sigkill_then_resume_is_bit_identical(scene_file: Path, tmp_path: Path, capsys) -> None:
    """`aca-warp hf` with its default, automatic checkpoints (here from the first chunk on) in a subprocess, killed with
    SIGKILL once the first checkpoint is on disk: only RUN.h5.partial is left; `analyze` of it calls the run killed
    and names the resume; it resumes with `hf --resume` (dropping that analysis), and the finished file equals an
    uninterrupted run (no checkpoints) dataset for dataset, bit for bit."""
    # 0.5 ms: the first automatic checkpoint comes at the first chunk end (2 µs), the run goes on ~0.5 s after it
    # (on the general engine: on the CPU the on-chip engine's first launch would cover the whole run)
    opts = ["--duration", "5e-4", "--sample-dt", "1e-6", "--record-patches", "velocity,displacement", "--no-progress"]
    opts += ["--engine", "general"]
    ref = tmp_path / "ref.h5"
    assert main(["hf", str(scene_file), "-o", str(ref), *opts, "--no-checkpoint"]) == 0

    out = tmp_path / "run.h5"
    part = tmp_path / "run.h5.partial"
    kill_after_first_checkpoint(["hf", str(scene_file), "-o", str(out), *opts], part, poll=0.01, python=AUTO_AT_ONCE)
    assert part.exists() and not out.exists()  # never a half-written final file
    with h5py.File(part, "r") as f:
        assert not f.attrs["complete"] and f.attrs["status"] == "running"
        at = float(f["checkpoint"].attrs["sim_time"])
    assert 0 < at < 5e-4
    # a new run cannot clobber the unfinished one by accident
    assert main(["hf", str(scene_file), "-o", str(out), *opts]) == 2
    capsys.readouterr()
    assert main(["analyze", str(part), "--no-sync"]) == 0
    said = capsys.readouterr().out
    assert "the run is incomplete (killed: no process writes it)" in said and f"'aca-warp hf --resume {out}'" in said

    assert main(["hf", "--resume", str(part), "--no-progress"]) == 0
    assert out.exists() and not part.exists()
    assert_same_file(out, ref)

    # the same over a complete earlier file (--overwrite): marked when it begins, so the killed run resumes beside
    # the earlier file, which it replaces only when it completes
    from aca_warp.common.files import REPLACES

    kill_after_first_checkpoint(
        ["hf", str(scene_file), "-o", str(out), *opts, "--overwrite"], part, poll=0.01, python=AUTO_AT_ONCE
    )
    with h5py.File(part, "r") as f:
        assert f.attrs[REPLACES] and f.attrs["status"] == "running"
    # a new run over it is refused naming the unfinished run and how to continue it, not the complete file alone
    capsys.readouterr()
    assert main(["hf", str(scene_file), "-o", str(out), *opts]) == 2
    err = capsys.readouterr().err
    assert f"{part.name} beside it" in err and f"--resume {out}" in err and "replace both" in err, err
    # one that cannot be read back (empty or damaged) has nothing to continue: only --overwrite goes on
    saved = part.read_bytes()
    part.write_bytes(b"")
    assert main(["hf", str(scene_file), "-o", str(out), *opts]) == 2
    err = capsys.readouterr().err
    assert "cannot be read back" in err and "--resume" not in err and "pass --overwrite to replace both" in err, err
    part.write_bytes(saved)
    # beside an output an interrupt left unfinished, the message is the unfinished run's too (--resume continues it)
    kept = out.read_bytes()
    with h5py.File(out, "r+") as f:
        f.attrs["status"] = "interrupted by the user"
    assert main(["hf", str(scene_file), "-o", str(out), *opts]) == 2
    err = capsys.readouterr().err
    assert f"{part.name} beside it" in err and "replace both" in err and "(an interrupted run)" not in err, err
    out.write_bytes(kept)
    assert main(["hf", "--resume", str(out), "--no-progress"]) == 0
    assert not part.exists()
    assert_same_file(out, ref)
    with h5py.File(out, "r") as f:
        assert REPLACES not in f.attrs


@pytest.mark.parametrize(
    ("integrator", "extra", "dt", "engine"),
    [
        ("adaptive", "", None, "general"),
        ("adaptive", "", None, "onchip"),
        ("symplectic-euler", GROWTH, 5e-9, "general"),
        ("strang", GROWTH, 1e-8, "onchip"),
        ("controlled", GROWTH, None, "general"),
        ("auto", "", None, "general"),
    ],
    ids=["adaptive", "onchip-adaptive", "growth", "onchip-growth", "controlled-growth", "auto"],
)
def test_interrupted_run_resumes_bit_identical(integrator, extra, dt, engine, tmp_path, monkeypatch) -> None:
    """Ctrl-C after the second checkpoint (the file is moved to RUN.h5, incomplete, checkpoint kept): `--resume
    RUN.h5` finishes it equal to an uninterrupted run, for the adaptive controller (clock, step counters), for
    patch growth (areas, normal forces, k_ij and the diagonal rewritten on the device), and on the on-chip engine
    (its staggered state and in-kernel growth between launches; its adaptive kernel's clocks and stages); for the
    error-controlled split step (its step history and the spring forces of its last two steps) and auto."""
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE + extra)
    opts = ["--integrator", integrator, "--no-progress", "--duration", "1e-5", "--record-patches", "velocity"]
    opts += ["--engine", engine] + ([] if dt is None else ["--dt", str(dt)])
    ref = tmp_path / "ref.h5"
    assert main(["hf", str(scene), "-o", str(ref), *opts]) == 0

    out = tmp_path / "run.h5"
    with interrupted_at_second_checkpoint(monkeypatch):
        assert main(["hf", str(scene), "-o", str(out), *opts, "--checkpoint-interval", "2e-6"]) == 130
    with h5py.File(out, "r") as f:
        assert not f.attrs["complete"] and "interrupted" in f.attrs["status"]
        assert has_checkpoint(f) and 4e-6 <= f["checkpoint"].attrs["sim_time"] < 1e-5
    assert main(["hf", "--resume", str(out), "--no-progress"]) == 0
    assert_same_file(out, ref)


def test_a_default_run_resumes_after_ctrl_c(scene_file: Path, tmp_path: Path, monkeypatch, capsys) -> None:
    """Without checkpoint options a run checkpoints automatically (here: AUTO_WALL_S = 0, from the first chunk on);
    Ctrl-C names the checkpoint and the command that continues the run, which then equals an uninterrupted run.
    A run stopped before its first checkpoint (the default 5 s of wall time not reached) says so and resumes
    from its start; --no-checkpoint (or --checkpoint-interval 0) writes none."""
    # the general engine, whose chunks end every 2 µs (on the CPU the on-chip engine's first launch is the whole run)
    opts = ["--no-progress", "--duration", "5e-5", "--record-patches", "velocity", "--engine", "general"]
    ref = tmp_path / "ref.h5"
    assert main(["hf", str(scene_file), "-o", str(ref), *opts, "--checkpoint-interval", "0"]) == 0
    real, written = runner.run_hf, []

    def interrupted(*args, on_checkpoint=None, sink=None, **kw):
        def ckpt(c):
            on_checkpoint(c)
            written.append(c.sim_time)
            if len(written) == 1:
                raise KeyboardInterrupt

        def chunk(c):
            sink(c)
            if stop_at_first_chunk:
                raise KeyboardInterrupt

        return real(*args, on_checkpoint=ckpt, sink=chunk, **kw)

    monkeypatch.setattr(runner, "run_hf", interrupted)
    monkeypatch.setattr(checkpoint, "AUTO_WALL_S", 0.0)
    for stop_at_first_chunk, flags, said, resumed in (
        (False, [], "continue it from its checkpoint at t = ", ": resumed from its checkpoint at t = "),
        (True, [], "continue it from t = 0 with 'aca-warp hf --resume", ": resumed again from t = 0 (it held no"),
    ):
        out = tmp_path / f"run{len(flags)}{stop_at_first_chunk}.h5"
        capsys.readouterr()
        assert main(["hf", str(scene_file), "-o", str(out), *opts, *flags]) == 130
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and said in err[0] and f"'aca-warp hf --resume {out}'" in err[0], err
        monkeypatch.setattr(runner, "run_hf", real)
        assert main(["hf", str(scene_file), "-o", str(out), *opts]) == 2  # the same command again: how to continue
        err = capsys.readouterr().err
        assert f"{out} exists (an interrupted run): " in err and f"'aca-warp hf --resume {out}'" in err, err
        assert main(["hf", "--resume", str(out), "--no-progress"]) == 0
        said_out = capsys.readouterr().out  # the summary says where the resume started, and the whole run's μ
        assert resumed in said_out and ", mean mu 0." in said_out, said_out
        assert_same_file(out, ref)
        monkeypatch.setattr(runner, "run_hf", interrupted)
    written.clear()
    monkeypatch.setattr(runner, "run_hf", real)
    for flags in (["--no-checkpoint"], ["--checkpoint-interval", "0"]):
        monkeypatch.setattr(RunWriter, "checkpoint", lambda self, c: written.append(c))
        assert main(["hf", str(scene_file), "-o", str(tmp_path / "off.h5"), *opts, *flags, "--overwrite"]) == 0
    assert written == []


def test_resume_refusals(scene_file: Path, tmp_path: Path, capsys) -> None:
    """Nothing to resume, a complete run, a run without checkpoints, options that would change the run: exit 2,
    one line each, and the files are left as they were."""
    done = tmp_path / "done.h5"
    assert main(["hf", str(scene_file), "-o", str(done), "--no-progress", "--duration", "1e-6"]) == 0
    capsys.readouterr()
    before = done.read_bytes()
    cases = [
        (["hf", "--resume", str(tmp_path / "none.h5")], "nothing to resume"),
        (["hf", "--resume", str(done)], "is a complete HF run; nothing to resume"),
        (["hf", "--resume", str(done), "--dt", "1e-9"], "drop --dt"),
        (["hf", "--resume", str(done), "-o", str(tmp_path / "x.h5")], "drop -o"),
        (["hf", str(scene_file)], "needs SCENE and -o"),
    ]
    assert_refused(capsys, cases)
    assert done.read_bytes() == before
    # an incomplete run without checkpoints
    part = tmp_path / "bare.h5.partial"
    with h5py.File(part, "w") as f:
        f.attrs["complete"] = False
    assert main(["hf", "--resume", str(part)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "lacks the attribute 'scene'" in err[0]
    assert part.exists()


def test_closed_on_failure_closes_and_names_the_file(tmp_path: Path) -> None:
    """The resume guard of both run files: a malformed file (KeyError, …, and h5py's RuntimeError) becomes a
    SceneError naming it, anything else passes through; the file is closed either way, and stays open when the body
    succeeds."""
    from aca_warp.common.checkpoint import closed_on_failure
    from aca_warp.common.errors import SceneError

    path = tmp_path / "x.h5.partial"
    for exc, check, expect in (
        (KeyError("global"), True, SceneError),
        (KeyError("global"), False, KeyError),
        (RuntimeError("Unable to read (bad heap)"), True, SceneError),
        (ZeroDivisionError("boom"), True, ZeroDivisionError),
    ):
        f = h5py.File(path, "w")
        with pytest.raises(expect) as info, closed_on_failure(f, path, scene_error=check):
            raise exc
        assert not f.id.valid
        if expect is SceneError:
            assert str(path) in str(info.value) and "do not match its checkpoint" in str(info.value)
    f = h5py.File(path, "w")
    with closed_on_failure(f, path):
        pass
    assert f.id.valid
    f.close()


def test_analysis_of_a_stopped_run_is_dropped_by_its_resume(tmp_path, monkeypatch) -> None:
    """`analyze` of a stopped run records the samples and time range it describes (/analysis `samples`,
    `time_range`); resuming the run drops that /analysis (before: it survived and described 0.58 of 2 ms of the
    finished file); a stored analysis that does not fit the file's samples is not used by the figures."""
    from procs import small_scene_toml

    from aca_warp.analysis import report
    from aca_warp.hf import runner

    (tmp_path / "s.toml").write_text(small_scene_toml("stale", count=10, duration=4.0e-6, sample_dt=1.0e-7))
    out = tmp_path / "run.h5"
    real = runner.run_hf

    def stop_at_second(*args, on_checkpoint=None, **kw):
        seen = []

        def ckpt(c):
            on_checkpoint(c)
            seen.append(c)
            if len(seen) == 2:
                raise KeyboardInterrupt

        return real(*args, on_checkpoint=ckpt, **kw)

    monkeypatch.setattr(runner, "run_hf", stop_at_second)
    argv = ["hf", str(tmp_path / "s.toml"), "-o", str(out), "--no-progress", "--checkpoint-interval", "1e-6"]
    assert main(argv) == 130
    monkeypatch.undo()
    report.analyze_run(out, sync=False)
    with h5py.File(out, "r") as f:
        n, t = f["global/time"].shape[0], f["global/time"][()]
        a = f["analysis"].attrs
        assert a["samples"] == n < 41 and list(a["time_range"]) == [t[0], t[-1]] and not a["run_complete"]
        assert report.stored(f, "spectra")
    with h5py.File(out, "r+") as f:
        f["analysis"].attrs["samples"] = n + 1  # as an analysis of other samples
    with h5py.File(out, "r") as f:
        assert not report.stored(f, "spectra")
    assert main(["hf", "--resume", str(out), "--no-progress"]) == 0
    with h5py.File(out, "r") as f:
        assert f.attrs["complete"] and f["global/time"].shape == (41,) and "analysis" not in f


def test_a_window_begun_after_the_resume_keeps_the_run_s_chunks(tmp_path, monkeypatch) -> None:
    """Per-patch histories whose window begins after the checkpoint are made by the resumed run: chunks as long as
    the run's rows, as an uninterrupted run makes them (before: full 4096/1024-row chunks, the file 3× as large)."""
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE)
    opts = ["--no-progress", "--duration", "2e-5", "--record-patches", "velocity", "--patch-window", "1.5e-5", "2e-5"]
    opts += ["--checkpoint-interval", "2e-6"]
    ref = tmp_path / "ref.h5"
    assert main(["hf", str(scene), "-o", str(ref), *opts]) == 0
    out = tmp_path / "run.h5"
    with interrupted_at_second_checkpoint(monkeypatch):
        assert main(["hf", str(scene), "-o", str(out), *opts]) == 130
    with h5py.File(out, "r") as f:
        assert "velocity" not in f["patches"]  # the window had not begun
    assert main(["hf", "--resume", str(out), "--no-progress"]) == 0
    assert_same_file(out, ref)
    with h5py.File(out, "r") as f, h5py.File(ref, "r") as g:
        for name in ("global/mu", "patches/time", "patches/velocity"):
            assert f[name].chunks == g[name].chunks and f[name].chunks[0] <= f[name].shape[0], name
    assert out.stat().st_size < 1.2 * ref.stat().st_size
