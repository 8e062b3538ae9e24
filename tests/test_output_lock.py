"""One writer per output: a second run, an ``--overwrite``, a ``--resume`` or a second sweep is refused with one line
while a live process writes the same output (real processes; the first one is held with SIGSTOP so the timing does
not matter), whatever HDF5_USE_FILE_LOCKING says; and a run file is readable from the moment it exists."""

from __future__ import annotations

import json
import os
import signal
import sys
from pathlib import Path

import h5py
import pytest
from procs import cli, error_lines, resume, small_lf_scene_toml, small_scene_toml, started, stop, wait_for

from aca_warp.cli import main
from aca_warp.common.errors import SceneError
from aca_warp.common.files import OutputLock, lock_path

SCENE = small_scene_toml("lock", count=40, duration=2.0e-4, sample_dt=1.0e-6)

LF_SCENE = small_lf_scene_toml("lflock", [{"kind": "application", "duration": 0.3, "normal_force": 300.0}])


def test_lock_in_process(tmp_path: Path) -> None:
    """A held lock refuses a second holder (even in the same process) and names the holder; release removes the
    lock file; a lock file left by a dead process (no flock on it) is simply taken over."""
    out = tmp_path / "run.h5"
    a = OutputLock.acquire(out)
    assert lock_path(out).is_file() and str(__import__("os").getpid()) in lock_path(out).read_text()
    with pytest.raises(SceneError, match=r"is being written by pid \d+ on") as e:
        OutputLock.acquire(out, what="wait")
    assert " ".join(sys.argv)[:200] in str(e.value)  # the holder's whole command line, its output named in it
    a.release()
    a.release()  # idempotent
    assert not lock_path(out).exists()
    lock_path(out).write_text("999999 elsewhere aca-warp hf\n")  # as a killed process leaves it
    b = OutputLock.acquire(out)
    assert b.held and "999999" not in lock_path(out).read_text()
    b.release()
    with pytest.raises(SceneError, match="does not exist"):
        OutputLock.acquire(tmp_path / "missing" / "run.h5")


def refused(capsys: pytest.CaptureFixture, argv: list[str], pid: int) -> None:
    """``aca-warp ARGV`` in this process: exit 2 and one line naming the holder ``pid``."""
    capsys.readouterr()
    code = main(argv)
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1, (argv, lines)
    assert f"is being written by pid {pid}" in lines[0], lines


def test_live_hf_run_is_not_replaced_or_resumed(tmp_path, capsys, monkeypatch) -> None:
    """While `hf` runs (held with SIGSTOP), a second `hf --overwrite` on the same output, an `hf` without it and an
    `hf --resume` are refused with one line naming the holder, with HDF5's own locking on and off (both against the
    same live run); nothing of the live `.partial` changes; the first run then finishes into a complete, readable
    file."""
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE)
    out = tmp_path / "run.h5"
    part = tmp_path / "run.h5.partial"
    args = ["hf", str(scene), "-o", str(out), "--no-progress", "--checkpoint-interval", "5e-5"]
    with started(args) as first:
        wait_for(part, first)
        stop(first)
        before = part.read_bytes()
        for locking in ("TRUE", "FALSE"):
            monkeypatch.setenv("HDF5_USE_FILE_LOCKING", locking)
            for argv in (
                ["hf", str(scene), "-o", str(out), "--overwrite", "--no-progress"],
                ["hf", str(scene), "-o", str(out), "--no-progress"],
                ["hf", "--resume", str(out), "--no-progress"],
                ["analyze", str(part)],
            ):
                refused(capsys, argv, first.pid)
            r = cli(["hf", "--resume", str(out), "--no-progress"], HDF5_USE_FILE_LOCKING=locking)  # a process too
            assert r.returncode == 2 and f"pid {first.pid}" in error_lines(r.stderr)[0], (locking, r.stderr)
            assert part.read_bytes() == before and not out.exists()
        resume(first)
        assert first.wait(timeout=120) == 0, first.stderr.read()
    with h5py.File(out, "r") as f:
        assert f.attrs["complete"] and f["global/mu"].shape == (201,)
    assert not part.exists() and not lock_path(out).exists()


def test_a_lock_that_cannot_note_its_holder_is_not_left(tmp_path: Path, monkeypatch) -> None:
    """A device that takes the lock file but not its holder's note (full): exit-4 error, no lock file left and no lock
    held, so the same process takes the output once there is room."""
    import errno

    from aca_warp.common import files
    from aca_warp.common.errors import StorageError

    out = tmp_path / "run.h5"
    real = os.write

    def full(fd: int, data: bytes) -> int:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(files.os, "write", full)
    with pytest.raises(StorageError, match="no space left"):
        OutputLock.acquire(out)
    monkeypatch.setattr(files.os, "write", real)
    assert not lock_path(out).exists()
    OutputLock.acquire(out).release()


def test_aliases_of_a_live_run_are_refused(tmp_path, capsys, monkeypatch) -> None:
    """One writer per file, not per name: while `hf` runs (held with SIGSTOP), `hf --resume` and `analyze` through a
    symbolic link or a hard link of its live `.partial`, or of the `.partial` moved to another name, are refused with
    one line naming the holder, with HDF5's own locking on and off (both against the same live run); the live file is
    unchanged and the run completes."""
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE)
    out = tmp_path / "run.h5"
    part = tmp_path / "run.h5.partial"
    with started(["hf", str(scene), "-o", str(out), "--no-progress", "--checkpoint-interval", "5e-5"]) as first:
        wait_for(part, first)
        stop(first)
        before = part.read_bytes()
        for locking in ("TRUE", "FALSE"):
            monkeypatch.setenv("HDF5_USE_FILE_LOCKING", locking)
            (tmp_path / "sym.h5.partial").symlink_to(part)
            os.link(part, tmp_path / "hard.h5.partial")
            for alias in ("sym.h5", "hard.h5"):
                refused(capsys, ["hf", "--resume", str(tmp_path / alias), "--no-progress"], first.pid)
                refused(capsys, ["analyze", str(tmp_path / f"{alias}.partial")], first.pid)
            for argv in (["hf", "--resume", str(tmp_path / "hard.h5")], ["analyze", str(tmp_path / "sym.h5.partial")]):
                r = cli(argv, HDF5_USE_FILE_LOCKING=locking)  # a process: HDF5 reads the variable when it starts
                assert r.returncode == 2 and f"pid {first.pid}" in error_lines(r.stderr)[0], (locking, r.stderr)
            (tmp_path / "sym.h5.partial").unlink()
            (tmp_path / "hard.h5.partial").unlink()
            os.replace(part, tmp_path / "moved.h5.partial")
            refused(capsys, ["hf", "--resume", str(tmp_path / "moved.h5"), "--no-progress"], first.pid)
            os.replace(tmp_path / "moved.h5.partial", part)
            assert part.read_bytes() == before and not out.exists()
        resume(first)
        assert first.wait(timeout=120) == 0, first.stderr.read()
    with h5py.File(out, "r") as f:
        assert f.attrs["complete"] and f["global/mu"].shape == (201,)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5", "s.toml"]


def test_live_lf_run_and_sweep_are_not_replaced(tmp_path: Path, capsys) -> None:
    """The same for `lf` (`--overwrite` and `lf --resume` refused while it runs) and for a second `sweep` into the
    folder of a running one (with and without `--overwrite`)."""
    scene = tmp_path / "lf.toml"
    scene.write_text(LF_SCENE)
    out = tmp_path / "lf.h5"
    lf = ["lf", str(scene), "-o", str(out), "--no-progress", "--checkpoint-interval", "0.05"]
    spec = tmp_path / "spec.toml"
    spec.write_text(
        '[sweep]\nbase = "hf1"\nshard_size = 1\n[run]\nduration = 2e-5\nprecision = "fp32"\n'
        '[base.patches]\ncount = 25\n[parameters]\n"friction.M" = [0.6, 0.7, 0.8]\n'
    )
    sweep_dir = tmp_path / "sweep"
    with started(lf) as first:
        wait_for(out.with_name("lf.h5.partial"), first)
        stop(first)
        for argv in (["lf", str(scene), "-o", str(out), "--overwrite"], ["lf", "--resume", str(out)]):
            refused(capsys, argv, first.pid)
        resume(first)
        assert first.wait(timeout=120) == 0, first.stderr.read()
    with started(["sweep", str(spec), "-o", str(sweep_dir), "--workers", "0", "--quiet"]) as sweep:
        wait_for(sweep_dir / "manifest.json", sweep)
        stop(sweep)
        manifest = (sweep_dir / "manifest.json").read_text()
        for extra in ([], ["--overwrite"]):
            refused(capsys, ["sweep", str(spec), "-o", str(sweep_dir), "--workers", "0", "--quiet", *extra], sweep.pid)
        assert (sweep_dir / "manifest.json").read_text() == manifest
        resume(sweep)
        assert sweep.wait(timeout=120) == 0, sweep.stderr.read()
    with h5py.File(out, "r") as f:
        assert f.attrs["complete"]
    assert [s["state"] for s in json.loads((sweep_dir / "manifest.json").read_text())["shards"]] == ["done"] * 3


@pytest.mark.parametrize("command", ["hf", "lf"])
def test_kill_right_after_the_file_appears(tmp_path: Path, command: str) -> None:
    """SIGKILL within a millisecond of `RUN.h5.partial` appearing (three times): the file opens and reads
    `status = running` (it is created as `.partial.new` and renamed only once its header is on disk)."""
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE if command == "hf" else LF_SCENE)
    out = tmp_path / "run.h5"
    part = tmp_path / "run.h5.partial"
    for _ in range(3):
        with started([command, str(scene), "-o", str(out), "--no-progress", "--overwrite"]) as proc:
            wait_for(part, proc, poll=0.0)
            proc.send_signal(signal.SIGKILL)
            proc.wait(timeout=30)
        assert proc.returncode == -signal.SIGKILL
        with h5py.File(part, "r") as f:
            assert f.attrs["status"] == "running" and not f.attrs["complete"] and "global" in f
    assert lock_path(out).exists()  # left by the killed run, unlocked: each next run above took it over


def test_identity_lock_in_process(tmp_path: Path, monkeypatch) -> None:
    """The identity lock of a file lives in the user's private folder (0700): a second owner of the same file under
    another name (a hard link) is refused, naming the holder; release removes the lock file; lock files of dead
    writers are removed when another file is locked, a live one is kept."""
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path / "run"))
    (tmp_path / "run").mkdir(mode=0o700)
    data = tmp_path / "a.h5.partial"
    data.write_bytes(b"x")
    os.link(data, tmp_path / "b.h5.partial")
    a = OutputLock.acquire(tmp_path / "a.h5")
    a.own(data)
    folder = tmp_path / "run" / "aca-warp" / "files"
    assert oct(folder.stat().st_mode & 0o777) == "0o700" and len(list(folder.iterdir())) == 1
    b = OutputLock.acquire(tmp_path / "b.h5")
    with pytest.raises(SceneError, match=r"b.h5.partial is being written by pid \d+"):
        b.own(tmp_path / "b.h5.partial")
    b.release()
    (folder / "0-1.lock").write_text("999999 elsewhere aca-warp hf\n")  # as a killed writer leaves it
    other = tmp_path / "c.h5.partial"
    other.write_bytes(b"y")
    c = OutputLock.acquire(tmp_path / "c.h5")
    c.own(other)
    assert len(list(folder.iterdir())) == 2 and not (folder / "0-1.lock").exists()  # a's and c's
    a.release()
    c.release()
    assert list(folder.iterdir()) == []


def test_a_momentary_unnamed_holder_is_waited_for(tmp_path: Path) -> None:
    """A lock file locked for a moment by no named writer — a sweep of stale identity locks that caught a file
    another writer had just created, or a probe — delays the writer instead of refusing it (a sweep's shard failed
    that way now and then); a lock held by no named writer for longer than that is refused, one held by a named
    writer at once."""
    import fcntl
    import threading
    import time

    from aca_warp.common import files

    out = tmp_path / "run.h5"
    lp = lock_path(out)
    fd = os.open(lp, os.O_RDWR | os.O_CREAT, 0o600)  # created, not yet named: as a stale-lock sweep holds it
    fcntl.flock(fd, fcntl.LOCK_EX)

    def sweep_drops_it() -> None:
        time.sleep(0.05)
        os.unlink(lp)
        os.close(fd)

    t = threading.Thread(target=sweep_drops_it)
    t.start()
    a = OutputLock.acquire(out)
    t.join()
    assert a.held and str(os.getpid()) in lp.read_text()
    a.release()
    fd = os.open(lp, os.O_RDWR | os.O_CREAT, 0o600)  # held, unnamed, past the wait
    fcntl.flock(fd, fcntl.LOCK_EX)
    t0 = time.monotonic()
    with pytest.raises(SceneError, match="is being written by another process"):
        OutputLock.acquire(out)
    assert files.TRANSIENT_S <= time.monotonic() - t0 < files.TRANSIENT_S + 1.0
    os.close(fd)
    lp.unlink()
    b = OutputLock.acquire(out)
    t0 = time.monotonic()
    with pytest.raises(SceneError, match=r"is being written by pid \d+"):
        OutputLock.acquire(out)
    assert time.monotonic() - t0 < 0.1  # a named writer: no wait
    b.release()
