"""Links planted by another user where aca-warp creates its lock, temporary and figure files: every command refuses
with one line (exit 2) and the file the link points to is left untouched (aca_warp.common.links; docs/faults.md,
"Threat model"). And the GPU turn lock of sweeps lives in the user's private folder, not in /tmp."""

from __future__ import annotations

import os
import stat
import types
from pathlib import Path

import pytest
from procs import small_scene_toml
from test_output_lock import LF_SCENE

from aca_warp.cli import main
from aca_warp.common import links
from aca_warp.common.errors import SceneError
from aca_warp.common.files import OutputLock
from aca_warp.hf import runner

SCENE = small_scene_toml("links", count=20, duration=2.0e-6)
SPEC = (
    '[sweep]\nbase = "hf1"\nshard_size = 1\n[run]\nduration = 1e-6\nprecision = "fp32"\n'
    '[base.patches]\ncount = 20\n[parameters]\n"friction.M" = [0.6, 0.8]\n'
)


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A finished HF run (per-patch velocities) and one stopped (Ctrl-C) at its first checkpoint."""
    d = tmp_path_factory.mktemp("links")
    (d / "s.toml").write_text(small_scene_toml("links", count=20, duration=4.0e-6, patches=("velocity",)))
    out = {"run": d / "run.h5", "stopped": d / "stopped.h5", "scene": d / "s.toml"}
    assert main(["hf", str(d / "s.toml"), "-o", str(out["run"]), "--no-progress"]) == 0
    real = runner.run_hf

    def once(*args, on_checkpoint=None, **kw):
        def ckpt(c):
            on_checkpoint(c)
            raise KeyboardInterrupt

        return real(*args, on_checkpoint=ckpt, **kw)

    mp = pytest.MonkeyPatch()
    mp.setattr(runner, "run_hf", once)
    try:
        argv = ["hf", str(d / "s.toml"), "-o", str(out["stopped"]), "--no-progress", "--checkpoint-interval", "1e-6"]
        assert main(argv) == 130
    finally:
        mp.undo()
    return out


def plant(link: Path, victim: Path) -> tuple[bytes, int]:
    """A symbolic link ``link`` → ``victim`` (a file with content); returns the victim's bytes and mtime."""
    victim.write_bytes(b"precious data\n")
    link.parent.mkdir(parents=True, exist_ok=True)
    link.symlink_to(victim)
    return victim.read_bytes(), victim.stat().st_mtime_ns


def refused(capsys: pytest.CaptureFixture, argv: list[str]) -> str:
    capsys.readouterr()
    code = main(argv)
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code == 2 and len(err) == 1 and err[0].startswith("aca-warp: error:"), (argv, code, err)
    assert "symbolic link" in err[0] and "never writes through a link" in err[0], err
    return err[0]


def untouched(victim: Path, before: tuple[bytes, int], link: Path) -> None:
    assert (victim.read_bytes(), victim.stat().st_mtime_ns) == before
    assert link.is_symlink()  # left for the user to look at


def cases(made: dict[str, Path], d: Path) -> dict[str, tuple[Path, list[str]]]:
    """name -> (where the link is planted, the command that must refuse it)."""
    d.mkdir()
    (d / "s.toml").write_text(SCENE)
    (d / "lf.toml").write_text(LF_SCENE)
    (d / "spec.toml").write_text(SPEC)
    sweep = ["sweep", str(d / "spec.toml"), "-o", str(d / "sw"), "--workers", "0", "--quiet"]
    stopped = d / "stopped.h5"
    stopped.write_bytes(made["stopped"].read_bytes())
    run = d / "run.h5"
    run.write_bytes(made["run"].read_bytes())
    return {
        "hf lock": (d / "out.h5.lock", ["hf", str(d / "s.toml"), "-o", str(d / "out.h5"), "--no-progress"]),
        "hf new file": (d / "out.h5.partial.new", ["hf", str(d / "s.toml"), "-o", str(d / "out.h5"), "--no-progress"]),
        "lf lock": (d / "lf.h5.lock", ["lf", str(d / "lf.toml"), "-o", str(d / "lf.h5"), "--no-progress"]),
        "rerun lock": (d / "new.h5.lock", ["rerun", str(run), "-o", str(d / "new.h5"), "--no-progress"]),
        "hf --resume lock": (d / "stopped.h5.lock", ["hf", "--resume", str(stopped), "--no-progress"]),
        "analyze lock": (d / "run.h5.lock", ["analyze", str(run)]),
        "sweep manifest lock": (d / "sw" / "manifest.json.lock", sweep),
        "sweep manifest tmp": (d / "sw" / "manifest.json.tmp", sweep),
        "sweep shard lock": (d / "sw" / "shard-00000.h5.lock", sweep),
        "plot figure": (d / "figs" / ".run_global.partial.png", ["plot", str(run), "-o", str(d / "figs")]),
        "plot --only": (
            d / "figs" / ".run_global.partial.png",
            ["plot", str(run), "-o", str(d / "figs"), "--only", "patch_map", "global"],
        ),
    }  # fmt: skip


NAMES = [
    "hf lock", "hf new file", "lf lock", "rerun lock", "hf --resume lock", "analyze lock", "sweep manifest lock",
    "sweep manifest tmp", "sweep shard lock", "plot figure", "plot --only",
]  # fmt: skip


@pytest.mark.parametrize("name", NAMES)
def test_planted_link_is_refused(name: str, made, tmp_path: Path, capsys) -> None:
    """A link at NAME.lock (hf, lf, rerun, --resume, analyze), NAME.partial.new, DIR/manifest.json.lock and .tmp,
    DIR/shard-NNNNN.h5.lock or figs/.STEM.partial.png: one line, exit 2; the victim and the link unchanged; no
    output written (plot --only: the figures it made before are removed again, all or nothing)."""
    d = tmp_path / "work"
    link, argv = cases(made, d)[name]
    victim = tmp_path / "victim.txt"
    before = plant(link, victim)
    if name == "sweep shard lock":  # a finished sweep whose shard 0 is gone: the next call runs it again
        link.unlink()
        assert main(argv) == 0
        (d / "sw" / "shard-00000.h5").unlink()
        link.symlink_to(victim)
    refused(capsys, argv)
    untouched(victim, before, link)
    assert not (d / "out.h5").exists() and not (d / "new.h5").exists() and not (d / "lf.h5").exists()
    assert not any(p.name.endswith(".partial") for p in d.rglob("*")), sorted(d.rglob("*"))
    if name.startswith("plot"):  # none of global; the figures made before it (patch_map) stay unless asked for
        assert not list((d / "figs").glob("run_global.*"))
        assert len(list((d / "figs").glob("run_patch_map.*"))) == (0 if "--only" in argv else 2)


def test_hard_link_lock_is_refused(tmp_path: Path) -> None:
    """A lock file that is a hard link of another file (two names) is refused like a symbolic link."""
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    os.link(victim, tmp_path / "run.h5.lock")
    with pytest.raises(links.LinkError, match="not a plain file of its own"):
        OutputLock.acquire(tmp_path / "run.h5")
    assert victim.read_text() == "precious\n"


def test_kernel_turn_lock_is_private(tmp_path: Path, monkeypatch) -> None:
    """The GPU turn lock of processes that share a GPU: in the user's private folder (0700), created 0600, not in
    the shared temporary folder; a link planted there is refused, never followed (and the turn not held)."""
    from aca_warp.sweep.overlap import KernelTurn

    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path / "run"))
    (tmp_path / "run").mkdir(mode=0o700)
    (tmp_path / "tmp").mkdir()
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path / "tmp"))  # the shared temporary folder, where it was
    gpu = types.SimpleNamespace(is_cuda=True, uuid="GPU-1234", pci_bus_id=None)
    turn = KernelTurn(gpu, None, processes=True)
    turn.enter()
    try:
        assert turn.fd is not None
        folder = tmp_path / "run" / "aca-warp" / "kernel"
        lock = folder / "GPU-1234.lock"
        assert lock.is_file() and stat.S_IMODE(lock.stat().st_mode) == 0o600
        assert stat.S_IMODE(folder.stat().st_mode) == 0o700 and stat.S_IMODE(folder.parent.stat().st_mode) == 0o700
        assert not list((tmp_path / "tmp").iterdir())
    finally:
        turn.exit()
    lock.unlink()
    victim = tmp_path / "victim.txt"
    before = plant(lock, victim)
    refused = KernelTurn(types.SimpleNamespace(is_cuda=True, uuid="GPU-1234", pci_bus_id=None), None, processes=True)
    with pytest.raises(links.LinkError):
        refused.enter()
    assert not refused.locked and not refused.lock.locked()
    untouched(victim, before, lock)


def test_private_dir_refuses_a_folder_of_another_owner(tmp_path: Path, monkeypatch) -> None:
    """A private folder that is a link, or whose path is taken by a file, is not used (OSError)."""
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "aca-warp").symlink_to(tmp_path / "elsewhere")
    with pytest.raises(OSError, match="not a folder of this user"):
        links.private_dir("kernel")


def test_lock_file_removed_by_its_holder_while_opened_is_opened_anew(tmp_path: Path, monkeypatch) -> None:
    """A lock file its holder removes (a release, or another writer's sweep of stale identity locks) between our open
    and the check has no name left: it is opened anew, not refused as a hard link (a concurrent overlapped sweep and
    a second test process sharing the private lock folder hit this)."""
    lp = tmp_path / "x.lock"
    lp.write_text("")
    real_open, calls = os.open, []

    def racing_open(path, flags, mode=0o777, **kw):
        fd = real_open(path, flags, mode, **kw)
        if not calls:
            calls.append(path)
            os.unlink(path)  # the holder's release lands between the open and the check
        return fd

    monkeypatch.setattr(links.os, "open", racing_open)
    fd = links.open_lock_file(lp)
    try:
        assert calls == [lp] and os.fstat(fd).st_nlink == 1 and lp.exists()
    finally:
        os.close(fd)


def test_a_folder_where_a_whole_file_goes_is_one_line(tmp_path: Path) -> None:
    """whole() (figures, a bench's results): a folder at the file's name is refused before anything is written, in
    one line (os.replace would fail after the drawing, with a traceback), and the folder is left as it was."""
    from aca_warp.common.errors import SceneError
    from aca_warp.common.files import whole

    target = tmp_path / "run_global.png"
    target.mkdir()
    with pytest.raises(SceneError, match="is a folder where a file of that name goes"), whole(target) as fh:
        fh.write(b"x")
    assert target.is_dir() and sorted(p.name for p in tmp_path.iterdir()) == ["run_global.png"]


@pytest.mark.parametrize("ending", ["completes", "fails", "ctrl-c"])
def test_all_or_nothing_puts_back_what_its_files_replaced(tmp_path: Path, ending: str) -> None:
    """Files written whole inside all_or_nothing(): when the block completes they stand and the earlier files they
    replaced are gone; when it fails or is interrupted, every file it wrote is removed (one new file written twice
    too) and every earlier file put back byte for byte (one written twice in the block as it was before the block; a
    link as the link it was); no hidden file is left beside them either way."""
    from aca_warp.common.files import all_or_nothing, whole

    earlier, new, link = tmp_path / "a.png", tmp_path / "b.png", tmp_path / "c.png"
    earlier.write_bytes(b"an earlier plot")
    (tmp_path / "real.png").write_bytes(b"the link's target")
    link.symlink_to("real.png")
    raised = {"completes": None, "fails": SceneError("drawing failed"), "ctrl-c": KeyboardInterrupt()}[ending]
    try:
        with all_or_nothing():
            for content in (b"first", b"second"):
                for path in (earlier, new):
                    with whole(path) as fh:
                        fh.write(content)
            with whole(link) as fh:
                fh.write(b"over the link")
            if raised is not None:
                raise raised
    except (SceneError, KeyboardInterrupt) as e:
        assert e is raised
    got = {p.name: p.read_bytes() for p in tmp_path.iterdir() if not p.is_symlink()}
    if raised is None:
        assert got == {
            "a.png": b"second",
            "b.png": b"second",
            "c.png": b"over the link",
            "real.png": b"the link's target",
        }
        assert not link.is_symlink()
    else:
        assert got == {"a.png": b"an earlier plot", "real.png": b"the link's target"}
        assert link.is_symlink() and os.readlink(link) == "real.png"


def test_all_or_nothing_holds_at_every_step(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    """An interrupt just after a new figure has been renamed into place still removes it (the figure is counted as
    written before its rename); an earlier figure that cannot be renamed back is said, with the hidden name it is
    kept under (which does not grow with the figure's name), and left there."""
    from aca_warp.common.files import all_or_nothing, whole

    real = os.replace
    new, earlier = tmp_path / "new.png", tmp_path / ("e" * 230 + ".png")  # 234 characters: its kept name must fit
    earlier.write_bytes(b"an earlier plot")

    def interrupt_after(src, dst):
        real(src, dst)
        if Path(dst) == new:
            raise KeyboardInterrupt

    monkeypatch.setattr(os, "replace", interrupt_after)
    with pytest.raises(KeyboardInterrupt), all_or_nothing(), whole(new) as fh:
        fh.write(b"new")
    assert list(tmp_path.iterdir()) == [earlier]

    def refuse_restore(src, dst):
        if Path(src).name.startswith(".aca-earlier-"):
            raise PermissionError(13, "Permission denied")
        real(src, dst)

    monkeypatch.setattr(os, "replace", refuse_restore)
    with pytest.raises(SceneError), all_or_nothing():
        with whole(earlier) as fh:
            fh.write(b"this call's figure")
        raise SceneError("a later figure failed")
    (kept,) = [p for p in tmp_path.iterdir() if p.name.startswith(".aca-earlier-")]
    assert kept.read_bytes() == b"an earlier plot" and not earlier.exists()
    err = capsys.readouterr().err
    assert f"the earlier {earlier} could not be put back (Permission denied); it is kept as {kept}" in err
