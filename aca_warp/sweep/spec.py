"""Sweep specs: a TOML spec expanded into pads (a Cartesian product or zipped lists of scene parameters).

:func:`load_spec` reads and checks a spec (docs/sweeps.md, "The spec") and returns a :class:`SweepSpec`: the base
scene, every pad's parameter values, the run settings, the shard size and the spec hash that a sweep directory is
keyed on. :func:`apply_parameters` makes one pad's scene from the base. Nothing here runs a pad.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import hashlib
import itertools
import json
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.common.bounds import MAX_PADS, read_toml
from aca_warp.common.errors import AcaError, SceneError, did_you_mean, sweep_spec
from aca_warp.scene import (
    GENERATOR_KINDS,
    PAD_KINDS,
    PRESETS,
    Friction,
    Material,
    Pad,
    PatchGenerator,
    Scene,
    check_numbers_plausible,
    preset_document,
    scene_from_dict,
    scene_to_dict,
)
from aca_warp.scene.files import refuse_hdf5

FORMAT = "aca_warp.sweep/1"
MODES = ("product", "zip")
DEFAULT_SHARD_SIZE = 64
PACKINGS = ("size", "none")
_SWEEP_KEYS = ("name", "base", "mode", "shard_size", "pack")
_RUN_KEYS = (
    "duration", "integrator", "precision", "dt", "tolerance", "sample_dt", "fast_math", "growth_dt", "crossing"
)  # fmt: skip

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
                raise SweepError(f"parameters.{key}: {form} takes [start, stop, count] with count ≥ 1, got {args!r}")
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
        ranged = isinstance(raw, dict) and "range" in raw
        hint = " (a range stops before its stop: [20, 20] is empty, and counting down needs a negative step)"
        raise SweepError(f"parameters.{key} has no values{hint if ranged else ''}")
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
        pack: How pads are cut into shards: ``"size"`` (default: by patch count, so that a shard's pads are alike)
            or ``"none"`` (in the spec's order).
        order: The pads in the order shards take them (global pad indices, shape (pads,)), or None for the spec's
            order (``pack = "none"``, or every pad of the same patch count).
        duration: Simulated duration of every pad [s].
        integrator, precision, dt, tolerance: Solver settings (as ``run_hf``).
        fast_math: The on-chip strang kernel compiled with CUDA fast math (``RunOptions.fast_math``: fp32 strang on
            CUDA only).
        growth_dt: Simulated time between growth events of growing pads [s] (``RunOptions.growth_dt``), written
            out (:func:`~aca_warp.hf.options.growth_asked`); None: the scenes' growth interval (``run.growth_dt =
            "scene"``, or an integrator other than strang).
        crossing: strang's treatment of steps that cross zero slip (``RunOptions.crossing``: ``point`` or ``mean``;
            the default, :func:`~aca_warp.hf.options.default_crossing`, written out).
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
    pack: str = "size"
    order: np.ndarray | None = field(default=None, repr=False)
    fast_math: bool = False
    growth_dt: float | None = None
    crossing: str = "point"
    _hash: str = field(default="", repr=False)

    @property
    def pad_count(self) -> int:
        """Number of pads."""
        return len(next(iter(self.parameters.values()))) if self.parameters else 1

    @property
    def shard_count(self) -> int:
        """Number of shards."""
        return math.ceil(self.pad_count / self.shard_size)

    def check_records(self) -> None:
        """Refuse a base scene that records per-patch histories, which a sweep's shards do not hold (global outputs
        only): checked where a sweep starts (a shard written before the check reads as it was)."""
        if self.base.record.patches:
            raise SweepError(
                f"the base scene records per-patch histories ({', '.join(self.base.record.patches)}), which a sweep's "
                "shards do not hold (global outputs only): leave record.patches out of the base ([base.record] "
                "patches = [] for a scene that sets it); for one pad's histories run its scene with aca-warp hf "
                "--record-patches"
            )

    @property
    def layout_count(self) -> int:
        """Number of distinct patch layouts the pads take: the combinations of the swept patch and pad parameters
        among the pads (1 when none is swept); the preparation of a shard generates the layouts of its pads."""
        keys = [k for k in self.parameters if PARAMETERS[k][1] in ("patches", "pad")]
        if not keys:
            return 1
        return len(set(zip(*(self.parameters[k] for k in keys), strict=True)))  # numbers: hashable

    def shard_range(self, index: int) -> tuple[int, int]:
        """[start, stop) positions of shard ``index`` in the order shards take the pads (:attr:`order`; the global pad
        indices themselves when pads are not reordered)."""
        a = index * self.shard_size
        return a, min(a + self.shard_size, self.pad_count)

    def shard_pads(self, index: int) -> np.ndarray:
        """Global indices of the pads of shard ``index``, in the shard's (and its file's) row order, int64."""
        a, b = self.shard_range(index)
        return np.arange(a, b, dtype=np.int64) if self.order is None else self.order[a:b]

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
            if self.order is not None:  # pads reordered into shards (absent otherwise: hashes of earlier sweeps hold)
                payload["pack"] = self.pack
            text = json.dumps(payload, sort_keys=True, default=str)
            self._hash = hashlib.sha256(text.encode()).hexdigest()
        return self._hash

    @functools.cached_property
    def patch_data(self) -> str | None:
        """SHA-256 of the base scene's patches (x, y, area, height [m, m, m², m] as float64) where they come from a
        patch file (``[patches] file``), else None. The spec names such a file by its path, so :attr:`hash` stays
        the same when the file is rewritten; the sweep's folder and shards record this digest beside it, and a
        sweep continued, or a pad taken out, over other patches is refused."""
        if "file" not in (self.base.origin or {}).get("patches", {}):
            return None
        digest = hashlib.sha256()
        p = self.base.patches
        for a in (p.x, p.y, p.area, p.height):
            digest.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
        return digest.hexdigest()

    def run_settings(self) -> dict:
        """Duration, integrator, precision, dt, tolerance and sample interval, and fast math where it is on, the
        growth events' spacing where it is set and the crossing treatment where it is not the point one (absent
        otherwise: hashes of earlier sweeps hold), as a JSON-able dict."""
        return {
            "duration": self.duration,
            "integrator": self.integrator,
            "precision": self.precision,
            "dt": self.dt,
            "tolerance": self.tolerance,
            "sample_dt": self.base.record.sample_dt,
            **({"fast_math": True} if self.fast_math else {}),
            **({"growth_dt": self.growth_dt} if self.growth_dt is not None else {}),
            **({"crossing": self.crossing} if self.crossing != "point" else {}),
        }

    def pad_values(self, pad: int) -> dict[str, Any]:
        """The parameter values of global pad ``pad``."""
        return {k: v[pad] for k, v in self.parameters.items()}

    def scene(self, pad: int) -> Scene:
        """The scene of global pad ``pad``."""
        return apply_parameters(self.base, self.base_doc, self.pad_values(pad), name=f"{self.name}[{pad}]")

    def scenes(self, pads: Any) -> list[Scene]:
        """Scenes of the global pads ``pads`` (an iterable of indices), in that order."""
        return [self.scene(int(p)) for p in pads]


def base_file(doc: dict) -> str | None:
    """The base scene file a spec doc names (``sweep.base`` as given), or None for a preset or an inline base."""
    base = doc.get("sweep", {}).get("base")
    return base if isinstance(base, str) and base not in PRESETS else None


def pad_list(pads: Any, most: int = 12) -> str:
    """Global pad indices in words for a message, sorted, runs of consecutive ones as ``a-b`` (``1-3, 7, 9-12``);
    beyond ``most`` items the first of them and the count (a shard's ``/pads/index`` lists every one)."""
    p = np.sort(np.asarray(pads, dtype=np.int64))
    starts = np.flatnonzero(np.diff(p, prepend=p[0] - 2) != 1)
    ends = np.append(starts[1:], p.size) - 1
    items = [f"{p[a]}" if a == b else f"{p[a]}-{p[b]}" for a, b in zip(starts, ends, strict=True)]
    if len(items) <= most:
        return ", ".join(items)
    return ", ".join(items[:most]) + f", … ({p.size} pads; the shard's /pads/index lists them)"


def stored_crossing(run: dict) -> str:
    """The crossing treatment of stored run settings (:meth:`SweepSpec.run_settings`, a shard's or a manifest's
    ``run``): the point treatment where none is stored."""
    return run.get("crossing", "point")


def load_spec(source: str | Path | dict, *, base_dir: Path | None = None, **overrides: Any) -> SweepSpec:
    """Read and validate a sweep spec (TOML path or dict); ``overrides`` (shard_size, duration, integrator,
    precision, dt, tolerance, fast_math, growth_dt, crossing; None = keep) replace the spec's values and so enter its
    hash."""
    with sweep_spec():  # messages name the spec's keys (run.sample_dt, [base.scene] allow_implausible)
        return _load(source, base_dir, overrides)


def _load(source: str | Path | dict, base_dir: Path | None, overrides: dict[str, Any]) -> SweepSpec:
    """:func:`load_spec`'s work."""
    if isinstance(source, dict):
        doc = copy.deepcopy(source)
        base_dir = base_dir or Path.cwd()
    else:
        p = Path(source)
        if p.is_dir():
            raise SweepError(f"sweep spec {p} is a folder, not a TOML spec file")
        if not p.is_file():
            shipped = resources.files("aca_warp.data") / p.name
            example = p.name.startswith("sweep_") and shipped.is_file()
            where = f"; the example of that name shipped with aca_warp is {shipped}" if example else ""
            raise SweepError(f"sweep spec {p} not found{where}")

        hint = f" (a run file is repeated with 'aca-warp rerun {p} -o NEW.h5')"
        try:
            doc = read_toml(p, "sweep spec", refuse=refuse_hdf5(p, "sweep spec", hint))
        except SceneError as e:
            raise SweepError(str(e)) from None
        if not doc:
            raise SweepError(
                f"sweep spec {p} is empty: it would run one pad of the default scene; give at least [sweep] base and "
                "[parameters] (docs/sweeps.md)"
            )
        base_dir = p.resolve().parent
    for table in doc:
        if table not in ("sweep", "run", "base", "parameters"):
            raise SweepError(f"unknown table [{table}] in the sweep spec; allowed: [sweep] [run] [base] [parameters]")
    sw = doc.setdefault("sweep", {})
    run = doc.setdefault("run", {})
    for key in sw:
        if key not in _SWEEP_KEYS:
            raise SweepError(
                f"unknown key {key!r} in [sweep]{did_you_mean(key, _SWEEP_KEYS)}; allowed: {', '.join(_SWEEP_KEYS)}"
            )
    for key in run:
        if key not in _RUN_KEYS:
            raise SweepError(
                f"unknown key {key!r} in [run]{did_you_mean(key, _RUN_KEYS)}; allowed: {', '.join(_RUN_KEYS)}"
            )
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
        return _merge(preset_document(base), inline), base_dir, base
    p = Path(base)
    if not p.is_absolute():
        p = base_dir / p
    if not p.is_file():
        looks = p.suffix == ".toml" or "/" in base
        raise SweepError(
            f"sweep.base {base!r}: no such file in {p.parent} (a relative path is read from the spec's folder)"
            if looks
            else f"sweep.base {base!r} is neither a preset ({', '.join(PRESETS)}) nor a TOML file"
        )
    try:
        return _merge(read_toml(p, "base scene"), inline), p.parent, p.stem
    except SceneError as e:
        raise SweepError(f"the base scene: {e}") from None


def _resolve(doc: dict, base_dir: Path, *, check: bool = True) -> SweepSpec:
    """The :class:`SweepSpec` of a spec doc; ``check``: build a few pads first (:func:`_check_pads`; a shard task
    skips it, its client checked the spec)."""
    from aca_warp.hf.model import PRECISIONS
    from aca_warp.hf.options import (
        DEFAULT_INTEGRATOR,
        DEFAULT_TOLERANCE,
        INTEGRATORS,
        SCENE_CLOCK,
        check_crossing,
        crossing_asked,
        default_follows,
        default_precision,
        default_step,
        fast_math_unfit,
        growth_asked,
        step_asked,
    )

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
    pack = sw.get("pack", "size")
    if pack not in PACKINGS:
        raise SweepError(f"sweep.pack must be one of {', '.join(PACKINGS)}, got {pack!r}")
    integrator = run.get("integrator", DEFAULT_INTEGRATOR)
    if integrator not in INTEGRATORS:
        raise SweepError(f"run.integrator must be one of {', '.join(INTEGRATORS)}, got {integrator!r}")
    precision = run.get("precision", default_precision(integrator))
    if precision not in PRECISIONS:
        raise SweepError(f"run.precision must be one of {', '.join(PRECISIONS)}, got {precision!r}")

    def num(key: str, default: Any) -> Any:
        v = run.get(key, default)
        if v is None:
            return None
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
            raise SweepError(f"run.{key} must be a positive number, got {v!r}")
        return float(v)

    fast_math = run.get("fast_math", False)
    if not isinstance(fast_math, bool):
        raise SweepError(f"run.fast_math must be true or false, got {fast_math!r}")
    unfit = fast_math_unfit(integrator, precision) if fast_math else None
    if unfit is not None:
        raise SweepError(f"run.fast_math (--fast-math): {unfit}")
    crossing = run.get("crossing")
    try:
        check_crossing(crossing, integrator)
    except SceneError as e:
        raise SweepError(f"run.crossing (--crossing): {e}") from None
    duration = num("duration", base.duration)
    scene_clock = run.get("growth_dt") == SCENE_CLOCK  # the events at the scenes' own interval: left out
    growth_dt = None if scene_clock else num("growth_dt", None)
    # (stored run settings hold the default for every integrator: a shard's spec read again)
    if run.get("tolerance", DEFAULT_TOLERANCE) != DEFAULT_TOLERANCE and integrator not in ("adaptive", "auto"):
        raise SweepError(
            f"run.tolerance is the tolerance of the explicit pair of adaptive (and of auto's sliding mode); "
            f"{integrator} takes none: leave it out"
        )
    tolerance = num("tolerance", DEFAULT_TOLERANCE)
    sample_dt = num("sample_dt", base.record.sample_dt)
    lists, params = _expand(doc.get("parameters", {}), mode, base, base_doc)
    # the default step and crossing treatment written out (the hash and the shards name them): the base scene's,
    # where every pad shares its physics, else those for any scene
    asked = num("dt", None)
    shared = (asked is None or crossing is None) and integrator == "strang"
    shared = shared and _shares_base_physics(base, base_doc, lists)
    dt = step_asked(integrator, asked, [base] if shared else [], sample_dt)
    crossing = crossing_asked(integrator, crossing, [base] if shared else [])
    try:
        from aca_warp.hf.recorder import check_run, check_sample_step

        record = dataclasses.replace(base.record, sample_dt=sample_dt)
        record.check_duration(duration, "run.sample_dt", "run.duration")  # before the scene's, which names its fields
        base = base.replace(duration=duration, record=record)
        check_run(duration, base.record)
        step = default_step(integrator) if dt is None else dt
        check_sample_step(sample_dt, step, follows=default_follows(integrator, asked, step))
    except SceneError as e:
        raise SweepError(f"run settings: {e}") from None
    if dt is not None and not duration / dt <= MAX_STEPS:
        raise SweepError(f"run.duration / run.dt = {duration / dt:.3g} steps per pad, more than {MAX_STEPS:.0e}")
    if (growth_dt is not None or scene_clock) and base.growth is None:  # (growth.* parameters need one too)
        raise SweepError("run.growth_dt sets the spacing of growth events; the base scene does not grow (no [growth])")
    if base.growth is not None and not scene_clock:  # written out, like the step: the hash and the shards name it
        growth_dt = growth_asked(integrator, growth_dt, base.growth.interval, duration)
    # the defaults resolved here written into the doc the workers resolve again, so that a worker whose code has
    # other defaults runs this spec's settings (its hash is the same either way)
    run.update({"precision": precision, "crossing": crossing, **({"dt": dt} if dt is not None else {})})
    run.update({"growth_dt": growth_dt} if growth_dt is not None else {})
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
        pack=pack,
        order=pack_order(params, pack),
        fast_math=fast_math,
        growth_dt=growth_dt,
        crossing=crossing,
    )
    if check:
        _check_pads(spec, lists)
    return spec


def _expand(raw: Any, mode: str, base: Scene, base_doc: dict) -> tuple[dict[str, list], dict[str, list]]:
    """The ``[parameters]`` table: (key -> its values, key -> its value per pad) in the sweep's ``mode``."""
    if not isinstance(raw, dict):
        raise SweepError("[parameters] must be a table of parameter = values")
    lists: dict[str, list] = {}
    for key, value in raw.items():
        if key not in PARAMETERS:
            raise SweepError(
                f"unknown sweep parameter {key!r}{did_you_mean(key, PARAMETERS)}; allowed: {', '.join(PARAMETERS)}"
            )
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
        return lists, {k: list(v) for k, v in lists.items()}
    total = math.prod(len(v) for v in lists.values())
    if total > MAX_PADS:
        raise SweepError(f"the parameter lists combine into {total} pads, more than a sweep runs ({MAX_PADS})")
    combos = list(itertools.product(*lists.values()))
    return lists, {k: [c[i] for c in combos] for i, k in enumerate(lists)}


def pack_order(parameters: dict[str, list], pack: str) -> np.ndarray | None:
    """The order in which shards take the pads (global pad indices, int64), or None for the spec's order.

    ``"size"``: pads sorted by patch count (stable: pads of equal count keep the spec's order), so that the pads of
    a shard, one batch on the device, are alike (the on-chip kernel sizes every block of a batch for its largest
    pad; only ``patches.count`` changes the count of a generated layout); the spec's order when every pad has the same
    count. ``"none"``: the spec's order.
    """
    counts = parameters.get("patches.count")
    if pack == "none" or counts is None or len(set(counts)) == 1:
        return None
    return np.argsort(np.asarray(counts, dtype=np.int64), kind="stable").astype(np.int64)


# parameters whose values select a random draw, not the geometry or the material: checked through the first and last
# pad only (a sweep over 2048 patch seeds would otherwise make every layout here, in one process, before any run)
DRAW_PARAMETERS = frozenset({"patches.seed", "initial.seed"})  # each value a draw, not a point of a range


def _shares_base_physics(base: Scene, base_doc: dict, lists: dict[str, list]) -> bool:
    """Whether every pad of a sweep has the physics of ``base``, a scene of a measured regime
    (:func:`~aca_warp.scene.regimes.preset_regime`): every listed parameter but the draws (patch and initial-state
    seeds) and the initial state takes only values that leave the base's regime as it is (the base with that one
    value applied is of the same regime). Stops at the first value that does not."""
    from aca_warp.scene.regimes import preset_regime

    regime = preset_regime(base)
    if regime is None:
        return False
    for key, values in lists.items():
        if key == "patches.seed" or PARAMETERS[key][1] == "initial":
            continue
        for v in {repr(v): v for v in values}.values():  # each distinct value once
            try:
                if preset_regime(apply_parameters(base, base_doc, {key: v})) != regime:
                    return False
            except SceneError:  # a value the pads refuse: its shard says so; it keeps no preset's physics
                return False
    return True


def _check_pads(spec: SweepSpec, lists: dict[str, list]) -> None:
    """Fail before any run: build the first and last pad and, for every value of every parameter but the seeds
    (:data:`DRAW_PARAMETERS`), one pad that has it (catches e.g. patches that do not fit; a bad combination of good
    values, or a seed whose draw fails, fails its shard at run time)."""
    check = {0, spec.pad_count - 1}
    for key, vals in lists.items():
        if key in DRAW_PARAMETERS:
            continue
        first: dict[str, int] = {}
        distinct = len(set(map(repr, vals)))
        for p, v in enumerate(spec.parameters[key]):
            first.setdefault(repr(v), p)
            if len(first) == distinct:
                break
        check.update(first.values())
    for p in sorted(check):
        try:
            spec.scene(p)
        except SceneError as e:
            raise SweepError(f"pad {p} ({spec.pad_values(p)}): {e}") from None


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
    if not base.allow_implausible:  # a radius in mm, an area in mm²: said so before they are compared
        check_numbers_plausible(groups.get("pad", {}), "pad", PAD_KINDS)
        check_numbers_plausible(groups.get("patches", {}), "patches", GENERATOR_KINDS)
    if "pad" in groups:
        pad = dataclasses.replace(base.pad, **groups["pad"])
        changes["pad"] = pad
    if "pad" in groups or "patches" in groups:
        gen_doc = dict(base_doc.get("patches", {}))
        gen_doc.update(groups.get("patches", {}))
        gen = PatchGenerator(**gen_doc)
        patches = _generate(pad, gen)
        changes["patches"] = patches
        src = base.origin or base_doc  # the other tables shared with the base (scene origins are never changed)
        changes["origin"] = {**src, "patches": {**src.get("patches", {}), **gen_doc}}
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


def hf1_product_doc(
    name: str,
    n_m: int,
    n_f: int,
    seeds: int,
    *,
    shard_size: int,
    duration: float,
    precision: str,
    patches: int | None = None,
) -> dict:
    """The spec (as for :func:`load_spec`) of a benchmark sweep of hf1 pads: ``n_m`` values of friction.M in
    0.6–0.9 × ``n_f`` normal forces in 300–600 N × ``seeds`` patch layouts, ``strang`` at 1e-8 s for ``duration``
    [s] in ``precision``; ``patches``: patches per pad (None: the preset's)."""
    doc: dict = {
        "sweep": {"name": name, "base": "hf1", "shard_size": shard_size},
        "run": {"duration": duration, "precision": precision, "integrator": "strang", "dt": 1e-8},
        "parameters": {
            "friction.M": {"linspace": [0.6, 0.9, n_m]},
            "load.normal_force": {"linspace": [300.0, 600.0, n_f]},
            "patches.seed": {"range": [1, seeds + 1]},
        },
    }
    if patches is not None:
        doc["base"] = {"patches": {"count": patches}}
    return doc
