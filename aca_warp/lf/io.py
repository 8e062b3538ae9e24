"""LF run files and snapshots; :func:`scene_from_snapshot` turns a saved patch coverage state into an HF scene.

Layout of an LF run file (docs/lf_model.md "Run file")::

    /global/time, mu, torque, friction_radius, patch_count, coverage,            (steps,)  one row per LF step
            disc_temperature_mean, disc_temperature_max, patch_temperature, patch_share, normal_force,
            births, deaths, merges, gap
    /snapshots/NAME/patches/x, y, area, height, thickness, normal_force, temperature, age, power   (n,)
    /snapshots/NAME/matrix/area, radius, height, x, y, normal_force, temperature, store             (C,)
    /snapshots/NAME/rings/radius, temperature, bulge                                               (R,)
    /calibration/death_age, death_area                                                             (deaths,)
    /initial_patches/x, y, area, height                                               (n0,)  initial patches
    /checkpoint/...                  only while a run is unfinished, after its first checkpoint

Every dataset has a ``unit`` attribute; snapshot groups carry ``time``, ``normal_force``, ``angular_velocity``,
``gap`` and ``height_shift`` attributes. Root attributes: ``scene`` (JSON, :func:`lf_scene_to_dict`), ``kind =
"lf"``, ``lf_run`` (JSON: ``duration`` [s] or null for the whole schedule, ``checkpoint_interval`` [s], 0 for none
or null for automatic, ``graph``), ``device``, ``versions``, ``complete``, ``status``, ``steps``, ``wall_time``. The
file is written as ``NAME.partial`` and renamed when the run ends. /global grows at checkpoints (and at the end), so
a killed run's ``.partial`` holds every row up to its last checkpoint; ``aca-warp lf --resume`` continues it from
there, or from its start when it has none (:meth:`LFRunWriter.reopen`) and ``aca-warp rerun`` repeats a finished
one. The lock, the ``.partial`` and a full device are handled as for every run file (:mod:`aca_warp.common.runfile`).
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from aca_warp.common.bounds import json_attribute
from aca_warp.common.checkpoint import (
    closed_on_failure,
    drop_checkpoint,
)
from aca_warp.common.errors import SceneError
from aca_warp.common.files import (
    OutputLock,
    check_output_path,
    machine,
    open_h5,
    reading,
    versions,
)
from aca_warp.common.runfile import RunFileWriter, write_attrs
from aca_warp.kernels.lf_record import H_NAMES, H_UNITS
from aca_warp.lf.scene import lf_scene_to_dict, load_lf_scene
from aca_warp.lf.solver import LFSimulation
from aca_warp.scene import Friction, Material, Matrix, Pad, Patches, Scene
from aca_warp.scene.regimes import measured_origin

_UNITS = {
    "x": "m", "y": "m", "area": "m2", "height": "m", "thickness": "m", "normal_force": "N", "temperature": "K",
    "age": "s", "power": "W", "radius": "m", "store": "kg", "bulge": "m",
}  # fmt: skip


class LFRunWriter(RunFileWriter):
    """Writes an LF run file: snapshots as they come, the global time series and calibration data at the end."""

    def __init__(
        self,
        path: str | Path,
        sim: LFSimulation,
        *,
        overwrite: bool = False,
        run: dict[str, Any] | None = None,
        lock: OutputLock | None = None,
    ) -> None:
        self.sim = sim
        self.rows = 0
        self._create(path, check_output_path, overwrite=overwrite, lock=lock, header=lambda: self._write_header(run))

    def _write_header(self, run: dict[str, Any] | None) -> None:
        """Attributes, the initial patches and the empty /global datasets."""
        f, sim = self.f, self.sim
        f.attrs["lf_run"] = json.dumps(run or {"duration": None, "checkpoint_interval": None})
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
        if sim.scene.patches is not None:  # the initial patches, so that a rerun needs no generator
            ip = f.create_group("initial_patches")
            for k in ("x", "y", "area", "height"):
                data = np.asarray(getattr(sim.scene.patches, k), np.float64)
                self.out.reserve(data.nbytes)
                ip.create_dataset(k, data=data).attrs["unit"] = _UNITS[k]
        chunk = (min(max(sim.table.steps, 1), 4096),)
        g = f.create_group("global")
        for name, unit in (("time", "s"), *zip(H_NAMES, H_UNITS, strict=True)):
            g.create_dataset(name, shape=(0,), maxshape=(None,), dtype="f8", chunks=chunk).attrs["unit"] = unit

    @classmethod
    def reopen(cls, partial: str | Path, sim: LFSimulation, *, lock: OutputLock) -> LFRunWriter:
        """Open a killed or stopped LF run's ``NAME.partial`` to continue it (``lock``: the lock of ``NAME``, held;
        the caller releases it when this fails): restore ``sim`` from its checkpoint, cut /global back to the
        checkpoint's rows, drop the snapshots taken after it, mark it running again. Without a checkpoint ``sim``
        starts from the beginning: /global and the snapshots are emptied."""
        self = cls.__new__(cls)
        self._open_partial(partial, lock)
        self.sim = sim
        f = self.f
        with closed_on_failure(f, self.partial, close=self.out.abandon):
            ckpt = self._stored_checkpoint()  # None: from the start
            rows = 0 if ckpt is None else int(ckpt.rows["global"])
            if ckpt is not None and rows != int(ckpt.counters["step_index"]):
                raise ValueError(f"{rows} rows of /global for step {ckpt.counters['step_index']}")
            g = f["global"]
            for name in ("time", *H_NAMES):
                if g[name].shape[0] < rows:
                    raise ValueError(f"/global/{name} has {g[name].shape[0]} rows, the checkpoint {rows}")
                g[name].resize(rows, axis=0)
            hist = np.column_stack([g[name][()] for name in H_NAMES]) if rows else None
            keep = [n for n, s in sim.table.snapshots if s < rows]
            if len(keep) != (0 if ckpt is None else int(ckpt.counters["snapshots"])) or not set(keep) <= set(
                f["snapshots"]
            ):
                raise ValueError("the snapshots do not match the checkpoint")
            for name in list(f["snapshots"]):
                if name not in keep:
                    del f["snapshots"][name]  # taken after the checkpoint: the resumed run takes it again
            if "calibration" in f:
                del f["calibration"]  # written when a stopped run was closed; rewritten at the end
        if ckpt is not None:
            with closed_on_failure(f, self.partial, scene_error=False, close=self.out.abandon):
                sim.restore(ckpt, hist)
        self.rows = rows
        self._mark_running(ckpt)
        return self

    def _append_rows(self) -> None:
        """Append the history rows of the steps done since the last call to /global."""
        n = self.sim.step_index
        if n <= self.rows:
            return
        h = self.sim.hist.numpy()[self.rows : n]
        g = self.f["global"]
        t = (np.arange(self.rows, n) + 1) * self.sim.scene.lf.dt
        for name in ("time", *H_NAMES):
            self.out.touch(g[name], self.rows, n)
        self.out.reserve()
        for name, col in (("time", t), *zip(H_NAMES, h.T, strict=True)):
            g[name].resize(n, axis=0)
            g[name][self.rows :] = col
        self.rows = n

    def snapshot(self, name: str, sim: LFSimulation) -> None:
        """Save ``sim``'s current patch coverage state under /snapshots/NAME (the run loop's callback)."""
        snap = sim.snapshot()
        self.out.reserve(sum(8 * np.size(v) for part in ("patches", "matrix", "rings") for v in snap[part].values()))
        write_snapshot(self.f["snapshots"].create_group(name), snap)
        self.out.flush()

    def checkpoint(self, sim: LFSimulation) -> None:
        """Store the run's state (the run loop's ``on_checkpoint``): /global up to this step, then the state into
        the inactive checkpoint slot (:func:`aca_warp.common.checkpoint.write_checkpoint`: flush, flip, flush)."""
        self._append_rows()
        ckpt = sim.checkpoint_state()
        ckpt.rows = {"global": self.rows}
        self._store_checkpoint(ckpt)

    def _write_closing(self, complete: bool, status: str, attrs: dict[str, Any]) -> None:
        """The rest of the time series, the calibration data and the closing attributes (a complete run drops its
        checkpoint; a stopped one keeps it for ``aca-warp lf --resume``)."""
        f = self.f
        self._append_rows()
        n = min(int(self.sim.death_count.numpy()[0]), self.sim.death_age.shape[0])
        self.out.reserve(16 * n)
        c = f.create_group("calibration")
        c.create_dataset("death_age", data=self.sim.death_age.numpy()[:n]).attrs["unit"] = "s"
        c.create_dataset("death_area", data=self.sim.death_area.numpy()[:n]).attrs["unit"] = "m2"
        f.attrs["complete"] = complete
        f.attrs["status"] = status
        f.attrs["steps"] = self.sim.step_index
        if complete:
            drop_checkpoint(f)
        write_attrs(f, attrs)


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
    with reading(path, "LF run file"), _open(path) as f:
        g = f["snapshots"]
        return sorted(g, key=lambda n: float(g[n].attrs["time"]))


def _open(path: str | Path) -> h5py.File:
    p = Path(path)
    f = open_h5(p, "LF run file")
    if f.attrs.get("kind") != "lf" or "snapshots" not in f:
        hf = "run_options" in f.attrs
        f.close()
        hint = f": an HF run file, repeated with 'aca-warp rerun {p} -o NEW.h5'" if hf else ""
        raise SceneError(f"{p} is not an LF run file (no kind = 'lf' attribute or /snapshots group){hint}")
    return f


def read_snapshot(path: str | Path, name: str) -> dict[str, Any]:
    """One snapshot as nested dicts of arrays plus its ``attrs``."""
    with reading(path, "LF run file"), _open(path) as f:
        if name not in f["snapshots"]:
            names = ", ".join(sorted(f["snapshots"])) or "none"
            raise SceneError(f"no snapshot {name!r} in {path}; it has: {names}")
        g = f["snapshots"][name]
        out: dict[str, Any] = {part: {k: g[part][k][()] for k in g[part]} for part in ("patches", "matrix", "rings")}
        out["attrs"] = {k: (v.item() if hasattr(v, "item") else v) for k, v in g.attrs.items()}
        try:
            out["scene"] = json_attribute(f.attrs["scene"], f"{path}: attribute 'scene'")
        except (KeyError, TypeError, ValueError) as e:
            raise SceneError(f"{path}: the stored LF scene is missing or damaged ({type(e).__name__}: {e})") from None
    return out


# the LF states of the multiscale preset whose HF statistics keep every measure at 1e-7 s with the point treatment of
# zero-slip crossings and at 2.5e-7 s with the crossings averaged (strang's default for them): the statistical
# work-precision's groups ms_mid (app1_end, app4_start, app4_end) and ms_app3 (app3_start, app3_end), one pad per state
# and LF seed (docs/work_precision_statistics.md); ms_fast (app2_start) and ms_short (app1_start, app2_end) need 5e-8 s
STATES_AT_PRESET_STEP = ("app1_end", "app4_start", "app4_end", "app3_start", "app3_end")


def _lf_physics(doc: dict) -> dict:
    """An LF scene document less what does not set the states' physics: its name, its snapshots and its seeds (the
    LF run's random numbers and the initial patches' layout)."""
    out = {k: v for k, v in doc.items() if k not in ("scene", "snapshots")}
    out["lf"] = {**out["lf"], "seed": None}
    out["patches"] = {**out["patches"], "seed": None}
    return out


@cache
def _preset_lf_physics() -> dict:
    return _lf_physics(json.loads(json.dumps(lf_scene_to_dict(load_lf_scene("multiscale")))))


def lf_state_regime(doc: dict, snapshot: str) -> str | None:
    """The measured regime of the HF scene of state ``snapshot`` of an LF run of scene document ``doc`` (as its run
    file stores it): ``multiscale <snapshot>`` for a state of :data:`STATES_AT_PRESET_STEP` of the multiscale preset
    with any seed, else None (``strang`` then takes its default for any other scene)."""
    if snapshot not in STATES_AT_PRESET_STEP:
        return None
    try:
        same = _lf_physics(doc) == _preset_lf_physics()
    except (KeyError, TypeError, AttributeError):  # a document of another shape: no preset's
        return None
    return f"multiscale {snapshot}" if same else None


def scene_from_snapshot(
    path: str | Path, name: str, *, duration: float | None = None, allow_implausible: bool = False
) -> Scene:
    """An HF scene of a saved LF state: its patches (areas frozen), matrix cells, load, speed and friction law.

    The HF contact solve of the returned scene reproduces the snapshot's normal forces (same springs, same
    elevations). Material constants come from the LF scene's ``[material]``; recording defaults are HF's. The
    scene accepts implausible values when ``allow_implausible`` or the LF scene did. A state of
    :data:`STATES_AT_PRESET_STEP` of an LF run of the multiscale preset is marked as its measured regime in the
    scene's ``origin`` (:func:`lf_state_regime`, :func:`~aca_warp.scene.regimes.measured_origin`): ``strang`` then
    takes :data:`~aca_warp.hf.options.PRESET_STEP` and :data:`~aca_warp.hf.options.PRESET_CROSSING` by default.
    """
    s = read_snapshot(path, name)
    doc = s["scene"]
    try:
        p = s["patches"]
        if len(p["x"]) == 0:
            raise SceneError(f"snapshot {name!r} has no patches; an HF scene needs at least one")
        patches = Patches(p["x"], p["y"], p["area"], p["height"], source=f"{path}:/snapshots/{name}")
        m = s["matrix"]
        matrix = Matrix(m["area"], m["radius"], m["height"])
    except SceneError as e:
        raise SceneError(f"{path}: snapshot {name!r} is not a valid HF scene: {e}") from None
    except (KeyError, TypeError, ValueError) as e:
        raise SceneError(f"{path}: snapshot {name!r} is incomplete or damaged ({type(e).__name__}: {e})") from None
    a = s["attrs"]
    load, omega = float(a.get("normal_force", 0.0)), float(a.get("angular_velocity", 0.0))
    if not (load > 0.0 and omega != 0.0):
        raise SceneError(
            f"{path}: snapshot {name!r} was taken with the pad unloaded or the disc at rest (normal force {load:g} N, "
            f"angular velocity {omega:g} rad/s: a pause of the schedule); its HF run would have no friction to "
            "vibrate: choose a snapshot of an application"
        )
    kw: dict[str, Any] = {}
    if duration is not None:
        kw["duration"] = duration
    try:
        scene = Scene(
            name=f"{doc['scene']['name']}:{name}",
            pad=Pad(**doc["pad"]),
            patches=patches,
            material=Material(**doc["material"]),
            friction=Friction(**doc["friction"]),
            normal_force=float(a["normal_force"]),
            angular_velocity=float(a["angular_velocity"]),
            matrix=matrix,
            allow_implausible=allow_implausible or doc["scene"].get("allow_implausible", False) is True,
            **kw,
        )
    except SceneError as e:
        raise SceneError(f"{path}: snapshot {name!r} is not a valid HF scene: {e}") from None
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise SceneError(f"{path}: snapshot {name!r} is incomplete or damaged ({type(e).__name__}: {e})") from None
    regime = lf_state_regime(doc, name)
    return scene if regime is None else scene.replace(origin=measured_origin(scene, regime))
