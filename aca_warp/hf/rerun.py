"""Repeat a run from its run file: ``aca-warp rerun RUN.h5 -o NEW.h5`` (and the settings ``--resume`` reads).

LF run files (``kind = "lf"``) are repeated by :func:`aca_warp.lf.commands.rerun_lf` (stored scene JSON, initial
patches, duration, device).

A run file holds everything a run depends on (docs/run_files.md): the scene as JSON (every constant, the
record settings, the duration), the patch arrays in ``/patches`` and the matrix cells in ``/matrix`` (so the
original patch file is not needed), the run options (integrator, step, tolerances, engine), the precision, the
device and the package versions. :func:`read_settings` rebuilds the scene from them; the rerun uses the same code
path as ``aca-warp hf`` and, on the same device and precision, gives the same bits.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from aca_warp.common.bounds import json_attribute
from aca_warp.common.errors import SceneError, option
from aca_warp.hf.options import DEFAULT_DT, STEP_CONTROLLED, WATCHDOG_FACTOR, RunOptions
from aca_warp.scene import Friction, Growth, Initial, Material, Matrix, Pad, Patches, Record, Scene


@dataclass
class RunSettings:
    """What a run file says about how it was made.

    Attributes:
        scene: The scene, rebuilt from the stored JSON, ``/patches`` and ``/matrix``.
        options: The run options (duration and engine resolved).
        precision: ``fp32`` or ``fp64``.
        device: Warp device alias the run used.
        versions: Package versions of the run (JSON dict).
        complete: Whether the run completed.
    """

    scene: Scene
    options: RunOptions
    precision: str
    device: str
    versions: dict[str, str]
    complete: bool

    def device_for(self, asked: str | None, path: str | Path) -> str:
        """The device a repeat of the run ``path`` takes: ``asked``, else the run's; a run with fast math repeats on
        CUDA only (SceneError in one line: its option came from the file, not from the command)."""
        device = asked or self.device
        if self.options.fast_math and device.startswith("cpu"):
            flag = option("device='cuda:0'", "--device cuda:N")
            raise SceneError(f"{path} ran with CUDA fast math, which runs on CUDA devices only: give {flag}")
        return device


def _json(attrs: Any, key: str, path: Path) -> Any:
    """The JSON root attribute ``key`` (:func:`~aca_warp.common.bounds.json_attribute`: text, bounded nesting)."""
    if key not in attrs:
        raise SceneError(f"{path} lacks the attribute {key!r}: not an aca-warp run file, or one too old to rerun")
    return json_attribute(attrs[key], f"{path}: attribute {key!r}")


def scene_from_run(f: h5py.File, path: Path) -> Scene:
    """The scene of an open run file (stored JSON, patches from ``/patches``, matrix from ``/matrix``)."""
    doc = _json(f.attrs, "scene", path)
    if not isinstance(doc, dict):
        raise SceneError(f"{path}: attribute 'scene' is not a JSON object (a crafted or damaged file)")
    try:
        patches = Patches(
            *(np.asarray(f["patches"][k][()], dtype=np.float64) for k in ("x", "y", "area", "height")),
            source=f"{path}:/patches",
        )
        matrix = (
            Matrix(*(np.asarray(f["matrix"][k][()], dtype=np.float64) for k in ("area", "radius", "height")))
            if "matrix" in f
            else None
        )
        rec = doc["record"]
        window = tuple(rec["window"])
        return Scene(
            name=str(doc["scene"]["name"]),
            pad=Pad(**doc["pad"]),
            patches=patches,
            material=Material(**doc["material"]),
            friction=Friction(**doc["friction"]),
            normal_force=doc["load"]["normal_force"],
            angular_velocity=doc["disc"]["angular_velocity"],
            initial=Initial(**doc["initial"]),
            record=Record(
                sample_dt=rec["sample_dt"],
                patches=tuple(rec["patches"]),
                window=(window[0], math.inf if window[1] >= 1e300 else window[1]),
                decimation=rec["decimation"],
            ),
            duration=doc["run"]["duration"],
            growth=Growth(**doc["growth"]) if "growth" in doc else None,
            matrix=matrix,
            origin={"patches": doc["patches"]},
            allow_implausible=doc["scene"].get("allow_implausible", False) is True,
        )
    except SceneError as e:
        raise SceneError(f"{path}: the stored scene is invalid: {e}") from None
    except (KeyError, TypeError, ValueError, AttributeError, OSError) as e:
        raise SceneError(f"{path}: the stored scene is incomplete or damaged ({type(e).__name__}: {e})") from None


def _options(f: h5py.File, path: Path, scene: Scene) -> RunOptions:
    """The stored run options (files written before ``run_options`` existed keep them as ``step_policy``). A
    fixed-step run without a stored step (files and sweep shards written while every fixed-step default was
    :data:`DEFAULT_DT`; since, the step is stored) is repeated at the step it took (the ``dt`` its file recorded when
    it closed), or, for a file stopped before, at :data:`DEFAULT_DT`: not at today's default. Likewise a growing
    ``scene``'s run without a stored spacing of growth events (files written while the events came at the scene's
    interval by default; since, the spacing is stored) is repeated at that interval, written out; and a run without
    a stored crossing treatment (files written before there was a choice) with the point treatment, the only one
    then."""
    if "run_options" in f.attrs:
        options = RunOptions.from_dict(_json(f.attrs, "run_options", path))
    else:
        policy = _json(f.attrs, "step_policy", path)
        keys = ("duration", "integrator", "dt", "tolerance", "force", "engine", "checkpoint_interval")
        options = RunOptions.from_dict({k: policy[k] for k in keys if k in policy})
    if options.dt is None and options.integrator not in STEP_CONTROLLED:
        taken = f.attrs.get("dt")  # the step the run took (written when it closed), else the default of its time
        options = dataclasses.replace(options, dt=float(taken) if taken is not None else DEFAULT_DT)
    if options.growth_dt is None and scene.growth is not None:
        options = dataclasses.replace(options, growth_dt=scene.growth.interval)
    if options.crossing is None:
        options = dataclasses.replace(options, crossing="point")
    return options


def relaxed_checks(s: RunSettings) -> list[str]:
    """The stored options of a run that relax a check, in words (``rerun`` names each one it applies)."""
    o = s.options
    out = []
    if o.force:
        out.append("force (a step beyond the stable-step estimate runs, with a warning)")
    if o.watchdog_factor is None:
        out.append("the watchdog off (only non-finite values stop the run)")
    elif o.watchdog_factor != WATCHDOG_FACTOR:
        out.append(f"a watchdog bound of {o.watchdog_factor:g} x the velocity scale (default {WATCHDOG_FACTOR:g})")
    if o.accept_unphysical:
        out.append("accept_unphysical (the physical sanity checks warn instead of stopping the run)")
    if s.scene.allow_implausible:
        out.append("allow_implausible (values far outside a brake pad's range are accepted)")
    return out


def read_settings(path: str | Path) -> RunSettings:
    """Read the settings of the run file ``path`` (SceneError with one line when it cannot be rerun)."""
    from aca_warp.common.files import open_h5, reading

    p = Path(path)
    with reading(p, "run file"), open_h5(p, "run file") as f:
        scene = scene_from_run(f, p)
        versions = _json(f.attrs, "versions", p) if "versions" in f.attrs else {}
        try:
            return RunSettings(
                scene=scene,
                options=_options(f, p, scene),
                precision=str(f.attrs["precision"]),
                device=str(f.attrs["device"]),
                versions=versions if isinstance(versions, dict) else {},
                complete=bool(f.attrs.get("complete", False)),
            )
        except (KeyError, TypeError, ValueError, AttributeError) as e:
            raise SceneError(f"{p}: the stored run options are incomplete ({type(e).__name__}: {e})") from None
