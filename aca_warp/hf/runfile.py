"""HDF5 run files: one file per run, SI ``unit`` attribute on every dataset, provenance as attributes.

Layout (docs/run_files.md)::

    /global/time, mu, torque, friction_radius, sum_velocity, sum_abs_velocity, friction_centroid     (samples,)
    /patches/x, y, area, height, mass, normal_force, predicted_growth_rate        (patches,)
    /patches/time, velocity[, displacement]     per-patch histories, (rows,) and (rows, patches), if recorded
    /patches/final/area, normal_force           after growth, if the scene grows
    /matrix/area, radius, height                the pad matrix cells the run started from (cells,)
    /checkpoint/...                             solver state of a resumable run (aca_warp/common/checkpoint.py)

Root attributes: ``scene`` (JSON), ``integrator``, ``run_options`` (JSON, :class:`~aca_warp.hf.options.RunOptions`),
``precision``, ``device``, ``versions`` (JSON), ``stages`` (JSON list), ``stable_step`` (JSON),
``predicted_growth_rate_min``, ``_median``, ``_max`` [1/s] (absent in files of earlier versions), ``complete``
(bool), ``status``, and for a stopped run ``fault``. The file is written as ``NAME.partial`` and renamed to ``NAME``
when the run ends, completed or not (then ``complete = False`` and ``status`` says why). A killed process leaves
only the ``.partial`` file behind: it holds everything up to the last checkpoint (automatic by default,
:class:`~aca_warp.common.checkpoint.CheckpointClock`) and ``aca-warp hf --resume`` continues it from there, or from
the start when the run had no checkpoint yet. Neither ``NAME`` nor a leftover ``NAME.partial`` is replaced without
``overwrite``. The lock, the ``.partial`` and the full device are handled as for every run file
(:mod:`aca_warp.common.runfile`).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from aca_warp.common.checkpoint import (
    Checkpoint,
    closed_on_failure,
    drop_checkpoint,
)
from aca_warp.common.files import OutputLock, check_output_path, open_h5, versions
from aca_warp.common.runfile import RunFileWriter, write_attrs
from aca_warp.common.storage import storage_errno, storage_error
from aca_warp.hf.model import PadModel
from aca_warp.hf.recorder import GLOBAL_NAMES, GLOBAL_UNITS, Chunk
from aca_warp.scene import Scene, scene_to_dict

SERIES_CHUNK = 4096  # samples per chunk of /global/* and /patches/time
HISTORY_CHUNK = (1024, 64)  # (samples, patches) per chunk of the per-patch histories (patches: at most 64)
# what else a file holds, on disk: object headers, chunk index nodes, the two checkpoint slots (measured by
# scripts/file_size.py: docs/faults.md, "Output folders")
HEADER_BYTES = 64 * 1024
BYTES_PER_CHUNK = 128
CHECKPOINT_BYTES_PER_PATCH = 2 * 16 * 8


def file_bytes(
    samples: int, rows: int, patches: int, histories: int, item: int, *, cells: int, checkpoints: bool
) -> int:
    """Bytes the run file takes on disk when it ends [B]: ``samples`` global samples, ``rows`` rows of
    ``histories`` per-patch histories (velocity, displacement) of ``patches`` patches in ``item``-byte values,
    ``cells`` matrix cells, with or without checkpoint slots. HDF5 allocates chunks whole, so the series round up to
    :data:`SERIES_CHUNK` samples and the histories to :data:`HISTORY_CHUNK` (a 40-patch history takes 64 columns),
    each no longer than the run's rows (:func:`chunk_rows`), and a deleted checkpoint leaves its space in the
    file."""

    def up(n: int, k: int) -> int:
        return -(-n // k) * k

    width = min(patches, HISTORY_CHUNK[1])
    s_chunk, r_series, r_chunk = chunk_rows(samples, SERIES_CHUNK), chunk_rows(rows, SERIES_CHUNK), chunk_rows(rows)
    series = (1 + len(GLOBAL_NAMES)) * up(samples, s_chunk) * 8
    history = up(rows, r_series) * 8 if rows else 0
    history += histories * up(rows, r_chunk) * up(patches, width) * item if rows else 0
    chunks = (1 + len(GLOBAL_NAMES)) * up(samples, s_chunk) // s_chunk
    if rows:
        chunks += histories * (up(rows, r_chunk) // r_chunk) * (up(patches, width) // width)
    fixed = 7 * patches * 8 + 3 * cells * 8 + (CHECKPOINT_BYTES_PER_PATCH * patches if checkpoints else 0)
    return series + history + fixed + chunks * BYTES_PER_CHUNK + HEADER_BYTES


def chunk_rows(planned: int | None, most: int = HISTORY_CHUNK[0]) -> int:
    """Rows per chunk of a series or history of ``planned`` rows: ``most``, or the planned rows where a run records
    fewer (a short run's file holds no chunk larger than its data); ``most`` where none were planned."""
    return most if planned is None else max(1, min(most, planned))


def write_predicted_growth_rate(
    f: h5py.File, scene: Scene, patch_force: np.ndarray, reserve: Callable[[int], None] | None = None
) -> None:
    """``/patches/predicted_growth_rate`` σ_i [1/s] of ``scene`` under the contact forces ``patch_force`` [N] of the
    start, shape (patches,), and its minimum, median and maximum as root attributes of ``f`` (a run file, or a
    shard's pad extracted as one); ``reserve`` is told its bytes first."""
    from aca_warp.analysis.saturation import scene_growth_rate

    sigma = scene_growth_rate(scene, patch_force)
    if reserve is not None:
        reserve(sigma.nbytes)
    d = f.create_dataset("patches/predicted_growth_rate", data=sigma)
    d.attrs["unit"] = "s-1"
    d.attrs["meaning"] = (
        "growth rate of each isolated patch linearised about steady sliding at the contact forces of the start, "
        "p_i |f'(omega r_i)| / (2 rho_A) - zeta omega_0,i (docs/analysis.md)"
    )
    for stat, value in (("min", sigma.min()), ("median", np.median(sigma)), ("max", sigma.max())):
        f.attrs[f"predicted_growth_rate_{stat}"] = float(value)


class RunWriter(RunFileWriter):
    """Streams one pad's recorded samples into an HDF5 run file (``pad`` selects it from a batch)."""

    RAW_CACHE = 64 * 2**20  # bytes of HDF5 chunk cache: appended rows of wide per-patch histories stay cached

    def __init__(
        self,
        path: str | Path,
        model: PadModel,
        *,
        pad: int = 0,
        overwrite: bool = False,
        attrs: dict[str, Any] | None = None,
        lock: OutputLock | None = None,
        planned: tuple[int, int] | None = None,
    ) -> None:
        """``planned``: the run's (global samples, per-patch rows), which bound the datasets' chunks
        (:func:`chunk_rows`); None: full chunks."""
        self._select(model, pad, planned)
        self._create(
            path,
            check_output_path,
            overwrite=overwrite,
            lock=lock,
            header=lambda: self._write_header(model.scenes[pad], attrs or {}),
        )

    def _select(self, model: PadModel, pad: int, planned: tuple[int, int] | None) -> None:
        """Write the pad ``pad`` of ``model``, its new datasets' chunks bounded by the ``planned`` rows (None: full
        chunks)."""
        self.pad = pad
        self.model = model
        a, b = (int(x) for x in model.pad_patch_start_host[pad : pad + 2])
        self.slice = slice(a, b)
        self.flush_each_chunk = True
        self._patch_ds: dict[str, h5py.Dataset] = {}
        self.planned: tuple[int | None, int | None] = (None, None) if planned is None else planned

    def _write_header(self, scene: Scene, attrs: dict[str, Any]) -> None:
        """Attributes, empty sample datasets, the patch set and the matrix cells."""
        f, pad = self.f, self.pad
        f.attrs["scene"] = json.dumps(scene_to_dict(scene))
        f.attrs["scene_name"] = scene.name
        f.attrs["versions"] = json.dumps(versions())
        f.attrs["complete"] = False
        f.attrs["status"] = "running"
        write_attrs(f, attrs)
        g = f.create_group("global")
        for name, unit in (("time", "s"), *zip(GLOBAL_NAMES, GLOBAL_UNITS, strict=True)):
            chunks = (chunk_rows(self.planned[0], SERIES_CHUNK),)
            d = g.create_dataset(name, shape=(0,), maxshape=(None,), dtype="f8", chunks=chunks)
            d.attrs["unit"] = unit
        p = f.create_group("patches")
        mass = scene.material.mass_per_area * scene.patches.area
        for name, data, unit in (
            ("x", scene.patches.x, "m"),
            ("y", scene.patches.y, "m"),
            ("area", scene.patches.area, "m2"),
            ("height", scene.patches.height, "m"),
            ("mass", mass, "kg"),
            ("normal_force", self.model.contacts[pad].patch_force, "N"),
        ):
            self.out.reserve(8 * len(data))
            p.create_dataset(name, data=np.asarray(data, dtype=np.float64)).attrs["unit"] = unit
        write_predicted_growth_rate(f, scene, self.model.contacts[pad].patch_force, self.out.reserve)
        mg = f.create_group("matrix")
        for name, unit in (("area", "m2"), ("radius", "m"), ("height", "m")):
            data = np.asarray(getattr(scene.matrix, name), np.float64)
            self.out.reserve(data.nbytes)
            mg.create_dataset(name, data=data).attrs["unit"] = unit

    @classmethod
    def reopen(
        cls,
        partial: str | Path,
        model: PadModel,
        *,
        pad: int = 0,
        lock: OutputLock,
        planned: tuple[int, int] | None = None,
    ) -> tuple[RunWriter, Checkpoint | None]:
        """Open a killed or stopped run's ``NAME.partial`` to continue it (``lock``: the lock of ``NAME``, held; the
        caller releases it when this fails): read its checkpoint, truncate the sample datasets to the checkpoint's
        rows (to none without a checkpoint: the run starts again; the checkpoint is then None) and mark the file
        running again. ``planned``: as for a new file, the rows that bound the chunks of datasets made from here
        on (per-patch histories whose window begins after the checkpoint)."""
        self = cls.__new__(cls)
        self._open_partial(partial, lock)
        self._select(model, pad, planned)
        try:
            ckpt = self._truncate_to_checkpoint()
        except BaseException as e:
            code = storage_errno(e)
            if code is not None:
                raise storage_error(code, self.partial, "it was not changed; make room and resume again") from None
            raise
        return self, ckpt

    def _truncate_to_checkpoint(self) -> Checkpoint | None:
        """Read the checkpoint, cut the sample datasets back to its rows (to none without one), mark the file
        running (reopen)."""
        f = self.f
        with closed_on_failure(f, self.partial, close=self.out.abandon):
            ckpt = self._stored_checkpoint()
            rows = {"global": 0, "patches": 0} if ckpt is None else ckpt.rows
            for name in ("time", *GLOBAL_NAMES):
                f["global"][name].resize(rows["global"], axis=0)
            self._patch_ds = {}
            for name in ("time", "velocity", "displacement"):
                if name in f["patches"]:
                    self._patch_ds[name] = f["patches"][name]
                    self._patch_ds[name].resize(rows["patches"], axis=0)
            # read the last kept row of every sample dataset: a damaged chunk index shows up here, not mid-run
            for d in (*(f["global"][name] for name in ("time", *GLOBAL_NAMES)), *self._patch_ds.values()):
                if d.shape[0]:
                    d[d.shape[0] - 1]
            if "final" in f["patches"]:
                del f["patches"]["final"]
            from aca_warp.analysis.groups import GROUP, TMP_GROUP

            for name in (GROUP, TMP_GROUP):  # an analysis of the samples as they were no longer describes the file
                if name in f:
                    del f[name]
        # a run resumed from a checkpoint keeps flushing at checkpoints only; one started again, at every chunk
        self.flush_each_chunk = ckpt is None
        self._mark_running(ckpt)
        return ckpt

    def rows(self) -> dict[str, int]:
        """Rows written so far: ``global`` (samples) and ``patches`` (per-patch samples)."""
        pt = self._patch_ds.get("time")
        return {"global": self.f["global"]["time"].shape[0], "patches": 0 if pt is None else pt.shape[0]}

    def checkpoint(self, ckpt: Checkpoint) -> None:
        """Store a checkpoint of the run (the run loop's ``on_checkpoint``); from then on the file is flushed only
        at checkpoints, so that what is on disk always fits the last one (:mod:`aca_warp.common.checkpoint`)."""
        self.flush_each_chunk = False
        ckpt.rows = self.rows()
        self._store_checkpoint(ckpt)

    def _patch_dataset(self, name: str, unit: str, width: int, dtype: Any) -> h5py.Dataset:
        if name not in self._patch_ds:
            shape = (0,) if width == 0 else (0, width)
            # narrow in patches, long in time: an analysis reads column blocks of patches in one pass
            rows = self.planned[1]
            chunks = (
                (chunk_rows(rows, SERIES_CHUNK),) if width == 0 else (chunk_rows(rows), min(width, HISTORY_CHUNK[1]))
            )
            d = self.f["patches"].create_dataset(
                name, shape=shape, maxshape=(None, *shape[1:]), dtype=dtype, chunks=chunks
            )
            d.attrs["unit"] = unit
            self._patch_ds[name] = d
        return self._patch_ds[name]

    def _append(self, d: h5py.Dataset, data: np.ndarray) -> None:
        n = d.shape[0]
        self.out.touch(d, n, n + len(data))
        self.out.reserve()
        d.resize(n + len(data), axis=0)
        d[n:] = data

    def write(self, chunk: Chunk) -> None:
        """Append one chunk of samples (the run loop's sink) and flush the file."""
        g = self.f["global"]
        self._append(g["time"], chunk.time)
        for k, name in enumerate(GLOBAL_NAMES):
            self._append(g[name], chunk.globals[:, self.pad, k])
        if len(chunk.patch_time):
            width = self.slice.stop - self.slice.start
            self._append(self._patch_dataset("time", "s", 0, "f8"), chunk.patch_time)
            for name, data, unit in (("velocity", chunk.velocity, "m s-1"), ("displacement", chunk.displacement, "m")):
                if data is not None:
                    self._append(self._patch_dataset(name, unit, width, data.dtype), data[:, self.slice])
        if self.flush_each_chunk:
            self.out.flush()

    def _write_closing(self, complete: bool, status: str, attrs: dict[str, Any]) -> None:
        """The closing attributes; a complete run drops its checkpoint; a growing scene's final areas and forces."""
        f = self.f
        f.attrs["complete"] = complete
        f.attrs["status"] = status
        write_attrs(f, attrs)
        if complete:
            drop_checkpoint(f)
        if self.model.scenes[self.pad].growth is not None:
            fin = f["patches"].create_group("final")
            for name, unit in (("area", "m2"), ("normal_force", "N")):
                data = self.model.host(name)[self.slice].astype(np.float64)
                self.out.reserve(data.nbytes)
                fin.create_dataset(name, data=data).attrs["unit"] = unit


def read_run(path: str | Path) -> dict[str, Any]:
    """Load a run file into a dict of NumPy arrays and decoded attributes (small runs; tests, plots)."""
    out: dict[str, Any] = {}
    with open_h5(path, "run file") as f:

        def visit(name: str, obj: Any) -> None:
            if isinstance(obj, h5py.Dataset):
                out[name] = obj[()]

        f.visititems(visit)
        attrs = {}
        for k, v in f.attrs.items():
            if isinstance(v, str) and v[:1] in "[{":
                try:
                    v = json.loads(v)
                except json.JSONDecodeError:
                    pass
            attrs[k] = v
        out["attrs"] = attrs
    return out
