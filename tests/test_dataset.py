"""``aca_warp.open_run``: HF, LF and sweep-shard run files as xarray Datasets (values, units, attributes), an
incomplete and a killed run, lazy reading of large per-patch histories, and one-line refusals."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
import xarray as xr

import aca_warp
from aca_warp.common.errors import SceneError
from aca_warp.dataset import open_run, open_snapshots

LF_DOC = {
    "scene": {"name": "tiny"},
    "pad": {"r_inner": 0.100, "r_outer": 0.110, "span_deg": 8.0},
    "patches": {"count": 30, "area_min": 2e-8, "area_max": 8e-8, "height": 3e-6, "seed": 5},
    "lf": {"capacity": 512, "p_birth": 1.0, "p_comp": 1e4, "p_store": 0.3, "wear_m": 2e-12, "lam0": 2.0},
    "snapshots": {"applications": True},
    "schedule": [
        {"kind": "application", "duration": 0.15, "normal_force": 300.0, "ramp": 0.03},
        {"kind": "pause", "duration": 0.03},
        {"kind": "application", "duration": 0.1, "normal_force": 200.0},
    ],
}


def _hf_scene(duration: float = 3e-6):
    from aca_warp.scene import Pad, PatchGenerator, Record, Scene

    pad = Pad()
    return Scene(
        name="small", pad=pad, patches=PatchGenerator(count=20, seed=4).generate(pad), normal_force=20.0,
        record=Record(sample_dt=1e-7, patches=("velocity", "displacement")), duration=duration,
    )  # fmt: skip


@pytest.fixture(scope="module")
def hf_run(tmp_path_factory):
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.runner import run_scene

    out = tmp_path_factory.mktemp("hf") / "hf.h5"
    run_scene(_hf_scene(), out, RunOptions(integrator="strang", dt=2e-8), device="cpu")
    return out


@pytest.fixture(scope="module")
def lf_run(tmp_path_factory):
    from aca_warp.lf.commands import run_lf
    from aca_warp.lf.scene import lf_scene_from_dict

    out = tmp_path_factory.mktemp("lf") / "lf.h5"
    run_lf(lf_scene_from_dict(LF_DOC), out)
    return out


def _datasets(f: h5py.Group) -> dict[str, h5py.Dataset]:
    out = {}
    f.visititems(lambda n, o: out.__setitem__(n, o) if isinstance(o, h5py.Dataset) else None)
    return out


def _assert_variable(v: xr.DataArray, d: h5py.Dataset) -> None:
    np.testing.assert_array_equal(v.values, d[()])
    assert v.attrs["units"] == d.attrs["unit"] and v.attrs["source"] == d.name
    assert v.attrs["long_name"] and v.attrs["long_name"] != d.name, d.name  # a real name for every known dataset


def test_hf_file_round_trips_values_units_and_attributes(hf_run):
    assert aca_warp.open_run is open_run
    ds = open_run(hf_run)
    assert ds.sizes == {"time": 31, "patch": 20, "patch_time": 31, "cell": 1}
    names = {"global": "{}", "patches": "{}", "patches/final": "final_{}", "matrix": "matrix_{}"}
    with h5py.File(hf_run, "r") as f:
        seen = 0
        for path, d in _datasets(f).items():
            group, _, leaf = path.rpartition("/")
            name = "patch_time" if path == "patches/time" else names[group].format(leaf)
            _assert_variable(ds[name], d)
            seen += 1
        assert seen == len(ds.variables) - 1  # every dataset, plus the patch index
        assert ds["velocity"].dims == ("patch_time", "patch") and ds["mu"].dims == ("time",)
        assert ds["velocity"].attrs["units"] == "m s-1" and ds["x"].attrs["units"] == "m"
        assert ds.attrs["scene"] == json.loads(f.attrs["scene"]) and isinstance(ds.attrs["scene"], dict)
        assert ds.attrs["run_options"] == json.loads(f.attrs["run_options"])
        assert ds.attrs["versions"]["h5py"] == h5py.__version__
        assert ds.attrs["stages"] == json.loads(f.attrs["stages"])
    assert ds.attrs["complete"] is True and ds.attrs["status"] == "complete" and ds.attrs["kind"] == "hf"
    assert ds.attrs["integrator"] == "strang" and "truncated" not in ds.attrs
    # labelled selection works as in a notebook
    assert float(ds.mu.sel(time=1e-6, method="nearest")) == pytest.approx(float(ds.mu[10]))


def test_large_histories_are_read_lazily(hf_run):
    """Above eager_bytes the per-patch history stays in the file until indexed; the file closes with the Dataset."""
    with h5py.File(hf_run, "r") as f:
        v = f["patches/velocity"][()]
    ds = open_run(hf_run, eager_bytes=0)
    sub = ds.velocity[3::4, [2, 7, 11]]
    np.testing.assert_array_equal(sub.values, v[3::4][:, [2, 7, 11]])
    np.testing.assert_array_equal(ds.displacement.isel(patch=5).values[-3:], ds.displacement.values[-3:, 5])
    mu = ds.mu.values.copy()
    ds.close()
    np.testing.assert_array_equal(ds.mu.values, mu)  # 1-D outputs were read at once
    with pytest.raises(ValueError, match="read lazily and its run file was closed"):
        _ = ds.velocity.values
    eager = open_run(hf_run)
    eager.close()
    np.testing.assert_array_equal(eager.velocity.values, v)


def test_lf_file_round_trips_series_and_snapshots(lf_run):
    ds = open_run(lf_run)
    assert ds.attrs["kind"] == "lf" and ds.attrs["complete"] is True
    assert ds.attrs["scene"]["lf"]["capacity"] == 512 and ds.attrs["lf_run"]["duration"] is None
    names = {
        "global": ("{}", "time"),
        "initial_patches": ("initial_{}", "initial_patch"),
        "calibration": ("{}", "death"),
    }
    snaps = open_snapshots(lf_run)
    with h5py.File(lf_run, "r") as f:
        for group, (fmt, dim) in names.items():
            for leaf, d in f[group].items():
                _assert_variable(ds[fmt.format(leaf)], d)
                assert ds[fmt.format(leaf)].dims == (dim,)
        assert ds.sizes["time"] == 28 and ds["normal_force"].attrs["long_name"] == "clamp force F_N"
        order = sorted(f["snapshots"], key=lambda n: f["snapshots"][n].attrs["time"])
        assert ds.attrs["snapshots"] == list(snaps) == order == ["app1_start", "app1_end", "app2_start", "app2_end"]
        for name, s in snaps.items():
            g = f["snapshots"][name]
            for part, fmt in (("patches", "{}"), ("matrix", "matrix_{}"), ("rings", "ring_{}")):
                for leaf, d in g[part].items():
                    _assert_variable(s[fmt.format(leaf)], d)
            assert s["normal_force"].dims == ("patch",) and s["matrix_store"].dims == ("cell",)
            assert float(s["time"]) == g.attrs["time"] and s["time"].attrs["units"] == "s"
            assert float(s["clamp_force"]) == g.attrs["normal_force"] and s["clamp_force"].attrs["units"] == "N"
            assert s.attrs["snapshot"] == name and s.attrs["kind"] == "lf"
    with pytest.raises(SceneError, match="no snapshot 'app9_end'.*app1_start, app1_end"):
        open_run(lf_run, snapshot="app9_end")


def test_incomplete_and_killed_runs_say_so(tmp_path, monkeypatch, hf_run):
    from aca_warp.hf import runfile
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.runner import run_scene

    real = runfile.RunWriter.write

    def write_then_interrupt(self, chunk):
        real(self, chunk)
        raise KeyboardInterrupt

    monkeypatch.setattr(runfile.RunWriter, "write", write_then_interrupt)
    out = tmp_path / "stopped.h5"
    with pytest.raises(KeyboardInterrupt):
        # the general engine: several chunks (on the CPU the on-chip engine's first launch is the whole run)
        run_scene(_hf_scene(2e-5), out, RunOptions(integrator="strang", dt=2e-8, engine="general"), device="cpu")
    ds = open_run(out)
    assert ds.attrs["complete"] is False and ds.attrs["status"] == "interrupted by the user"
    assert 0 < ds.sizes["time"] < 201 and ds.sizes["patch_time"] == ds.sizes["time"]
    # a killed run leaves NAME.partial, marked running, /global possibly written further for some datasets
    part = tmp_path / "killed.h5.partial"
    shutil.copy(hf_run, part)
    with h5py.File(part, "r+") as f:
        f.attrs["complete"] = False
        f.attrs["status"] = "running"
        f["global/mu"].resize(25, axis=0)
    ds = open_run(part)
    assert ds.attrs["partial"] is True and ds.attrs["complete"] is False and ds.attrs["status"] == "running"
    assert ds.sizes["time"] == 25 and "/global" in ds.attrs["truncated"] and "25" in ds.attrs["truncated"]
    with h5py.File(hf_run, "r") as f:
        np.testing.assert_array_equal(ds.torque.values, f["global/torque"][:25])


def test_sweep_shard_has_a_pad_dimension(tmp_path):
    from aca_warp.sweep import load_spec, run_sweep

    doc = {
        "sweep": {"base": "hf1", "shard_size": 3},
        "run": {"duration": 4e-6, "precision": "fp32"},
        "base": {"patches": {"count": 25}},
        "parameters": {"friction.M": [0.6, 0.8], "initial.state": ["rest", "equilibrium"]},
    }
    run_sweep(load_spec(doc, base_dir=Path.cwd()), tmp_path / "sw", device="cpu", workers=0)
    shard = tmp_path / "sw" / "shard-00001.h5"
    ds = open_run(shard)
    assert ds.attrs["kind"] == "sweep_shard" and ds.mu.dims == ("pad", "time") and ds.sizes == {"pad": 1, "time": 5}
    assert ds["pad"].values.tolist() == [3] and ds["initial.state"].values.tolist() == ["equilibrium"]
    assert float(ds["friction.M"][0]) == 0.8 and ds.mu.attrs["units"] == "1"
    with h5py.File(shard, "r") as f:
        np.testing.assert_array_equal(ds.torque.values, f["global/torque"][()])


def test_non_run_files_are_refused_in_one_line(tmp_path, hf_run):
    plain = tmp_path / "plain.h5"
    with h5py.File(plain, "w") as f:
        f["global/time"] = np.arange(3.0)
    text = tmp_path / "notes.h5"
    text.write_text("not HDF5\n")
    for path, message in (
        (plain, "not an aca_warp run file"),
        (text, "not an HDF5 file"),
        (tmp_path / "missing.h5", "not found"),
    ):
        with pytest.raises(SceneError, match=message) as e:
            open_run(path)
        assert "\n" not in str(e.value)
    with pytest.raises(SceneError, match="only LF run files hold snapshots"):
        open_run(hf_run, snapshot="app1_end")
    with pytest.raises(SceneError, match="not an LF run file"):
        open_snapshots(hf_run)
