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
        speed = growth_speed(exp, cfg, base.duration)
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


def growth_speed(exp: Experiment, cfg: Config, duration: float) -> float:
    """Compression of a growing scene of ``duration`` [s] (the preset's 0.36 s): the experiment's own speedup or the
    configured one, at least ``duration / cfg.paper_length`` (1 in the full variant; the quick variant's paper
    length is shorter)."""
    own = exp.growth_speedup if exp.growth_speedup is not None else cfg.growth_speedup
    return max(own, duration / cfg.paper_length)


# ------------------------------------------------------------------------------------------------ plan


@dataclass(frozen=True)
class Plan:
    """How long an experiment runs and what it records.

    The run is stepped in **segments** (``run_engine`` calls on the same model and state, one after the other): the
    per-patch velocities are recorded only in the segments that hold a window of them, so the host receives no
    per-patch samples between the windows.

    Attributes:
        duration: Simulated time [s].
        settle: Predicted time to saturation of the slowest member [s] (0 for a window run).
        v0: Initial velocity amplitude the growth starts from [m/s].
        v_sat: Saturated velocity amplitude (the disc speed at the mean radius) [m/s].
        sigma_q25: 25th percentile of the predicted σ_i over the slowest member's pads [1/s].
        window_start: Time of the first per-patch sample of the final window [s] (the run's end when none).
        patch_samples: Per-patch samples per patch of the final window.
        segments: (start, end, per-patch record) [s] of the run's segments, in order, covering [0, duration].
        tracks: (start, end) [s] of the per-patch windows over the run (``Experiment.tracks``), before the final one.
        velocity_bytes: Host memory of the float32 per-patch record of all windows [bytes].
    """

    duration: float
    settle: float
    v0: float
    v_sat: float
    sigma_q25: float
    window_start: float
    patch_samples: int
    segments: tuple[tuple[float, float, bool], ...]
    tracks: tuple[tuple[float, float], ...]
    velocity_bytes: int

    def record(self, cfg: Config) -> Any:
        """The ``Record`` of the run stepped in one go instead of in segments: the global outputs every
        ``cfg.sample_dt``, the per-patch velocities every ``cfg.decimation`` samples from the final window's start
        (none for a growing run)."""
        from aca_warp.scene import Record

        if self.patch_samples == 0:
            return Record(sample_dt=cfg.sample_dt)
        end = self.duration * (1 + 1e-9)
        return Record(sample_dt=cfg.sample_dt, patches=("velocity",), window=(self.window_start, end),
                      decimation=cfg.decimation)  # fmt: skip

    def steps(self, dt: float, sample_dt: float) -> int:
        """Time steps of the run at the step ``dt`` [s] as the run fits it to the sample interval [s]."""
        from aca_warp.hf.solver import fitted_step

        return int(round(self.duration / fitted_step(dt, sample_dt)))


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


def predicted_settle(
    exp: Experiment, scenes: list[Any], contacts: list[Any], sigma: list[np.ndarray], cfg: Config,
    members: list[str | None],
) -> tuple[float, float, float, float]:  # fmt: skip
    """(settle [s], v0 [m/s], v_sat [m/s], σ_25 [1/s]) of the slowest member (package docstring, stage 2)."""
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
            if exp.duration is None and exp.kind == "saturated" and not exp.tracks:
                raise ValueError(f"{exp.name}: no growth to plan for{f' ({m})' if m else ''} (v0 = {v0:g} m/s, "
                                 f"σ_25 = {q25:g} 1/s)")  # fmt: skip
            continue
        settle = cfg.settle_safety * max(math.log(v_sat / v0), 1.0) / q25
        if settle >= slowest[0]:
            slowest = (settle, v0, q25)
    return slowest[0], slowest[1], v_sat, slowest[2]


def natural_duration(exp: Experiment, scenes: list[Any], settle: float, cfg: Config) -> float:
    """The run length an experiment asks for on its own [s]: the growing scene's (compressed) duration, the fixed
    duration, the paper's length for a tracked run, or max(settle, window) + window (at least one window of
    settling: μ's detector, 64 windows over the record, needs both parts)."""
    if exp.kind == "growth":
        return exp.duration if exp.duration is not None else float(scenes[0].duration)
    if exp.duration is not None:
        return exp.duration
    if exp.tracks:
        return cfg.paper_length
    win = cfg.window * exp.window_scale
    return max(settle, win) + win


def track_windows(duration: float, final_start: float, cfg: Config) -> tuple[tuple[float, float], ...]:
    """``cfg.track_windows`` per-patch windows of ``cfg.track_window`` [s] before the final window, their starts
    spaced geometrically from 2 windows' length to the final window's start (early windows resolve the release from
    rest, later ones the approach to the paper's length), on the per-patch grid."""
    dtp = cfg.sample_dt * cfg.decimation
    n, w = cfg.track_windows, cfg.track_window
    last = final_start - w
    first = 2.0 * w
    if n < 1 or last <= first:
        return ()
    starts = np.geomspace(first, last, n) if n > 1 else np.array([last])
    starts = np.round(starts / dtp) * dtp
    return tuple((float(a), float(a + w)) for a in starts)


def plan_run(
    exp: Experiment,
    scenes: list[Any],
    contacts: list[Any],
    sigma: list[np.ndarray],
    cfg: Config,
    members: list[str | None] | None = None,
    duration: float | None = None,
) -> Plan:
    """Run length from the predicted growth (package docstring, stage 2), the per-patch windows and the segments.

    The predicted settling time is taken per member (e.g. per LF state, pooled over its seeds) and the run sized
    by the slowest; an experiment without members is one member. ``duration`` [s] replaces the experiment's own
    length (a batch runs as long as its longest member). A ``"window"`` run records the patches from
    ``window_start``; a ``"growth"`` run records the global outputs only (its settle is the predicted first
    saturation, for the analysis); a ``"saturated"`` run records the patches over the last window and, with
    ``tracks``, over the track windows.
    """
    members = members or [None] * len(scenes)
    settle, v0, v_sat, q25 = predicted_settle(exp, scenes, contacts, sigma, cfg, members)
    dtp = cfg.sample_dt * cfg.decimation
    if duration is None:
        duration = natural_duration(exp, scenes, settle, cfg)
    n_samples = int(math.ceil(duration / cfg.sample_dt - 1e-9))
    n_dur = n_samples * cfg.sample_dt
    tracks: tuple[tuple[float, float], ...] = ()
    if exp.kind == "growth":
        n_win, j0 = 0, n_samples
        windows: list[tuple[float, float]] = []
    else:
        span = n_dur - exp.window_start if exp.kind == "window" else cfg.window * exp.window_scale
        n_win = min(max(16, int(round(span / dtp))), (n_samples // cfg.decimation) + 1)
        j0 = n_samples - (n_win - 1) * cfg.decimation
        if exp.tracks:
            tracks = track_windows(n_dur, j0 * cfg.sample_dt, cfg)
        windows = [*tracks, (j0 * cfg.sample_dt, n_dur)]
    # segment bounds on whole samples (a segment is at least one sample long), windows that would overlap the one
    # before start where it ends: the run's clock and the sink's offsets stay the same
    segments, t = [], 0
    for a, b in windows:
        ia, ib = max(int(round(a / cfg.sample_dt)), t), int(round(b / cfg.sample_dt))
        if ib <= ia:
            continue
        if ia > t:
            segments.append((t * cfg.sample_dt, ia * cfg.sample_dt, False))
        segments.append((ia * cfg.sample_dt, ib * cfg.sample_dt, True))
        t = ib
    if t < n_samples:
        segments.append((t * cfg.sample_dt, n_dur, False))
    samples = sum(int(round((b - a) / dtp)) + 1 for a, b in windows)
    return Plan(
        duration=n_dur,
        settle=settle if exp.kind != "window" else 0.0,
        v0=v0,
        v_sat=v_sat,
        sigma_q25=q25,
        window_start=j0 * cfg.sample_dt,
        patch_samples=n_win,
        segments=tuple(segments),
        tracks=tracks,
        velocity_bytes=4 * samples * sum(sc.patches.count for sc in scenes),
    )
