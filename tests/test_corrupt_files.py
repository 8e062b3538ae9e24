"""Damaged input files: every command that reads a run file answers a bit flip in its metadata or a truncation with
one ``aca-warp: error:`` line and exit 2, never a traceback (the read boundaries, aca_warp.common.files.reading).

The flips hit HDF5 structures on purpose, so that the library fails: the signatures of the groups' local heaps
("HEAP"; a damaged group: the run file opens, its members do not) and of the chunk index nodes ("TREE" of type 1; a
damaged dataset: it opens and has its shape, its samples cannot be read, so the command fails in the middle of its
work). A flip in raw sample data is not detectable (HDF5 keeps no checksum of unfiltered data): docs/faults.md."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import h5py
import pytest
from procs import small_scene_toml
from scriptload import load_script
from test_lf_checkpoint import lf_scene

from aca_warp.cli import main
from aca_warp.sweep import SweepError, load_sweep

HF_SCENE = small_scene_toml("corrupt", count=30, duration=3.0e-5, patches=("velocity",))


def damage(path: Path, how: str) -> None:
    """Flip one bit of every local-heap signature ("heap"), of every chunk-index node signature ("tree"), or cut
    the file in half ("truncate")."""
    data = bytearray(path.read_bytes())
    if how == "truncate":
        path.write_bytes(bytes(data[: len(data) // 2]))
        return
    sig = b"HEAP" if how == "heap" else b"TREE"
    hits = 0
    i = data.find(sig, 8)
    while i >= 0:
        if sig == b"HEAP" or data[i + 4] == 1:  # TREE node type 1: raw-data chunks
            data[i] ^= 0x01
            hits += 1
        i = data.find(sig, i + 4)
    assert hits, f"no {sig!r} in {path}"
    path.write_bytes(bytes(data))


def one_error_line(capsys: pytest.CaptureFixture, argv: list[str]) -> str:
    capsys.readouterr()
    code = main(argv)
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code == 2 and len(err) == 1 and err[0].startswith("aca-warp: error:"), (argv, code, err)
    return err[0]


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A finished HF run (per-patch velocities), an HF run stopped at its first checkpoint, a finished LF run with
    snapshots and an LF run stopped at its first checkpoint, a finished two-shard sweep."""
    d = tmp_path_factory.mktemp("corrupt")
    out = CORRUPT.build_inputs(d, HF_SCENE, lf_scene(0.6), hf_interval=1e-5)
    spec = d / "spec.toml"
    spec.write_text(
        '[sweep]\nbase = "hf1"\nshard_size = 1\n[run]\nduration = 1e-6\nprecision = "fp32"\n'
        '[base.patches]\ncount = 25\n[parameters]\n"friction.M" = [0.6, 0.8]\n'
    )
    out["spec"] = spec
    out["sweep"] = d / "sweep"
    assert main(["sweep", str(spec), "-o", str(out["sweep"]), "--workers", "0", "--quiet"]) == 0
    return out


CASES = [
    ("rerun", "hf", "heap", lambda f, d: ["rerun", str(f), "-o", str(d / "new.h5"), "--no-progress"]),
    ("rerun", "hf", "truncate", lambda f, d: ["rerun", str(f), "-o", str(d / "new.h5"), "--no-progress"]),
    ("analyze", "hf", "tree", lambda f, d: ["analyze", str(f)]),
    ("analyze", "hf", "heap", lambda f, d: ["analyze", str(f)]),
    ("plot", "hf", "tree", lambda f, d: ["plot", str(f), "-o", str(d / "figs"), "--only", "global", "patch_map"]),
    ("hf --resume", "hf_stopped", "heap", lambda f, d: ["hf", "--resume", str(f), "--no-progress"]),
    ("hf --resume", "hf_stopped", "tree", lambda f, d: ["hf", "--resume", str(f), "--no-progress"]),
    ("hf --resume", "hf_stopped", "truncate", lambda f, d: ["hf", "--resume", str(f), "--no-progress"]),
    ("lf --resume", "lf_stopped", "heap", lambda f, d: ["lf", "--resume", str(f), "--no-progress"]),
    ("lf --resume", "lf_stopped", "tree", lambda f, d: ["lf", "--resume", str(f), "--no-progress"]),
    ("hf --snapshot", "lf", "heap", lambda f, d: ["hf", str(f), "--snapshot", "app1_end", "-o", str(d / "x.h5")]),
    ("hf --snapshot", "lf", "truncate", lambda f, d: ["hf", str(f), "--snapshot", "app1_end", "-o", str(d / "x.h5")]),
    ("rerun lf", "lf", "heap", lambda f, d: ["rerun", str(f), "-o", str(d / "new.h5"), "--no-progress"]),
]


@pytest.mark.parametrize(("command", "which", "how", "argv"), CASES, ids=[f"{c[0]}-{c[2]}" for c in CASES])
def test_damaged_input_gives_one_line(command, which, how, argv, files, tmp_path, capsys) -> None:
    src = files[which]
    f = tmp_path / src.name
    shutil.copy(src, f)
    damage(f, how)
    line = one_error_line(capsys, argv(f, tmp_path))
    assert str(f) in line or f.name in line, line
    assert not (tmp_path / "new.h5").exists() and not (tmp_path / "x.h5").exists()


def test_damaged_sweep_shard(files, tmp_path, capsys) -> None:
    """A damaged finished shard: reading the sweep is one SweepError line naming it; running the same sweep again
    finds the shard unreadable and runs it again (exit 0)."""
    d = tmp_path / "sweep"
    shutil.copytree(files["sweep"], d)
    damage(d / "shard-00001.h5", "heap")
    with pytest.raises(SweepError, match="cannot read shard .*shard-00001.h5"):
        load_sweep(d)
    assert main(["sweep", str(files["spec"]), "-o", str(d), "--workers", "0", "--quiet"]) == 0
    manifest = json.loads((d / "manifest.json").read_text())
    assert [s["state"] for s in manifest["shards"]] == ["done", "done"]
    assert load_sweep(d)["mu"].shape[0] == 2
    with h5py.File(d / "shard-00001.h5", "r") as f:
        assert f.attrs["complete"]


CORRUPT = load_script("corrupt_files")
CRAFTED = [(case, command) for case, command, _ in CORRUPT.crafted_trials({})]


@pytest.mark.parametrize("index", range(len(CRAFTED)), ids=[f"{c} / {m}" for c, m in CRAFTED])
def test_crafted_input_gives_one_line(index, files, tmp_path, capsys, monkeypatch) -> None:
    """Every crafted file of scripts/corrupt_files.py (a `scene` attribute nested 20 000 deep, an int or an array;
    /global/mu as strings or a compound type; /global/time a group; a 2-D /patches/x; a checkpoint array of
    another shape; datasets declaring 2^28 or 2^40 rows, never written; an external or a soft link; TOML scenes
    and specs nested 20 000 deep, or of 64 GiB, refused unread), fed to each command that reads it: one line, exit
    2, nothing written."""
    case, command, prepare = CORRUPT.crafted_trials(files)[index]
    monkeypatch.chdir(tmp_path)
    argv = prepare(tmp_path)
    line = one_error_line(capsys, argv)
    assert "larger than 64 MiB" in line if case.startswith("oversized") else "larger than" not in line, line
    assert not (tmp_path / "out.h5").exists() and not (tmp_path / "sweep").exists()
    assert not list(tmp_path.glob("*.partial")) and not list(tmp_path.glob("figs/*"))
