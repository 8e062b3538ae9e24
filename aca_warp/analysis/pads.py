"""One pad of a sweep shard as an HF run file: what ``aca-warp analyze/plot SHARD --pad K`` work on.

A shard (``aca-warp sweep``) holds the global outputs of many pads, ``/global/NAME`` (pads, samples), their
parameters and the sweep's spec, but no per-patch data. :func:`write_pad_run` writes pad ``K`` (its index in the
sweep) as an ordinary HF run file: its global series, its scene (the spec's base with the pad's parameter values,
patches and matrix cells from it), the shard's integrator, precision, device and versions, and the run options of
the sweep, so that ``analyze``, ``plot`` and ``rerun`` take it like any run. Its root attributes ``source_shard``,
``source_spec_hash`` and ``pad`` say where it comes from.
"""

from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from aca_warp.common.errors import SceneError, StorageError, option

SHARD_FORMAT = "aca_warp.sweep/"  # the start of a shard's ``format`` attribute


def shard_pads(path: str | Path) -> np.ndarray | None:
    """The sweep's indices of the pads a sweep shard holds, in its row order (``/pads/index``: a sweep packed by size
    holds pads from anywhere in the sweep), shape (pads,) int64; None when ``path`` is no shard (or no HDF5 file).
    The index is read only when it is a dataset of this file, 1-D, of integers, with the shard's pad count
    (``pad_stop - pad_start``, at most a sweep's pads) of rows: a crafted file is no shard."""
    from aca_warp.common.bounds import MAX_PADS

    if not Path(path).is_file():  # a pipe or device would block h5py's open
        return None
    try:
        with h5py.File(path, "r") as f:
            fmt = f.attrs.get("format", "")
            if not str(fmt.decode() if isinstance(fmt, bytes) else fmt).startswith(SHARD_FORMAT):
                return None
            rows = int(f.attrs["pad_stop"]) - int(f.attrs["pad_start"])
            if not 0 < rows <= MAX_PADS:
                return None
            index = f.get("pads/index")
            here = isinstance(f.get("pads/index", getlink=True), h5py.HardLink)
            if not (here and isinstance(index, h5py.Dataset) and index.shape == (rows,) and index.dtype.kind in "iu"):
                return None
            return np.asarray(index[()], dtype=np.int64)
    except (OSError, KeyError, ValueError, TypeError, MemoryError):
        return None


HELD_BY_FILES = 256  # shard files beside a shard looked into for the one that holds a pad (an error's clause)


def _held_by(shard: Path, pad: int) -> str:
    """The clause naming the other shard file of ``shard``'s folder that holds pad ``pad`` (its ``/pads/index``),
    or "" (none does, none is readable, or the folder holds more than :data:`HELD_BY_FILES` of them)."""
    others = sorted(shard.parent.glob("shard-*.h5"))
    if len(others) > HELD_BY_FILES:
        return ""
    for other in others:
        held = None if other.resolve() == shard.resolve() else shard_pads(other)
        if held is not None and bool((held == pad).any()):
            return f": it is in {other}"
    return ""


def pad_run_path(shard: str | Path, pad: int) -> Path:
    """Where ``analyze SHARD --pad K`` keeps pad ``K``'s run file: ``SHARD_padK.h5`` beside the shard."""
    p = Path(shard)
    return p.with_name(f"{p.stem}_pad{pad}.h5")


def shard_refusal(path: str | Path, pads: np.ndarray, command: str) -> SceneError:
    """The one-line refusal of ``command`` (analyze, plot) given a shard without ``--pad``."""
    from aca_warp.sweep.spec import pad_list

    return SceneError(
        f"{path} is a sweep shard of pads {pad_list(pads)}: {command} one of them with "
        f"{option('pad=K', '--pad K')} (K one of those, the pad's index in the sweep)"
    )


def write_pad_run(shard: str | Path, pad: int, dest: str | Path) -> Path:
    """Write pad ``pad`` (its index in the sweep) of the sweep shard ``shard`` as the HF run file ``dest`` (written
    whole under a temporary name, then renamed; an earlier extraction of the same pad is replaced, any other file
    refused). The samples end at the pad's last finite μ (a pad stopped on a fault, or a shard still running); a
    shard without a sample yet (a stopped sweep's ``.partial``), or a pad without a finite μ, is refused in one line
    and nothing is written."""
    from aca_warp.common.files import UNWRITABLE, new_path, reading
    from aca_warp.common.storage import storage_errno, storage_error
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.recorder import GLOBAL_NAMES
    from aca_warp.sweep.spec import SweepError, base_file, load_spec, pad_list, stored_crossing

    shard, dest = Path(shard), Path(dest)
    pads = shard_pads(shard)
    if pads is None:
        raise SceneError(f"{shard} is not a sweep shard ({option('pad', '--pad')} picks a pad of one)")
    rows = np.flatnonzero(pads == pad)
    if rows.size != 1:
        raise SceneError(f"{shard} holds pads {pad_list(pads)}; pad {pad} is not one of them{_held_by(shard, pad)}")
    _check_replaceable(dest, shard)
    with reading(shard, "sweep shard"), h5py.File(shard, "r") as f:
        row = int(rows[0])
        count, spec_hash = int(f["pads/patch_count"][row]), _text(f.attrs.get("spec_hash", ""))
        patch_data = _text(f.attrs["patch_data"]) if "patch_data" in f.attrs else None  # a patch file's digest
        time = f["global/time"][()]
        series = {k: f[f"global/{k}"][row, : time.size] for k in GLOBAL_NAMES}
        end = int(np.flatnonzero(np.isfinite(series["mu"]))[-1]) + 1 if np.isfinite(series["mu"]).any() else 0
        attrs = {k: _text(f.attrs[k]) for k in ("integrator", "precision", "device", "device_name", "versions")}
        attrs["source_spec_hash"] = spec_hash  # with source_shard and pad: which shard of which sweep
        run, doc, finished = json.loads(_text(f.attrs["run"])), json.loads(_text(f.attrs["spec"])), f.attrs["complete"]
    if end == 0:
        raise SceneError(_no_sample(shard, pad, time.size))
    # the run settings as the shard ran them (a default written out since would change the hash, not the pad)
    run = {**run, "crossing": stored_crossing(run)}
    try:
        spec = load_spec({**doc, "run": run}, base_dir=_base_dir(shard))
        scene = spec.scene(pad).replace(duration=float(run["duration"]))
    except SweepError as e:
        raise SceneError(f"{shard}: the pad's scene cannot be rebuilt from the shard's spec: {e}") from None
    if patch_data is not None and spec.patch_data != patch_data:
        raise SceneError(
            f"{shard}: the pad ran over other patches than its patch file {scene.patches.source} holds now (their "
            f"SHA-256 {patch_data[:12]} in the shard, {str(spec.patch_data)[:12]} here): the file has changed since; "
            "restore it to take the pad out"
        )
    if (spec_hash and spec.hash != spec_hash) or scene.patches.count != count:
        base = base_file(doc)
        named = f"the base scene file {base}" if base else "a file it names"
        raise SceneError(
            f"{shard}: the pad's scene rebuilt from the shard's spec is not the one it ran (spec hash "
            f"{spec.hash[:12]} here, {spec_hash[:12]} in the shard; {scene.patches.count} patches here, {count} in the "
            f"shard): {named} changed since, or this aca_warp builds the scene otherwise than the one that wrote the "
            f"shard (its versions: {attrs['versions']}); restore that to take the pad out"
        )
    options = RunOptions(
        duration=float(run["duration"]),
        integrator=run["integrator"],
        dt=run["dt"],
        tolerance=run["tolerance"],
        fast_math=bool(run.get("fast_math", False)),  # absent in the shards of an exact sweep
        growth_dt=run.get("growth_dt"),  # absent in the shards of a sweep at the scenes' growth interval
        crossing=run["crossing"],
    )
    complete = bool(finished) and end == time.size
    tmp = new_path(dest)
    try:
        _write(tmp, attrs, scene, options, complete, time, end, series, shard, pad)
    except BaseException as e:
        with contextlib.suppress(OSError):  # on a read-only file system even a missing file's unlink fails
            tmp.unlink(missing_ok=True)
        if isinstance(e, OSError) and e.errno in UNWRITABLE:  # a read-only folder, no permission, no room
            err = StorageError(
                f"cannot write {dest.name} beside the shard in {dest.parent} ({UNWRITABLE[e.errno]}); nothing was "
                "written: copy the shard to a folder you can write to (plot --pad needs no such folder)"
            )
            err.errno = e.errno  # type: ignore[attr-defined]
            raise err from None
        code = storage_errno(e)
        if code is not None:
            raise storage_error(code, dest, "the shard is as it was") from None
        raise
    os.replace(tmp, dest)
    return dest


def _no_sample(shard: Path, pad: int, samples: int) -> str:
    """Why pad ``pad`` of ``shard``, whose time axis holds ``samples`` samples, gives no run file: the shard holds no
    sample yet (a sweep stopped before it wrote any), or the pad's μ is finite at none of them."""
    if samples == 0:
        return (
            f"{shard} holds no sample yet (its sweep stopped before writing any): run the same sweep command again; it "
            "continues the sweep and completes the shard"
        )
    return f"pad {pad} of {shard} holds no finite sample (μ is not finite from the first one on): nothing to take out"


def _write(
    tmp: Path,
    attrs: dict[str, Any],
    scene: Any,
    options: Any,
    complete: bool,
    time: np.ndarray,
    end: int,
    series: dict[str, np.ndarray],
    shard: Path,
    pad: int,
) -> None:
    """The pad's run file at ``tmp`` (:func:`write_pad_run`)."""
    from aca_warp.hf.contact import solve_scene_contact
    from aca_warp.hf.recorder import GLOBAL_NAMES, GLOBAL_UNITS
    from aca_warp.hf.runfile import write_predicted_growth_rate
    from aca_warp.scene import scene_to_dict

    with h5py.File(tmp, "w") as out:
        out.attrs.update(attrs)
        out.attrs.update(
            scene=json.dumps(scene_to_dict(scene)),
            scene_name=scene.name,
            run_options=options.to_json(),
            complete=complete,
            status="complete" if complete else f"incomplete in the shard: samples to t = {time[end - 1]:.6g} s",
            source_shard=str(shard),
            pad=pad,
        )
        out.create_dataset("global/time", data=time[:end]).attrs["unit"] = "s"
        for name, unit in zip(GLOBAL_NAMES, GLOBAL_UNITS, strict=True):
            out.create_dataset(f"global/{name}", data=series[name][:end]).attrs["unit"] = unit
        for name in ("x", "y", "area", "height"):
            unit = "m2" if name == "area" else "m"
            out.create_dataset(f"patches/{name}", data=getattr(scene.patches, name)).attrs["unit"] = unit
        for name in ("area", "radius", "height"):
            unit = "m2" if name == "area" else "m"
            out.create_dataset(f"matrix/{name}", data=np.asarray(getattr(scene.matrix, name), np.float64))
            out[f"matrix/{name}"].attrs["unit"] = unit
        write_predicted_growth_rate(out, scene, solve_scene_contact(scene).patch_force)  # the contact the pad began in


def extracted_from(dest: str | Path, shard: str | Path) -> bool:
    """Whether ``dest`` is a pad run file :func:`write_pad_run` extracted from ``shard`` (the same file, however its
    path was spelled)."""
    try:
        with h5py.File(dest, "r") as f:
            source = _text(f.attrs.get("source_shard", ""))
            recorded = _text(f.attrs.get("source_spec_hash", ""))
    except OSError:
        return False
    if not source:
        return False
    with contextlib.suppress(OSError):
        if os.path.samefile(source, shard):
            return True
    # the path as recorded, relative to another folder or to a folder since moved: a shard of that name beside it, of
    # the same sweep where the pad file records which
    if Path(source).name != Path(shard).name or Path(dest).resolve().parent != Path(shard).resolve().parent:
        return False
    try:
        with h5py.File(shard, "r") as s:
            return not recorded or recorded == _text(s.attrs.get("spec_hash", ""))
    except OSError:
        return False


def _check_replaceable(dest: Path, shard: Path) -> None:
    """Refuse to replace ``dest`` unless it is an earlier extraction from ``shard``."""
    if dest.exists() and not extracted_from(dest, shard):
        raise SceneError(f"{dest} exists and is not a pad extracted from {shard}; move it away")


def _base_dir(shard: Path) -> Path:
    """The folder the sweep's spec resolved its files against (the manifest's ``base_dir``), else the shard's."""
    from aca_warp.sweep.manifest import MANIFEST

    try:
        return Path(json.loads((shard.parent / MANIFEST).read_text())["base_dir"])
    except (OSError, KeyError, ValueError, TypeError):
        return shard.parent


def _text(value: Any) -> Any:
    return value.decode() if isinstance(value, bytes) else value
