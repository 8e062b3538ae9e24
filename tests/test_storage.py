"""A full device or a file-size limit in the middle of a run: one line, exit 4, the `.partial` left as it was at its
last checkpoint, and once the limit is lifted `--resume` finishes the run bit-identical to an uninterrupted one.

The limit is RLIMIT_FSIZE in a subprocess (SIGXFSZ ignored, so writes past it fail with EFBIG), the same failure path
as ENOSPC on a full device (aca_warp/common/storage.py); docs/faults.md lists a tmpfs check of ENOSPC itself."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import pytest
from procs import HF_DT, HF_SCENE, assert_same_datasets, cli, error_lines, small_scene_toml

from aca_warp.cli import main
from aca_warp.common.storage import GuardedFile, storage_errno


def test_hf_file_size_limit_then_resume(tmp_path: Path, references: dict[str, Path]) -> None:
    scene = tmp_path / "s.toml"
    scene.write_text(HF_SCENE)
    ref = references["hf"]
    out = tmp_path / "run.h5"
    r = cli(
        ["hf", str(scene), "-o", str(out), "--no-progress", *HF_DT, "--checkpoint-interval", "1e-4"], limit=1_300_000
    )
    lines = error_lines(r.stderr)
    assert r.returncode == 4 and len(lines) == 1, r.stderr
    assert "file size limit reached while writing" in lines[0] and "checkpoint at t = 0.0005 s" in lines[0]
    part = tmp_path / "run.h5.partial"
    assert part.exists() and not out.exists()
    with h5py.File(part, "r") as f:  # as it was at its last checkpoint, still readable
        assert f.attrs["status"] == "running" and float(f["checkpoint"].attrs["sim_time"]) == pytest.approx(5e-4)
    assert main(["hf", "--resume", str(out), "--no-progress"]) == 0
    assert_same_datasets(out, ref)
    with h5py.File(out, "r") as f:
        assert f.attrs["complete"] and "checkpoint" not in f
    # a limit below the first chunk: nothing to resume, one line; the next run (without the limit) replaces it
    r = cli(["hf", str(scene), "-o", str(tmp_path / "b.h5"), "--no-progress", *HF_DT], limit=200_000)
    lines = error_lines(r.stderr)
    assert r.returncode == 4 and len(lines) == 1 and "no checkpoint" in lines[0], r.stderr


def test_advice_after_a_file_size_stop_is_one_and_true(tmp_path: Path, references: dict[str, Path], capsys) -> None:
    """A checkpointed run stopped by a file-size limit before its first checkpoint: the stop and a new run onto the
    same name give the same advice, that the run stopped before its first checkpoint and that `--resume` starts it
    again from t = 0 (before: `--resume` said it ran without checkpoint_interval, and the suggested rerun pointed
    back to `--resume`); following it finishes the run, equal to an uninterrupted one. Only the limited run needs a
    process of its own; the refusal and the resume run in this one."""
    scene = tmp_path / "s.toml"
    scene.write_text(HF_SCENE)
    out = tmp_path / "run.h5"
    args = ["hf", str(scene), "-o", str(out), "--no-progress", *HF_DT]
    r = cli([*args, "--checkpoint-interval", "1e-4"], limit=200_000)
    assert r.returncode == 4, r.stderr
    advice = f"continue it from t = 0 with 'aca-warp hf --resume {out}' (it holds no checkpoint: it stopped before "
    advice += "its first one)"
    assert error_lines(r.stderr)[0].endswith("make room, then " + advice), r.stderr
    capsys.readouterr()
    assert main(args) == 2
    err = error_lines(capsys.readouterr().err)
    assert len(err) == 1 and advice in err[0], err
    assert main(["hf", "--resume", str(out), "--no-progress"]) == 0
    assert_same_datasets(out, references["hf"])


def test_lf_file_size_limit_then_resume(tmp_path: Path, references: dict[str, Path]) -> None:
    scene = references["lf_scene"]
    ref = references["lf"]
    out = tmp_path / "run.h5"
    r = cli(["lf", str(scene), "-o", str(out), "--no-progress", "--checkpoint-interval", "0.1"], limit=400_000)
    lines = error_lines(r.stderr)
    assert r.returncode == 4 and len(lines) == 1 and "continue it from its checkpoint" in lines[0], r.stderr
    assert main(["lf", "--resume", str(out), "--no-progress"]) == 0
    assert_same_datasets(out, ref)


def test_sweep_file_size_limit_then_rerun(tmp_path: Path) -> None:
    """A sweep whose shard hits the limit stops with one line (exit 4, the shard `failed` in the manifest); the same
    sweep without the limit reruns that shard and finishes."""
    spec = tmp_path / "spec.toml"
    spec.write_text(
        '[sweep]\nbase = "hf1"\nshard_size = 2\n[run]\nduration = 4e-4\nprecision = "fp32"\n'
        '[base.patches]\ncount = 25\n[base.record]\nsample_dt = 1e-7\n[parameters]\n"friction.M" = [0.6, 0.7, 0.8]\n'
    )
    d = tmp_path / "sweep"
    args = ["sweep", str(spec), "-o", str(d), "--workers", "0", "--quiet"]
    r = cli(args, limit=120_000)
    lines = error_lines(r.stderr)
    assert r.returncode == 4 and len(lines) == 1 and "file size limit reached" in lines[0], r.stderr
    states = [s["state"] for s in json.loads((d / "manifest.json").read_text())["shards"]]
    assert "failed" in states
    assert main(args) == 0  # without the limit: in this process
    assert [s["state"] for s in json.loads((d / "manifest.json").read_text())["shards"]] == ["done", "done"]


def test_guarded_file_reserves_and_trims(tmp_path: Path) -> None:
    """The reservation makes the file longer than HDF5's end of file only until the next flush; a finished file
    ends where HDF5's end of file says (no padding); the storage errno is found in h5py's messages."""
    f = h5py.File(tmp_path / "g.h5", "w")
    g = GuardedFile(f, tmp_path / "g.h5")
    d = f.create_dataset("x", shape=(0, 40), maxshape=(None, 40), chunks=(1024, 40), dtype="f8")
    g.touch(d, 0, 10)
    assert g.pending == 1024 * 40 * 8  # one chunk begun
    g.reserve()
    assert (tmp_path / "g.h5").stat().st_size >= f.id.get_filesize() + 1024 * 40 * 8
    d.resize(10, axis=0)
    d[:] = 1.0
    g.flush()
    assert (tmp_path / "g.h5").stat().st_size == f.id.get_filesize() and g.pending == 0
    g.touch(d, 10, 20)
    assert g.pending == 0  # the chunk exists already
    g.close()
    with h5py.File(tmp_path / "g.h5", "r") as r:
        assert r["x"].shape == (10, 40)
    assert storage_errno(RuntimeError("file write failed: errno = 28, error message = 'No space'")) == 28
    assert storage_errno(OSError(27, "File too large")) == 27
    assert storage_errno(RuntimeError("errno = 2")) is None


def test_free_space_check_asks_for_the_file_as_it_will_be(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The free-space check asks for the file on disk, chunks allocated whole, no chunk longer than the run's rows
    (a 1000-patch history of 201 samples in fp32, strang's default: its samples 0.82 MB, the file 0.93 MB; with
    1024-sample chunks it had been 4.6 MB), never less than the file (scripts/file_size.py): a folder with room for
    the samples but not for the file is refused, exit 4, nothing written (before: accepted, and the run met a full
    device)."""
    import os
    import types

    from scriptload import load_script

    from aca_warp.common.errors import StorageError
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.runner import plan_run, run_scene
    from aca_warp.scene import load_scene

    sizes = load_script("file_size")
    monkeypatch.setattr(sizes, "CASES", {k: v for k, v in sizes.CASES.items() if "1000" in k or "window" in k})
    for r in sizes.measure(tmp_path):
        assert r["file"] <= r["estimate"] <= 1.15 * r["file"] + 64 * 1024, r
    assert r["recorded"] < r["file"] < 1.2 * r["recorded"]  # the 1000-patch run: chunks no longer than its 201 rows
    (tmp_path / "s.toml").write_text(sizes.SCENE.format(**{"count": 1000, "sample_dt": 1e-6, "patches": ["velocity"],
                                                            "window": "", "duration": 2e-4}))  # fmt: skip
    scene = load_scene(tmp_path / "s.toml")
    plan = plan_run(scene, RunOptions())
    free = (plan.output_bytes + plan.file_bytes) // 2
    real = os.statvfs
    monkeypatch.setattr(
        "aca_warp.common.files.os.statvfs",
        lambda p: types.SimpleNamespace(f_bavail=free, f_frsize=1, f_blocks=1) if str(p) == str(tmp_path) else real(p),
    )
    with pytest.raises(StorageError, match=f"file will take about {plan.file_bytes / 1e6:.4g} MB"):
        run_scene(scene, tmp_path / "full.h5", RunOptions())
    assert not list(tmp_path.glob("full.h5*"))


def test_a_short_run_allocates_no_chunk_longer_than_its_rows(tmp_path: Path) -> None:
    """Eleven samples of 40 patches' velocities: every dataset's chunks as long as the run's rows (before, a whole
    4096-sample series chunk and a 1024-sample history row: a 10 µs run of hf1 left 7.7 MB), the file within the
    plan's estimate."""
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.runner import plan_run, run_scene
    from aca_warp.scene import load_scene

    (tmp_path / "s.toml").write_text(small_scene_toml("short", count=40, duration=1e-6, patches=("velocity",)))
    scene = load_scene(tmp_path / "s.toml")
    plan = plan_run(scene, RunOptions())
    run_scene(scene, tmp_path / "r.h5", RunOptions())
    with h5py.File(tmp_path / "r.h5") as f:
        assert f["global/mu"].chunks == (11,) and f["patches/time"].chunks == (11,)
        assert f["patches/velocity"].chunks == (11, 40) and f["patches/velocity"].shape == (11, 40)
    assert (tmp_path / "r.h5").stat().st_size <= plan.file_bytes < 200_000
