"""Scenes: pad geometry, patch coverage state, material constants, loads, friction law, initial state, recording.

A scene holds everything one HF run of one pad needs (paper §2.1.2, §3.1; ``docs/model.md`` §1–2).
Scenes come from Python objects, from TOML files (:func:`load_scene`) or from the built-in presets
``hf1``…``hf4`` and ``varying_area`` and their equal-height variants ``hf1_equal``… (:func:`preset`, files in
``aca_warp/data``; ``docs/presets.md``). Everything is
validated here, before any simulation starts; errors are :class:`~aca_warp.common.errors.SceneError` with a
one-line message. All quantities are SI (m, m², kg, N, s, rad).

The code lives in modules of one concern each, re-exported here (``from aca_warp.scene import Scene`` etc.):

* :mod:`aca_warp.scene.parts`: the parts of a scene (:class:`Pad`, :class:`Patches`, :class:`Material`,
  :class:`Friction`, :class:`Initial`, :class:`Growth`, :class:`Record`, :class:`Matrix`) and :class:`Scene`;
* :mod:`aca_warp.scene.generator`: seeded patch layouts (:class:`PatchGenerator`);
* :mod:`aca_warp.scene.files`: TOML scenes, presets and HDF5 patch files.
"""

from __future__ import annotations

from aca_warp.scene.files import (
    GENERATOR_KINDS,
    PAD_KINDS,
    PRESETS,
    check_numbers_plausible,
    load_scene,
    preset,
    preset_document,
    read_patch_file,
    read_scene_toml,
    scene_from_dict,
    scene_to_dict,
    write_patch_file,
)
from aca_warp.scene.generator import PatchGenerator
from aca_warp.scene.parts import (
    HEIGHT_LAWS,
    INITIAL_STATES,
    PATCH_VARIABLES,
    Friction,
    Growth,
    Initial,
    Material,
    Matrix,
    Pad,
    Patches,
    Record,
    Scene,
    check_pad_plausible,
    overlapping_pairs,
)

__all__ = [
    "GENERATOR_KINDS",
    "PAD_KINDS",
    "HEIGHT_LAWS",
    "INITIAL_STATES",
    "PATCH_VARIABLES",
    "PRESETS",
    "Friction",
    "Growth",
    "Initial",
    "Material",
    "Matrix",
    "Pad",
    "PatchGenerator",
    "Patches",
    "Record",
    "Scene",
    "check_numbers_plausible",
    "check_pad_plausible",
    "load_scene",
    "overlapping_pairs",
    "preset",
    "preset_document",
    "read_patch_file",
    "read_scene_toml",
    "scene_from_dict",
    "scene_to_dict",
    "write_patch_file",
]
