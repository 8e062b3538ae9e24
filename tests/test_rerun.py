"""`aca-warp rerun RUN.h5 -o NEW.h5`: a run file alone (its patch file deleted) reproduces the run bit for bit."""

from __future__ import annotations

import json

import h5py
import numpy as np
from procs import datasets

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


def test_rerun_names_what_it_applies_and_keeps_the_size_limits(tmp_path, capsys):
    """A run file whose stored options relax checks (force, the watchdog off, allow_implausible) and ask for 1e5 s
    at strang's default for a small scene, 5e-8 s (2e12 steps, 1e8 samples): `rerun` names each stored relaxation on
    stderr and refuses the run with one line, nothing written (before: silently applied, and a 1e13-step run
    started); the same file asking for 2 µs reruns, with the same note."""
    from procs import small_scene_toml

    (tmp_path / "s.toml").write_text(small_scene_toml("relaxed", count=10, duration=2.0e-6))
    run = tmp_path / "run.h5"
    # a fixed-step run: its step count is what the size limits bound
    assert main(["hf", str(tmp_path / "s.toml"), "-o", str(run), "--no-progress", "--integrator", "strang"]) == 0
    for duration, code in ((1.0e5, 2), (2.0e-6, 0)):
        with h5py.File(run, "r+") as f:
            options = {**json.loads(f.attrs["run_options"]), "force": True, "watchdog_factor": None}
            f.attrs["run_options"] = json.dumps({**options, "duration": duration})
            scene = json.loads(f.attrs["scene"])
            scene["scene"]["allow_implausible"] = True
            scene["run"]["duration"] = duration
            scene["record"]["sample_dt"] = 1e-3 if duration > 1 else 1e-7  # 1e8 samples: below the sample limits
            f.attrs["scene"] = json.dumps(scene)
        capsys.readouterr()
        new = tmp_path / f"new-{code}.h5"
        assert main(["rerun", str(run), "-o", str(new), "--no-progress"]) == code
        err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("aca-warp:")]
        note = f"aca-warp: note: {run} stores, and the rerun applies: force ("
        assert err[0].startswith(note) and "the watchdog off" in err[0] and "allow_implausible" in err[0], err
        if code == 2:
            assert len(err) == 2 and "2e+12 steps, more than 1e+10" in err[1] and "--force runs it anyway" in err[1]
            assert not new.exists() and not new.with_name(new.name + ".partial").exists()
        else:
            with h5py.File(new, "r") as f:
                assert f.attrs["complete"] and json.loads(f.attrs["run_options"])["watchdog_factor"] is None


def test_rerun_repeats_the_crossing_treatment(tmp_path, capsys):
    """A run with strang's crossing treatment (``--crossing mean``) is repeated with it, bit for bit; a file that
    stores no treatment (written before there was a choice) is repeated with the point treatment, the only one then,
    not with today's default."""
    src = load_scene("hf1").patches
    keep = np.flatnonzero((np.abs(src.x) < 4e-3) & (np.abs(src.y - 0.13) < 4e-3))
    write_patch_file(tmp_path / "patches.h5", type(src)(src.x[keep], src.y[keep], src.area[keep], src.height[keep]))
    (tmp_path / "s.toml").write_text(SCENE)
    run, new = tmp_path / "run.h5", tmp_path / "new.h5"
    assert main(["hf", str(tmp_path / "s.toml"), "-o", str(run), "--no-progress", "--crossing", "mean"]) == 0
    assert read_settings(run).options.crossing == "mean"
    assert main(["rerun", str(run), "-o", str(new), "--no-progress"]) == 0
    a, b = datasets(run), datasets(new)
    assert all(a[k].tobytes() == b[k].tobytes() for k in a)
    with h5py.File(run, "r+") as f:
        doc = json.loads(f.attrs["run_options"])
        f.attrs["run_options"] = json.dumps({k: v for k, v in doc.items() if k != "crossing"})
    assert read_settings(run).options.crossing == "point"
