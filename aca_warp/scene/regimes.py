"""Which shipped preset's physics a scene shares: the regime its statistics were measured in.

The statistical work-precision (docs/work_precision_statistics.md) measured how far each validation measure moves
with the step on seed ensembles of the shipped HF presets and of LF states. A scene shares a preset's physics when
it differs from the preset at most in what those ensembles varied or what does not enter the equations of motion:
the patch seed (the layout is a draw of the same generator), the initial state, the recording and the duration.
Everything else must be the preset's: the pad outline, the load, the disc speed, the friction law, the material
constants, the growth, a fresh matrix (one cell at elevation 0), and the generator of the patches (count, area range,
height law): the one the scene's ``origin`` names (a scene read from TOML, or back from a run file), else the one the
patches' ``source`` describes (:meth:`~aca_warp.scene.generator.PatchGenerator.describe`, numbers to 6 significant
digits).

Every shipped preset was measured so, the equal-height variants too (docs/work_precision_statistics.md and its
``equal_heights`` figures).

An HF scene of a saved LF state (:func:`~aca_warp.lf.io.scene_from_snapshot`) is a measured regime when the LF run was
the shipped multiscale preset (any seed) and the state one of the groups that keep their statistics at strang's
default for them (2.5e-7 s with the crossings averaged; 1e-7 s with the point treatment too): the
snapshot marks it in its ``origin`` with :func:`measured_origin`, which also records the scene's physics
(:func:`physics_digest`), so that a scene changed afterwards (another load, other patches) is no longer one.
"""

from __future__ import annotations

import dataclasses
import hashlib
import re
from functools import cache
from typing import Any

import numpy as np

from aca_warp.common.errors import SceneError
from aca_warp.scene.files import PRESETS, preset_document
from aca_warp.scene.generator import PatchGenerator
from aca_warp.scene.parts import Friction, Growth, Material, Pad, Scene

_SEED = re.compile(r"seed=\d+")


def _parts(scene: Scene) -> tuple[Any, ...]:
    """The parts of a scene that set its motion besides its patches and matrix: pad, load, disc speed, friction law,
    material and growth."""
    return (scene.pad, scene.normal_force, scene.angular_velocity, scene.friction, scene.material, scene.growth)


def _physics(scene: Scene) -> tuple[Any, ...]:
    """What a scene's motion depends on beyond its patch seed, initial state, recording and duration."""
    return (*_parts(scene), _generator(scene))


def _generator(scene: Scene) -> str:
    """The description of the generator of a scene's patches, its seed masked: from ``origin`` where that holds a
    generator's parameters, else the patches' ``source``."""
    gen = (scene.origin or {}).get("patches", {})
    if isinstance(gen, dict) and gen and set(gen) <= {f.name for f in dataclasses.fields(PatchGenerator)}:
        try:
            return _SEED.sub("seed=*", PatchGenerator(**gen).describe())
        except (SceneError, TypeError):  # not a valid generator: the patches' own source decides
            pass
    return _SEED.sub("seed=*", scene.patches.source)


@cache
def _preset_physics() -> dict[tuple[Any, ...], str]:
    """The physics of every shipped preset, from its document: the key :func:`_physics` gives the preset's scene,
    built without generating its patches (``_physics(preset(name))`` would place 10 × 1758 patches, ≈ 0.26 s on
    every command that resolves a default step; the test that every preset is its own regime holds the two equal)."""
    out = {}
    for name in PRESETS:
        doc = preset_document(name)
        pad = Pad(**doc["pad"])
        disc = doc.get("disc", {})
        omega = disc["angular_velocity"] if "angular_velocity" in disc else disc["sliding_speed"] / pad.mean_radius
        key = (
            pad,
            doc["load"]["normal_force"],
            omega,
            Friction(**doc.get("friction", {})),
            Material(**doc.get("material", {})),
            Growth(**doc["growth"]) if "growth" in doc else None,
            _SEED.sub("seed=*", PatchGenerator(**doc["patches"]).describe()),
        )
        out[key] = name
    return out


def physics_digest(scene: Scene) -> str:
    """A digest of what a scene's motion depends on beyond its initial state, recording and duration: the pad, load,
    disc speed, friction law, material and growth (their numbers as Python floats, however they were given), the
    patches' source, and the patches' and the matrix cells' arrays themselves (each with its length)."""
    numbers = []
    for part in _parts(scene):
        values = dataclasses.astuple(part) if dataclasses.is_dataclass(part) else (part,)
        numbers.append(tuple(float(v) if isinstance(v, (int, float, np.number)) else v for v in values))
    h = hashlib.sha256(repr((*numbers, scene.patches.source)).encode())
    p, m = scene.patches, scene.matrix
    for a in (p.x, p.y, p.area, p.height) + (() if m is None else (m.area, m.radius, m.height)):
        a = np.ascontiguousarray(a, dtype=np.float64)
        h.update(np.int64(a.size).tobytes() + a.tobytes())
    return h.hexdigest()


def measured_origin(scene: Scene, regime: str) -> dict[str, Any]:
    """The ``origin`` that marks ``scene`` as of the measured regime ``regime`` (a name for messages), as long as its
    physics stays what it is now."""
    return {"measured_regime": {"name": regime, "physics": physics_digest(scene)}}


def preset_regime(scene: Scene) -> str | None:
    """The shipped preset (:data:`~aca_warp.scene.files.PRESETS`) whose physics ``scene`` shares, or the measured
    regime its ``origin`` marks (:func:`measured_origin`) while its physics is unchanged, or None.

    hf1 with another patch seed, from rest or saturated, recorded at any interval, is hf1's regime; hf1 at another
    load, speed or patch count, or with patches from a file, is no preset's; an LF state is one where
    :func:`~aca_warp.lf.io.scene_from_snapshot` marked it.
    """
    marked = (scene.origin or {}).get("measured_regime")
    if isinstance(marked, dict):  # an LF state of a measured group, unless changed since (measured_origin)
        return str(marked.get("name")) if marked.get("physics") == physics_digest(scene) else None
    m = scene.matrix
    if m is not None and not (m.is_flat and m.height[0] == 0.0):  # a worn or raised matrix: no fresh pad's
        return None
    try:
        return _preset_physics().get(_physics(scene))
    except TypeError:  # an unhashable part (a scene built by hand with lists): no preset's
        return None
