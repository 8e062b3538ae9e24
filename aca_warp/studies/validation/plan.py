"""The pads and the run of an experiment (stages 1 and 2 of :mod:`aca_warp.studies.validation`): each pad's
scene (the preset, or a changed copy, with seed ``first_seed + k`` for pad k), the predicted linear growth rates,
the plan of the run (its length from the predicted settling, what it records) and the estimated wall time per step.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from aca_warp.studies.validation.base import MM2, Config, Experiment

HF1_PRESSURE = 487.2 / (1758 * 5.0e-8)  # Pa: hf1's clamp force over its nominal patch area (the sweep keeps it)
AREA_SPREAD = (0.4, 1.6)  # sweep areas uniform in [0.4, 1.6] x mean (the paper's 0.02-0.08 and 0.5-2.0 mm²)
HEIGHT_MARGIN = 0.10  # sweep loads 10 % above the all-in-contact load, as the presets (docs/presets.md)


# ------------------------------------------------------------------------------------------------ scenes


def reduced_pad(pad: Any, fraction: float) -> Any:
    """The sector of ``pad`` with ``fraction`` of its angular span (same radii): fewer patches at the same density."""
    return dataclasses.replace(pad, span_deg=pad.span_deg * fraction)


_PATCH_CACHE: dict[str, Any] = {}


def _generate(gen: dict[str, Any], pad: Any) -> Any:
    """``PatchGenerator(**gen).generate(pad)``, cached per process (experiments share layouts)."""
    from aca_warp.scene import PatchGenerator

    key = json.dumps([gen, dataclasses.asdict(pad)], sort_keys=True)
    if key not in _PATCH_CACHE:
        _PATCH_CACHE[key] = PatchGenerator(**gen).generate(pad)
    return _PATCH_CACHE[key]


def spread_for_margin(gen: dict[str, Any], pad: Any, force: float, margin: float, K_N: float) -> tuple[Any, float]:
    """Patches of ``gen`` with the height spread s that puts ``force`` [N] ``margin`` above the all-in-contact load.

    Heights are h_0 + s z_i with z_i independent of s (``PatchGenerator.heights``), so the all-in-contact load
    F_all = s Σ k_N,i (z_i − z_min) is linear in s and s = F / ((1 + margin) Σ k_N,i (z_i − z_min)) (the
    derivation of docs/presets.md). Returns the patches with those heights (what ``PatchGenerator(**gen,
    height_spread=s)`` draws) and s [m].
    """
    from aca_warp.scene import Patches

    c = float(gen.get("height_truncation", 2.0))
    probe = float(gen["height"]) / (2.0 * c)
    p = _generate({**gen, "height_spread": probe}, pad)
    z = (p.height - float(gen["height"])) / probe
    s = force / ((1.0 + margin) * float(np.sum(K_N * np.sqrt(p.area) * (z - z.min()))))
    s = min(s, float(gen["height"]) / c)
    height = np.clip(float(gen["height"]) + s * z, float(gen["height"]) - c * s, float(gen["height"]) + c * s)
    return Patches(
        p.x, p.y, p.area, height, source=p.source.replace(f"height_spread={probe:g}", f"height_spread={s:g}")
    ), s


def experiment_scene(exp: Experiment, k: int, cfg: Config) -> Any:
    """Pad ``k`` of experiment ``exp``: its preset with seed ``first_seed + k``, the changes, the initial state."""
    if exp.builder is not None:
        return exp.builder(exp, k, cfg)
    from aca_warp.scene import Initial, preset

    base = preset(exp.preset)
    seed = cfg.first_seed + k
    gen = dict(base.origin["patches"])
    gen["seed"] = seed
    pad, force, nominal = base.pad, base.normal_force, int(gen["count"])
    if cfg.patches is not None and cfg.patches != nominal:
        pad = reduced_pad(pad, cfg.patches / nominal)
        force *= cfg.patches / nominal
        gen["count"] = cfg.patches
    if exp.mean_area_mm2 is not None:
        mean = exp.mean_area_mm2 * MM2
        gen.update(area_min=AREA_SPREAD[0] * mean, area_max=AREA_SPREAD[1] * mean)
        force = HF1_PRESSURE * gen["count"] * mean
        patches, spread = spread_for_margin(gen, pad, force, HEIGHT_MARGIN, base.material.K_N)
        gen["height_spread"] = spread
    else:
        patches = _generate(gen, pad)
    friction = base.friction if exp.M is None else dataclasses.replace(base.friction, M=exp.M)
    initial = Initial(
        state=exp.initial, perturbation=cfg.perturbation if exp.initial == "equilibrium" else 0.0, seed=seed
    )
    growth, duration = base.growth, base.duration
    if growth is not None:  # the same area path in 1/speedup of the time (docs/validation.md, §3.2)
        speed = exp.growth_speedup or cfg.growth_speedup * exp.growth_clock
        growth = dataclasses.replace(growth, increment=growth.increment * speed)
        duration = base.duration / speed
    origin = dict(base.origin)  # the scene as a table of tables, naming the generator that draws these patches
    origin.update(
        patches=gen,
        load={"normal_force": force},
        pad=dataclasses.asdict(pad),
        friction=dataclasses.asdict(friction),
        initial=dataclasses.asdict(initial),
    )
    if growth is not None:
        origin.update(growth=dataclasses.asdict(growth), run={**origin.get("run", {}), "duration": duration})
    return base.replace(
        name=f"{exp.name}_seed{seed}",
        pad=pad,
        patches=patches,
        normal_force=force,
        friction=friction,
        initial=initial,
        growth=growth,
        duration=duration,
        origin=origin,
    )


# ------------------------------------------------------------------------------------------------ plan


@dataclass(frozen=True)
class Plan:
    """How long an experiment runs and what it records.

    Attributes:
        duration: Simulated time [s].
        settle: Predicted time to saturation of the slowest member [s] (0 for a window run).
        v0: Initial velocity amplitude the growth starts from [m/s].
        v_sat: Saturated velocity amplitude (the disc speed at the mean radius) [m/s].
        sigma_q25: 25th percentile of the predicted σ_i over the slowest member's pads [1/s].
        record: The ``Record`` (global outputs every sample_dt, per-patch velocities over the window).
        window_start: Time of the first per-patch sample [s].
        patch_samples: Per-patch samples per patch.
        steps: Time steps of the run.
        velocity_bytes: Host memory of the float32 per-patch record [bytes].
    """

    duration: float
    settle: float
    v0: float
    v_sat: float
    sigma_q25: float
    record: Any
    window_start: float
    patch_samples: int
    steps: int
    velocity_bytes: int


def predicted_sigma(scenes: list[Any], contacts: list[Any]) -> list[np.ndarray]:
    """σ_i [1/s] of every pad (isolated patch linearised about steady sliding; ``scene_growth_rate``), one
    array per pad, from the host contact solves ``contacts`` (what ``build_model`` loads)."""
    from aca_warp.analysis.saturation import scene_growth_rate

    return [scene_growth_rate(s, c.patch_force) for s, c in zip(scenes, contacts, strict=True)]


def start_amplitude(scenes: list[Any], contacts: list[Any]) -> float:
    """Median velocity amplitude of a patch released from rest, F_N,i |f(ω r_i)| / √(k_T,i m_i) [m/s]."""
    amps = []
    for s, c in zip(scenes, contacts, strict=True):
        a, m = s.patches.area, s.material
        f = np.abs(s.friction.coefficient(s.angular_velocity * s.patches.friction_radius))
        amps.append(c.patch_force * f / np.sqrt(m.K_T * np.sqrt(a) * m.mass_per_area * a))
    return float(np.median(np.concatenate(amps)))


def plan_run(
    exp: Experiment,
    scenes: list[Any],
    contacts: list[Any],
    sigma: list[np.ndarray],
    cfg: Config,
    members: list[str | None] | None = None,
) -> Plan:
    """Run length from the predicted growth (package docstring, stage 2) and the recording of the window.

    The predicted settling time is taken per member (e.g. per LF state, pooled over its seeds) and the run sized
    by the slowest; an experiment without members is one member. A ``"window"`` run has its fixed duration and
    records the patches from ``window_start``; a ``"growth"`` run has its scene's (compressed) duration and
    records the global outputs only (its settle is the predicted first saturation, for the analysis).
    """
    from aca_warp.scene import Record

    members = members or [None] * len(scenes)
    v_sat = float(np.median([s.sliding_speed for s in scenes]))
    slowest = (0.0, float("nan"), float("nan"))  # (settle, v0, σ_25) of the slowest member
    for m in dict.fromkeys(members):
        idx = [i for i, x in enumerate(members) if x == m]
        sc, cs = [scenes[i] for i in idx], [contacts[i] for i in idx]
        rest = {s.initial.state for s in sc} == {"rest"}
        v0 = start_amplitude(sc, cs) if rest else max(s.initial.perturbation for s in sc)
        pos = np.concatenate([sigma[i][sigma[i] > 0] for i in idx])
        q25 = float(np.percentile(pos, 25)) if pos.size else float("nan")
        if not (v0 > 0 and q25 > 0):
            if exp.duration is None and exp.kind == "saturated":
                raise ValueError(f"{exp.name}: no growth to plan for{f' ({m})' if m else ''} (v0 = {v0:g} m/s, "
                                 f"σ_25 = {q25:g} 1/s)")  # fmt: skip
            continue
        settle = cfg.settle_safety * max(math.log(v_sat / v0), 1.0) / q25
        if settle >= slowest[0]:
            slowest = (settle, v0, q25)
    settle, v0, q25 = slowest
    dtp = cfg.sample_dt * cfg.decimation
    if exp.kind == "growth":
        duration = exp.duration if exp.duration is not None else float(scenes[0].duration)
    elif exp.kind == "window":
        if exp.duration is None or exp.window_start is None:
            raise ValueError(f"{exp.name}: a window experiment needs duration and window_start")
        duration = exp.duration
    else:  # at least one window of settling: μ's detector (64 windows over the record) needs both parts
        win = cfg.window * exp.window_scale
        duration = exp.duration if exp.duration is not None else max(settle, win) + win
    n_samples = int(math.ceil(duration / cfg.sample_dt - 1e-9))
    n_dur = n_samples * cfg.sample_dt
    if exp.kind == "growth":
        record, j0, n_win = Record(sample_dt=cfg.sample_dt), n_samples, 0
    else:
        span = duration - exp.window_start if exp.kind == "window" else cfg.window * exp.window_scale
        n_win = min(max(16, int(round(span / dtp))), (n_samples // cfg.decimation) + 1)
        j0 = n_samples - (n_win - 1) * cfg.decimation
        record = Record(
            sample_dt=cfg.sample_dt,
            patches=("velocity",),
            window=(j0 * cfg.sample_dt, n_samples * cfg.sample_dt * (1 + 1e-9)),
            decimation=cfg.decimation,
        )
    return Plan(
        duration=n_dur,
        settle=settle if exp.kind != "window" else 0.0,
        v0=v0,
        v_sat=v_sat,
        sigma_q25=q25,
        record=record,
        window_start=j0 * cfg.sample_dt,
        patch_samples=n_win,
        steps=int(round(n_dur / cfg.dt)),
        velocity_bytes=4 * n_win * sum(sc.patches.count for sc in scenes),
    )


GROWTH_FLOOR_S = {"fp32": 2.7e-6, "fp64": 3.9e-6}
"""Seconds per step of a batch of growing pads that fits one wave on an H100 (on-chip engine, growth in the kernel,
a cluster of 8 blocks per pad): 2.7 µs measured in fp32 for one varying_area pad (an event every 20 steps;
``default_cluster``'s docstring, docs/onchip.md); fp64 estimated as 1.45 × that, the fp64/fp32 ratio of one
non-growing hf1 pad on 8 blocks (2.6 / 1.8 µs, docs/onchip.md)."""


def step_seconds(cfg: Config, total_patches: int, calibration: dict[str, float], growth: bool = False) -> float:
    """Estimated wall seconds per time step of a batch of ``total_patches`` patches (on CUDA: pads × the largest
    pad's patches, since every block's tiles are sized for the largest pad of the batch).

    ``calibration`` (seconds per step per patch, measured by earlier experiments of the same kind — growing or
    not — on this device) when present; otherwise: CPU ≈ 1e7 patch-steps/s (general engine, 2-core AMD EPYC,
    measured with 400–600 patches); CUDA (on-chip engine, H100,
    docs/benchmarks/onchip_h100/cluster_waves_default.md) ≈ max(3.4 µs, n/8e9 s) in fp64 and max(2.7 µs,
    n/1.2e10 s) in fp32 — a batch below about 30 000 patches is latency-bound; growing pads at least
    :data:`GROWTH_FLOOR_S`.
    """
    kind = "growth" if growth else "fixed"
    if f"per_patch_{kind}" in calibration:
        per_step = calibration[f"per_patch_{kind}"] * total_patches
        return per_step if cfg.device == "cpu" else max(per_step, calibration.get(f"floor_{kind}", 0.0))
    if cfg.device == "cpu":
        return total_patches / 1.0e7
    fixed = max(3.4e-6, total_patches / 8.0e9) if cfg.precision == "fp64" else max(2.7e-6, total_patches / 1.2e10)
    return max(fixed, GROWTH_FLOOR_S[cfg.precision]) if growth else fixed
