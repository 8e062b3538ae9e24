"""Run files as labelled xarray Datasets for notebooks: :func:`open_run` and :func:`open_snapshots`.

``aca_warp.open_run(path)`` reads an HF run file (``aca-warp hf``), an LF run file (``aca-warp lf``) or a sweep
shard (``aca-warp sweep``) into an :class:`xarray.Dataset` (docs/run_files.md "Python: xarray"):

* dimensions ``time`` (the global samples, or the LF steps), ``patch``, ``patch_time`` (rows of the per-patch
  histories), ``cell`` (matrix cells), ``pad`` (sweep shards), ``initial_patch`` and ``death`` (LF files);
* every variable carries ``attrs["units"]`` (the dataset's ``unit`` attribute: SI, "1" for dimensionless),
  ``attrs["long_name"]`` and ``attrs["source"]`` (its HDF5 path);
* the root attributes become ``Dataset.attrs``, JSON decoded (``scene``, ``run_options``, ``versions``,
  ``stages``, ``lf_run``, …), plus ``file``, ``kind`` ("hf", "lf" or "sweep_shard") and ``complete``; a run that
  did not finish has ``complete = False`` and ``status`` saying why, a killed run's ``NAME.partial`` also
  ``partial = True``, and rows of a group written unevenly by a killed run are cut to the shortest (``truncated``).

LF snapshots are separate Datasets (their patch sets differ in size): ``open_run(path, snapshot=NAME)`` or
``open_snapshots(path)`` (a dict in time order); ``open_run(path).attrs["snapshots"]`` lists them.

Datasets of up to ``eager_bytes`` (default 256 MiB) are read into memory at once and the file is closed; larger
ones (long per-patch histories) stay in the file and are read when indexed or loaded, which keeps the file open
until ``Dataset.close()`` (or the end of a ``with`` block).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import h5py
import numpy as np
import xarray as xr
from xarray.backends import BackendArray
from xarray.core import indexing

from aca_warp.common.errors import SceneError
from aca_warp.common.files import attr_value, open_h5

EAGER_BYTES = 256 * 2**20
"""Datasets up to this size [bytes] are read at once; larger ones are read lazily."""

_LONG_NAMES = {
    ("global", "time"): "time",
    ("global", "mu"): "global friction coefficient μ (signed with the sliding direction)",
    ("global", "torque"): "friction torque about the disc axis",
    ("global", "friction_radius"): "effective friction radius (torque / total friction force)",
    ("global", "friction_centroid"): "distance of the friction-force centroid from the disc axis |Σ F_i r_i| / |Σ F_i|",
    ("global", "sum_velocity"): "sum of the patch velocities Σ u̇_i (pad frame)",
    ("global", "sum_abs_velocity"): "sum of the absolute patch velocities Σ |u̇_i| (pad frame)",
    ("global", "patch_count"): "alive patches",
    ("global", "coverage"): "patch coverage Σ A_i / pad area",
    ("global", "disc_temperature_mean"): "disc temperature, mean over the rings",
    ("global", "disc_temperature_max"): "disc temperature, hottest ring",
    ("global", "patch_temperature"): "area-weighted patch temperature",
    ("global", "patch_share"): "patches' share of the clamp force",
    ("global", "normal_force"): "clamp force F_N",
    ("global", "births"): "patch births in the step",
    ("global", "deaths"): "patch deaths in the step (merges not counted)",
    ("global", "merges"): "patches absorbed by merges in the step",
    ("global", "gap"): "backplate gap of the contact solve",
    ("global", "contact_passes"): "contact-solve passes in the step",
    ("patches", "time"): "time of the per-patch samples",
    ("patches", "x"): "patch centre x",
    ("patches", "y"): "patch centre y",
    ("patches", "area"): "patch area",
    ("patches", "height"): "patch height (top elevation)",
    ("patches", "mass"): "patch mass",
    ("patches", "normal_force"): "patch normal force (contact solution)",
    ("patches", "predicted_growth_rate"): "predicted linear growth rate σ_i of the patch (steady sliding, start)",
    ("patches", "velocity"): "patch velocity u̇_i (pad frame)",
    ("patches", "displacement"): "patch displacement u_i",
    ("patches", "thickness"): "patch thickness",
    ("patches", "temperature"): "patch temperature",
    ("patches", "age"): "patch age",
    ("patches", "power"): "patch friction power",
    ("final", "area"): "patch area after growth",
    ("final", "normal_force"): "patch normal force after growth",
    ("matrix", "area"): "free (uncovered) matrix area of the cell",
    ("matrix", "radius"): "cell radius",
    ("matrix", "height"): "cell elevation",
    ("matrix", "x"): "cell centre x",
    ("matrix", "y"): "cell centre y",
    ("matrix", "normal_force"): "cell normal force",
    ("matrix", "temperature"): "cell temperature",
    ("matrix", "store"): "debris stored on the cell",
    ("rings", "radius"): "disc ring radius",
    ("rings", "temperature"): "disc ring temperature",
    ("rings", "bulge"): "thermal bulge of the disc ring toward the pad",
    ("initial_patches", "x"): "initial patch centre x",
    ("initial_patches", "y"): "initial patch centre y",
    ("initial_patches", "area"): "initial patch area",
    ("initial_patches", "height"): "initial patch height",
    ("calibration", "death_age"): "age of a patch at its death",
    ("calibration", "death_area"): "area of a patch at its death",
    ("pads", "patch_count"): "patches of the pad",
}

_SNAPSHOT_ATTRS = {
    "time": ("time", "s", "snapshot time"),
    "normal_force": ("clamp_force", "N", "clamp force F_N at the snapshot"),
    "angular_velocity": ("angular_velocity", "rad s-1", "disc angular velocity at the snapshot"),
    "gap": ("gap", "m", "backplate gap of the contact solve (heights shifted by height_shift)"),
    "height_shift": ("height_shift", "m", "constant subtracted from every elevation (lowest element at 0)"),
}


class _H5Array(BackendArray):
    """An HDF5 dataset (its first ``rows`` rows) read only where xarray indexes it."""

    def __init__(self, data: h5py.Dataset, rows: int) -> None:
        self.data = data
        self.shape = (rows, *data.shape[1:])
        self.dtype = data.dtype

    def __getitem__(self, key: Any) -> np.ndarray:
        return indexing.explicit_indexing_adapter(key, self.shape, indexing.IndexingSupport.BASIC, self._read)

    def _read(self, key: tuple) -> np.ndarray:
        if not self.data.id.valid:
            raise ValueError(f"{self.data.name} is read lazily and its run file was closed; open the file again")
        key = tuple(slice(*k.indices(n)) if isinstance(k, slice) else k for k, n in zip(key, self.shape, strict=False))
        return np.asarray(self.data[key])


class _Reader:
    """Turns the datasets of one open file into xarray Variables (eager or lazy)."""

    def __init__(self, f: h5py.File, eager_bytes: int) -> None:
        self.f = f
        self.eager_bytes = eager_bytes
        self.lazy = False
        self.truncated: list[str] = []

    def rows(self, group: h5py.Group, names: list[str]) -> int:
        """Common first-axis length of ``names`` in ``group`` (the shortest; noted when they differ)."""
        n = [group[k].shape[0] for k in names]
        if len(set(n)) > 1:
            self.truncated.append(f"{group.name}: {', '.join(names)} cut to {min(n)} rows (lengths {sorted(set(n))})")
        return min(n)

    def variable(self, d: h5py.Dataset, dims: tuple[str, ...], key: tuple[str, str], rows: int | None = None) -> Any:
        """The dataset ``d`` (first ``rows`` rows) as an xarray Variable with units, long name and source."""
        attrs = {
            "units": _text(d.attrs.get("unit", "1")),
            "long_name": _LONG_NAMES.get(key, d.name),
            "source": d.name,
        }
        if d.ndim == 0:
            return xr.Variable(dims, _attr(d[()]), attrs)
        rows = d.shape[0] if rows is None else rows
        if h5py.check_string_dtype(d.dtype) is not None:
            return xr.Variable(dims, np.asarray(d.asstr()[:rows], dtype=str), attrs)
        if d.ndim >= 2 and d.dtype.itemsize * rows * int(np.prod(d.shape[1:])) > self.eager_bytes:
            self.lazy = True
            return xr.Variable(dims, indexing.LazilyIndexedArray(_H5Array(d, rows)), attrs)
        return xr.Variable(dims, d[:rows], attrs)


def _text(v: Any) -> Any:
    return v.decode() if isinstance(v, bytes) else v


def _attr(v: Any) -> Any:
    """A root attribute as a Python value: arrays → lists, else :func:`~aca_warp.common.files.attr_value`."""
    return v.tolist() if isinstance(v, np.ndarray) else attr_value(v)


def _kind(f: h5py.File) -> str | None:
    if _text(f.attrs.get("kind")) == "lf" and "global/time" in f:
        return "lf"
    if str(_text(f.attrs.get("format", ""))).startswith("aca_warp.sweep/") and "global/time" in f:
        return "sweep_shard"
    if "scene" in f.attrs and "global/time" in f and "patches" in f:
        return "hf"
    return None


def _open(path: str | Path) -> tuple[h5py.File, str]:
    p = Path(path)
    # missing, not HDF5, links, declared sizes: checked before anything is read
    f = open_h5(p, "run file", text=("parameters",))
    kind = _kind(f)
    if kind is None:
        f.close()
        raise SceneError(
            f"{p} is not an aca_warp run file (no /global/time with a 'scene', kind = 'lf' or sweep 'format' "
            "root attribute)"
        )
    return f, kind


def _root_attrs(f: h5py.File, path: Path, kind: str) -> dict[str, Any]:
    attrs = {k: _attr(v) for k, v in f.attrs.items()}
    attrs["file"] = str(path)
    attrs["kind"] = kind
    attrs["complete"] = bool(attrs.get("complete", False))
    attrs.setdefault("status", "unknown")
    if path.name.endswith(".partial"):
        attrs["partial"] = True
        attrs["complete"] = False
    if "analysis" in f:
        attrs["analysis_groups"] = sorted(f["analysis"])
    return attrs


def _series(r: _Reader, group: h5py.Group, *, pads: bool = False) -> dict[str, Any]:
    """Every dataset of a /global group on ``time`` (or ``pad``, ``time`` for a sweep shard), the sample axis cut to
    the shortest dataset (a killed run may have written some of them further)."""
    order = [k for g, k in _LONG_NAMES if g == "global"]
    names = [k for k, d in group.items() if isinstance(d, h5py.Dataset)]
    names.sort(key=lambda k: order.index(k) if k in order else len(order))
    if not pads:
        n = r.rows(group, names)
        return {k: r.variable(group[k], ("time",), ("global", k), n) for k in names}
    wide = [k for k in names if group[k].ndim == 2]
    lengths = {group["time"].shape[0], *(group[k].shape[1] for k in wide)}
    n = min(lengths)
    if len(lengths) > 1:
        r.truncated.append(f"{group.name}: samples cut to {n} (lengths {sorted(lengths)})")
    out = {"time": r.variable(group["time"], ("time",), ("global", "time"), n)}
    for k in wide:
        out[k] = r.variable(group[k], ("pad", "time"), ("global", k))[:, :n]
    return out


def _hf(r: _Reader) -> xr.Dataset:
    f = r.f
    data = _series(r, f["global"])
    p = f["patches"]
    for k, d in p.items():
        if isinstance(d, h5py.Dataset) and d.ndim == 1 and k != "time":
            data[k] = r.variable(d, ("patch",), ("patches", k))
    histories = [k for k, d in p.items() if isinstance(d, h5py.Dataset) and d.ndim == 2]
    if "time" in p:
        n = r.rows(p, ["time", *histories])
        data["patch_time"] = r.variable(p["time"], ("patch_time",), ("patches", "time"), n)
        for k in histories:
            data[k] = r.variable(p[k], ("patch_time", "patch"), ("patches", k), n)
    if "final" in p:
        for k, d in p["final"].items():
            data[f"final_{k}"] = r.variable(d, ("patch",), ("final", k))
    if "matrix" in f:
        for k, d in f["matrix"].items():
            data[f"matrix_{k}"] = r.variable(d, ("cell",), ("matrix", k))
    ds = xr.Dataset(data)
    return ds.assign_coords(patch=("patch", np.arange(f["patches/x"].shape[0]), _index("patch")))


def _index(what: str) -> dict[str, str]:
    return {"units": "1", "long_name": f"{what} index"}


def _lf(r: _Reader) -> xr.Dataset:
    f = r.f
    data = _series(r, f["global"])
    for group, prefix, dim in (("initial_patches", "initial_", "initial_patch"), ("calibration", "", "death")):
        if group in f:
            for k, d in f[group].items():
                data[f"{prefix}{k}"] = r.variable(d, (dim,), (group, k))
    return xr.Dataset(data)


def _sweep(r: _Reader) -> xr.Dataset:
    f = r.f
    data = _series(r, f["global"], pads=True)
    coords: dict[str, Any] = {}
    if "pads" in f:
        if "patch_count" in f["pads"]:
            data["patch_count"] = r.variable(f["pads/patch_count"], ("pad",), ("pads", "patch_count"))
        if "index" in f["pads"]:
            coords["pad"] = ("pad", f["pads/index"][()], {"units": "1", "long_name": "pad index in the sweep"})
    if "parameters" in f:
        for k, d in f["parameters"].items():
            v = r.variable(d, ("pad",), ("parameters", k))
            v.attrs["long_name"] = f"swept parameter {k}"
            coords[k] = v
    return xr.Dataset(data, coords=coords)


def _snapshot(r: _Reader, name: str) -> xr.Dataset:
    f = r.f
    names = sorted(f["snapshots"], key=lambda n: float(f["snapshots"][n].attrs["time"])) if "snapshots" in f else []
    if name not in names:
        raise SceneError(f"no snapshot {name!r} in {f.filename}; it has: {', '.join(names) or 'none'}")
    g = f["snapshots"][name]
    data: dict[str, Any] = {}
    for part, prefix, dim in (("patches", "", "patch"), ("matrix", "matrix_", "cell"), ("rings", "ring_", "ring")):
        for k, d in g[part].items():
            data[f"{prefix}{k}"] = r.variable(d, (dim,), (part, k))
    for k, v in g.attrs.items():
        var, unit, long_name = _SNAPSHOT_ATTRS.get(k, (k, "1", k))
        data[var] = xr.Variable((), _attr(v), {"units": unit, "long_name": long_name, "source": f"{g.name}@{k}"})
    return xr.Dataset(data)


def open_run(path: str | Path, *, snapshot: str | None = None, eager_bytes: int = EAGER_BYTES) -> xr.Dataset:
    """A run file as a labelled :class:`xarray.Dataset` (module docstring; docs/run_files.md).

    Args:
        path: HF run file, LF run file or sweep shard (also a killed run's ``NAME.partial``).
        snapshot: LF run files only: return this snapshot (dimensions ``patch``, ``cell``, ``ring``; 0-d
            ``time``, ``clamp_force``, ``angular_velocity``, ``gap``, ``height_shift``) instead of the time series.
        eager_bytes: Datasets of at most this many bytes are read at once, larger 2-D ones lazily (the file then
            stays open until ``Dataset.close()``).

    Raises:
        SceneError: The path is missing, not HDF5, not a run file, or names no snapshot of the file (one line).
    """
    p = Path(path)
    f, kind = _open(p)
    r = _Reader(f, eager_bytes)
    try:
        if snapshot is not None:
            if kind != "lf":
                raise SceneError(f"{p} is not an LF run file; only LF run files hold snapshots")
            ds = _snapshot(r, snapshot)
        else:
            ds = {"hf": _hf, "lf": _lf, "sweep_shard": _sweep}[kind](r)
        ds.attrs = _root_attrs(f, p, kind)
        if kind == "lf" and "snapshots" in f:
            g = f["snapshots"]
            ds.attrs["snapshots"] = sorted(g, key=lambda n: float(g[n].attrs["time"]))
        if snapshot is not None:
            ds.attrs["snapshot"] = snapshot
        if r.truncated:
            ds.attrs["truncated"] = "; ".join(r.truncated)
    except BaseException:
        f.close()
        raise
    if r.lazy:
        ds.set_close(f.close)
    else:
        f.close()
    return ds


def open_snapshots(path: str | Path, *, eager_bytes: int = EAGER_BYTES) -> dict[str, xr.Dataset]:
    """Every snapshot of an LF run file as ``{name: Dataset}`` in time order (see :func:`open_run`)."""
    names = open_run(path, eager_bytes=eager_bytes).attrs.get("snapshots")
    if names is None:
        raise SceneError(f"{path} is not an LF run file; only LF run files hold snapshots")
    return {n: open_run(path, snapshot=n, eager_bytes=eager_bytes) for n in names}
