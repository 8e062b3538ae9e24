"""Checkpoint, resume and rerun of LF runs: a run killed with SIGKILL (or stopped by Ctrl-C) and resumed from its last
checkpoint ends in a file whose every dataset, /snapshots included, equals an uninterrupted run's bit for bit (CPU).

The scene is test_lf.py's tiny pad (~150 cells, births, deaths and merges within a few dozen steps), with the
schedule set in the TOML written to tmp_path.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import pytest
from procs import assert_refused, assert_same_run_file, datasets, small_lf_scene_toml, three_applications
from sigkill import AUTO_AT_ONCE, kill_after_first_checkpoint

from aca_warp.cli import main
from aca_warp.common.checkpoint import has_checkpoint
from aca_warp.lf import io as lf_io


def lf_scene(first: float) -> str:
    """The tiny pad with snapshots at every application and at 0.3 s and 0.75 s (those within its schedule of
    ``first`` + 0.5 s), first applied for ``first`` [s]."""
    lf = {"wear_m": 2e-12, "p_remob": 0.0, "p_store": 0.3, "p_birth": 1.0, "p_comp": 1e4, "k_shrink": 2e-14}
    lf |= {"p_cap": 0.8, "lam0": 2.0, "T_c": 293.15, "compact_every": 25}
    snapshots = {"applications": True, "times": [t for t in (0.3, 0.75) if t <= first + 0.5]}
    return small_lf_scene_toml("lfckpt", three_applications(first), lf=lf, snapshots=snapshots)


def assert_same_lf_file(a: Path, b: Path) -> None:
    """Same dataset names, shapes, dtypes and bits, same snapshot attributes; both complete, no checkpoint."""
    assert_same_run_file(a, b, ("steps", "scene", "kind"))
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        assert any(k.startswith("snapshots/") for k in datasets(a)) and "global/mu" in fa
        for name in fa["snapshots"]:
            assert dict(fa["snapshots"][name].attrs) == dict(fb["snapshots"][name].attrs), name


def scene_file(tmp_path: Path, first: float) -> Path:
    p = tmp_path / "lfckpt.toml"
    p.write_text(lf_scene(first))
    return p


def test_sigkill_then_resume_is_bit_identical(tmp_path: Path) -> None:
    """`aca-warp lf` with its default, automatic checkpoints (here from the first step on) in a subprocess, killed
    with SIGKILL once the first checkpoint is in the .partial: only LF.h5.partial is left, a new run refuses to
    clobber it, `lf --resume LF.h5.partial` finishes it, and the file equals an uninterrupted run (no checkpoints)
    dataset for dataset, bit for bit."""
    scene = scene_file(tmp_path, 12.0)  # 1250 steps, ~1 s of stepping
    ref = tmp_path / "ref.h5"
    assert main(["lf", str(scene), "-o", str(ref), "--no-progress", "--no-checkpoint"]) == 0

    out = tmp_path / "run.h5"
    part = tmp_path / "run.h5.partial"
    kill_after_first_checkpoint(
        ["lf", str(scene), "-o", str(out), "--no-progress"], part, poll=0.005, python=AUTO_AT_ONCE
    )
    assert part.exists() and not out.exists()  # never a half-written final file
    with h5py.File(part, "r") as f:
        assert not f.attrs["complete"] and f.attrs["status"] == "running"
        at = float(f["checkpoint"].attrs["sim_time"])
        slot = f["checkpoint"][f"slot{f['checkpoint'].attrs['active']}"]
        rows = int(slot["rows/global"][()])
        assert f["global/mu"].shape[0] >= rows == round(at / 0.01)  # every row up to the checkpoint is on disk
        assert "arrays/glob" in slot and "arrays/alive" in slot and "arrays/cand_index" in slot
    assert 0 < at < 12.5
    assert main(["lf", str(scene), "-o", str(out), "--no-progress"]) == 2  # the unfinished run is not clobbered

    assert main(["lf", "--resume", str(part), "--no-progress"]) == 0
    assert out.exists() and not part.exists()
    assert_same_lf_file(out, ref)


def test_interrupted_run_resumes_and_reruns_bit_identical(tmp_path: Path, monkeypatch, capsys) -> None:
    """Ctrl-C right after the snapshot t0.75s, which follows the checkpoint at 0.6 s: the file is closed as
    LF.h5 (incomplete, rows and calibration beyond the checkpoint, checkpoint kept); `lf --resume LF.h5` cuts it
    back, drops the later snapshot, takes it again and ends equal to an uninterrupted run. `aca-warp rerun` of
    the finished file gives the same bits again (scene, initial patches and duration come from the file)."""
    scene = scene_file(tmp_path, 0.8)  # 130 steps
    ref = tmp_path / "ref.h5"
    assert main(["lf", str(scene), "-o", str(ref), "--no-progress", "--seed", "7"]) == 0

    real = lf_io.LFRunWriter.snapshot

    def interrupted(self, name, sim):
        real(self, name, sim)
        if name == "t0.75s":
            raise KeyboardInterrupt

    monkeypatch.setattr(lf_io.LFRunWriter, "snapshot", interrupted)
    out = tmp_path / "run.h5"
    argv = ["lf", str(scene), "-o", str(out), "--no-progress", "--seed", "7", "--checkpoint-interval", "0.2"]
    assert main(argv) == 130
    monkeypatch.setattr(lf_io.LFRunWriter, "snapshot", real)
    with h5py.File(out, "r") as f:
        assert not f.attrs["complete"] and "interrupted" in f.attrs["status"]
        assert has_checkpoint(f) and f["checkpoint"].attrs["sim_time"] == pytest.approx(0.6)
        assert f["global/mu"].shape == (75,) and "t0.75s" in f["snapshots"] and "calibration" in f
    assert main(["lf", "--resume", str(out), "--no-progress"]) == 0
    assert ": resumed from its checkpoint at t = 0.6 s, " in capsys.readouterr().out
    assert_same_lf_file(out, ref)

    again = tmp_path / "rerun.h5"
    assert main(["rerun", str(ref), "-o", str(again), "--no-progress"]) == 0
    assert_same_lf_file(again, ref)


def test_lf_output_and_resume_refusals(tmp_path: Path, capsys) -> None:
    """Existing output without --overwrite, an unfinished .partial, --resume with options, a complete run: exit 2
    with one line each, files untouched; a stopped run without a checkpoint resumes from its start; --overwrite
    replaces."""
    scene = scene_file(tmp_path, 0.1)
    done = tmp_path / "done.h5"
    assert main(["lf", str(scene), "-o", str(done), "--no-progress"]) == 0
    capsys.readouterr()
    before = done.read_bytes()
    (tmp_path / "half.h5.partial").write_bytes(b"")
    hf_done = tmp_path / "hf_done.h5"  # a complete HF run file, as find_resumable reads one
    with h5py.File(hf_done, "w") as f:
        f.attrs["complete"] = True
    cases = [
        (["lf", str(scene), "-o", str(done)], "pass --overwrite"),
        (["lf", str(scene), "-o", str(tmp_path / "half.h5")], "empty or damaged); pass --overwrite"),
        (["lf", "--resume", str(done)], "is a complete LF run; nothing to resume"),
        (["lf", "--resume", str(hf_done)], "is a complete HF run; nothing to resume"),
        (["lf", "--resume", str(done), "--seed", "3"], "drop --seed"),
        (["lf", "--resume", str(tmp_path / "none.h5")], "nothing to resume"),
        (["lf", str(scene)], "needs SCENE and -o"),
    ]
    assert_refused(capsys, cases)
    assert done.read_bytes() == before
    from aca_warp.common.errors import SceneError
    from aca_warp.lf.commands import run_lf
    from aca_warp.lf.scene import load_lf_scene

    with pytest.raises(SceneError, match="checkpoint interval"):
        run_lf(load_lf_scene(scene), tmp_path / "x.h5", checkpoint_interval=float("nan"))
    assert not (tmp_path / "x.h5").exists() and not (tmp_path / "x.h5.partial").exists()
    # a stopped run without a checkpoint resumes from its start, snapshots and all
    same = tmp_path / "same.h5"
    same.write_bytes(before)
    with h5py.File(done, "r+") as f:
        f.attrs["complete"] = False
    assert main(["lf", "--resume", str(done), "--no-progress"]) == 0
    assert_same_lf_file(done, same)
    assert main(["lf", str(scene), "-o", str(done), "--no-progress", "--overwrite"]) == 0
    with h5py.File(done, "r") as f:
        assert f.attrs["complete"]


def test_a_duration_past_the_schedule_is_noted(tmp_path: Path, capsys) -> None:
    """--duration beyond the end of the scene's schedule runs (the pad unloaded, the disc at rest) with one note
    naming how far past the schedule it goes."""
    scene = scene_file(tmp_path, 0.1)  # schedule 0.6 s
    out = tmp_path / "long.h5"
    assert main(["lf", str(scene), "-o", str(out), "--no-progress", "--duration", "0.7"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("aca-warp: note: the run's 0.7 s go 0.1 s past the end"), err
    with h5py.File(out, "r") as f:
        assert f["global/time"].shape == (70,) and f.attrs["complete"]


def test_a_duration_rounded_to_whole_steps_is_noted_and_a_refused_one_is_not(tmp_path: Path, capsys) -> None:
    """A --duration that whole LF steps round (to the nearest step): one note saying what is run; a duration refused
    for its length: the error alone, without a note about the schedule before it."""
    scene = scene_file(tmp_path, 0.1)
    assert main(["lf", str(scene), "-o", str(tmp_path / "a.h5"), "--no-progress", "--duration", "0.015"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0] == "aca-warp: note: 0.015 s is run as 2 whole LF steps of 0.01 s: 0.02 s", err
    assert all(line.startswith("aca-warp: note: ") for line in err), err  # the scene's later snapshots: noted too
    assert main(["lf", str(scene), "-o", str(tmp_path / "b.h5"), "--no-progress", "--duration", "1e6"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "more than" in err[0] and not (tmp_path / "b.h5").exists(), err


def test_a_checkpoint_interval_below_a_step_is_noted(tmp_path: Path, capsys) -> None:
    """A checkpoint interval shorter than an LF step: one note on stderr (a checkpoint follows every step), the run
    as asked; none at the automatic interval."""
    scene = scene_file(tmp_path, 0.1)
    for extra, noted in ((["--checkpoint-interval", "1e-3"], True), ([], False)):
        out = tmp_path / f"run{len(extra)}.h5"
        assert main(["lf", str(scene), "-o", str(out), "--no-progress", "--duration", "0.05", *extra]) == 0
        err = capsys.readouterr().err
        note = "note: a checkpoint interval of 0.001 s is shorter than an LF step (0.01 s): a checkpoint follows every"
        assert (note in err) == noted, err
