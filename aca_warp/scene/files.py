"""Scene files: TOML scenes (:func:`load_scene`, :func:`scene_from_dict`, :func:`scene_to_dict`), the built-in presets
(:func:`preset`, files in ``aca_warp/data``; ``docs/presets.md``) and HDF5 patch files (:func:`read_patch_file`,
:func:`write_patch_file`). Unknown tables and keys, and values far outside a brake pad's range, are refused with one
line (:class:`~aca_warp.common.errors.SceneError`) before a scene is built."""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Callable
from importlib import resources
from pathlib import Path

import numpy as np

from aca_warp.common import plausible
from aca_warp.common.bounds import check_h5, read_toml
from aca_warp.common.errors import SceneError, did_you_mean
from aca_warp.scene.generator import PatchGenerator
from aca_warp.scene.parts import (
    Friction,
    Growth,
    Initial,
    Material,
    Pad,
    Patches,
    Record,
    Scene,
    _finite,
)

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

# the paper's scenes (heights spread so the loads meet §3.1/§3.2), then the same with equal heights (docs/presets.md)
PRESETS = (
    "hf1",
    "hf2",
    "hf3",
    "hf4",
    "varying_area",
    "hf1_equal",
    "hf2_equal",
    "hf3_equal",
    "hf4_equal",
    "varying_area_equal",
)


def read_patch_file(path: str | Path) -> Patches:
    """Read patches from an HDF5 file with 1-D datasets ``x``, ``y``, ``area``, ``height`` (SI units)."""
    import h5py

    p = Path(path)
    if p.is_dir():
        raise SceneError(f"patch file {p} is a folder; give the HDF5 file with datasets x, y, area, height")
    if not p.is_file():
        raise SceneError(f"patch file not found: {p}")
    try:
        with h5py.File(p, "r") as f:
            check_h5(f, p, "patch file")  # links, declared sizes, numbers: before anything is read
            missing = [k for k in ("x", "y", "area", "height") if k not in f]
            if missing:
                raise SceneError(f"patch file {p} lacks dataset(s) {', '.join(missing)}")
            data = {k: np.asarray(f[k][()], dtype=np.float64) for k in ("x", "y", "area", "height")}
    except SceneError:
        raise
    except (OSError, ValueError, TypeError, KeyError, AttributeError, RuntimeError) as e:  # not HDF5, damaged, …
        raise SceneError(f"cannot read patch file {p}: {type(e).__name__}: {e}") from None
    return Patches(**data, source=str(p))


def write_patch_file(path: str | Path, patches: Patches) -> None:
    """Write patches to an HDF5 file readable by :func:`read_patch_file`, with ``unit`` attributes."""
    import h5py

    with h5py.File(path, "w") as f:
        for name, unit in (("x", "m"), ("y", "m"), ("area", "m2"), ("height", "m")):
            f.create_dataset(name, data=getattr(patches, name)).attrs["unit"] = unit


GENERATOR_KINDS = {"area_min": "area", "area_max": "area", "height": "height", "height_spread": "height"}
PAD_KINDS = {"r_inner": "length", "r_outer": "length"}  # the [pad] keys whose plausibility is checked


def check_numbers_plausible(table: dict, name: str, kinds: dict[str, str]) -> None:
    """Refuse the numbers of the TOML table ``[name]`` whose keys ``kinds`` names (key: kind of
    :data:`aca_warp.common.plausible.RANGES`) beyond a brake pad's range, before the table is built into a pad or
    patches (a unit mistake would otherwise fail later with a less helpful message: an ordering of radii, the
    placement of patches)."""
    for key, kind in kinds.items():
        value = table.get(key)
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            plausible.check(f"{name}.{key}", value, kind)


# ----------------------------------------------------------------------------------------------- TOML

_TABLES: dict[str, tuple[str, ...]] = {
    "scene": ("name", "allow_implausible"),
    "pad": tuple(f.name for f in dataclasses.fields(Pad)),
    "load": ("normal_force",),
    "disc": ("sliding_speed", "angular_velocity"),
    "friction": tuple(f.name for f in dataclasses.fields(Friction)),
    "patches": ("file", *(f.name for f in dataclasses.fields(PatchGenerator))),
    "material": tuple(f.name for f in dataclasses.fields(Material)),
    "initial": tuple(f.name for f in dataclasses.fields(Initial)),
    "growth": tuple(f.name for f in dataclasses.fields(Growth)),
    "record": ("sample_dt", "patches", "window", "decimation"),
    "run": ("duration",),
}


def scene_from_dict(
    doc: dict, *, base_dir: Path | None = None, name: str = "scene", allow_implausible: bool = False
) -> Scene:
    """Build and validate a scene from a TOML-shaped dict (see ``docs/scenes.md`` for every key);
    ``allow_implausible`` accepts implausible values as ``[scene] allow_implausible = true`` does."""
    for table, value in doc.items():
        if table not in _TABLES:
            raise SceneError(f"unknown table [{table}]; allowed: {', '.join('[' + t + ']' for t in _TABLES)}")
        if not isinstance(value, dict):
            raise SceneError(f"[{table}] must be a table")
        for key in value:
            if key not in _TABLES[table]:
                raise SceneError(f"unknown key {key!r} in [{table}]; allowed: {', '.join(_TABLES[table])}")
    t = {k: dict(doc.get(k, {})) for k in _TABLES}
    allow = plausible.flag(t["scene"].get("allow_implausible", False)) or allow_implausible
    pt = t["patches"]
    if not allow:  # before the pad's own checks: r_inner = 100 is a unit mistake before it is an ordering one
        check_numbers_plausible(t["pad"], "pad", PAD_KINDS)
        check_numbers_plausible(pt, "patches", GENERATOR_KINDS)
    pad = Pad(**t["pad"])
    if "file" in pt:
        extra = sorted(set(pt) - {"file"})
        if extra:
            raise SceneError(f"[patches] file = ... cannot be combined with generator keys {', '.join(extra)}")
        f = Path(pt["file"])
        if not f.is_absolute() and base_dir is not None:
            f = base_dir / f
        patches = read_patch_file(f)
    else:
        patches = PatchGenerator(**pt).generate(pad)
    disc = t["disc"]
    if "sliding_speed" in disc and "angular_velocity" in disc:
        raise SceneError("[disc] takes sliding_speed or angular_velocity, not both")
    if "angular_velocity" in disc:
        omega = _finite("disc.angular_velocity", disc["angular_velocity"])
    else:
        omega = _finite("disc.sliding_speed", disc.get("sliding_speed", 10.0)) / pad.mean_radius
    rec = t["record"]
    if "window" in rec:
        if not isinstance(rec["window"], list):
            raise SceneError("record.window must be [start, end] in seconds")
        rec["window"] = tuple(rec["window"])
    if "patches" in rec:
        if isinstance(rec["patches"], str) or not isinstance(rec["patches"], list):
            raise SceneError('record.patches must be a list such as ["velocity"]')
        rec["patches"] = tuple(rec["patches"])
    try:
        return Scene(
            name=str(t["scene"].get("name", name)),
            pad=pad,
            patches=patches,
            material=Material(**t["material"]),
            friction=Friction(**t["friction"]),
            normal_force=t["load"].get("normal_force", 487.2),
            angular_velocity=omega,
            initial=Initial(**t["initial"]),
            record=Record(**rec),
            duration=t["run"].get("duration", 1.0e-3),
            growth=Growth(**t["growth"]) if "growth" in doc else None,
            origin=doc,
            allow_implausible=allow,
        )
    except TypeError as e:  # a wrongly typed value that slipped through, e.g. a table for a number
        raise SceneError(f"invalid scene value: {e}") from None


HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"  # the first bytes of an HDF5 file (a run file, a patch file)


def refuse_hdf5(p: Path, what: str, hint: str) -> Callable[[bytes], None]:
    """A ``refuse`` for :func:`~aca_warp.common.bounds.read_toml`: one SceneError line when the file's first bytes
    are an HDF5 file's (a run file given where the TOML ``what`` is asked for), ``hint`` after it."""

    def refuse(head: bytes) -> None:
        if head.startswith(HDF5_SIGNATURE):
            raise SceneError(f"{p} is an HDF5 file, not a TOML {what}{hint}")

    return refuse


def read_scene_toml(p: Path, what: str) -> dict:
    """The TOML document of the scene file ``p`` (a ``what`` such as "LF scene file") as
    :func:`~aca_warp.common.bounds.read_toml` reads it; one SceneError line when it cannot be read, or when it is an
    HDF5 file (a run file given where a scene is asked for: the line says what takes one)."""

    hint = (
        f": a run file is repeated with 'aca-warp rerun {p} -o NEW.h5' and continued with --resume; an LF run's "
        f"snapshot runs as HF with 'aca-warp hf {p} --snapshot NAME -o RUN.h5'"
    )
    try:
        return read_toml(p, what, refuse=refuse_hdf5(p, what, hint))
    except OSError as e:
        raise SceneError(f"cannot read {what} {p}: {e.strerror}") from None


def load_scene(spec: str | Path, *, allow_implausible: bool = False) -> Scene:
    """A preset name (:data:`PRESETS`) or the path of a TOML scene file (``allow_implausible``: as the scene key)."""
    s = str(spec)
    if s in PRESETS:
        scene = preset(s)
        return scene.replace(allow_implausible=True) if allow_implausible else scene
    p = Path(s)
    if p.is_dir():
        raise SceneError(f"scene {s!r} is a folder; give a preset ({', '.join(PRESETS)}) or a TOML scene file")
    if not p.is_file() and "lf" in _packaged(s):
        raise SceneError(
            f"{s!r} is an LF scene: run it with 'aca-warp lf {s} -o LF.h5', then HF on one of its snapshots with "
            "'aca-warp hf LF.h5 --snapshot app1_start -o RUN.h5'"
        )
    if not p.is_file():
        raise SceneError(
            f"scene {s!r} is neither a preset ({', '.join(PRESETS)}) nor an existing TOML file"
            f"{did_you_mean(s, PRESETS)}"
        )
    doc = read_scene_toml(p, "scene file")
    if not doc:
        raise SceneError(
            f"scene file {p} is empty (no table, no key): it would silently run the defaults; start from a preset "
            "file (aca_warp/data/hf1.toml, docs/scenes.md) or name the preset (hf1)"
        )
    lf_tables = [t for t in ("lf", "schedule", "snapshots") if t in doc]
    if lf_tables:
        raise SceneError(
            f"{p} is an LF scene file (it has {', '.join(f'[{t}]' for t in lf_tables)}): run it with 'aca-warp lf "
            f"{p} -o LF.h5'"
        )
    return scene_from_dict(doc, base_dir=p.parent, name=p.stem, allow_implausible=allow_implausible)


def preset(name: str) -> Scene:
    """The built-in scene ``name`` (files ``aca_warp/data/<name>.toml``; docs/model.md §2.9)."""
    if name not in PRESETS:
        raise SceneError(f"unknown preset {name!r}; choose from {', '.join(PRESETS)}")
    return scene_from_dict(preset_document(name), name=name)


def _packaged(name: str) -> dict:
    """The packaged scene file ``aca_warp/data/<name>.toml`` of any kind (HF or LF), or {} where there is none."""
    if not name.isidentifier():
        return {}
    try:
        return preset_document(name)
    except OSError:  # none of that name (or a name too long for the file system)
        return {}


def preset_document(name: str) -> dict:
    """The TOML document of the packaged scene file ``aca_warp/data/<name>.toml`` (an HF or LF preset)."""
    return tomllib.loads(resources.files("aca_warp.data").joinpath(f"{name}.toml").read_text())


def scene_to_dict(scene: Scene) -> dict:
    """The scene as a TOML-shaped dict with every value explicit (patch data excepted: see ``patches.source``).

    Run files store it (JSON) so a run can be repeated; ``scene_from_dict`` reads it back when the
    patches come from a generator or a file that still exists.
    """
    origin = scene.origin or {}
    patches = dict(origin.get("patches", {})) or {"source": scene.patches.source}
    doc = {
        "scene": {"name": scene.name, **({"allow_implausible": True} if scene.allow_implausible else {})},
        "pad": dataclasses.asdict(scene.pad),
        "load": {"normal_force": scene.normal_force},
        "disc": {"angular_velocity": scene.angular_velocity},
        "friction": dataclasses.asdict(scene.friction),
        "patches": patches,
        "material": dataclasses.asdict(scene.material),
        "initial": dataclasses.asdict(scene.initial),
        "record": {
            "sample_dt": scene.record.sample_dt,
            "patches": list(scene.record.patches),
            "window": [
                scene.record.window[0],
                scene.record.window[1] if math.isfinite(scene.record.window[1]) else 1e300,
            ],
            "decimation": scene.record.decimation,
        },
        "run": {"duration": scene.duration},
    }
    if scene.growth is not None:
        doc["growth"] = dataclasses.asdict(scene.growth)
    return doc
