"""What a user meets at the command line when something is wrong (docs/faults.md): every case ends with its exit
code, one line, and nothing half-written left behind.

* Output paths known bad before any simulation (a name ending in ``/``, a folder, a missing folder, a path under a
  file): exit 2; a read-only folder: exit 4 (a read-only bind mount in a user namespace when run as root, who passes
  every permission check, else a folder without write permission), for hf, lf, rerun, analyze and plot.
* Too little space for the samples a run records, known from the plan: exit 4 before anything is written.
* A file-size limit (RLIMIT_FSIZE in a subprocess) met by rerun, analyze and plot (hf, lf and sweep in
  test_storage.py): exit 4, what was written kept whole.
* Ctrl-C (SIGINT) and SIGTERM in a subprocess: one line, exit 130 and 143, no traceback, the run file closed,
  marked incomplete and resumable to the same bits as an uninterrupted run; analyze and plot leave no half-written
  group or figure.
* Values far outside a brake pad's range (likely unit mistakes), empty scene files, patch windows outside the run:
  exit 2, the mistake named; the summary of a run that stopped early gives the time it stopped at.
* Messages name Python parameters from the Python API, flags from the command line.
"""

from __future__ import annotations

import os
import shutil
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import h5py
import pytest
from procs import HF_DT, HF_SCENE, assert_same_datasets, cli, datasets, env, error_lines, small_scene_toml
from test_lf_checkpoint import lf_scene

from aca_warp.cli import main
from aca_warp.common.errors import SceneError
from aca_warp.common.files import REPLACES
from aca_warp.scene import load_scene, scene_from_dict, write_patch_file

SMALL = small_scene_toml(patches=("velocity",))


def listing(folder: Path) -> list[str]:
    """Every path under ``folder``, relative, sorted."""
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


def one_line(capsys: pytest.CaptureFixture) -> list[str]:
    return error_lines(capsys.readouterr().err)


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Scene files and a small HF run file (with per-patch velocities) shared by the tests of this module."""
    d = tmp_path_factory.mktemp("runs")
    (d / "small.toml").write_text(SMALL)
    (d / "lf.toml").write_text(lf_scene(0.2))
    (d / "long.toml").write_text(HF_SCENE)
    assert main(["hf", str(d / "small.toml"), "-o", str(d / "small.h5"), "--no-progress"]) == 0
    assert (
        main(["hf", str(d / "long.toml"), "-o", str(d / "long.h5"), "--duration", "2e-4", "--no-progress", *HF_DT]) == 0
    )
    return {"hf": d / "small.toml", "lf": d / "lf.toml", "run": d / "small.h5", "long": d / "long.h5"}


def command(kind: str, runs: dict[str, Path], out: str) -> list[str]:
    """The command line of ``kind`` writing ``out``."""
    return {
        "hf": ["hf", str(runs["hf"]), "-o", out, "--no-progress"],
        "lf": ["lf", str(runs["lf"]), "-o", out, "--no-progress"],
        "rerun": ["rerun", str(runs["run"]), "-o", out, "--no-progress"],
        "plot": ["plot", str(runs["run"]), "-o", out, "--only", "global"],
    }[kind]


# ------------------------------------------------------------------------------------------- output paths


@pytest.mark.parametrize("kind", ["hf", "lf", "rerun"])
@pytest.mark.parametrize(
    ("name", "message"),
    [
        ("sub/", "names a folder; give a file name such as"),
        ("folder", "is a folder; give a file name such as"),
        ("missing/run.h5", "does not exist"),
        ("file.txt/run.h5", "is not a folder"),
    ],
    ids=["trailing-slash", "folder", "missing-folder", "under-a-file"],
)
def test_bad_output_paths_are_refused_first(tmp_path, capsys, runs, kind, name, message) -> None:
    """Exit 2, one line naming the problem, nothing created (no file, no lock, no folder)."""
    (tmp_path / "folder").mkdir()
    (tmp_path / "file.txt").write_text("x")
    before = listing(tmp_path)
    assert main(command(kind, runs, f"{tmp_path}/{name}")) == 2
    err = one_line(capsys)
    assert len(err) == 1 and message in err[0], err
    assert listing(tmp_path) == before


@pytest.mark.parametrize("kind", ["hf", "lf", "rerun"])
@pytest.mark.parametrize("name", [".", ""], ids=["dot", "empty"])
def test_an_output_or_resume_that_names_no_file_is_one_line(tmp_path, capsys, monkeypatch, runs, kind, name) -> None:
    """``-o .``, ``-o ''`` and ``--resume ''`` (in the working folder): exit 2 and one line, nothing created."""
    monkeypatch.chdir(tmp_path)
    before = listing(tmp_path)
    assert main(command(kind, runs, name)) == 2
    assert ("names no file" if name == "" else "names a folder") in one_line(capsys)[0]
    if kind != "rerun":
        assert main([kind, "--resume", name]) == 2
        assert "names no run file" in one_line(capsys)[0]
    assert listing(tmp_path) == before


@pytest.mark.parametrize("kind", ["hf", "lf", "rerun"])
def test_an_output_that_is_not_a_regular_file_is_refused_even_with_overwrite(tmp_path, capsys, runs, kind) -> None:
    """A pipe (or a device) at the output name: --overwrite would replace it with a regular file; exit 2, one line."""
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    assert main([*command(kind, runs, str(fifo)), "--overwrite"]) == 2
    assert "exists and is not a regular file" in one_line(capsys)[0]
    assert stat.S_ISFIFO(fifo.stat().st_mode)


def test_an_output_that_is_an_input_is_refused(tmp_path, capsys, runs) -> None:
    """hf -o its own scene file, its LF run file (however spelled: a link) or its patch file, rerun -o its run file:
    exit 2 and one line, the input unchanged, even with --overwrite."""
    scene = tmp_path / "scene.toml"
    shutil.copy(runs["hf"], scene)
    before = scene.read_bytes()
    assert main(["hf", str(scene), "-o", str(scene), "--overwrite", "--no-progress"]) == 2
    assert f"hf writes a new file; {scene} is its scene file" in one_line(capsys)[0]
    run = tmp_path / "run.h5"
    shutil.copy(runs["run"], run)
    os.link(run, tmp_path / "hard.h5")  # another name of the same file
    assert main(["rerun", str(tmp_path / "hard.h5"), "-o", str(run), "--overwrite", "--no-progress"]) == 2
    assert f"rerun writes a new file; {run} is its run file" in one_line(capsys)[0]
    os.replace(run, tmp_path / "run.h5.partial")  # the output's .partial is the input: --overwrite would remove it
    assert main(["rerun", str(tmp_path / "run.h5.partial"), "-o", str(run), "--overwrite", "--no-progress"]) == 2
    assert f"rerun writes a new file; {tmp_path / 'run.h5.partial'} is its run file" in one_line(capsys)[0]
    lf = tmp_path / "lf.h5"
    with h5py.File(lf, "w") as f:
        f.attrs["kind"] = "lf"
    assert main(["hf", str(lf), "--snapshot", "app1_start", "-o", str(lf), "--overwrite", "--no-progress"]) == 2
    assert f"hf writes a new file; {lf} is its LF run file" in one_line(capsys)[0]
    patches = tmp_path / "p.h5"
    write_patch_file(patches, load_scene("hf1").patches)
    with_file = tmp_path / "with_file.toml"
    with_file.write_text('[scene]\nname = "f"\n[patches]\nfile = "p.h5"\n')
    assert main(["hf", str(with_file), "-o", str(patches), "--overwrite", "--no-progress"]) == 2
    assert f"hf writes a new file; {patches} is its patch file" in one_line(capsys)[0]
    assert scene.read_bytes() == before and (tmp_path / "run.h5.partial").exists() and patches.exists()


@pytest.mark.parametrize(
    ("name", "message"), [("file.txt", "exists and is not a folder"), ("file.txt/figs", "is not a folder")]
)
def test_bad_plot_folders_are_refused_first(tmp_path, capsys, runs, name, message) -> None:
    (tmp_path / "file.txt").write_text("x")
    before = listing(tmp_path)
    assert main(command("plot", runs, str(tmp_path / name))) == 2
    err = one_line(capsys)
    assert len(err) == 1 and message in err[0], err
    assert listing(tmp_path) == before


@pytest.mark.parametrize(
    ("name", "message"),
    [("file.txt", "file.txt exists and is not a folder"), ("file.txt/sweep", "file.txt is not a folder")],
)
def test_sweep_folder_checked_before_the_spec(tmp_path, capsys, name, message) -> None:
    """sweep shares the output-folder check: a file, or a path under one, is refused before the spec is expanded
    (no line of the expansion printed first)."""
    (tmp_path / "file.txt").write_text("x")
    spec = tmp_path / "spec.toml"
    spec.write_text('[sweep]\nbase = "hf1"\n[parameters]\n"friction.M" = [0.6, 0.7]\n')
    before = listing(tmp_path)
    assert main(["sweep", str(spec), "-o", str(tmp_path / name), "--workers", "0"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.splitlines()) == 1 and message in err, (out, err)
    assert listing(tmp_path) == before


# runs ``aca_warp.cli.main`` on every argv of the JSON list argv[1] in this one process; prints [[code, stderr], ...]
EACH = (
    "import contextlib, io, json, sys\nfrom aca_warp.cli import main\nout = []\n"
    "for argv in json.loads(sys.argv[1]):\n    err = io.StringIO()\n    with contextlib.redirect_stderr(err):\n"
    "        out.append([main(argv), err.getvalue()])\nprint(json.dumps(out))"
)


def read_only(folder: Path, commands: list[list[str]]) -> list[tuple[int, str]] | None:
    """Exit code and stderr of each ``aca-warp`` command line of ``commands``, run one after another in one process
    with ``folder`` read-only: as root (who passes every permission check, so ``chmod`` would not do) through a
    read-only bind mount in a user namespace; otherwise a folder without write permission. None when neither is
    possible here."""
    import json

    argv = [sys.executable, "-c", EACH, json.dumps(commands)]
    if os.geteuid() != 0:
        folder.chmod(0o555)
        try:
            if os.access(folder, os.W_OK):
                return None
            r = subprocess.run(argv, env=env(), capture_output=True, text=True, timeout=300)
        finally:
            folder.chmod(0o755)
    else:
        if shutil.which("unshare") is None:
            return None
        mount = 'mount --bind "$1" "$1" && mount -o remount,bind,ro "$1" || exit 99; shift; exec "$@"'
        r = subprocess.run(["unshare", "-rm", "sh", "-c", mount, "sh", str(folder), *argv], env=env(),
                           capture_output=True, text=True, timeout=300)  # fmt: skip
        if r.returncode == 99:
            return None
    assert r.returncode == 0, r.stderr
    return [(int(code), err) for code, err in json.loads(r.stdout.strip().splitlines()[-1])]


def test_read_only_folder(tmp_path, runs) -> None:
    """hf, lf, rerun, plot and analyze with their output folder read-only: exit 4 and one line each, before any
    simulation; the folder as it was (analyze: the run file unchanged). One process runs the five commands."""
    ro = tmp_path / "ro"
    ro.mkdir()
    shutil.copy(runs["run"], ro / "run.h5")
    kinds = ["hf", "lf", "rerun", "plot"]
    commands = [command(k, runs, str(ro / ("figs" if k == "plot" else f"{k}.h5"))) for k in kinds]
    commands.append(["analyze", str(ro / "run.h5")])
    before = {p: (ro / p).read_bytes() for p in listing(ro)}
    results = read_only(ro, commands)
    if results is None:
        pytest.skip("no way to make a folder read-only here (no user namespaces, and root ignores permissions)")
    for kind, (code, err) in zip([*kinds, "analyze"], results, strict=True):
        lines = error_lines(err)
        assert code == 4 and len(lines) == 1, (kind, err)
        assert "read-only file system" in lines[0] or "permission denied" in lines[0], (kind, lines)
    assert {p: (ro / p).read_bytes() for p in listing(ro)} == before


def test_too_little_space_is_refused_before_the_run(tmp_path, capsys, runs, monkeypatch) -> None:
    """The plan's recorded bytes against the free space of the output folder: exit 4, one line, nothing written."""
    from aca_warp.common import files

    real = os.statvfs

    class Full:
        def __init__(self, st: os.statvfs_result) -> None:
            self.f_frsize, self.f_blocks, self.f_bavail = st.f_frsize, st.f_blocks, 0

    monkeypatch.setattr(files.os, "statvfs", lambda p: Full(real(p)))
    assert main(command("hf", runs, str(tmp_path / "run.h5"))) == 4
    err = one_line(capsys)
    assert len(err) == 1 and "MB free; nothing was written" in err[0], err
    assert listing(tmp_path) == []


# -------------------------------------------------------------------------------- file-size limit mid-run


def test_rerun_file_size_limit_then_resume(tmp_path: Path, references) -> None:
    """rerun under a file-size limit: exit 4, one line, the .partial kept at its checkpoint; --resume then
    finishes it bit-identical to the run it repeats (the limit as in test_storage.py)."""
    ref = references["hf"]
    out = tmp_path / "again.h5"
    r = cli(["rerun", str(ref), "-o", str(out), "--no-progress", "--checkpoint-interval", "1e-4"], limit=1_300_000)
    lines = error_lines(r.stderr)
    assert r.returncode == 4 and len(lines) == 1, r.stderr
    assert "file size limit reached" in lines[0] and f"with 'aca-warp hf --resume {out}'" in lines[0]
    assert (tmp_path / "again.h5.partial").exists() and not out.exists()
    assert main(["hf", "--resume", str(out), "--no-progress"]) == 0
    assert_same_datasets(out, ref)


def test_analyze_file_size_limit_keeps_the_run_file(tmp_path: Path, runs) -> None:
    """analyze under a file-size limit just above the run file: exit 4, one line; the file keeps every dataset
    it had, and no half-written /analysis."""
    run = tmp_path / "run.h5"
    shutil.copy(runs["long"], run)
    before = datasets(run)
    r = cli(["analyze", str(run)], limit=run.stat().st_size + 4096)
    lines = error_lines(r.stderr)
    assert r.returncode == 4 and len(lines) == 1, r.stderr
    assert "file size limit reached while writing /analysis" in lines[0] and "keeps its samples" in lines[0]
    after = datasets(run)
    assert sorted(after) == sorted(before) and all(after[k].tobytes() == before[k].tobytes() for k in before)
    assert main(["analyze", str(run)]) == 0  # the file takes the analysis once there is room


def test_plot_file_size_limit_leaves_whole_figures(tmp_path: Path, runs) -> None:
    """plot under a file-size limit below one figure: exit 4, one line, no half-written figure (the folder it
    created removed again, as nothing was written into it)."""
    out = tmp_path / "figs"
    r = cli(["plot", str(runs["run"]), "-o", str(out), "--only", "global"], limit=20_000)
    lines = error_lines(r.stderr)
    assert r.returncode == 4 and len(lines) == 1 and "file size limit reached while writing figures" in lines[0], r
    assert f"none of its figures is left in {out} (--only: all or nothing" in lines[0], lines  # --only said so
    assert not out.exists()


# ------------------------------------------------------------------------------------------------- interrupts


def start(args: list[str]) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "aca_warp.cli", *args],
        env=env(HDF5_USE_FILE_LOCKING="FALSE"),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def has_checkpoint(part: Path) -> bool:
    from aca_warp.common.checkpoint import has_checkpoint as holds

    try:
        with h5py.File(part, "r", locking=False) as f:
            return holds(f)
    except Exception:  # noqa: BLE001  (mid-write: look again)
        return False


def opened(proc: subprocess.Popen, path: Path) -> bool:
    """Whether ``proc`` has ``path`` open (Linux /proc)."""
    fds = Path(f"/proc/{proc.pid}/fd")
    try:
        return any(os.readlink(fd) == str(path) for fd in fds.iterdir())
    except OSError:
        return False


def interrupt_when(proc: subprocess.Popen, ready, sig: int, *, timeout: float = 120.0) -> tuple[int, list[str]]:
    """Stop ``proc`` (SIGSTOP) as soon as ``ready()`` holds, send ``sig``, let it go on; (exit code, stderr lines)."""
    deadline = time.monotonic() + timeout
    try:
        while True:
            assert proc.poll() is None, f"ended before it could be interrupted: {proc.stderr.read()}"
            assert time.monotonic() < deadline
            os.kill(proc.pid, signal.SIGSTOP)
            if ready():
                break
            os.kill(proc.pid, signal.SIGCONT)
            time.sleep(0.002)
        os.kill(proc.pid, sig)
        os.kill(proc.pid, signal.SIGCONT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.returncode, error_lines(err)


def assert_interrupted(code: int, lines: list[str], sig: int) -> None:
    assert code == 128 + sig, (code, lines)
    assert len(lines) == 1 and lines[0].startswith("aca-warp: interrupted"), lines
    assert ("SIGTERM" if sig == signal.SIGTERM else "Ctrl-C") in lines[0]


@pytest.mark.parametrize(
    ("kind", "sig"),
    [("hf", signal.SIGINT), ("hf", signal.SIGTERM), ("rerun", signal.SIGINT), ("lf", signal.SIGTERM)],
    ids=["hf-SIGINT", "hf-SIGTERM", "rerun-SIGINT", "lf-SIGTERM"],
)
def test_interrupt_then_resume(tmp_path: Path, references, kind: str, sig: int) -> None:
    """Interrupted after its first checkpoint: one line naming what the file keeps and how to continue, exit
    128 + signal, the file closed and marked incomplete (no .partial, no lock); --resume finishes it with the bits
    of the uninterrupted run."""
    out = tmp_path / "run.h5"
    if kind == "lf":
        ref = references["lf"]
        args = ["lf", str(references["lf_scene"]), "-o", str(out), "--checkpoint-interval", "0.05", "--no-progress"]
    else:
        ref = references["hf"]
        first = ["hf", str(references["hf_scene"]), *HF_DT] if kind == "hf" else ["rerun", str(ref)]
        args = [*first, "-o", str(out), "--checkpoint-interval", "5e-5", "--no-progress"]
    part = tmp_path / "run.h5.partial"
    code, lines = interrupt_when(start(args), lambda: part.exists() and has_checkpoint(part), sig)
    assert_interrupted(code, lines, sig)
    resume = "lf" if kind == "lf" else "hf"
    assert f"aca-warp {resume} --resume {out}" in lines[0] and "marked incomplete" in lines[0]
    assert out.exists() and not part.exists() and not (tmp_path / "run.h5.lock").exists()
    with h5py.File(out, "r") as f:
        assert not f.attrs["complete"] and str(f.attrs["status"]).startswith("interrupted")
    assert main([resume, "--resume", str(out), "--no-progress"]) == 0
    assert_same_datasets(out, ref)


@pytest.mark.parametrize("kind", ["hf", "lf"])
def test_an_interrupted_overwrite_keeps_the_earlier_file(tmp_path: Path, references, kind: str) -> None:
    """A run that was to replace a complete file (--overwrite), interrupted: the earlier file stays as it was, the
    interrupted run stays NAME.partial (the line says both), and --resume NAME finishes it, which then replaces the
    earlier file with the bits of an uninterrupted run."""
    out, part = tmp_path / "run.h5", tmp_path / "run.h5.partial"
    if kind == "lf":
        ref, earlier = references["lf"], references["hf"]  # any complete run file stands for the earlier one
        args = ["lf", str(references["lf_scene"]), "-o", str(out), "--checkpoint-interval", "0.05", "--no-progress"]
    else:
        ref, earlier = references["hf"], references["lf"]
        args = ["hf", str(references["hf_scene"]), *HF_DT, "-o", str(out), "--checkpoint-interval", "5e-5"]
        args.append("--no-progress")
    shutil.copy(earlier, out)
    before = out.read_bytes()
    code, lines = interrupt_when(
        start([*args, "--overwrite"]), lambda: part.exists() and has_checkpoint(part), signal.SIGINT
    )
    assert_interrupted(code, lines, signal.SIGINT)
    assert f"{part} keeps the interrupted run and {out}, the earlier file it was to replace, is unchanged" in lines[0]
    assert f"aca-warp {kind} --resume {out}" in lines[0]
    assert out.read_bytes() == before and part.exists() and not (tmp_path / "run.h5.lock").exists()
    with h5py.File(part, "r") as f:
        assert not f.attrs["complete"] and str(f.attrs["status"]).startswith("interrupted") and f.attrs[REPLACES]
    assert main([kind, "--resume", str(out), "--no-progress"]) == 0
    assert not part.exists()
    assert_same_datasets(out, ref)
    with h5py.File(out, "r") as f:
        assert REPLACES not in f.attrs
    if kind == "lf":  # its rate counts the steps this process ran, not those before the checkpoint
        with h5py.File(out, "r") as f:
            ran = f.attrs["steps_per_second"] * f.attrs["wall_time"]
            assert 0 < ran < int(f.attrs["steps"]) - 0.5


def test_an_interrupted_overwrite_of_an_incomplete_file_replaces_it(tmp_path: Path, references) -> None:
    """The earlier file, itself incomplete, is not kept: the interrupted run takes its name, as any interrupted run,
    and --resume continues it."""
    out, part = tmp_path / "run.h5", tmp_path / "run.h5.partial"
    shutil.copy(references["lf"], out)
    with h5py.File(out, "a") as f:
        f.attrs["complete"] = False
    args = ["hf", str(references["hf_scene"]), *HF_DT, "-o", str(out), "--checkpoint-interval", "5e-5"]
    code, lines = interrupt_when(
        start([*args, "--no-progress", "--overwrite"]), lambda: part.exists() and has_checkpoint(part), signal.SIGINT
    )
    assert_interrupted(code, lines, signal.SIGINT)
    assert "marked incomplete" in lines[0] and not part.exists()
    assert main(["hf", "--resume", str(out), "--no-progress"]) == 0
    assert_same_datasets(out, references["hf"])


def test_a_partial_beside_a_complete_file_is_resumed_only_when_it_was_kept_there(tmp_path: Path, references) -> None:
    """A .partial beside a complete NAME that no interrupted --overwrite left (a killed run's, say): --resume NAME
    refuses both (move one away), so that an old .partial never replaces a good file unasked."""
    from aca_warp.common.files import find_resumable

    out, part = tmp_path / "run.h5", tmp_path / "run.h5.partial"
    shutil.copy(references["hf"], out)
    shutil.copy(references["hf"], part)
    with h5py.File(part, "a") as f:
        f.attrs["complete"] = False
    with pytest.raises(SceneError, match="both .* exist; move the one you do not want to resume away"):
        find_resumable(out)
    with h5py.File(part, "a") as f:
        f.attrs[REPLACES] = True
    assert find_resumable(out) == (out, part)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_interrupted_analyze_leaves_the_run_file(tmp_path: Path, runs, sig: int) -> None:
    """analyze interrupted once it has the run file open: one line, exit 128 + signal, the file's datasets as they
    were and no half-written /analysis — or, when the signal came as /analysis was swapped in (the command's output
    then whole), a line that says the work was not stopped and the samples as they were beside a whole /analysis."""
    run = tmp_path / "run.h5"
    shutil.copy(runs["long"], run)
    before = datasets(run)
    proc = start(["analyze", str(run)])
    code, lines = interrupt_when(proc, lambda: opened(proc, run), sig)
    assert_interrupted(code, lines, sig)
    after = datasets(run)
    if "work was not stopped" in lines[0]:
        assert main(["analyze", str(run)]) == 0  # what a whole /analysis holds: the groups of a fresh analysis
        whole = datasets(run)
        assert sorted(k for k in after if k.startswith("analysis/")) == sorted(
            k for k in whole if k.startswith("analysis/")
        )
        after = {k: v for k, v in after.items() if not k.startswith("analysis/")}
    assert sorted(after) == sorted(before) and all(after[k].tobytes() == before[k].tobytes() for k in before)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_interrupted_plot_leaves_no_half_figure(tmp_path: Path, runs, sig: int) -> None:
    """plot interrupted while it draws: one line, exit 128 + signal, only whole figures in the folder — or, when
    code beyond the command's caught the interrupt and the plot went on to its end (its own notes then before it),
    a last line that says the work was not stopped, with the same exit code."""
    out = tmp_path / "figs"
    proc = start(["plot", str(runs["run"]), "-o", str(out)])
    code, lines = interrupt_when(proc, lambda: opened(proc, runs["run"]), sig)
    if lines and "work was not stopped" in lines[-1]:
        assert all(line.startswith("aca-warp plot: ") for line in lines[:-1]), lines
        lines = lines[-1:]
    assert_interrupted(code, lines, sig)
    figures = listing(out) if out.exists() else []
    assert not any(".partial" in p for p in figures), figures


# ---------------------------------------------------------------------------------- implausible values


@pytest.mark.parametrize(
    ("tables", "extra", "message", "hint"),
    [
        ({"pad": {"r_inner": 100, "r_outer": 160}}, [], "pad.r_inner = 100 m — beyond 2 m", "did you mean mm?"),
        ({"patches": {"area_min": 20, "area_max": 80}}, [], "patches.area_min = 20 m² — beyond", "did you mean mm²"),
        ({"load": {"normal_force": 5e7}}, [], "load.normal_force = 5e+07 N — beyond 1e+06 N", "did you mean mN?"),
        ({"disc": {"sliding_speed": 360}}, [], "mean radius = 360 m/s — beyond 200 m/s", "did you mean km/h"),
        ({}, ["--duration", "1e3"], "run.duration = 1000 s — beyond 1 s", "did you mean µs?"),
        ({}, ["--dt", "1e-20"], "dt = 1e-20 s — below 1e-13 s", "check the exponent"),
    ],
    ids=["length-mm", "area-mm2", "load-mN", "speed-kmh", "duration-us", "step"],
)
def test_unit_mistakes_are_named(tmp_path, capsys, tables, extra, message, hint) -> None:
    """Exit 2, one line with the value, the range and the likely unit, nothing written; --allow-implausible lifts
    the check (the run then goes on to its other checks)."""
    s = tmp_path / "s.toml"
    s.write_text(small_scene_toml(tables=tables))
    out = tmp_path / "run.h5"
    argv = ["hf", str(s), "-o", str(out), "--no-progress", *extra]
    assert main(argv) == 2
    err = one_line(capsys)
    assert len(err) == 1 and message in err[0] and hint in err[0], err
    assert "pass --allow-implausible" in err[0] and "allow_implausible=True" not in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]
    main([*argv, "--allow-implausible"])
    assert "— beyond" not in capsys.readouterr().err


def test_implausible_values_in_python(tmp_path) -> None:
    """The Python API names its parameter; allow_implausible=True (or the scene key) accepts the value."""
    import tomllib

    doc = tomllib.loads(small_scene_toml(tables={"pad": {"r_inner": 100, "r_outer": 160}}))
    with pytest.raises(SceneError, match="did you mean mm") as e:
        scene_from_dict(doc)
    assert "allow_implausible=True" in str(e.value) and "--allow-implausible" not in str(e.value)
    assert scene_from_dict(doc, allow_implausible=True).pad.r_inner == 100
    doc["scene"]["allow_implausible"] = True
    scene = scene_from_dict(doc)
    assert scene.allow_implausible and scene.pad.r_inner == 100
    s = tmp_path / "s.toml"
    s.write_text(small_scene_toml(tables={"load": {"normal_force": 5e7}}))
    with pytest.raises(SceneError, match="did you mean mN"):
        load_scene(s)
    assert load_scene(s, allow_implausible=True).normal_force == 5e7


def test_friction_factor_in_percent_is_named(tmp_path, capsys) -> None:
    """Eq. 4's M (it bounds a patch's μ) and the matrix's μ beyond 5: refused as a likely percentage, a bare number
    (μ has no unit), nothing written; 5 itself runs."""
    s = tmp_path / "s.toml"
    for key, value, ok in (("M", 50, False), ("mu_pad", 30, False), ("M", 5.0, True)):
        s.write_text(small_scene_toml(tables={"friction": {key: value}}))
        if ok:
            assert load_scene(s).friction.M == value
            continue
        assert main(["hf", str(s), "-o", str(tmp_path / "r.h5"), "--no-progress"]) == 2
        err = one_line(capsys)
        assert len(err) == 1 and f"friction.{key} = {value} — beyond 5 (" in err[0], err
        assert f"did you mean %? ({value} % = {value / 100:.3g})" in err[0]
        assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]
        assert load_scene(s, allow_implausible=True).friction.__dict__[key] == value


def test_lf_unit_mistakes_are_named(tmp_path, capsys) -> None:
    """LF scenes too: a schedule load in mN, the LF step of an HF run."""
    s = tmp_path / "lf.toml"
    for old, new, message in (
        ("normal_force = 300.0", "normal_force = 3e7", "schedule[0].normal_force = 3e+07 N — beyond"),
        ("[lf]", "[lf]\ndt = 1e-8", "lf.dt = 1e-08 s — below 1e-05 s"),
    ):
        s.write_text(lf_scene(0.2).replace(old, new, 1))
        assert main(["lf", str(s), "-o", str(tmp_path / "lf.h5"), "--no-progress"]) == 2
        err = one_line(capsys)
        assert len(err) == 1 and message in err[0] and "--allow-implausible" in err[0], err
        assert sorted(p.name for p in tmp_path.iterdir()) == ["lf.toml"]


# --------------------------------------------------------------------------- empty files, windows, summaries


@pytest.mark.parametrize("kind", ["hf", "lf"])
@pytest.mark.parametrize("text", ["", "# only a comment\n\n"], ids=["empty", "comment"])
def test_empty_scene_file(tmp_path, capsys, kind, text) -> None:
    """An empty scene file would run the defaults silently: exit 2, one line, nothing written."""
    s = tmp_path / "s.toml"
    s.write_text(text)
    assert main([kind, str(s), "-o", str(tmp_path / "run.h5"), "--no-progress"]) == 2
    err = one_line(capsys)
    assert len(err) == 1 and "is empty" in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


def test_hf_notes_what_it_runs_otherwise_than_asked(runs, tmp_path, capsys) -> None:
    """A duration that whole sample intervals round, a step that whole steps per sample interval shorten, and a
    checkpoint interval shorter than a sample interval: one note each on stderr (as ``lf`` gives them), the run as
    before; none for a duration of whole intervals at the default step."""
    small = str(runs["hf"])
    for extra, notes, end in (  # the scene samples every 1e-7 s
        (["--duration", "2.43e-6"], ["2.43e-06 s is run as 24 whole sample intervals of 1e-07 s: 2.4e-06 s"], 2.4e-6),
        (
            ["--duration", "2e-6", "--checkpoint-interval", "1e-9"],
            ["a checkpoint interval of 1e-09 s is shorter"],
            2e-6,
        ),
        (["--duration", "2e-6", "--dt", "3e-8"], ["--dt 3e-08 s is run as 2.5e-08 s, so that whole steps fill"], 2e-6),
        (["--duration", "2e-6"], [], 2e-6),
    ):
        out = tmp_path / "r.h5"
        assert main(["hf", small, "-o", str(out), "--no-progress", "--overwrite", *extra]) == 0
        err = one_line(capsys)
        assert len(err) == len(notes), err
        assert all(n in e and e.startswith("aca-warp: note: ") for n, e in zip(notes, err, strict=True)), err
        with h5py.File(out) as f:
            assert f["global/time"][-1] == pytest.approx(end)


@pytest.mark.parametrize(
    "how",
    [
        ["--record-patches", "velocity", "--patch-window", "5e-6", "6e-6"],
        ["--duration", "2e-6", "SCENE_WINDOW"],
    ],
    ids=["option", "scene"],
)
def test_patch_window_outside_the_run(tmp_path, capsys, how) -> None:
    """A per-patch window after the run's end records nothing: exit 2, one line, nothing written."""
    s = tmp_path / "s.toml"
    record = {"sample_dt": 1.0e-7}
    if "SCENE_WINDOW" in how:
        record = {**record, "patches": ["velocity"], "window": [1e-3, 2e-3]}
        how = how[:-1]
    s.write_text(small_scene_toml(tables={"record": record}))
    assert main(["hf", str(s), "-o", str(tmp_path / "run.h5"), "--no-progress", *how]) == 2
    err = one_line(capsys)
    assert len(err) == 1 and "holds no sample of the run" in err[0] and "choose a window inside the run" in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


def test_patch_window_without_patch_histories(tmp_path, capsys) -> None:
    """--patch-window without per-patch histories would be ignored silently: exit 2, one line."""
    s = tmp_path / "s.toml"
    s.write_text(small_scene_toml())
    argv = ["hf", str(s), "-o", str(tmp_path / "run.h5"), "--no-progress", "--patch-window", "0", "1e-6"]
    assert main(argv) == 2
    err = one_line(capsys)
    assert len(err) == 1 and "add --record-patches velocity" in err[0], err


# ---------------------------------------------------------------------------------------------- wording


def test_python_api_names_parameters_and_the_cli_flags(tmp_path, capsys, runs) -> None:
    """The same refusal from run_scene names overwrite=True; from aca-warp it names --overwrite."""
    from aca_warp.hf.runner import run_scene

    out = tmp_path / "run.h5"
    out.write_bytes(b"precious")
    with pytest.raises(SceneError) as e:
        run_scene(load_scene(runs["hf"]), out)
    assert "pass overwrite=True to replace it" in str(e.value) and "--" not in str(e.value)
    assert main(["hf", str(runs["hf"]), "-o", str(out), "--no-progress"]) == 2
    err = one_line(capsys)
    assert len(err) == 1 and "pass --overwrite to replace it" in err[0] and "overwrite=True" not in err[0]
    assert out.read_bytes() == b"precious"


# a signal while the process cleans up after the command: sent by an atexit hook, registered first so that it runs last
AT_EXIT = (
    "import atexit, os, runpy, sys; sig = int(sys.argv[1]); "
    "atexit.register(lambda: os.kill(os.getpid(), sig)); "
    "sys.argv = ['aca-warp', *sys.argv[2:]]; runpy.run_module('aca_warp.cli', run_name='__main__')"
)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_while_the_process_exits(tmp_path: Path, sig: int) -> None:
    """A SIGINT or SIGTERM after the command's work, while the process runs its exit clean-ups (the window of
    ≈ 0.5 s of interpreter shutdown in which it used to die with −2 or −15, or exit 143 without a word): exit
    128 + signal and one line saying the command had ended and with which code; the run file complete."""
    (tmp_path / "s.toml").write_text(small_scene_toml("late", count=10, duration=2.0e-6))
    out = tmp_path / "run.h5"
    args = ["hf", str(tmp_path / "s.toml"), "-o", str(out), "--no-progress"]
    r = subprocess.run([sys.executable, "-c", AT_EXIT, str(int(sig)), *args], env=env(), capture_output=True, text=True)
    lines = error_lines(r.stderr)
    assert r.returncode == 128 + sig and len(lines) == 1, (r.returncode, r.stderr)
    name = "SIGTERM" if sig == signal.SIGTERM else "Ctrl-C"
    assert lines[0].startswith(f"aca-warp: interrupted ({name}), but the command's work was not stopped: it ended with")
    assert "exit code 0" in lines[0]
    assert r.stdout.startswith(f"{out}: 21 samples")
    with h5py.File(out, "r") as f:
        assert f.attrs["complete"]


def test_interrupt_message_for_a_file_without_samples(tmp_path: Path) -> None:
    """A run stopped before its first sample: the message says the file holds no sample yet (and how to go on)."""
    import h5py

    from aca_warp.cli import _run_file_state

    run = tmp_path / "early.h5"
    with h5py.File(run, "w") as f:
        f.attrs["complete"] = False
        f.create_dataset("global/time", shape=(0,), maxshape=(None,), dtype="f8")
    text = _run_file_state(run)
    assert text.startswith(f"{run} holds no sample yet, marked incomplete; continue it from t = 0"), text
    with h5py.File(run, "a") as f:
        f["global/time"].resize((2,))
        f["global/time"][:] = [0.0, 1.0e-6]
    assert _run_file_state(run).startswith(f"{run} keeps the samples to t = 1e-06 s, marked incomplete; ")
