"""`aca-warp rerun RUN.h5 -o NEW.h5`: a run file alone (its patch file deleted) reproduces the run bit for bit."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np

from aca_warp.cli import main
from aca_warp.hf.rerun import read_settings
from aca_warp.scene import load_scene, scene_to_dict, write_patch_file

SCENE = """
[scene]
name = "from-file"
[load]
normal_force = 30.0
[disc]
sliding_speed = 8.0
[patches]
file = "patches.h5"
[initial]
state = "equilibrium"
perturbation = 2.0e-3
seed = 7
[record]
sample_dt = 2.0e-7
patches = ["displacement"]
window = [1.0e-6, 4.0e-6]
decimation = 2
[run]
duration = 5.0e-6
"""


def datasets(path: Path) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda n, o: out.__setitem__(n, o[()]) if isinstance(o, h5py.Dataset) else None)
    return out


def test_rerun_without_the_patch_file_is_bit_identical(tmp_path, capsys):
    """A scene whose patches come from a file, seeded perturbation, equilibrium start, a patch-history window and
    the adaptive integrator: after the patch file is deleted, `rerun` rebuilds the scene from the run file and the
    new file equals the old one in every dataset and in the stored scene; the output needs --overwrite."""
    src = load_scene("hf1").patches
    keep = np.flatnonzero((np.abs(src.x) < 4e-3) & (np.abs(src.y - 0.13) < 4e-3))
    write_patch_file(tmp_path / "patches.h5", type(src)(src.x[keep], src.y[keep], src.area[keep], src.height[keep]))
    (tmp_path / "s.toml").write_text(SCENE)
    run = tmp_path / "run.h5"
    argv = ["hf", str(tmp_path / "s.toml"), "-o", str(run), "--no-progress", "--integrator", "adaptive"]
    assert main([*argv, "--tolerance", "1e-5"]) == 0
    (tmp_path / "patches.h5").unlink()

    s = read_settings(run)
    o = s.options
    assert o.integrator == "adaptive" and o.tolerance == 1e-5 and s.precision == "fp64" and s.device == "cpu"
    assert s.scene.patches.count == len(keep)
    with h5py.File(run, "r") as f:
        assert scene_to_dict(s.scene) == json.loads(f.attrs["scene"])

    new = tmp_path / "new.h5"
    assert main(["rerun", str(run), "-o", str(new), "--no-progress"]) == 0
    a, b = datasets(run), datasets(new)
    assert sorted(a) == sorted(b) and "patches/displacement" in a
    for k in a:
        assert a[k].dtype == b[k].dtype and a[k].tobytes() == b[k].tobytes(), k
    with h5py.File(run, "r") as fa, h5py.File(new, "r") as fb:
        for key in ("scene", "integrator", "precision", "device", "steps", "rejected_steps", "stages", "dt"):
            assert fa.attrs[key] == fb.attrs[key], key
    capsys.readouterr()
    assert main(["rerun", str(run), "-o", str(new), "--no-progress"]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert main(["rerun", str(run), "-o", str(run), "--no-progress", "--overwrite"]) == 2
    assert main(["rerun", str(tmp_path / "s.toml"), "-o", str(tmp_path / "x.h5"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(e.startswith("aca-warp: error:") for e in err)
    assert not (tmp_path / "x.h5").exists() and not (tmp_path / "x.h5.partial").exists()
