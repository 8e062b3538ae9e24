"""Start states of the work-precision scenes (:mod:`aca_warp.studies.work_precision`).

``hf1``, ``hf2``, ``stickslip`` (hf1 with the disc at 0.5 m/s at the mean radius) and ``va_start`` (varying_area
at its start, growth off) start from their scenes' own initial states. ``va_late`` (varying_area with its growth
×100 run for 2 ms from rest, then frozen: grown areas, stiffnesses and normal forces) and ``hf1_sat``/``hf3_sat``
(hf1 and hf3 from equilibrium + 0.01 m/s velocity perturbation run to saturation with strang) need a run; that run
is made once and cached as ``OUT/state_<scene>_<patches>.npz`` with how it was made and the saturation detector's
verdict (:func:`start_state`).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.scene import Growth, Initial, PatchGenerator, Record, Scene, preset
from aca_warp.studies.runs import batch_at_start, run_engine

SAMPLE_DT = 1.0e-6  # s, sample interval of the study's records
STICK_SPEED = 0.5  # m/s at the mean radius 0.13 m
SAT_PERTURBATION = 1.0e-2  # m/s, velocity perturbation about equilibrium of the saturated states
SAT_SEED = 1
SPIN_DT = 5.0e-8  # s, strang step of the spin-up runs (0.3 of hf1's friction step 1.65e-7 s)
SPIN = {"hf1_sat": ("hf1", 20.0e-3), "hf3_sat": ("hf3", 40.0e-3)}  # preset, run length [s]
VA_SPEEDUP = 100.0  # varying_area growth ×100: the paper's 0.36 s of growth in 3.6 ms
VA_GROW = 2.0e-3  # s of compressed growth before va_late is frozen (0.2 s of the paper's growth)
VA_DT = 1.0e-8  # s, strang step of the growth run (within varying_area's friction step 1.4e-8 s)
SPIN_SAMPLES = 400  # samples of a spin-up record (the saturation detector needs ≥ 64)


@dataclass
class Start:
    """A scene's start state: the (frozen) scene, u [m] and u̇ [m/s] of shape (patches,), model arrays to assign
    (a grown pad's areas, stiffnesses, normal forces), and how it was made."""

    scene: Scene
    u: np.ndarray
    v: np.ndarray
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)


def sector(scene: Scene, patches: int) -> Scene:
    """``scene`` (a preset) cut to a sector with ``patches`` patches at the same density and load per patch."""
    gen = dict(scene.origin["patches"])
    frac = patches / int(gen["count"])
    gen["count"] = patches
    pad = dataclasses.replace(scene.pad, span_deg=scene.pad.span_deg * frac)
    return scene.replace(pad=pad, patches=PatchGenerator(**gen).generate(pad), normal_force=scene.normal_force * frac)


def make_scene(name: str, patches: int | None = None) -> Scene:
    """The scene of ``name`` before its start state is made (``patches``: a sector of that many patches)."""
    base = {"stickslip": "hf1", "va_start": "varying_area", "va_late": "varying_area"}.get(name, name)
    base = SPIN[name][0] if name in SPIN else base
    s = preset(base)
    if patches is not None and patches != s.patches.count:
        s = sector(s, patches)
    s = s.replace(name=name, record=Record(sample_dt=SAMPLE_DT))
    if name == "stickslip":
        return s.replace(angular_velocity=STICK_SPEED / s.pad.mean_radius)
    if name == "va_start":
        return s.replace(growth=None)
    if name == "va_late":
        g = s.growth or Growth()
        return s.replace(growth=Growth(increment=g.increment * VA_SPEEDUP, interval=g.interval))
    if name in SPIN:
        return s.replace(initial=Initial(state="equilibrium", perturbation=SAT_PERTURBATION, seed=SAT_SEED))
    return s


def _verdict(res: Any) -> Any:
    """The saturation detector's result on Σ|u̇| of a finished run's record (``SPIN_SAMPLES`` samples)."""
    from aca_warp.analysis.saturation import saturation

    c = res.collect()
    return saturation(c.time, c.globals[:, 0, 4].astype(np.float64), statistic="mean")


def _saturate(scene: Scene, duration: float, device: str) -> Start:
    """Run ``scene`` for ``duration`` [s] with strang at SPIN_DT (at most half its friction step, h γ_max = 2); the
    state at the end and the saturation detector's verdict on Σ|u̇|."""
    from aca_warp.hf.solver import friction_step, stable_step

    model, state = batch_at_start([scene], device, "fp64")
    dt = min(SPIN_DT, 0.5 * friction_step(stable_step(model)))
    rec = Record(sample_dt=duration / SPIN_SAMPLES)
    res = run_engine(model, state, engine="auto", duration=duration, integrator="strang", dt=dt, record=rec)
    if not res.complete:
        raise RuntimeError(f"spin-up of {scene.name} stopped: {res.fault}")
    sat = _verdict(res)
    u, v = state.numpy()
    info = {
        "how": f"{scene.initial.state} + N(0, ({scene.initial.perturbation:g} m/s)²) velocities (seed "
        f"{scene.initial.seed}), strang fp64 at {dt:.3g} s for {duration * 1e3:g} ms",
        "wall_s": res.wall_time,
        "saturated_from_s": sat.t_s,
        "verdict": sat.verdict,
    }
    return Start(scene.replace(initial=Initial()), u.astype(np.float64), v.astype(np.float64), {}, info)


def _grow(scene: Scene, duration: float, device: str) -> Start:
    """Run the growing ``scene`` for ``duration`` [s] with strang at VA_DT; the grown pad, frozen, and its state."""
    from aca_warp.hf.solver import GROWTH_MUTABLE

    model, state = batch_at_start([scene], device, "fp64")
    before = model.host("area").astype(np.float64)
    rec = Record(sample_dt=duration / SPIN_SAMPLES)
    res = run_engine(model, state, engine="general", duration=duration, integrator="strang", dt=VA_DT, record=rec)
    if not res.complete:
        raise RuntimeError(f"growth run of {scene.name} stopped: {res.fault}")
    sat = _verdict(res)
    # the grown arrays; the matrix gap only feeds the contact re-solve of growth events
    arrays = {k: model.host(k).astype(np.float64) for k in GROWTH_MUTABLE if k != "pad_gap"}
    u, v = state.numpy()
    share = float(arrays["normal_force"].sum() / scene.normal_force)
    info = {
        "how": f"from rest, growth ×{VA_SPEEDUP:g} (increment {scene.growth.increment:g} m), strang fp64 at "
        f"{VA_DT:g} s for {duration * 1e3:g} ms, then frozen",
        "wall_s": res.wall_time,
        "mean_area_growth": float(arrays["area"].mean() / before.mean()),
        "patch_share": share,
        "saturated_from_s": sat.t_s,
        "verdict": sat.verdict,
    }
    return Start(
        scene.replace(growth=None, initial=Initial()), u.astype(np.float64), v.astype(np.float64), arrays, info
    )


def start_state(name: str, args: argparse.Namespace, log: Any = print) -> Start:
    """The start state of scene ``name``; made by a run once and then read from ``OUT/state_<name>.npz`` (the
    file is remade when its settings differ from these)."""
    scene = make_scene(name, args.patches)
    if name not in SPIN and name != "va_late":
        model, state = batch_at_start([scene], args.device, "fp64")
        u, v = state.numpy()
        return Start(scene, u.astype(np.float64), v.astype(np.float64), {}, {"how": f"{scene.initial.state}"})
    duration = SPIN[name][1] if name in SPIN else VA_GROW
    key = {"scene": name, "patches": scene.patches.count, "duration": duration, "spin_dt": SPIN_DT, "va_dt": VA_DT}
    key |= {"perturbation": SAT_PERTURBATION, "seed": SAT_SEED, "speedup": VA_SPEEDUP}
    path = Path(args.out) / f"state_{name}_{scene.patches.count}.npz"
    if path.exists():
        d = np.load(path, allow_pickle=False)
        meta = json.loads(str(d["meta"]))
        if meta["key"] == key:
            log(f"[{name}] start state from {path}")
            arrays = {k[6:]: d[k] for k in d.files if k.startswith("model_")}
            frozen = scene.replace(growth=None, initial=Initial())
            return Start(frozen, d["u"], d["v"], arrays, {**meta["info"], "cached": str(path)})
    log(f"[{name}] making the start state ({duration * 1e3:g} ms on {args.device})")
    start = _saturate(scene, duration, args.device) if name in SPIN else _grow(scene, duration, args.device)
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays = {f"model_{k}": a for k, a in start.arrays.items()}
    np.savez_compressed(path, u=start.u, v=start.v, meta=json.dumps({"key": key, "info": start.info}), **arrays)
    log(f"[{name}] {start.info['verdict']}")
    return start
