"""Parameter sweeps: a TOML spec expanded into many pads, run in shards (serially or through Dask), resumable.

A sweep spec (``docs/sweeps.md``) names a base scene (a preset, a TOML scene file, or inline tables) and grids
or lists of scene parameters (``friction.M``, ``load.normal_force``, ``disc.sliding_speed``, ``patches.seed``,
``patches.area_min``, ``material.K_C``, ...), combined as a Cartesian product or zipped. Every combination is
one pad. Pads are cut into shards of a fixed size; each shard is one batched HF run (one :func:`build_model`,
one :func:`aca_warp.hf.loop.run_hf` with the engine ``auto``: the on-chip kernel on CUDA, else the general one;
split only when the estimated device memory says the batch does not fit) and one HDF5 file::

    DIR/manifest.json            spec, spec hash, shards and their state (written only by the client)
    DIR/shard-00000.h5           /global/time (samples,) [s]
                                 /global/mu, torque, friction_radius, sum_velocity, sum_abs_velocity, friction_centroid
                                     (pads, samples), unit attributes as in run files
                                 /parameters/<key> (pads,) one dataset per swept parameter, unit attribute
                                 /pads/index (pads,) global pad index, /pads/patch_count (pads,)
                                 attrs: spec (JSON), spec_hash, shard, pad_start, pad_stop, complete,
                                     finished, status, device, integrator, precision, dt, steps, ...

A shard file is written as ``NAME.partial`` and renamed when its run ends: a final name always holds a whole
shard. A rerun skips a shard only when the manifest *and* the file agree that it finished under the same spec
hash; everything else (a ``.partial`` left by a killed worker, a missing or foreign file) is run again. The
time axis is shared by all pads of a shard (one batch advances together), hence 1-D.

Execution: in this process (``workers=0``), or on a Dask cluster: a local one started here (one worker
process per GPU, each pinned to its GPU through ``CUDA_VISIBLE_DEVICES``; one per CPU core for the CPU; one
thread each), or an existing scheduler. Tasks are shards; workers write their shard files; the client alone
updates the manifest.
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import functools
import hashlib
import itertools
import json
import math
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.common.errors import AcaError, SceneError, StorageError
from aca_warp.scene import (
    PRESETS,
    Friction,
    Material,
    Pad,
    PatchGenerator,
    Scene,
    scene_from_dict,
    scene_to_dict,
)

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

FORMAT = "aca_warp.sweep/1"
MANIFEST = "manifest.json"
MODES = ("product", "zip")
SHARD_STATES = ("pending", "queued", "done", "fault", "failed")
DEFAULT_SHARD_SIZE = 64
_SWEEP_KEYS = ("name", "base", "mode", "shard_size")
_RUN_KEYS = ("duration", "integrator", "precision", "dt", "tolerance", "sample_dt")

# Parameters a sweep may vary: key -> (unit, kind); kind says how the value is applied to the base scene.
PARAMETERS: dict[str, tuple[str, str]] = {
    **{
        f"friction.{f.name}": ("1" if f.name in ("M", "mu_pad") else "s m-1", "friction")
        for f in dataclasses.fields(Friction)
    },
    **{
        f"material.{f.name}": (
            {
                "K_N": "N m-2",
                "K_T": "N m-2",
                "K_C": "N m-2",
                "coupling_radius": "m",
                "damping_ratio": "1",
                "mass_per_area": "kg m-2",
                "matrix_stiffness": "N m-3",
            }[f.name],
            "material",
        )
        for f in dataclasses.fields(Material)
    },
    "load.normal_force": ("N", "load"),
    "disc.sliding_speed": ("m s-1", "disc"),
    "disc.angular_velocity": ("rad s-1", "disc"),
    "patches.count": ("1", "patches"),
    "patches.area_min": ("m2", "patches"),
    "patches.area_max": ("m2", "patches"),
    "patches.height": ("m", "patches"),
    "patches.seed": ("1", "patches"),
    **{f"pad.{f.name}": ("deg" if f.name == "span_deg" else "m", "pad") for f in dataclasses.fields(Pad)},
    "initial.state": ("", "initial"),
    "initial.perturbation": ("m s-1", "initial"),
    "initial.seed": ("1", "initial"),
    "growth.increment": ("m", "growth"),
}
_INT_PARAMETERS = ("patches.count", "patches.seed", "initial.seed")
MAX_PADS = 10**6  # pads of one sweep (refused before the combinations are expanded)
MAX_STEPS = 10**11  # steps of one pad's run (duration / dt; larger is a typo, not a run)


class SweepError(AcaError, ValueError):
    """A sweep spec or sweep directory is invalid (the CLI prints it as one line, exit code 2)."""


# ------------------------------------------------------------------------------------------------ spec


def _values(key: str, raw: Any) -> list:
    """The list of values of one parameter: a list, or {linspace|geomspace = [a, b, n]} or {range = [a, b(, s)]}."""
    if isinstance(raw, list):
        vals = list(raw)
    elif isinstance(raw, dict) and len(raw) == 1:
        ((form, args),) = raw.items()
        if form in ("linspace", "geomspace"):
            if not (isinstance(args, list) and len(args) == 3 and isinstance(args[2], int) and args[2] >= 1):
                raise SweepError(f"parameters.{key}: {form} takes [start, stop, count], got {args!r}")
            if args[2] > MAX_PADS:
                raise SweepError(f"parameters.{key}: {args[2]} values, more than a sweep runs ({MAX_PADS} pads)")
            try:
                vals = getattr(np, form)(float(args[0]), float(args[1]), args[2]).tolist()
            except (TypeError, ValueError) as e:
                raise SweepError(f"parameters.{key}: bad {form} {args!r}: {e}") from None
        elif form == "range":
            if not (
                isinstance(args, list)
                and 2 <= len(args) <= 3
                and all(isinstance(a, int) and not isinstance(a, bool) for a in args)
            ) or (len(args) == 3 and args[2] == 0):
                raise SweepError(
                    f"parameters.{key}: range takes integers [start, stop] or [start, stop, step] (step != 0)"
                )
            if len(range(*args)) > MAX_PADS:
                raise SweepError(f"parameters.{key}: {len(range(*args))} values, more than a sweep runs ({MAX_PADS})")
            vals = list(range(*args))
        else:
            raise SweepError(f"parameters.{key}: unknown form {form!r}; use a list, linspace, geomspace or range")
    else:
        raise SweepError(
            f"parameters.{key} must be a list of values or a table such as {{ linspace = [a, b, n] }}, got {raw!r}"
        )
    if not vals:
        raise SweepError(f"parameters.{key} has no values")
    if key in _INT_PARAMETERS:
        if not all(isinstance(v, int) and not isinstance(v, bool) for v in vals):
            raise SweepError(f"parameters.{key} takes integers, got {vals!r}")
    elif key == "initial.state":
        if not all(isinstance(v, str) for v in vals):
            raise SweepError(f"parameters.{key} takes strings, got {vals!r}")
    else:
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals):
            raise SweepError(f"parameters.{key} takes numbers, got {vals!r}")
        vals = [float(v) for v in vals]
    return vals


def _merge(base: dict, over: dict) -> dict:
    """Table-wise merge of TOML scene docs: keys of ``over`` replace those of ``base`` within each table."""
    out = copy.deepcopy(base)
    for table, value in over.items():
        if isinstance(value, dict) and isinstance(out.get(table), dict):
            if table == "patches" and ("file" in value) != ("file" in out[table]):
                out[table] = dict(value)  # a patch file and generator keys do not mix
            else:
                out[table].update(value)
        else:
            out[table] = copy.deepcopy(value)
    return out


@dataclass
class SweepSpec:
    """A resolved sweep: base scene, parameter values per pad, run settings, sharding.

    Attributes:
        doc: The spec as a TOML-shaped dict with CLI overrides applied (what the hash covers, with the base doc).
        base_dir: Folder that relative paths of the spec resolve against.
        name: Sweep name.
        base_doc: The base scene as a TOML-shaped dict (preset or file content merged with ``[base]`` tables).
        base: The base scene (run overrides applied).
        parameters: Parameter values per pad, key -> list of length ``pad_count`` (order of the spec).
        mode: ``"product"`` or ``"zip"``.
        shard_size: Pads per shard.
        duration: Simulated duration of every pad [s].
        integrator, precision, dt, tolerance: Solver settings (as ``run_hf``).
    """

    doc: dict
    base_dir: Path
    name: str
    base_doc: dict
    base: Scene
    parameters: dict[str, list]
    mode: str
    shard_size: int
    duration: float
    integrator: str
    precision: str
    dt: float | None
    tolerance: float
    _hash: str = field(default="", repr=False)

    @property
    def pad_count(self) -> int:
        """Number of pads."""
        return len(next(iter(self.parameters.values()))) if self.parameters else 1

    @property
    def shard_count(self) -> int:
        """Number of shards."""
        return math.ceil(self.pad_count / self.shard_size)

    def shard_range(self, index: int) -> tuple[int, int]:
        """[start, stop) global pad indices of shard ``index``."""
        a = index * self.shard_size
        return a, min(a + self.shard_size, self.pad_count)

    @property
    def hash(self) -> str:
        """SHA-256 of everything that decides the results: base scene, parameter values, run settings, shards."""
        if not self._hash:
            payload = {
                "format": FORMAT,
                "base": scene_to_dict(self.base),
                "parameters": self.parameters,
                "run": self.run_settings(),
                "shard_size": self.shard_size,
            }
            text = json.dumps(payload, sort_keys=True, default=str)
            self._hash = hashlib.sha256(text.encode()).hexdigest()
        return self._hash

    def run_settings(self) -> dict:
        """Duration, integrator, precision, dt, tolerance and sample interval, as a JSON-able dict."""
        return {
            "duration": self.duration,
            "integrator": self.integrator,
            "precision": self.precision,
            "dt": self.dt,
            "tolerance": self.tolerance,
            "sample_dt": self.base.record.sample_dt,
        }

    def pad_values(self, pad: int) -> dict[str, Any]:
        """The parameter values of global pad ``pad``."""
        return {k: v[pad] for k, v in self.parameters.items()}

    def scene(self, pad: int) -> Scene:
        """The scene of global pad ``pad``."""
        return apply_parameters(self.base, self.base_doc, self.pad_values(pad), name=f"{self.name}[{pad}]")

    def scenes(self, start: int, stop: int) -> list[Scene]:
        """Scenes of global pads [start, stop)."""
        return [self.scene(p) for p in range(start, stop)]


def load_spec(source: str | Path | dict, *, base_dir: Path | None = None, **overrides: Any) -> SweepSpec:
    """Read and validate a sweep spec (TOML path or dict); ``overrides`` (shard_size, duration, integrator,
    precision, dt, tolerance; None = keep) replace the spec's values and so enter its hash."""
    if isinstance(source, dict):
        doc = copy.deepcopy(source)
        base_dir = base_dir or Path.cwd()
    else:
        p = Path(source)
        if not p.is_file():
            raise SweepError(f"sweep spec {p} not found")
        try:
            doc = tomllib.loads(p.read_text())
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
            raise SweepError(f"cannot parse {p}: {e}") from None
        base_dir = p.resolve().parent
    for table in doc:
        if table not in ("sweep", "run", "base", "parameters"):
            raise SweepError(f"unknown table [{table}] in the sweep spec; allowed: [sweep] [run] [base] [parameters]")
    sw = doc.setdefault("sweep", {})
    run = doc.setdefault("run", {})
    for key in sw:
        if key not in _SWEEP_KEYS:
            raise SweepError(f"unknown key {key!r} in [sweep]; allowed: {', '.join(_SWEEP_KEYS)}")
    for key in run:
        if key not in _RUN_KEYS:
            raise SweepError(f"unknown key {key!r} in [run]; allowed: {', '.join(_RUN_KEYS)}")
    if "shard_size" in overrides and overrides["shard_size"] is not None:
        sw["shard_size"] = overrides.pop("shard_size")
    overrides.pop("shard_size", None)
    for key, value in overrides.items():
        if key not in _RUN_KEYS:
            raise SweepError(f"unknown run override {key!r}")
        if value is not None:
            run[key] = value
    return _resolve(doc, base_dir)


def _base_doc(doc: dict, base_dir: Path) -> tuple[dict, Path, str]:
    """The base scene doc, the folder its relative paths resolve against, and its name."""
    base = doc["sweep"].get("base")
    inline = doc.get("base", {})
    if not isinstance(inline, dict) or not all(isinstance(v, dict) for v in inline.values()):
        raise SweepError("[base] holds scene tables, e.g. [base.friction] M = 0.7")
    if base is None:
        return copy.deepcopy(inline), base_dir, "scene"
    if not isinstance(base, str):
        raise SweepError(f"sweep.base must be a preset name or a TOML scene path, got {base!r}")
    if base in PRESETS:
        text = resources.files("aca_warp.data").joinpath(f"{base}.toml").read_text()
        return _merge(tomllib.loads(text), inline), base_dir, base
    p = Path(base)
    if not p.is_absolute():
        p = base_dir / p
    if not p.is_file():
        raise SweepError(f"sweep.base {base!r} is neither a preset ({', '.join(PRESETS)}) nor a TOML file")
    try:
        return _merge(tomllib.loads(p.read_text()), inline), p.parent, p.stem
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise SweepError(f"cannot parse the base scene {p}: {e}") from None


def _resolve(doc: dict, base_dir: Path) -> SweepSpec:
    from aca_warp.hf.model import PRECISIONS
    from aca_warp.hf.options import DEFAULT_INTEGRATOR, DEFAULT_TOLERANCE, INTEGRATORS

    sw, run = doc["sweep"], doc["run"]
    base_doc, scene_dir, base_name = _base_doc(doc, base_dir)
    # patch files named relative to the base scene: make them absolute so workers elsewhere find them
    if "file" in base_doc.get("patches", {}) and not Path(base_doc["patches"]["file"]).is_absolute():
        base_doc["patches"]["file"] = str((scene_dir / base_doc["patches"]["file"]).resolve())
    try:
        base = scene_from_dict(base_doc, base_dir=scene_dir, name=base_name)
    except SceneError as e:
        raise SweepError(f"base scene: {e}") from None
    name = str(sw.get("name", base_name))
    mode = sw.get("mode", "product")
    if mode not in MODES:
        raise SweepError(f"sweep.mode must be one of {', '.join(MODES)}, got {mode!r}")
    shard_size = sw.get("shard_size", DEFAULT_SHARD_SIZE)
    if isinstance(shard_size, bool) or not isinstance(shard_size, int) or shard_size < 1:
        raise SweepError(f"sweep.shard_size must be a positive integer, got {shard_size!r}")
    integrator = run.get("integrator", DEFAULT_INTEGRATOR)
    if integrator not in INTEGRATORS:
        raise SweepError(f"run.integrator must be one of {', '.join(INTEGRATORS)}, got {integrator!r}")
    precision = run.get("precision", "fp64")
    if precision not in PRECISIONS:
        raise SweepError(f"run.precision must be one of {', '.join(PRECISIONS)}, got {precision!r}")

    def num(key: str, default: Any) -> Any:
        v = run.get(key, default)
        if v is None:
            return None
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
            raise SweepError(f"run.{key} must be a positive number, got {v!r}")
        return float(v)

    duration = num("duration", base.duration)
    dt = num("dt", None)
    tolerance = num("tolerance", DEFAULT_TOLERANCE)
    sample_dt = num("sample_dt", base.record.sample_dt)
    try:
        from aca_warp.hf.recorder import check_run

        base = base.replace(duration=duration, record=dataclasses.replace(base.record, sample_dt=sample_dt))
        check_run(duration, base.record)
    except SceneError as e:
        raise SweepError(f"run settings: {e}") from None
    if dt is not None and not duration / dt <= MAX_STEPS:
        raise SweepError(f"run.duration / run.dt = {duration / dt:.3g} steps per pad, more than {MAX_STEPS:.0e}")
    raw = doc.get("parameters", {})
    if not isinstance(raw, dict):
        raise SweepError("[parameters] must be a table of parameter = values")
    lists: dict[str, list] = {}
    for key, value in raw.items():
        if key not in PARAMETERS:
            raise SweepError(f"unknown sweep parameter {key!r}; allowed: {', '.join(PARAMETERS)}")
        lists[key] = _values(key, value)
    if "disc.sliding_speed" in lists and "disc.angular_velocity" in lists:
        raise SweepError("sweep disc.sliding_speed or disc.angular_velocity, not both")
    if any(PARAMETERS[k][1] in ("patches", "pad") for k in lists) and "file" in base_doc.get("patches", {}):
        raise SweepError("patch and pad parameters need a generated base scene, not [patches] file = ...")
    if "growth.increment" in lists and base.growth is None:
        raise SweepError("growth.increment is swept but the base scene has no [growth] table")
    if mode == "zip":
        lengths = {k: len(v) for k, v in lists.items()}
        if len(set(lengths.values())) > 1:
            raise SweepError(f"mode = 'zip' needs lists of equal length, got {lengths}")
        params = {k: list(v) for k, v in lists.items()}
    else:
        total = math.prod(len(v) for v in lists.values())
        if total > MAX_PADS:
            raise SweepError(f"the parameter lists combine into {total} pads, more than a sweep runs ({MAX_PADS})")
        combos = list(itertools.product(*lists.values()))
        params = {k: [c[i] for c in combos] for i, k in enumerate(lists)}
    spec = SweepSpec(
        doc=doc,
        base_dir=base_dir,
        name=name,
        base_doc=base_doc,
        base=base,
        parameters=params,
        mode=mode,
        shard_size=shard_size,
        duration=duration,
        integrator=integrator,
        precision=precision,
        dt=dt,
        tolerance=tolerance,
    )
    # fail before any run: build the first and last pad and, for every value of every parameter, one pad that
    # has it (catches e.g. patches that do not fit; a bad combination of good values fails its shard at run time)
    check = {0, spec.pad_count - 1}
    for key, vals in lists.items():
        first: dict[str, int] = {}
        distinct = len(set(map(repr, vals)))
        for p, v in enumerate(params[key]):
            first.setdefault(repr(v), p)
            if len(first) == distinct:
                break
        check.update(first.values())
    for p in sorted(check):
        try:
            spec.scene(p)
        except SceneError as e:
            raise SweepError(f"pad {p} ({spec.pad_values(p)}): {e}") from None
    return spec


@functools.lru_cache(maxsize=64)
def _generate(pad: Pad, gen: PatchGenerator):
    return gen.generate(pad)


def apply_parameters(base: Scene, base_doc: dict, values: dict[str, Any], *, name: str | None = None) -> Scene:
    """``base`` with the swept ``values`` (key -> value, keys of :data:`PARAMETERS`) applied via ``Scene.replace``.

    Patch and pad parameters regenerate the patches with the base's generator settings (cached per process);
    ``disc.sliding_speed`` is measured at the mean radius of the (possibly swept) pad.
    """
    groups: dict[str, dict[str, Any]] = {}
    for key, v in values.items():
        table, attr = key.split(".", 1)
        groups.setdefault(PARAMETERS[key][1], {})[attr] = v
    changes: dict[str, Any] = {}
    pad = base.pad
    if "pad" in groups:
        pad = dataclasses.replace(base.pad, **groups["pad"])
        changes["pad"] = pad
    if "pad" in groups or "patches" in groups:
        gen_doc = dict(base_doc.get("patches", {}))
        gen_doc.update(groups.get("patches", {}))
        gen = PatchGenerator(**gen_doc)
        patches = _generate(pad, gen)
        changes["patches"] = patches
        changes["origin"] = _merge(base.origin or base_doc, {"patches": gen_doc})
    if "friction" in groups:
        changes["friction"] = dataclasses.replace(base.friction, **groups["friction"])
    if "material" in groups:
        changes["material"] = dataclasses.replace(base.material, **groups["material"])
    if "initial" in groups:
        changes["initial"] = dataclasses.replace(base.initial, **groups["initial"])
    if "growth" in groups:
        changes["growth"] = dataclasses.replace(base.growth, **groups["growth"])
    d = groups.get("disc", {})
    if "angular_velocity" in d:
        changes["angular_velocity"] = float(d["angular_velocity"])
    elif "sliding_speed" in d:
        changes["angular_velocity"] = float(d["sliding_speed"]) / pad.mean_radius
    if "load" in groups:
        changes["normal_force"] = float(groups["load"]["normal_force"])
    if name is not None:
        changes["name"] = name
    return base.replace(**changes)


# -------------------------------------------------------------------------------------------- memory


def pad_bytes(scene: Scene, precision: str) -> int:
    """Estimated device bytes of one pad in a batch (model, state, solver scratch, CSR, recorder) [B].

    Per patch: 10 model arrays and ``patch_pad`` (10 T + 4), state u, u̇, force and the synchronous velocity
    (4 T), adaptive trial buffers (5 T); per directed link: index, inverse distance, stiffness (4 + 2 T); per
    pad: 257 recorded rows × 5 float64. Doubled for the neighbour build's temporaries and allocator slack.
    """
    from scipy.spatial import cKDTree

    t = 4 if precision == "fp32" else 8
    p = scene.patches
    links = 2 * len(cKDTree(np.column_stack([p.x, p.y])).query_pairs(scene.material.coupling_radius))
    per_patch = 10 * t + 4 + 4 * t + 5 * t + 4
    return int(2 * (p.count * per_patch + links * (4 + 2 * t) + 257 * 5 * 8))


def device_memory(device: str) -> int:
    """Free memory of a Warp device (CUDA: free device memory; CPU: available host memory) [B]."""
    import warp as wp

    dev = wp.get_device(device)
    if dev.is_cuda:
        return int(dev.free_memory)
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover
        return int(dev.total_memory or 8 * 2**30)


def batch_capacity(scene: Scene, precision: str, device: str, *, fraction: float = 0.5, sharing: int = 1) -> int:
    """How many pads like ``scene`` fit in ``fraction`` of the device's free memory, split ``sharing`` ways."""
    return max(1, int(fraction * device_memory(device) / max(1, sharing) / pad_bytes(scene, precision)))


# ---------------------------------------------------------------------------------------------- shard


def shard_name(index: int) -> str:
    """File name of shard ``index``."""
    return f"shard-{index:05d}.h5"


def run_shard(
    doc: dict,
    base_dir: str,
    out_dir: str,
    index: int,
    device: str = "cpu",
    *,
    memory_fraction: float = 0.5,
    sharing: int = 1,
) -> dict:
    """Run shard ``index`` of the spec ``doc`` (already resolved, overrides applied) and write its file.

    This is the task a Dask worker runs; it rebuilds the spec from ``doc`` (cheap, deterministic), runs the
    shard's pads as one batch (several when the memory estimate says they do not fit), streams the samples
    into ``shard-NNNNN.h5.partial`` and renames it when done. Returns a summary for the manifest.
    """
    import h5py
    import warp as wp

    from aca_warp.common.files import OutputLock, new_path, versions
    from aca_warp.common.storage import GuardedFile, storage_errno, storage_error
    from aca_warp.hf.loop import run_hf
    from aca_warp.hf.model import build_model
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.recorder import GLOBAL_NAMES, GLOBAL_UNITS
    from aca_warp.hf.state import initial_state

    wp.config.log_level = wp.LOG_WARNING
    t_start = time.perf_counter()
    spec = _resolve(copy.deepcopy(doc), Path(base_dir))
    start, stop = spec.shard_range(index)
    scenes = spec.scenes(start, stop)
    dev = wp.get_device(device)
    cap = batch_capacity(scenes[0], spec.precision, device, fraction=memory_fraction, sharing=sharing)
    final = Path(out_dir) / shard_name(index)
    partial = final.with_name(final.name + ".partial")
    n = stop - start
    n_samples = max(1, round(spec.duration / spec.base.record.sample_dt)) + 1
    summary: dict[str, Any] = {"index": index, "device": str(dev), "device_name": dev.name, "batches": 0}
    steps = 0
    wall = compile_time = 0.0
    engines: set[str] = set()
    fault = None
    dt_used = math.nan
    lock = OutputLock.acquire(final, what="a worker of another sweep still writes this shard")
    tmp = new_path(partial)
    out = None
    try:
        tmp.unlink(missing_ok=True)
        f = h5py.File(tmp, "w")
        out = GuardedFile(f, partial)
        f.attrs["format"] = FORMAT
        f.attrs["spec"] = json.dumps(spec.doc, default=str)
        f.attrs["spec_hash"] = spec.hash
        f.attrs["shard"] = index
        f.attrs["pad_start"] = start
        f.attrs["pad_stop"] = stop
        f.attrs["complete"] = False
        f.attrs["finished"] = False
        f.attrs["status"] = "running"
        f.attrs["device"] = str(dev)
        f.attrs["device_name"] = dev.name
        f.attrs["integrator"] = spec.integrator
        f.attrs["precision"] = spec.precision
        f.attrs["run"] = json.dumps(spec.run_settings())
        f.attrs["versions"] = json.dumps(versions())
        g = f.create_group("global")
        g.create_dataset("time", shape=(0,), maxshape=(None,), dtype="f8", chunks=(4096,)).attrs["unit"] = "s"
        for nm, unit in zip(GLOBAL_NAMES, GLOBAL_UNITS, strict=True):
            d = g.create_dataset(
                nm, shape=(n, 0), maxshape=(n, None), dtype="f8", chunks=(1, min(n_samples, 4096)), fillvalue=np.nan
            )
            d.attrs["unit"] = unit
        pg = f.create_group("parameters")
        for key, vals in spec.parameters.items():
            v = vals[start:stop]
            data = np.array(v, dtype=h5py.string_dtype()) if key == "initial.state" else np.asarray(v)
            out.reserve(data.nbytes)
            pg.create_dataset(key, data=data).attrs["unit"] = PARAMETERS[key][0]
        pads = f.create_group("pads")
        pads.create_dataset("index", data=np.arange(start, stop, dtype=np.int64))
        pads.create_dataset("patch_count", data=np.array([s.patches.count for s in scenes], dtype=np.int64))
        out.flush()
        os.replace(tmp, partial)  # readable from the moment it has this name
        for b0 in range(0, n, cap):
            b1 = min(b0 + cap, n)
            model = build_model(scenes[b0:b1], device=dev, precision=spec.precision)
            state = initial_state(model)
            row = [0]

            def sink(chunk: Any, b0: int = b0, b1: int = b1, row: list = row) -> None:
                k = len(chunk.time)
                if k == 0:
                    return
                r0 = row[0]
                out.touch(g["time"], r0, r0 + k)
                for nm in GLOBAL_NAMES:
                    out.touch(g[nm], r0, r0 + k, axis=1)
                out.reserve()
                if b0 == 0:
                    t = g["time"]
                    t.resize((r0 + k,))
                    t[r0:] = chunk.time
                for j, nm in enumerate(GLOBAL_NAMES):
                    d = g[nm]
                    if d.shape[1] < r0 + k:
                        d.resize((n, r0 + k))
                    d[b0:b1, r0 : r0 + k] = chunk.globals[:, :, j].T
                row[0] = r0 + k

            options = RunOptions(
                duration=spec.duration, integrator=spec.integrator, dt=spec.dt, tolerance=spec.tolerance
            )  # engine auto: the on-chip kernel on CUDA where the model allows it, else the general one
            res = run_hf(model, state, options, record=spec.base.record, sink=sink)
            summary["batches"] += 1
            steps = max(steps, res.steps)
            wall += res.wall_time
            engines.add("onchip" if "step:strang:onchip" in res.stages else "general")
            compile_time += res.compile_time
            dt_used = res.dt
            if res.fault is not None:
                fault = f"pads {start + b0}..{start + b1 - 1}: {res.fault}"
                break
            del model, state
        f.attrs["complete"] = fault is None
        f.attrs["finished"] = True
        f.attrs["status"] = "complete" if fault is None else f"stopped: {fault}"
        f.attrs["steps"] = steps
        f.attrs["dt"] = dt_used
        f.attrs["wall_time"] = wall
        f.attrs["compile_time"] = compile_time
        f.attrs["engine"] = ",".join(sorted(engines))
        f.attrs["batch_capacity"] = cap
        out.close()
        os.replace(partial, final)
    except BaseException as e:
        if out is not None:
            out.abandon()
        tmp.unlink(missing_ok=True)
        code = storage_errno(e)
        if code is not None:
            raise storage_error(code, partial, "the shard runs again when the sweep is rerun") from None
        raise
    finally:
        lock.release()
    summary.update(
        state="done" if fault is None else "fault",
        file=final.name,
        pads=n,
        steps=steps,
        wall_time=wall,
        compile_time=compile_time,
        task_time=time.perf_counter() - t_start,
        patch_steps=int(sum(s.patches.count for s in scenes)) * steps,
        fault=fault,
    )
    return summary


def shard_finished(path: Path, spec_hash: str, start: int, stop: int) -> str | None:
    """``"done"``/``"fault"`` when ``path`` holds a finished, readable shard of this spec and pad range, else None
    (then it runs again). Readable: every object opens and the last sample of every output reads (a damaged group
    or chunk index shows up here)."""
    import h5py

    from aca_warp.hf.recorder import GLOBAL_NAMES

    if not path.is_file():
        return None
    try:
        with h5py.File(path, "r") as f:
            a = f.attrs
            if not (
                bool(a.get("finished", False))
                and a.get("spec_hash") == spec_hash
                and int(a.get("pad_start", -1)) == start
                and int(a.get("pad_stop", -1)) == stop
            ):
                return None
            f.visititems(lambda name, obj: None)
            f["global/time"][-1:]
            for k in GLOBAL_NAMES:
                f["global"][k][:, -1:]
            return "done" if bool(a.get("complete", False)) else "fault"
    except (OSError, KeyError, ValueError, RuntimeError, TypeError):  # missing, truncated or damaged: run it again
        return None


# ------------------------------------------------------------------------------------------- manifest


def _write_json(path: Path, doc: dict) -> None:
    """Write ``doc`` to ``path`` atomically (a temporary file, then a rename); a full device keeps the old one."""
    from aca_warp.common.storage import storage_errno, storage_error

    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text(json.dumps(doc, indent=1, default=str))
        os.replace(tmp, path)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        code = storage_errno(e)
        if code is None:
            raise
        raise storage_error(code, path, "it keeps its previous state; make room and run the sweep again") from None


def read_manifest(out_dir: str | Path) -> dict | None:
    """The manifest of a sweep directory, or None when there is none."""
    p = Path(out_dir) / MANIFEST
    if not p.is_file():
        return None
    try:
        return json.loads(p.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise SweepError(f"{p} is not a sweep manifest ({e}); remove it or pass --overwrite") from None


def prepare_dir(spec: SweepSpec, out_dir: str | Path, *, overwrite: bool = False) -> dict:
    """Create or reopen the sweep directory; returns the manifest with every shard's verified state.

    A directory that holds another sweep (different spec hash) is refused unless ``overwrite``, which removes
    that sweep's manifest and shard files (nothing else). The caller holds the directory's lock
    (:func:`run_sweep`); a shard still being written by a worker of an earlier sweep is refused.
    """
    from aca_warp.common.files import locked_output

    d = Path(out_dir)
    if d.exists() and not d.is_dir():
        raise SweepError(f"{d} exists and is not a directory")
    d.mkdir(parents=True, exist_ok=True)
    old = read_manifest(d)
    stray = sorted(d.glob("shard-*.h5*"))
    if (old is not None and old.get("spec_hash") != spec.hash) or (old is None and stray):
        if not overwrite:
            if old is not None:
                what = f"a different sweep ({old.get('name', '?')!r}, spec hash {str(old.get('spec_hash'))[:12]})"
            else:
                what = f"{len(stray)} shard file(s) without a manifest"
            raise SweepError(
                f"{d} holds {what}, not this spec (hash {spec.hash[:12]}); "
                "pass --overwrite to replace it, or choose another output directory"
            )
        for p in stray:
            with locked_output(d / p.name.removesuffix(".partial"), what="it belongs to a sweep that still runs"):
                p.unlink(missing_ok=True)
        (d / MANIFEST).unlink(missing_ok=True)
        old = None
    shards = []
    for i in range(spec.shard_count):
        a, b = spec.shard_range(i)
        prev = (old or {}).get("shards", [])
        entry = dict(prev[i]) if i < len(prev) else {}
        entry.update(index=i, file=shard_name(i), pad_start=a, pad_stop=b)
        verified = shard_finished(d / shard_name(i), spec.hash, a, b)
        if verified is None:
            entry["state"] = "pending"
            with locked_output(d / shard_name(i), what="a worker of an earlier sweep still runs; stop it first"):
                (d / (shard_name(i) + ".partial")).unlink(missing_ok=True)
        elif entry.get("state") != verified:
            entry["state"] = verified  # the worker finished; the client died before recording it
        shards.append(entry)
    manifest = {
        "format": FORMAT,
        "name": spec.name,
        "spec_hash": spec.hash,
        "spec": spec.doc,
        "base_dir": str(spec.base_dir),
        "pads": spec.pad_count,
        "shard_size": spec.shard_size,
        "parameters": list(spec.parameters),
        "run": spec.run_settings(),
        "shards": shards,
    }
    _write_json(d / MANIFEST, manifest)
    return manifest


# ------------------------------------------------------------------------------------------- execution


@dataclass
class SweepResult:
    """What a sweep call did.

    Attributes:
        out_dir: The sweep directory.
        ran: Indices of the shards run by this call.
        skipped: Indices of the shards found finished and skipped.
        failed: Shard index -> error text, for shards that raised (state ``failed``; rerun to retry).
        faults: Indices of shards whose run stopped on a non-finite value (state ``fault``).
        wall_time: Wall time of the whole call, cluster start included [s].
        patch_steps: Patch-steps done by this call.
        workers: Number of workers used (0: this process).
    """

    out_dir: Path
    ran: list[int]
    skipped: list[int]
    failed: dict[int, str]
    faults: list[int]
    wall_time: float
    patch_steps: int
    workers: int
    summaries: list[dict] = field(default_factory=list)


def cuda_ordinals(device: str) -> list[int]:
    """GPU ordinals named by ``device``: ``cuda`` (all), ``cuda:1`` or ``cuda:0,cuda:1``."""
    import warp as wp

    if device == "cuda":
        n = wp.get_cuda_device_count()
        if n == 0:
            raise SweepError("device 'cuda': no CUDA device is available")
        return list(range(n))
    out = []
    for part in device.split(","):
        part = part.strip()
        if not part.startswith("cuda:") or not part[5:].isdigit():
            raise SweepError(f"device {device!r}: expected cpu, cuda, cuda:N or a list cuda:0,cuda:1")
        out.append(int(part[5:]))
    return out


LOOPBACK = "127.0.0.1"  # the only address a local cluster binds


def local_cluster(device: str, workers: int | None = None) -> Any:
    """A local Dask cluster: one single-threaded worker process per GPU (``CUDA_VISIBLE_DEVICES`` pinned)
    or, for ``cpu``, ``workers`` of them (default one per core). Returns (cluster, device seen by workers).

    Scheduler, nannies and workers listen on 127.0.0.1 only and serve no dashboard: a Dask worker executes
    whatever pickled function reaches it, so nothing of a local cluster may be reachable from another host.
    Other hosts join only through an external scheduler (``--scheduler``; docs/sweeps.md, "Security")."""
    import logging

    from distributed import Nanny, Scheduler, SpecCluster

    if device == "cpu":
        n = workers or os.cpu_count() or 1
        envs = [{} for _ in range(n)]
        worker_device = "cpu"
    else:
        ords = cuda_ordinals(device)
        visible = os.environ.get("CUDA_VISIBLE_DEVICES")
        names = visible.split(",") if visible else [str(i) for i in range(max(ords) + 1)]
        n = workers or len(ords)
        envs = [{"CUDA_VISIBLE_DEVICES": names[ords[i % len(ords)]]} for i in range(n)]
        worker_device = "cuda:0"
    # every process on loopback: a Dask worker runs the pickled functions sent to it, unauthenticated
    opts = {
        "nthreads": 1,
        "memory_limit": 0,
        "silence_logs": logging.ERROR,
        "host": LOOPBACK,
        "dashboard": False,
        "dashboard_address": f"{LOOPBACK}:0",
    }
    spec = {f"w{i}": {"cls": Nanny, "options": {**opts, "env": env}} for i, env in enumerate(envs)}
    cluster = SpecCluster(
        workers=spec,
        scheduler={
            "cls": Scheduler,
            "options": {"dashboard": False, "dashboard_address": f"{LOOPBACK}:0", "host": LOOPBACK},
        },
        silence_logs=logging.ERROR,
        name="aca-warp-sweep",
    )
    return cluster, worker_device


def warm_workers(client: Any, device: str) -> dict[str, float]:
    """Load (compile or fetch from the kernel cache) the HF kernel modules on every worker: address -> [s]."""
    from aca_warp.bench import load_modules

    def load(dev: str) -> float:
        import warp as wp

        wp.config.log_level = wp.LOG_WARNING
        return load_modules(wp.get_device(dev))

    return client.run(load, device)


def _have_dask() -> bool:
    import importlib.util

    return importlib.util.find_spec("distributed") is not None


def run_sweep(
    spec: SweepSpec,
    out_dir: str | Path,
    *,
    device: str = "cpu",
    workers: int | None = None,
    scheduler: str | None = None,
    overwrite: bool = False,
    memory_fraction: float = 0.5,
    log: Callable[[str], None] | None = None,
    client: Any = None,
) -> SweepResult:
    """Run every unfinished shard of ``spec`` into ``out_dir``.

    ``workers=0`` runs the shards one after another in this process (no Dask). Otherwise a local Dask cluster
    is started (``workers`` processes; default one per GPU of ``device``, or one per CPU core for ``cpu``), or
    the cluster at ``scheduler`` is used (its workers run on ``device``: ``cuda`` there means each worker's
    first visible GPU), or an open Dask ``client`` (``device`` as for a scheduler; see :func:`local_cluster`).
    The manifest is updated as shards finish.
    """
    t0 = time.perf_counter()
    say = log or (lambda s: None)
    out = Path(out_dir)
    if device != "cpu" and scheduler is None and client is None:
        cuda_ordinals(device)  # validate before anything is written
    if out.exists() and not out.is_dir():
        raise SweepError(f"{out} exists and is not a directory")
    out.mkdir(parents=True, exist_ok=True)
    from aca_warp.common.files import locked_output

    # one sweep per directory: held until the last shard is recorded
    with locked_output(out / MANIFEST, what="wait for that sweep to finish or stop it"):
        return _run_sweep(spec, out, device, workers, scheduler, overwrite, memory_fraction, say, client, t0)


def _run_sweep(
    spec: SweepSpec,
    out: Path,
    device: str,
    workers: int | None,
    scheduler: str | None,
    overwrite: bool,
    memory_fraction: float,
    say: Callable[[str], None],
    client: Any,
    t0: float,
) -> SweepResult:
    """:func:`run_sweep` with the directory locked."""
    manifest = prepare_dir(spec, out, overwrite=overwrite)
    todo = [s["index"] for s in manifest["shards"] if s["state"] not in ("done", "fault")]
    skipped = [s["index"] for s in manifest["shards"] if s["state"] in ("done", "fault")]
    if skipped:
        say(f"{len(skipped)} of {spec.shard_count} shard(s) already finished, skipped")
    result = SweepResult(out, [], skipped, {}, [], 0.0, 0, 0)

    def record(index: int, summary: dict | None, error: str | None) -> None:
        entry = manifest["shards"][index]
        if summary is not None:
            entry.update({k: v for k, v in summary.items() if k != "index"})
            result.ran.append(index)
            result.patch_steps += int(summary["patch_steps"])
            result.summaries.append(summary)
            if summary["state"] == "fault":
                result.faults.append(index)
            say(
                f"shard {index}: {summary['pads']} pads, {summary['state']} on {summary['device_name']}, "
                f"{summary['patch_steps'] / max(summary['wall_time'], 1e-12):.3g} patch-steps/s"
            )
        else:
            entry["state"] = "failed"
            entry["error"] = error
            result.failed[index] = error or "failed"
            say(f"shard {index}: failed: {error}")
        _write_json(out / MANIFEST, manifest)

    if not todo:
        result.wall_time = time.perf_counter() - t0
        return result
    args = (spec.doc, str(spec.base_dir), str(out.resolve()))
    if workers is None and scheduler is None and client is None and not _have_dask():
        say("Dask is not installed (pip install 'aca-warp[sweep]'): running the shards in this process")
        workers = 0
    if workers == 0 and scheduler is None and client is None:
        dev = device if device == "cpu" else f"cuda:{cuda_ordinals(device)[0]}"
        for i in todo:
            manifest["shards"][i]["state"] = "queued"
            _write_json(out / MANIFEST, manifest)
            try:
                summary = run_shard(*args, i, dev, memory_fraction=memory_fraction)
            except StorageError as e:  # the device is full: the other shards would fail the same way
                record(i, None, f"{type(e).__name__}: {e}")
                raise
            except AcaError as e:  # e.g. a pad whose combination of values is invalid: as on a Dask worker
                (out / (shard_name(i) + ".partial")).unlink(missing_ok=True)
                record(i, None, f"{type(e).__name__}: {e}")
                continue
            record(i, summary, None)
        result.wall_time = time.perf_counter() - t0
        return result

    try:
        from distributed import Client, as_completed
    except ImportError:
        raise SweepError(
            "Dask is not installed: pip install 'aca-warp[sweep]' (or dask[distributed]), or run with --workers 0"
        ) from None
    cluster = None
    own_client = client is None
    if client is not None:
        worker_device = "cuda:0" if device.startswith("cuda") else device
        sharing = len(client.scheduler_info(n_workers=-1)["workers"]) if device == "cpu" else 1
    elif scheduler is None:
        cluster, worker_device = local_cluster(device, workers)
        client = Client(cluster)
        sharing = len(cluster.workers) if device == "cpu" else 1
    else:
        client = Client(scheduler)
        worker_device = "cuda:0" if device == "cuda" else device
        sharing = 1
    try:
        result.workers = len(client.scheduler_info(n_workers=-1)["workers"])
        say(f"running {len(todo)} shard(s) on {result.workers} Dask worker(s), device {worker_device}")
        futures = {}
        for i in todo:
            fut = client.submit(
                run_shard,
                *args,
                i,
                worker_device,
                memory_fraction=memory_fraction,
                sharing=sharing,
                key=f"shard-{spec.hash[:12]}-{i}",
                pure=False,
            )
            futures[fut] = i
            manifest["shards"][i]["state"] = "queued"
        _write_json(out / MANIFEST, manifest)
        for fut in as_completed(list(futures)):
            i = futures[fut]
            try:
                record(i, fut.result(), None)
            except Exception as e:  # a worker died (KilledWorker) or the shard raised: record, go on
                record(i, None, f"{type(e).__name__}: {e}")
    finally:
        if own_client:
            client.close()
        if cluster is not None:
            cluster.close()
    result.wall_time = time.perf_counter() - t0
    return result


def load_sweep(out_dir: str | Path) -> dict[str, Any]:
    """Read every finished shard of a sweep directory into one dict, pads in global order.

    Keys: ``time`` (samples,) [s] of the first shard, the global outputs (pads, samples), ``parameters``
    (key -> (pads,)), ``pad_index`` (pads,), ``manifest``. Shards with different sample counts (a fault) are
    padded with NaN.
    """
    import h5py

    from aca_warp.hf.recorder import GLOBAL_NAMES

    d = Path(out_dir)
    manifest = read_manifest(d)
    if manifest is None:
        raise SweepError(f"{d} has no {MANIFEST}: not a sweep directory")
    parts: list[dict] = []
    for s in manifest["shards"]:
        if s["state"] not in ("done", "fault"):
            continue
        try:
            with h5py.File(d / s["file"], "r") as f:
                parts.append(
                    {
                        "time": f["global/time"][()],
                        **{k: f["global"][k][()] for k in GLOBAL_NAMES},
                        "parameters": {k: v[()] for k, v in f["parameters"].items()},
                        "pad_index": f["pads/index"][()],
                    }
                )
        except (OSError, RuntimeError, KeyError, ValueError, TypeError) as e:  # missing, truncated or damaged
            raise SweepError(
                f"cannot read shard {d / s['file']} ({type(e).__name__}: {e}); remove it and rerun the sweep"
            ) from None
    if not parts:
        raise SweepError(f"{d}: no finished shard yet")
    width = max(len(p["time"]) for p in parts)

    def pad_cols(a: np.ndarray) -> np.ndarray:
        return a if a.shape[1] == width else np.pad(a, ((0, 0), (0, width - a.shape[1])), constant_values=np.nan)

    out: dict[str, Any] = {"time": max((p["time"] for p in parts), key=len), "manifest": manifest}
    for k in GLOBAL_NAMES:
        out[k] = np.concatenate([pad_cols(p[k]) for p in parts])
    out["parameters"] = {k: np.concatenate([p["parameters"][k] for p in parts]) for k in parts[0]["parameters"]}
    out["pad_index"] = np.concatenate([p["pad_index"] for p in parts])
    return out


# ------------------------------------------------------------------------------------------------- CLI

EPILOG = """\
SPEC is a TOML sweep spec (docs/sweeps.md; example: aca_warp/data/sweep_hf1.toml). DIR receives manifest.json and
one HDF5 file per shard. A rerun in the same DIR skips finished shards and redoes unfinished ones.
Examples:
  aca-warp sweep aca_warp/data/sweep_hf1.toml -o sweep_out --workers 2            # two CPU worker processes
  aca-warp sweep aca_warp/data/sweep_hf1.toml -o sweep_out --device cuda          # one worker per GPU
  aca-warp sweep aca_warp/data/sweep_hf1.toml -o sweep_out --device cuda --scheduler tcp://host:8786
Exit codes: 0 every shard finished, 2 bad input, 3 some shard stopped on a fault or failed (rerun to retry).
"""


def add_parsers(sub: Any) -> None:
    """Register ``aca-warp sweep``."""
    from aca_warp.common.argtypes import fraction, int_at_least, positive
    from aca_warp.hf.options import INTEGRATORS

    p = sub.add_parser(
        "sweep",
        help="run a parameter sweep (many pads, batched, sharded, resumable; Dask for several workers)",
        description="Expand a TOML sweep spec into pads, run them in shards of batched pads and write one HDF5 "
        "file per shard plus a manifest. Several GPUs, CPU cores or hosts through Dask distributed.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=EPILOG,
    )
    p.add_argument("spec", metavar="SPEC", help="TOML sweep spec")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="sweep directory (created if missing)")
    p.add_argument(
        "--device", default="cpu", help="cpu (default), cuda (every GPU), cuda:N, or a list such as cuda:0,cuda:1"
    )
    p.add_argument(
        "--shard-size", type=int_at_least(1), metavar="N", help="pads per shard (default: the spec's, else 64)"
    )
    g = p.add_mutually_exclusive_group()
    g.add_argument(
        "--workers",
        type=int_at_least(0),
        metavar="N",
        help="local Dask workers (default: one per GPU, or one per CPU core for cpu); 0 runs in this process",
    )
    g.add_argument("--scheduler", metavar="ADDRESS", help="use the Dask cluster at this scheduler address")
    p.add_argument("--overwrite", action="store_true", help="replace a different sweep in DIR")
    p.add_argument("--duration", type=positive, metavar="S", help="simulated time per pad [s] (default: the spec's)")
    p.add_argument("--integrator", choices=INTEGRATORS, help="time integrator (default: the spec's, else strang)")
    p.add_argument("--precision", choices=("fp32", "fp64"), help="state precision (default: the spec's, else fp64)")
    p.add_argument("--dt", type=positive, metavar="S", help="fixed step [s] (default: the spec's, else 1e-8)")
    p.add_argument(
        "--memory-fraction",
        type=fraction,
        default=0.5,
        metavar="F",
        help="share of free device memory one batch may use (default 0.5); larger shards are split",
    )
    p.add_argument("--quiet", action="store_true", help="print only the summary")
    p.set_defaults(handler=_cmd_sweep)


def _cmd_sweep(args: argparse.Namespace) -> int:
    spec = load_spec(
        args.spec,
        shard_size=args.shard_size,
        duration=args.duration,
        integrator=args.integrator,
        precision=args.precision,
        dt=args.dt,
    )
    log = None if args.quiet else (lambda s: print(s, flush=True))
    if log:
        log(
            f"sweep {spec.name!r}: {spec.pad_count} pads ({', '.join(spec.parameters) or 'base only'}), "
            f"{spec.shard_count} shard(s) of {spec.shard_size}, {spec.duration:g} s each, "
            f"{spec.integrator} {spec.precision}, spec hash {spec.hash[:12]}"
        )
    res = run_sweep(
        spec,
        args.output,
        device=args.device,
        workers=args.workers,
        scheduler=args.scheduler,
        overwrite=args.overwrite,
        memory_fraction=args.memory_fraction,
        log=log,
    )
    rate = res.patch_steps / max(res.wall_time, 1e-12)
    print(
        f"{args.output}: {len(res.ran)} shard(s) run, {len(res.skipped)} skipped, {len(res.faults)} stopped on a "
        f"fault, {len(res.failed)} failed; {res.wall_time:.3g} s wall, {rate:.3g} patch-steps/s overall"
    )
    return 3 if res.failed or res.faults else 0
