"""The study's scenes: the presets with its recording (and fewer patches, load scaled), the area sweep's scenes
(hf1 with other patch areas, M, speed and load) and the facts of a scene that ``study.json`` records."""

from __future__ import annotations

import argparse
import dataclasses
from typing import Any

from aca_warp.studies.hf_study.base import MM2, NOMINAL_PATCHES, SPREAD, isolated_frequency


def record_for(args: argparse.Namespace) -> Any:
    """The study's recording: global outputs every --sample-dt, per-patch velocities from --transient."""
    from aca_warp.scene import Record

    return Record(
        sample_dt=args.sample_dt,
        patches=("velocity",),
        window=(args.transient, args.duration),
        decimation=args.decimation,
    )


def _with_patches(scene: Any, gen: dict[str, Any], normal_force: float, **changes: Any) -> Any:
    """``scene`` with generated patches; the matrix is rebuilt (``matrix=None``) and ``origin`` updated so the
    run file's scene JSON names the new generator (``Scene.replace`` keeps both otherwise)."""
    from aca_warp.scene import PatchGenerator

    patches = PatchGenerator(**gen).generate(scene.pad)
    origin = dict(scene.origin or {})
    origin["patches"] = dict(gen)
    origin["load"] = {"normal_force": normal_force}
    return scene.replace(patches=patches, normal_force=normal_force, matrix=None, origin=origin, **changes)


def preset_scene(name: str, args: argparse.Namespace) -> Any:
    """Preset ``name`` with the study's recording (and ``--patches`` patches, load scaled to keep the pressure)."""
    from aca_warp.scene import preset

    scene = preset(name)
    if args.patches is not None and args.patches != scene.patches.count:
        gen = dict(scene.origin["patches"])
        force = scene.normal_force * args.patches / gen["count"]
        gen["count"] = args.patches
        scene = _with_patches(scene, gen, force)
    return scene.replace(record=record_for(args), duration=args.duration)


def sweep_scene(mean_mm2: float, args: argparse.Namespace) -> Any:
    """hf1 with patch areas uniform in SPREAD x mean, load = pressure x N x mean, M and speed of the sweep."""
    from aca_warp.scene import preset

    base = preset("hf1")
    n = args.patches or NOMINAL_PATCHES
    mean = mean_mm2 * MM2
    gen = {
        "count": n,
        "area_min": SPREAD[0] * mean,
        "area_max": SPREAD[1] * mean,
        "height": float(base.origin["patches"].get("height", 3.0e-6)),
        "seed": args.seed,
    }
    force = args.sweep_pressure * n * mean
    return _with_patches(
        base,
        gen,
        force,
        name=f"sweep_{mean_mm2:g}mm2",
        friction=dataclasses.replace(base.friction, M=args.sweep_M),
        angular_velocity=args.sweep_speed / base.pad.mean_radius,
        record=record_for(args),
        duration=args.duration,
    )


def scene_info(scene: Any) -> dict[str, Any]:
    """Patch count and areas, load, mean patch pressure, M, speed and isolated-patch frequency of ``scene``."""
    a = scene.patches.area
    return {
        "patches": int(scene.patches.count),
        "area_min_m2": float(a.min()),
        "area_max_m2": float(a.max()),
        "mean_area_m2": float(a.mean()),
        "normal_force_N": float(scene.normal_force),
        "mean_patch_pressure_Pa": float(scene.normal_force / a.sum()),
        "M": float(scene.friction.M),
        "sliding_speed_m_s": float(scene.sliding_speed),
        "isolated_patch_hz_at_mean_area": isolated_frequency(float(a.mean()), scene.material),
    }
