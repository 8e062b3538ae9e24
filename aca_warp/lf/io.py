"""LF run files and snapshots; :func:`scene_from_snapshot` turns a saved patch coverage state into an HF scene.

Layout of an LF run file (docs/lf_model.md "Run file")::

    /global/time, mu, torque, friction_radius, patch_count, coverage,            (steps,)  one row per LF step
            disc_temperature_mean, disc_temperature_max, patch_temperature, patch_share, normal_force,
            births, deaths, merges, gap
    /snapshots/NAME/patches/x, y, area, height, thickness, normal_force, temperature, age, power   (n,)
    /snapshots/NAME/matrix/area, radius, height, x, y, normal_force, temperature, store             (C,)
    /snapshots/NAME/rings/radius, temperature, bulge                                               (R,)
    /calibration/death_age, death_area                                                             (deaths,)

Every dataset has a ``unit`` attribute; snapshot groups carry ``time``, ``normal_force``, ``angular_velocity``,
``gap`` and ``height_shift`` attributes. Root attributes: ``scene`` (JSON, :func:`lf_scene_to_dict`),
``kind = "lf"``, ``device``, ``versions``, ``complete``, ``status``, ``steps``, ``wall_time``. The file is written
as ``NAME.partial`` and renamed when the run ends.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from aca_warp.errors import SceneError
from aca_warp.io import check_output_path, machine, versions
from aca_warp.kernels.lf import H_NAMES, H_UNITS
from aca_warp.lf.scene import lf_scene_to_dict
from aca_warp.lf.solver import LFSimulation
from aca_warp.scene import Friction, Material, Matrix, Pad, Patches, Scene

_UNITS = {
    "x": "m", "y": "m", "area": "m2", "height": "m", "thickness": "m", "normal_force": "N", "temperature": "K",
    "age": "s", "power": "W", "radius": "m", "store": "kg", "bulge": "m",
}  # fmt: skip


class LFRunWriter:
    """Writes an LF run file: snapshots as they come, the global time series and calibration data at the end."""

    def __init__(self, path: str | Path, sim: LFSimulation, *, overwrite: bool = False) -> None:
        self.path = check_output_path(path, overwrite=overwrite)
        self.partial = self.path.with_name(self.path.name + ".partial")
        self.sim = sim
        self.f = h5py.File(self.partial, "w")
        f = self.f
        f.attrs["kind"] = "lf"
        f.attrs["scene"] = json.dumps(lf_scene_to_dict(sim.scene))
        f.attrs["scene_name"] = sim.scene.name
        f.attrs["versions"] = json.dumps(versions())
        for k, v in machine(sim.device).items():
            f.attrs[k] = v
        f.attrs["precision"] = "fp64"
        f.attrs["grid"] = json.dumps(
            {"rings": sim.n_r, "columns": sim.n_t, "cells": sim.n_cells, "capacity": sim.capacity}
        )
        f.attrs["complete"] = False
        f.attrs["status"] = "running"
        f.create_group("snapshots")

    def snapshot(self, name: str, sim: LFSimulation) -> None:
        """Save ``sim``'s current patch coverage state under /snapshots/NAME (the run loop's callback)."""
        write_snapshot(self.f["snapshots"].create_group(name), sim.snapshot())
        self.f.flush()

    def close(self, *, complete: bool, status: str, attrs: dict[str, Any] | None = None) -> Path:
        """Write the time series and closing attributes, close, and move the file to its final name."""
        f = self.f
        h = self.sim.history()
        g = f.create_group("global")
        g.create_dataset("time", data=h["time"]).attrs["unit"] = "s"
        for name, unit in zip(H_NAMES, H_UNITS, strict=True):
            g.create_dataset(name, data=h[name]).attrs["unit"] = unit
        n = min(int(self.sim.death_count.numpy()[0]), self.sim.death_age.shape[0])
        c = f.create_group("calibration")
        c.create_dataset("death_age", data=self.sim.death_age.numpy()[:n]).attrs["unit"] = "s"
        c.create_dataset("death_area", data=self.sim.death_area.numpy()[:n]).attrs["unit"] = "m2"
        f.attrs["complete"] = complete
        f.attrs["status"] = status
        f.attrs["steps"] = self.sim.step_index
        for k, v in (attrs or {}).items():
            f.attrs[k] = v if isinstance(v, (str, int, float, bool, np.number)) else json.dumps(v)
        f.close()
        os.replace(self.partial, self.path)
        return self.path


def write_snapshot(group: h5py.Group, snap: dict[str, Any]) -> None:
    """Write a :meth:`LFSimulation.snapshot` dict into ``group`` (unit attributes on every dataset)."""
    for part in ("patches", "matrix", "rings"):
        sub = group.create_group(part)
        for k, v in snap[part].items():
            sub.create_dataset(k, data=np.asarray(v, dtype=np.float64)).attrs["unit"] = _UNITS[k]
    for k, v in snap["attrs"].items():
        group.attrs[k] = v


def snapshot_names(path: str | Path) -> list[str]:
    """Names of the snapshots in an LF run file, in time order."""
    with _open(path) as f:
        g = f["snapshots"]
        return sorted(g, key=lambda n: float(g[n].attrs["time"]))


def _open(path: str | Path) -> h5py.File:
    p = Path(path)
    if not p.is_file():
        raise SceneError(f"LF run file not found: {p}")
    try:
        f = h5py.File(p, "r")
    except OSError as e:
        raise SceneError(f"cannot read {p}: {e}") from None
    if f.attrs.get("kind") != "lf" or "snapshots" not in f:
        f.close()
        raise SceneError(f"{p} is not an LF run file (no kind = 'lf' attribute or /snapshots group)")
    return f


def read_snapshot(path: str | Path, name: str) -> dict[str, Any]:
    """One snapshot as nested dicts of arrays plus its ``attrs``."""
    with _open(path) as f:
        if name not in f["snapshots"]:
            names = ", ".join(sorted(f["snapshots"])) or "none"
            raise SceneError(f"no snapshot {name!r} in {path}; it has: {names}")
        g = f["snapshots"][name]
        out: dict[str, Any] = {part: {k: g[part][k][()] for k in g[part]} for part in ("patches", "matrix", "rings")}
        out["attrs"] = {k: (v.item() if hasattr(v, "item") else v) for k, v in g.attrs.items()}
        out["scene"] = json.loads(f.attrs["scene"])
    return out


def scene_from_snapshot(path: str | Path, name: str, *, duration: float | None = None) -> Scene:
    """An HF scene of a saved LF state: its patches (areas frozen), matrix cells, load, speed and friction law.

    The HF contact solve of the returned scene reproduces the snapshot's normal forces (same springs, same
    elevations). Material constants come from the LF scene's ``[material]``; recording defaults are HF's.
    """
    s = read_snapshot(path, name)
    doc = s["scene"]
    p = s["patches"]
    if len(p["x"]) == 0:
        raise SceneError(f"snapshot {name!r} has no patches; an HF scene needs at least one")
    patches = Patches(p["x"], p["y"], p["area"], p["height"], source=f"{path}:/snapshots/{name}")
    m = s["matrix"]
    matrix = Matrix(m["area"], m["radius"], m["height"])
    a = s["attrs"]
    kw: dict[str, Any] = {}
    if duration is not None:
        kw["duration"] = duration
    return Scene(
        name=f"{doc['scene']['name']}:{name}",
        pad=Pad(**doc["pad"]),
        patches=patches,
        material=Material(**doc["material"]),
        friction=Friction(**doc["friction"]),
        normal_force=float(a["normal_force"]),
        angular_velocity=float(a["angular_velocity"]),
        matrix=matrix,
        **kw,
    )
