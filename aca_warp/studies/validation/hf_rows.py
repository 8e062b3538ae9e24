"""Validation against the paper's statements from seed ensembles of saturated runs: the runner, the §3.1 rows and the
page (§3.2 in :mod:`~aca_warp.studies.validation_area`, §3.3 and §4 in :mod:`~aca_warp.studies.validation_multiscale`,
the candidate causes of open verdicts in :mod:`~aca_warp.studies.validation_causes`; settings, registries and
verdicts in :mod:`~aca_warp.studies.validation_base`).

The paper's findings (§3) describe the saturated state of the friction instability; a single run stopped in its
linear growth says nothing about them. Every number here comes from an **experiment**: one batch of N pads that
differ in their seed (patch layout, areas and heights, ``[patches] seed``; initial perturbation, ``[initial]
seed``), run with the one run loop (engine ``auto``: on-chip on CUDA, general on the CPU) until every pad has
saturated, then analysed over the saturated part only. A **row** compares one statement of the paper with an
ensemble measure: the mean over seeds with its 95 % Student-t interval (``ensemble_interval``), the paper's value
and a verdict whose criterion is fixed in advance (:data:`CRITERIA`).

Stages of an experiment (:func:`run_experiment`):

1. **Scenes**: the preset (or a changed copy: another M, another mean patch area, another initial state) with
   seed ``first_seed + k`` for pad k; ``--patches`` fewer patches on a sector of the pad of the same patch
   density and pressure (``reduced_pad``).
2. **Plan** (:func:`plan_run`): the predicted linear growth rate σ_i of every patch (``predicted_growth_rate``);
   the run lasts ``settle_safety · ln(v_sat / v_0) / σ_25`` (e-folds from the initial velocity amplitude v_0 to
   the disc speed v_sat, at the 25th percentile of σ_i, because Σ|u̇| settles only when most patches have
   saturated) plus the measurement window. Global outputs every ``sample_dt`` over the whole run, per-patch
   velocities every ``decimation`` samples over the window only.
3. **Run** through :func:`aca_warp.studies.runs.run_engine`, samples collected by a sink (per-patch velocities
   as float32).
4. **Saturation** per pad (``saturation``) on Σ|u̇| (envelope: window mean) and on μ (window standard deviation
   over 64 windows of the record); a pad counts only when Σ|u̇| has a growth phase and a saturated part that
   starts at least half a window before the end. The analysis segment of the experiment starts at the latest
   saturated start of its pads (and no earlier than the window), so that every pad gives spectra on one grid.
5. **Measures** per pad (:func:`pad_measures`): spectra of the global outputs and of the patch velocities, the
   first velocity-spectrum peak, the Fig. 8 shape measures, S(f) under the ``relative`` and the ``snr`` rule with
   the random-phase null level, S at equal Φ, the spatial correlation of the directions of motion (Figs. 4/6) and
   of the spectral phases at the first peak, the STFT maximum of μ over windows of 2^12 … 2^17 samples.
6. **Checkpoint**: ``<out>/<experiment>/result.json`` and ``arrays.npz`` as soon as the experiment is done; a
   rerun with the same settings reuses them.

Experiments of other kinds follow the same stages: ``"window"`` (a fixed run analysed over its per-patch window
whether saturated or not: the linear phase of the single-run studies) and ``"growth"`` (the varying-area runs,
analysed from the global outputs after the first saturation, :mod:`~aca_warp.studies.validation_area`); an
experiment with members (the LF states of §3.3) has one pad per member and seed, its run sized by the slowest
member. Rows (:data:`ROWS`) read only the saved results, so the table can be rebuilt from checkpoints, and a row
that fails is marked, not fatal. New experiments and rows plug in with :func:`register_experiment` and
:func:`register_row`.

Examples::

    python3 scripts/validation.py --device cuda:0 --seeds 8 --out DIR --page docs/validation.md   # GPU, full size
    python3 scripts/validation.py --quick --out DIR --page docs/validation.md                    # CPU smoke check
    python3 scripts/validation.py --device cuda:0 --out DIR --only hf1 hf3 --max-wall 300
    python3 scripts/validation.py --device cuda:0 --seeds 8 --workers 8 --dry-run         # the cost, runs nothing
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as _dt
import json
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.studies import validation_area, validation_causes, validation_multiscale
from aca_warp.studies.report import Log, clean, command_line, fmt, generated_markers, md_table, replace_generated
from aca_warp.studies.validation_base import (  # noqa: F401 (re-exported: the validation API in one module)
    CRITERIA,
    EXPERIMENTS,
    FULL,
    MM2,
    QUICK,
    ROWS,
    USABLE,
    Config,
    Experiment,
    Row,
    RowValue,
    _all_of,
    _get,
    _need,
    by_seed,
    ci,
    close_pools,
    direction_verdict,
    equal_phi,
    equal_verdict,
    evaluate_rows,
    interval,
    map_pads,
    pad_member,
    paired,
    register_experiment,
    register_row,
    side,
    tables,
    threshold_verdict,
    usable,
    value_verdict,
    values,
)

HF1_PRESSURE = 487.2 / (1758 * 5.0e-8)  # Pa: hf1's clamp force over its nominal patch area (the sweep keeps it)
AREA_SPREAD = (0.4, 1.6)  # sweep areas uniform in [0.4, 1.6] x mean (the paper's 0.02-0.08 and 0.5-2.0 mm²)
HEIGHT_MARGIN = 0.10  # sweep loads 10 % above the all-in-contact load, as the presets (docs/presets.md)
MARKER = "scripts/validation.py"  # the generated section's marker on the page

PAPER = {
    "first_peak_hz": {"hf1": 73.0e3, "hf2": 32.8e3, "hf3": 73.0e3, "hf4": 32.8e3},
    "exponent": -0.25,
    "source": "Merlis & Ostermeyer 2019",
}

SWEEP_AREAS_MM2 = (0.125, 0.3, 0.6)  # between hf1 (0.05) and hf2 (1.25): five mean areas with the presets

for _exp in (
    Experiment("hf1", "§3.1", "HF1: 0.02–0.08 mm², M = 0.8, 487.2 N", "hf1"),
    Experiment("hf2", "§3.1", "HF2: 0.5–2 mm², M = 0.8, 12.37 kN", "hf2"),
    Experiment("hf3", "§3.1", "HF3: 0.02–0.08 mm², M = 0.4, 487.2 N", "hf3"),
    Experiment("hf4", "§3.1", "HF4: 0.5–2 mm², M = 0.4, 12.37 kN", "hf4"),
    Experiment("hf1_rest", "§3.1", "HF1 started from rest (initial-state comparison)", "hf1", initial="rest"),
    *(
        Experiment(
            f"sweep_{a:g}".replace(".", "p"),
            "§3.1",
            f"area sweep: mean {a:g} mm² (uniform 0.4–1.6 × mean), hf1 pressure, M = 0.8",
            "hf1",
            mean_area_mm2=a,
        )
        for a in SWEEP_AREAS_MM2
    ),
):
    register_experiment(_exp)
SWEEP = ("hf1", *(f"sweep_{a:g}".replace(".", "p") for a in SWEEP_AREAS_MM2), "hf2")


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
    """Run length from the predicted growth (module docstring, stage 2) and the recording of the window.

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


# ------------------------------------------------------------------------------------------------ saturation


def pad_saturation(time: np.ndarray, glob: np.ndarray, window_end: float, window: float) -> dict[str, Any]:
    """Saturation of one pad (``record_saturation``: Σ|u̇| by window means, μ by standard deviations over N/64
    windows) as plain figures. ``status``: "saturated" (Σ|u̇| grows, then settles early enough: the analysed part
    starts at least half a window before ``window_end``), "not saturated", "no growth phase" (settled without
    growing: not the instability's saturated state) or "saturated too late".
    """
    from aca_warp.analysis.saturation import record_saturation

    out = record_saturation(time, glob[:, 0], glob[:, 4]).figures()
    if out["status"] == "saturated" and out["t_start"] > window_end - 0.5 * window:
        out["status"] = "saturated too late"
    return out


# ------------------------------------------------------------------------------------------------ measures


FIRST_PEAK_FRACTION = 0.1  # the first peak: the lowest peak of the mean per-patch spectrum reaching 1/10 of its maximum


def global_spectra(seg: np.ndarray, sample_dt: float) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Hann amplitude spectra of one pad's global outputs over a segment (N, 5), all dimensionless.

    μ, torque, friction radius and Σ|u̇| divided by their mean (paper Fig. 8); the "velocity" spectrum is Σu̇ (the
    patches' velocities in the pad frame) divided by the mean of Σ|u̇|, since Σu̇ itself has zero mean.
    """
    from aca_warp.analysis.spectra import amplitude_spectrum

    freq, amp = amplitude_spectrum(seg[:, [0, 1, 2, 4]], sample_dt, normalise="mean", axis=0)
    _, v = amplitude_spectrum(seg[:, 3], sample_dt, normalise=None)
    out = {"mu": amp[:, 0], "torque": amp[:, 1], "friction_radius": amp[:, 2], "abs_velocity": amp[:, 3]}
    out["velocity"] = v / abs(float(np.mean(seg[:, 4])))
    return freq, out


_NULL_TABLES: dict[int, np.ndarray] = {}


def null_table(n_max: int) -> np.ndarray:
    """S_null for Φ = 0 … n_max (``sync_null_level`` with its defaults, so equal to what ``sync_index`` stores)."""
    from aca_warp.analysis.sync import sync_null_level

    if n_max not in _NULL_TABLES:
        _NULL_TABLES[n_max] = sync_null_level(np.arange(n_max + 1))
    return _NULL_TABLES[n_max]


def sync_measures(
    freq: np.ndarray, X: np.ndarray, f1: float, mu_amp: np.ndarray, rule: str, coherence: np.ndarray | None = None
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """S(f) of one pad's per-patch spectra X (F, n) under ``rule``, with S_null, and its summaries (scalars, arrays).

    Summaries: the equal-Φ tables over the whole band and above f1 (octave classes of Φ, ``sync_by_prevalence``),
    the median S − S_null over bins with Φ ≥ 10, the share of defined bins with S > S_null, the *spread* (share of
    the bins in [f1/8, 2 f1] with S − S_null > 0.05) and *prevalence* (mean Φ over the bins of that band with S
    defined), S and Φ at f1, and the agreement with the μ spectrum (``spectral_agreement``, 20–80 kHz); for §3.3:
    ``top_excess`` (mean of the top 1 % of S − S_null over the defined bins: "individual high-valued S"),
    ``phi_sync`` and ``phi_sync_share`` (mean Φ, and Φ over the patches, of the bins with S − S_null > 0.05) and,
    with the neighbours' phase coherence C(f) (``neighbour_coherence``), ``cluster_phi_rho``: Spearman ρ of C
    against Φ over the bins with Φ ≥ 2.
    """
    from aca_warp.analysis.measures import prevalence_classes, spectral_agreement, sync_by_prevalence
    from aca_warp.analysis.sync import sync_index

    res = sync_index(X, freq=freq, rule=rule, null_trials=0)
    S, phi = res.S, res.Phi
    null = null_table(X.shape[1])[phi]
    edges = prevalence_classes(X.shape[1])
    table = sync_by_prevalence(S, null, phi, edges=edges)
    high = freq > f1
    table_high = sync_by_prevalence(S[high], null[high], phi[high], edges=edges)
    ok = np.isfinite(S) & np.isfinite(null)
    rel = ok & (freq >= f1 / 8) & (freq <= 2 * f1)
    i1 = int(np.argmin(np.abs(freq - f1)))
    prevalent = ok & (phi >= 10)
    band = (20e3, 80e3)
    in_band = (freq >= band[0]) & (freq <= band[1])
    scalars = {
        "table": _table_dict(table),
        "table_high": _table_dict(table_high),
        "median_excess_phi10": float(np.median(S[prevalent] - null[prevalent])) if prevalent.any() else None,
        "fraction_above_null": float(np.mean(S[ok] > null[ok])) if ok.any() else None,
        "spread": float(np.mean(S[rel] - null[rel] > 0.05)) if rel.any() else None,
        "prevalence": float(np.mean(phi[rel])) if rel.any() else None,
        "S_at_f1": float(S[i1]),
        "Phi_at_f1": int(phi[i1]),
        "agreement": spectral_agreement(freq, S, phi, mu_amp, band=band) if in_band.sum() > 2 else None,
        "params": res.params,
    }
    scalars.update(local_sync_measures(S, null, phi, X.shape[1], coherence))
    return scalars, {"S": S.astype(np.float32), "Phi": phi.astype(np.int32), "S_null": null.astype(np.float32)}


def local_sync_measures(
    S: np.ndarray, null: np.ndarray, phi: np.ndarray, patches: int, coherence: np.ndarray | None
) -> dict[str, Any]:
    """The §3.3 summaries of S(f) (:func:`sync_measures`): top-1 % excess, Φ of the synchronised bins, and the
    rank correlation of the neighbours' coherence C(f) with Φ(f)."""
    import scipy.stats

    ok = np.isfinite(S) & np.isfinite(null)
    ex = np.sort((S - null)[ok])[::-1]
    sync = ok & (S - null > SYNC_EXCESS)
    out: dict[str, Any] = {
        "top_excess": float(np.mean(ex[: max(1, ex.size // 100)])) if ex.size else None,
        "phi_sync": float(np.mean(phi[sync])) if sync.any() else None,
        "phi_sync_share": float(np.mean(phi[sync]) / patches) if sync.any() else None,
        "sync_bins": int(sync.sum()),
        "cluster_phi_rho": None,
    }
    if coherence is not None:
        use = (phi >= 2) & np.isfinite(coherence)
        if use.sum() > 2 and np.ptp(coherence[use]) > 0 and np.ptp(phi[use]) > 0:
            out["cluster_phi_rho"] = float(scipy.stats.spearmanr(coherence[use], phi[use]).statistic)
    return out


SYNC_EXCESS = 0.05  # S − S_null above which a bin counts as synchronised (the spread of §3.1, Φ of §3.3)


def _table_dict(t: Any) -> dict[str, list]:
    return {
        k: np.asarray(getattr(t, k)).tolist()
        for k in ("lower", "upper", "bins", "mean_S", "mean_S_null", "mean_excess")
    }


def fig8_measures(freq: np.ndarray, spectra: dict[str, np.ndarray], f1: float) -> dict[str, Any]:
    """The Fig. 8 shape measures of one pad at its first velocity peak f1 (global spectra of one segment).

    * ``contrast_*``: peak_to_floor at f1 (±2 bins over the median of [f1/2, 2 f1]) of velocity, μ, torque, radius;
    * ``plateau_*``: plateau_excess (median over [1.1, 2] f1 against [2.5, 4] f1) of the same four;
    * ``overlap_mu_torque`` / ``overlap_mu_radius``: spectral_overlap D over 1–200 kHz;
    * ``shared_*``: shared_peak_fraction of μ's peaks in μ, torque and radius (1–200 kHz), with chance, and the
      share of those shared peaks also in the velocity spectrum;
    * ``peak_*``: peak_width (FWHM) of the velocity spectrum's peak at f1: frequency, height, width, width/f.
    """
    import warnings

    from aca_warp.analysis.measures import (
        peak_to_floor,
        peak_width,
        plateau_excess,
        shared_peak_fraction,
        shared_peaks,
        spectral_overlap,
    )

    out: dict[str, Any] = {}
    names = {"velocity": "velocity", "mu": "mu", "torque": "torque", "radius": "friction_radius"}
    for short, key in names.items():
        out[f"contrast_{short}"] = peak_to_floor(freq, spectra[key], f1).ratio
        out[f"plateau_{short}"] = plateau_excess(freq, spectra[key], f1).excess
    band = (1.0e3, min(200.0e3, float(freq[-1])))
    out["overlap_mu_torque"] = spectral_overlap(freq, spectra["mu"], spectra["torque"], band=band).mean_abs_log
    out["overlap_mu_radius"] = spectral_overlap(freq, spectra["mu"], spectra["friction_radius"], band=band).mean_abs_log
    trio = {k: spectra[k] for k in ("mu", "torque", "friction_radius")}
    sf = shared_peak_fraction(freq, trio, "mu", band=band)
    out.update(
        shared_fraction=sf.fraction, shared_count=sf.shared, shared_chance=sf.chance, mu_peaks=sf.reference_peaks
    )
    four = shared_peaks(freq, {**trio, "velocity": spectra["velocity"]}, band=band)
    out["shared_in_velocity"] = len(four) / sf.shared if sf.shared else None
    with warnings.catch_warnings():  # the prominence of a largest bin that is no local maximum is 0: said, not warned
        warnings.filterwarnings("ignore", message="some peaks have a prominence of 0")
        w = peak_width(freq, spectra["velocity"], f1, search=max(2.0 * (freq[1] - freq[0]), 0.01 * f1))
    out.update(
        peak_frequency=w.frequency, peak_height=w.height, peak_width=w.width, peak_relative_width=w.width / w.frequency
    )
    return out


SNAPSHOTS = 64  # instants of the direction-of-motion pattern (Figs. 4/6) per pad


def correlation_measures(x: np.ndarray, y: np.ndarray, v: np.ndarray, X: np.ndarray, i1: int) -> dict[str, Any]:
    """Spatial correlation C(d) of the patch motion over pairs closer than 20 mm (or half the patches' extent)
    (``phase_correlation_length``, 20 distance bins), summarised by

    * ``*_near``: C over the pairs within the coupling radius 5 mm (pair-weighted): > 0 when coupled neighbours move
      together (synchronised islands), < 0 when they move against each other;
    * ``*_zero``: where C first falls to 0 (linear interpolation; 0 when it starts at or below 0, the reach when it
      stays positive): the size of the co-moving groups;

    for ``corr``: the direction-of-motion pattern of Figs. 4/6 — sign(u̇_i) at ``SNAPSHOTS`` instants evenly spread
    over the segment (phase 0 with the disc, π against it, so cos(φ_i − φ_j) = s_i s_j), unweighted; and for
    ``corr_f1``: the phases of the patch spectra at the first peak, bins f1 ± 2, weighted by the amplitudes.
    """
    from aca_warp.analysis.measures import phase_correlation_length

    reach = min(20.0e-3, 0.5 * float(np.hypot(np.ptp(x), np.ptp(y))))
    rows = np.linspace(0, v.shape[0] - 1, min(SNAPSHOTS, v.shape[0])).round().astype(int)
    sign = np.where(v[rows] < 0, np.pi, 0.0)
    spec = X[max(i1 - 2, 0) : i1 + 3]
    out: dict[str, Any] = {"corr_reach": reach}
    for key, c in (
        ("corr", phase_correlation_length(x, y, sign, max_distance=reach)),
        ("corr_f1", phase_correlation_length(x, y, np.angle(spec), np.abs(spec), max_distance=reach)),
    ):
        ok = np.isfinite(c.correlation) & (c.pairs > 0)
        d, cc, n = c.distance[ok], c.correlation[ok], c.pairs[ok]
        near = d <= COUPLING_RADIUS
        out[f"{key}_near"] = float(np.average(cc[near], weights=n[near])) if near.any() else None
        out[f"{key}_zero"] = _zero_crossing(d, cc, reach)
        out[f"{key}_curve"] = {"distance": d.tolist(), "C": cc.tolist()}
    return out


COUPLING_RADIUS = 5.0e-3  # m: the default coupling radius (docs/model.md §2.5)


def _zero_crossing(d: np.ndarray, c: np.ndarray, reach: float) -> float:
    """First distance where c falls to 0 (linear interpolation); 0 if c[0] <= 0, ``reach`` if it never does."""
    below = np.flatnonzero(c <= 0)
    if below.size == 0:
        return reach
    k = int(below[0])
    if k == 0:
        return 0.0
    return float(d[k - 1] + c[k - 1] / (c[k - 1] - c[k]) * (d[k] - d[k - 1]))


def stft_measures(mu: np.ndarray, sample_dt: float) -> list[dict[str, Any]]:
    """Largest STFT amplitude of μ over the saturated part divided by its mean (Fig. 10's normalisation), for every
    window of 2^12 … 2^17 samples that fits, with the window named."""
    from aca_warp.analysis.measures import stft_peaks

    t = np.arange(mu.size) * sample_dt
    return [
        {"window": p.window, "samples": p.window_samples, "amplitude": p.amplitude, "frequency": p.frequency}
        for p in stft_peaks(t, mu)
    ]


def mu_measures(freq: np.ndarray, spectra: dict[str, np.ndarray], mu: np.ndarray) -> dict[str, Any]:
    """μ's oscillation over the segment: mean, standard deviation (the amplitude of §3.3) and the largest peak
    of |μ(f)|/μ̄ at or above 5 kHz (frequency and height)."""
    from aca_warp.analysis.spectra import peak

    f, a = peak(freq, spectra["mu"], fmin=5.0e3)
    return {"mu_mean": float(np.mean(mu)), "mu_std": float(np.std(mu)), "mu_peak_hz": f, "mu_peak_amplitude": a}


def pad_measures(
    gseg: np.ndarray, vseg: np.ndarray, xy: tuple[np.ndarray, np.ndarray], cfg: Config
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Every measure of one saturated pad over its analysis segment.

    Args:
        gseg: Global outputs over the segment, shape (decimation·M, 5), sampled every ``cfg.sample_dt``.
        vseg: Patch velocities over the same span, shape (M, n) float32, every ``cfg.sample_dt·decimation``.
        xy: Patch centres (x, y) [m], each (n,).
        cfg: Settings.

    Returns:
        (scalars, arrays): JSON-ready numbers, and the spectra and S(f) for the arrays file.
    """
    from aca_warp.analysis.measures import first_peak, neighbour_coherence
    from aca_warp.analysis.spectra import complex_spectrum, peak

    dtp = cfg.sample_dt * cfg.decimation
    fg, spectra = global_spectra(gseg, cfg.sample_dt)
    top = min(cfg.sync_band[1], 0.9 / (2.0 * dtp))
    fp, X = complex_spectrum(vseg, dtp, axis=0, freq_range=(cfg.sync_band[0], top))
    mean_amp = np.abs(X).mean(axis=1)
    df = fp[1] - fp[0]
    fmin = max(cfg.sync_band[0], 3.0 * df)
    f1, a1 = first_peak(fp, mean_amp, fraction=FIRST_PEAK_FRACTION, fmin=fmin)
    f_max, a_max = peak(fp, mean_amp, fmin=fmin)
    i1 = int(np.argmin(np.abs(fp - f1)))
    lo = int(round(fp[0] / (fg[1] - fg[0])))
    mu_on_p = spectra["mu"][lo : lo + fp.size]
    out: dict[str, Any] = {"f1": f1, "f1_amplitude": a1, "f_largest": f_max, "largest_amplitude": a_max}
    out.update(resolution_hz=df, segment_s=vseg.shape[0] * dtp)
    out.update(fig8_measures(fg, spectra, f1))
    out.update(mu_measures(fg, spectra, gseg[:, 0]))
    arrays: dict[str, np.ndarray] = {"patch_mean_amplitude": mean_amp.astype(np.float32)}
    try:
        coherence = neighbour_coherence(xy[0], xy[1], X, COUPLING_RADIUS)
        arrays["neighbour_coherence"] = coherence.astype(np.float32)
    except ValueError:  # no two patches within the coupling radius: no local clustering to measure
        coherence = None
    for rule in ("relative", "snr"):
        scalars, arr = sync_measures(fp, X, f1, mu_on_p, rule, coherence)
        out[f"sync_{rule}"] = scalars
        arrays.update({f"{k}_{rule}": v for k, v in arr.items()})
    out.update(correlation_measures(xy[0], xy[1], vseg, X, i1))
    out["stft"] = stft_measures(gseg[:, 0], cfg.sample_dt)
    arrays.update({f"spectrum_{k}": v.astype(np.float32) for k, v in spectra.items()})
    return out, arrays


# ------------------------------------------------------------------------------------------------ running


class Collector:
    """Sink of the run loop: keeps the global outputs (float64) and the per-patch velocities (float32)."""

    def __init__(self) -> None:
        self.time: list[np.ndarray] = []
        self.globals: list[np.ndarray] = []
        self.patch_time: list[np.ndarray] = []
        self.velocity: list[np.ndarray] = []

    def __call__(self, chunk: Any) -> None:
        self.time.append(chunk.time)
        self.globals.append(np.asarray(chunk.globals, dtype=np.float64))
        if chunk.velocity is not None and len(chunk.patch_time):
            self.patch_time.append(chunk.patch_time)
            self.velocity.append(np.asarray(chunk.velocity, dtype=np.float32))

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(time (N,), globals (N, pads, 5), patch time (M,), velocity (M, patches))."""

        def cat(parts: list[np.ndarray], empty: tuple[int, ...]) -> np.ndarray:
            return np.concatenate(parts) if parts else np.zeros(empty)

        v = cat(self.velocity, (0, 0)).astype(np.float32, copy=False)
        self.velocity.clear()
        return cat(self.time, (0,)), cat(self.globals, (0, 0, 5)), cat(self.patch_time, (0,)), v


def analysis_segment(sat: list[dict[str, Any]], patch_time: np.ndarray) -> int | None:
    """First per-patch sample of the common analysis segment: the latest saturated start of the usable pads (no
    earlier than the window); None when no pad is usable."""
    starts = [s["t_start"] for s in sat if s["status"] == "saturated"]
    if not starts or patch_time.size == 0:
        return None
    return int(np.searchsorted(patch_time, max(starts) - 1e-12))


def analyse_batch(
    scenes: list[Any],
    time: np.ndarray,
    glob: np.ndarray,
    ptime: np.ndarray,
    vel: np.ndarray,
    plan: Plan,
    cfg: Config,
    kind: str = "saturated",
    members: list[str | None] | None = None,
) -> tuple[list[dict[str, Any]], dict[str, np.ndarray], dict[str, Any]]:
    """Saturation of every pad, the common segment, and the measures of each usable pad.

    ``kind`` "saturated": the segment starts at the latest saturated start of the usable pads, the others are not
    analysed; "window": every pad is analysed over the whole per-patch record, saturated or not (status
    "linear phase"; the detector's verdict is kept as ``detector_status``). Pads are analysed in ``cfg.workers``
    processes. Returns (pads, arrays, segment): one dict per pad (seed, member, status, saturation figures,
    measures), the arrays for ``arrays.npz`` (stacked over the analysed pads, their indices in "pad"), and the
    segment's start, length and resolution.
    """
    window = plan.patch_samples * cfg.sample_dt * cfg.decimation
    sat = [pad_saturation(time, glob[:, p], plan.duration, window) for p in range(len(scenes))]
    if kind == "window":
        for s in sat:
            s.update(
                detector_status=s["status"], status="linear phase", t_start=float(ptime[0]) if ptime.size else None
            )
        k0 = 0 if ptime.size else None
    else:
        k0 = analysis_segment(sat, ptime)
    pads: list[dict[str, Any]] = []
    segment: dict[str, Any] = {"start_s": None, "samples": 0}
    jobs: list[tuple[int, tuple]] = []
    start = np.concatenate([[0], np.cumsum([s.patches.count for s in scenes])])
    if k0 is not None:
        m = ptime.size - k0 - 1  # one short: the global segment (m·decimation samples) must end inside the record
        j0 = int(round(ptime[k0] / cfg.sample_dt))
        segment = {"start_s": float(ptime[k0]), "samples": m, "seconds": m * cfg.sample_dt * cfg.decimation}
        segment["resolution_hz"] = 1.0 / segment["seconds"]
    for p, s in enumerate(scenes):
        a, b = int(start[p]), int(start[p + 1])
        entry: dict[str, Any] = {"seed": s.initial.seed, "patches": b - a, **sat[p]}
        if members is not None and members[p] is not None:
            entry["member"] = members[p]
        pads.append(entry)
        if sat[p]["status"] in USABLE and k0 is not None:
            gseg = glob[j0 : j0 + m * cfg.decimation, p]
            jobs.append((p, (gseg, vel[k0 : k0 + m, a:b], (s.patches.x, s.patches.y), cfg)))
    arrays: dict[str, list] = {}
    for (p, _), (scal, arr) in zip(jobs, map_pads(_pad_job, [j for _, j in jobs], cfg.workers), strict=True):
        if isinstance(scal, str):  # the pad is reported, never silently used
            pads[p]["status"] = f"analysis failed: {scal}"
            continue
        pads[p]["measures"] = scal
        for k, v in arr.items():
            arrays.setdefault(k, []).append(v)
        arrays.setdefault("pad", []).append(p)
    return pads, {k: np.asarray(v) for k, v in arrays.items()}, segment


def _pad_job(args: tuple) -> tuple[Any, Any]:
    """:func:`pad_measures` of one pad; ("ErrorType: message", None) when its analysis fails."""
    try:
        return pad_measures(*args)
    except (ValueError, FloatingPointError, IndexError) as e:
        return f"{type(e).__name__}: {e}", None


def pad_facts(scenes: list[Any], contacts: list[Any], sigma: list[np.ndarray]) -> list[dict[str, Any]]:
    """Per pad: patches in contact, matrix load share, mean area, predicted σ min / median / max [1/s]."""
    out = []
    for p, (s, c) in enumerate(zip(scenes, contacts, strict=True)):
        out.append(
            {
                "patches": int(s.patches.count),
                "in_contact": int(np.count_nonzero(c.patch_force > 0)),
                "matrix_share": float(c.matrix_force.sum() / s.normal_force) if s.normal_force > 0 else 0.0,
                "mean_area_m2": float(s.patches.area.mean()),
                "sigma_min": float(sigma[p].min()),
                "sigma_median": float(np.median(sigma[p])),
                "sigma_max": float(sigma[p].max()),
                "normal_force_N": float(s.normal_force),
            }
        )
    return out


@dataclass
class Prepared:
    """An experiment's scenes, their host contact solves, predicted growth rates and plan (before any run);
    ``members``: the member (e.g. LF state) of each pad, None without members."""

    exp: Experiment
    scenes: list[Any]
    contacts: list[Any]
    sigma: list[np.ndarray]
    plan: Plan
    members: list[str | None]

    @property
    def patch_count(self) -> int:
        return sum(s.patches.count for s in self.scenes)

    def cost_patches(self, cfg: Config) -> int:
        """Patches that set the step time: on CUDA pads × the largest pad (blocks are sized for it), else all."""
        if cfg.device == "cpu":
            return self.patch_count
        return len(self.scenes) * max(s.patches.count for s in self.scenes)

    def estimate(self, cfg: Config, calibration: dict[str, float]) -> float:
        """Estimated wall seconds of the run (stepping only; see :func:`step_seconds`)."""
        growth = self.exp.kind == "growth"
        return self.plan.steps * step_seconds(cfg, self.cost_patches(cfg), calibration, growth)


def prepare(exp: Experiment, cfg: Config) -> Prepared:
    """Scenes, contact solves, predicted σ and plan of ``exp`` (host only: cheap)."""
    from aca_warp.hf.contact import solve_scene_contact

    n = cfg.seeds * exp.pads_per_seed
    members = [pad_member(exp, k, cfg)[0] for k in range(n)]
    scenes = [experiment_scene(exp, k, cfg) for k in range(n)]
    contacts = [solve_scene_contact(s) for s in scenes]
    sigma = predicted_sigma(scenes, contacts)
    plan = plan_run(exp, scenes, contacts, sigma, cfg, members)
    return Prepared(exp, scenes, contacts, sigma, plan, members)


def run_experiment(
    prep: Prepared,
    cfg: Config,
    out: Path,
    log: Log,
    calibration: dict[str, float],
    budget: float | None,
    keep_records: bool = False,
) -> dict[str, Any]:
    """Run, analyse and save one prepared experiment (module docstring); returns its result dict.

    A run the ``budget`` [s of wall time left] cannot hold is not started: the result says so.
    """
    from aca_warp.hf.solver import stable_step
    from aca_warp.studies.runs import batch_at_start, run_engine

    t0 = time.perf_counter()
    exp, scenes, plan = prep.exp, prep.scenes, prep.plan
    est = prep.estimate(cfg, calibration)
    sizes = sorted({s.patches.count for s in scenes})
    log(
        f"{exp.name}: {len(scenes)} pads × {'/'.join(map(str, sizes))} patches, {exp.initial}, {exp.kind} run "
        f"{plan.duration * 1e3:.1f} ms (settle {plan.settle * 1e3:.1f} ms; per-patch window "
        f"{plan.patch_samples * cfg.sample_dt * cfg.decimation * 1e3:.1f} ms) = {plan.steps:,} steps; per-patch "
        f"record {plan.velocity_bytes / 2**20:.0f} MiB; estimated {est:.0f} s"
    )
    result = _result_head(exp, cfg, plan, pad_facts(scenes, prep.contacts, prep.sigma), est)
    if budget is not None and est > budget:
        log(f"{exp.name}: not run: estimated {est:.0f} s exceeds the {budget:.0f} s left of --max-wall")
        return {**result, "status": "skipped (--max-wall)"}
    model, state = batch_at_start(scenes, cfg.device, cfg.precision)
    # strang's step must resolve sticking (docs/stability.md): the configured step or 0.9 × that bound; the quick
    # variant keeps its coarse step, forced (a smoke check, named as such in the table)
    dt = cfg.dt if cfg.quick else min(cfg.dt, 0.9 * stable_step(model).sticking)
    if dt < cfg.dt:
        log(f"{exp.name}: step {dt:.3g} s (strang's sticking bound), not {cfg.dt:.3g} s")
    sink = Collector()
    res = run_engine(
        model,
        state,
        engine=cfg.engine,
        duration=plan.duration,
        integrator="strang",
        dt=dt,
        record=plan.record,
        sink=sink,
        force=cfg.quick,
    )
    result["run"] = _run_facts(res, model, cfg)
    per = res.wall_time / max(res.steps, 1)
    grown = "growth" if exp.kind == "growth" else "fixed"
    calibration[f"per_patch_{grown}"] = per / prep.cost_patches(cfg)
    calibration[f"floor_{grown}"] = per if cfg.device != "cpu" else 0.0
    del model, state
    log(
        f"{exp.name}: {'complete' if res.complete else 'stopped: ' + str(res.fault)} in {res.wall_time:.1f} s "
        f"({res.steps / max(res.wall_time, 1e-9):,.0f} steps/s, {per * 1e6:.2f} µs/step, "
        f"compile {res.compile_time:.1f} s)"
    )
    t, g, pt, v = sink.arrays()
    del sink
    result["total_s"] = time.perf_counter() - t0
    return finish_experiment(prep, cfg, out, log, result, (t, g, pt, v), keep_records)


def finish_experiment(
    prep: Prepared,
    cfg: Config,
    out: Path,
    log: Log,
    result: dict[str, Any],
    records: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    keep_records: bool,
) -> dict[str, Any]:
    """Analyse the records (time, globals, patch time, velocity) of a run and save the result (and, with
    ``keep_records``, the records themselves as ``records.npz``, for :func:`reanalyse`)."""
    t, g, pt, v = records
    name = prep.exp.name
    ta = time.perf_counter()
    if prep.exp.kind == "growth":
        from aca_warp.studies.validation_area import analyse_growth

        pads, arrays, segment = analyse_growth(prep.scenes, t, g, prep.plan, cfg)
    else:
        pads, arrays, segment = analyse_batch(prep.scenes, t, g, pt, v, prep.plan, cfg, prep.exp.kind, prep.members)
    result["pads"] = pad_facts(prep.scenes, prep.contacts, prep.sigma)
    for entry, facts in zip(pads, result["pads"], strict=True):
        facts.update(entry)
    run = result.get("run") or {}
    result.update(segment=segment, status="done" if run.get("complete", True) else "stopped")
    result["analysis_s"] = time.perf_counter() - ta
    series = {"time": t.astype(np.float32), "globals": g.astype(np.float32)}
    save_result(out / name, clean(result), {**series, **arrays})
    if keep_records:
        np.savez(out / name / "records.npz", time=t, globals=g, patch_time=pt, velocity=v)
    usable_pads = sum(p["status"] in USABLE and "measures" in p for p in pads)
    log(f"{name}: {usable_pads}/{len(pads)} pads analysed ({prep.exp.kind}) in {result['analysis_s']:.1f} s; saved")
    return clean(result)


def reanalyse(prep: Prepared, cfg: Config, out: Path, log: Log) -> dict[str, Any] | None:
    """Analyse again the kept records of a saved run of ``prep`` (same settings); None when there are none."""
    folder = out / prep.exp.name
    path, res = folder / "records.npz", folder / "result.json"
    if not (path.is_file() and res.is_file()):
        return None
    result = json.loads(res.read_text())
    if result.get("experiment") != clean(prep.exp.key()) or result.get("config") != cfg.run_key():
        return None
    with np.load(path) as d:
        records = (d["time"], d["globals"], d["patch_time"], d["velocity"])
    log(f"{prep.exp.name}: analysing the kept records again")
    return finish_experiment(prep, cfg, out, log, result, records, keep_records=False)


def _result_head(exp: Experiment, cfg: Config, plan: Plan, facts: list[dict], est: float) -> dict[str, Any]:
    return {
        "experiment": exp.key(),
        "config": cfg.run_key(),
        "plan": {
            "duration_s": plan.duration,
            "settle_s": plan.settle,
            "v0_m_s": plan.v0,
            "v_sat_m_s": plan.v_sat,
            "sigma_q25": plan.sigma_q25,
            "window_start_s": plan.window_start,
            "patch_samples": plan.patch_samples,
            "steps": plan.steps,
            "velocity_bytes": plan.velocity_bytes,
            "estimate_s": est,
        },
        "pads": facts,
    }


def _run_facts(res: Any, model: Any, cfg: Config) -> dict[str, Any]:
    from aca_warp.common.files import machine

    return {
        "complete": bool(res.complete),
        "fault": None if res.fault is None else str(res.fault),
        "steps": int(res.steps),
        "wall_s": float(res.wall_time),
        "compile_s": float(res.compile_time),
        "us_per_step": 1e6 * res.wall_time / max(res.steps, 1),
        "blocks_per_pad": int(res.blocks_per_pad),
        "stages": list(res.stages),
        "device": machine(model.device),
        "engine": cfg.engine,
    }


def save_result(folder: Path, result: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
    """``result.json`` (written last, so its presence marks a finished experiment) and ``arrays.npz``."""
    folder.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(folder / "arrays.npz", **arrays)
    tmp = folder / "result.json.tmp"
    tmp.write_text(json.dumps(result, indent=1, ensure_ascii=False) + "\n")
    tmp.replace(folder / "result.json")


def load_result(folder: Path, exp: Experiment, cfg: Config) -> dict[str, Any] | None:
    """The saved result of ``exp`` if it was made with the same definition and settings, else None."""
    path = folder / "result.json"
    if not path.is_file():
        return None
    try:
        res = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    same = res.get("experiment") == clean(exp.key()) and res.get("config") == cfg.run_key()
    return res if same and res.get("status") in ("done", "stopped") else None


# ------------------------------------------------------------------------------------------------ rows: §3.1

PRESETS = ("hf1", "hf2", "hf3", "hf4")
PEAK_TOLERANCE = 0.05  # relative: "around 73 kHz" read off Fig. 8
EXPONENT_TOLERANCE = 0.025  # absolute: 10 % of 1/4
OVERLAP_LIMIT = math.log(1.25)  # D = mean |ln μ − ln T| ≤ ln 1.25: a typical difference below 25 %
SHARED_LIMIT = 0.5  # "similar characteristic peaks": at least half of μ's peaks in torque and radius too
EQUAL_MARGIN = 0.05  # S − S_null: a difference below 0.05 counts as "not significantly affected"


def _first_peak(name: str) -> Callable[[dict[str, dict], Config], RowValue]:
    def measure(results: dict[str, dict], cfg: Config) -> RowValue:
        f = values(results.get(name), "f1")
        paper = PAPER["first_peak_hz"][name]
        sumv = values(results.get(name), "peak_frequency")
        largest = values(results.get(name), "f_largest")
        return RowValue(
            interval(f, ".1f", 1e-3, "kHz"),
            value_verdict(f, paper, PEAK_TOLERANCE * paper),
            f"first peak: the lowest peak of the mean per-patch velocity spectrum reaching {FIRST_PEAK_FRACTION:g} of "
            f"its maximum; the Σu̇ spectrum's peak there {interval(sumv, '.1f', 1e-3, 'kHz')}; the largest peak "
            f"{interval(largest, '.1f', 1e-3, 'kHz')}",
        )

    return measure


for _name in PRESETS:
    register_row(
        Row(
            "§3.1, Fig. 8",
            f"{_name.upper()}: first velocity-spectrum peak",
            f"≈ {PAPER['first_peak_hz'][_name] / 1e3:g} kHz",
            "value",
            (_name,),
            _first_peak(_name),
            f"± {100 * PEAK_TOLERANCE:g} %",
        )
    )


def exponent_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """f1 ∝ A^b per seed over the mean areas of SWEEP (at least 3 areas per seed); b against −1/4."""
    from aca_warp.studies.hf_study import fit_power_law

    points: dict[int, list[tuple[float, float]]] = {}
    for name in SWEEP:
        for p in usable(results.get(name)):
            f = _get(p, "f1")
            if math.isfinite(f):
                points.setdefault(int(p["seed"]), []).append((p["mean_area_m2"], f))
    b = np.array(
        [fit_power_law(*map(np.array, zip(*pts, strict=True)))["exponent"] for pts in points.values() if len(pts) >= 3]
    )
    allp = [q for pts in points.values() for q in pts]
    pooled = fit_power_law(*map(np.array, zip(*allp, strict=True))) if len(allp) >= 3 else {}
    areas = sorted({round(a / MM2, 3) for a, _ in allp})
    note = f"fit per seed over the mean areas {', '.join(f'{a:g}' for a in areas)} mm²"
    if pooled.get("stderr") is not None:
        note += (
            f"; pooled over all {pooled['n_points']} pads {pooled['exponent']:.3f} ± {pooled['stderr']:.3f} (1 s.e.)"
        )
    return RowValue(interval(b, ".3f"), value_verdict(b, PAPER["exponent"], EXPONENT_TOLERANCE), note)


register_row(
    Row(
        "§3.1",
        "f_p ∝ A_p^(−1/4): exponent of the first velocity peak against the mean patch area",
        "−1/4",
        "value",
        SWEEP,
        exponent_row,
        f"± {EXPONENT_TOLERANCE:g}",
        min_experiments=3,
    )
)


def two_area_exponent_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """b = ln(f1(HF2)/f1(HF1)) / ln(A(HF2)/A(HF1)) per seed (the two presets of the paper, paired by seed)."""

    def lnf(name: str) -> dict[int, float]:
        return by_seed(results.get(name), lambda p: math.log(_get(p, "f1")))

    def lna(name: str) -> dict[int, float]:
        return by_seed(results.get(name), lambda p: math.log(p["mean_area_m2"]))

    df, da = paired(lnf("hf2"), lnf("hf1")), paired(lna("hf2"), lna("hf1"))
    b = df / da if df.size == da.size else np.array([])
    f1 = [interval(values(results.get(n), "f1"), ".1f", 1e-3, "kHz") for n in ("hf1", "hf2")]
    return RowValue(
        interval(b, ".3f"),
        value_verdict(b, PAPER["exponent"], EXPONENT_TOLERANCE),
        f"first peaks hf1 {f1[0]}, hf2 {f1[1]}; the paper's own peaks (73 and 32.8 kHz at 0.05 and 1.25 mm²) give "
        f"{math.log(32.8 / 73.0) / math.log(25.0):.3f}",
    )


register_row(
    Row(
        "§3.1",
        "f_p ∝ A_p^(−1/4) from the two patch sizes of Table 1 (HF1, HF2)",
        "−1/4",
        "value",
        ("hf1", "hf2"),
        two_area_exponent_row,
        f"± {EXPONENT_TOLERANCE:g}",
    )
)


def _per_preset(
    results: dict[str, dict], value: Callable[[dict[str, Any]], float], verdict: Callable[[np.ndarray], Any]
) -> tuple[list[str], list[Any]]:
    """Per preset: the interval text of value(pad) and verdict(values)."""
    texts, verdicts = [], []
    for name in PRESETS:
        v = np.array(list(by_seed(results.get(name), value).values()))
        texts.append(f"{name}: {interval(v)}")
        verdicts.append(verdict(v))
    return texts, verdicts


def _combine(sides: list[int]) -> str:
    return direction_verdict(sides)


def pronounced_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """ln of the velocity spectrum's peak contrast at f1 over the largest of μ's, torque's and radius's."""

    def ratio(p: dict[str, Any]) -> float:
        others = max(_get(p, k) for k in ("contrast_mu", "contrast_torque", "contrast_radius"))
        return math.log(_get(p, "contrast_velocity") / others)

    texts, sides = _per_preset(results, ratio, side)
    mu = [f"{n}: μ {interval(values(results.get(n), 'contrast_mu'), '.2g')}" for n in PRESETS]
    return RowValue(
        "ln(contrast ratio) " + "; ".join(texts),
        _combine(sides),
        "contrast = height at f1 over the median of [f1/2, 2 f1]; velocity = |Σu̇(f)| / mean Σ|u̇|; " + "; ".join(mu),
    )


def plateau_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """Plateau excess of the velocity spectrum minus the largest of μ's, torque's and radius's."""

    def diff(p: dict[str, Any]) -> float:
        return _get(p, "plateau_velocity") - max(_get(p, k) for k in ("plateau_mu", "plateau_torque", "plateau_radius"))

    texts, sides = _per_preset(results, diff, side)
    vel = [f"{n}: {interval(values(results.get(n), 'plateau_velocity'), '.2g')}" for n in PRESETS]
    return RowValue(
        "excess difference " + "; ".join(texts),
        _combine(sides),
        "excess = ln median [1.1, 2] f1 − ln median [2.5, 4] f1; velocity's own excess " + "; ".join(vel),
    )


def overlap_row(results: dict[str, dict], cfg: Config) -> RowValue:
    texts, verdicts = _per_preset(
        results, lambda p: _get(p, "overlap_mu_torque"), lambda v: threshold_verdict(v, OVERLAP_LIMIT, True)
    )
    radius = [f"{n}: {interval(values(results.get(n), 'overlap_mu_radius'), '.2g')}" for n in PRESETS]
    return RowValue(
        "D(μ, torque) " + "; ".join(texts),
        _all_of(verdicts),
        "D = mean |ln a − ln b| over 1–200 kHz; for contrast D(μ, friction radius) " + "; ".join(radius),
    )


def shared_row(results: dict[str, dict], cfg: Config) -> RowValue:
    texts, verdicts = _per_preset(
        results, lambda p: _get(p, "shared_fraction"), lambda v: threshold_verdict(v, SHARED_LIMIT, False)
    )
    chance = [f"{n}: {interval(values(results.get(n), 'shared_chance'), '.2g')}" for n in PRESETS]
    vel = [f"{n}: {interval(values(results.get(n), 'shared_in_velocity'), '.2g')}" for n in PRESETS]
    return RowValue(
        "share of μ's peaks " + "; ".join(texts),
        _all_of(verdicts),
        "peaks ≥ 4× their surroundings, within 2 bins, 1–200 kHz; chance "
        + "; ".join(chance)
        + "; share of the shared peaks also in the velocity spectrum "
        + "; ".join(vel),
    )


for _row in (
    Row("§3.1, Fig. 8", "the first velocity peak is significantly more pronounced than in μ, torque, friction radius",
        "yes, in all four", "direction", PRESETS, pronounced_row, "ln ratio > 0 in each preset"),
    Row("§3.1, Fig. 8", "broad-band plateaus follow the first peak in the velocity spectra, not in the other outputs",
        "yes, in all four", "direction", PRESETS, plateau_row, "excess difference > 0 in each preset"),
    Row("§3.1, Fig. 8", "μ and torque spectra nearly completely overlap", "yes", "threshold", PRESETS, overlap_row,
        f"D ≤ ln 1.25 = {OVERLAP_LIMIT:.3f} in each preset"),
    Row("§3.1, Fig. 8", "similar characteristic peaks of μ, torque and friction radius", "yes", "threshold", PRESETS,
        shared_row, f"share ≥ {SHARED_LIMIT:g} in each preset"),
):  # fmt: skip
    register_row(_row)


def _sync_claim(results: dict[str, dict], a: str, b: str) -> tuple[str, str, list[int], int]:
    """S of a above S of b at equal Φ: primary (relative rule, S − S_null) and the secondary measures."""
    primary, classes = equal_phi(results, a, b)
    sec = {
        "raw S, relative": equal_phi(results, a, b, value="S")[0],
        "S − S_null, snr": equal_phi(results, a, b, rule="snr")[0],
        "median S − S_null (Φ ≥ 10), relative": paired(
            by_seed(results.get(a), lambda p: _get(p, "sync_relative.median_excess_phi10")),
            by_seed(results.get(b), lambda p: _get(p, "sync_relative.median_excess_phi10")),
        ),
    }
    notes = f"{classes}; " + "; ".join(f"{k}: {interval(v)}" for k, v in sec.items())
    return interval(primary), notes, [side(v) for v in sec.values()], side(primary)


def lower_m_row(a: str, b: str) -> Callable[[dict[str, dict], Config], RowValue]:
    def measure(results: dict[str, dict], cfg: Config) -> RowValue:
        value, notes, sec, prim = _sync_claim(results, a, b)
        return RowValue(f"Δ(S − S_null) at equal Φ {a} − {b}: {value}", direction_verdict([prim], sec), notes)

    return measure


def less_for_large_row(results: dict[str, dict], cfg: Config) -> RowValue:
    small, _ = equal_phi(results, "hf3", "hf1")
    large, _ = equal_phi(results, "hf4", "hf2")
    ds = by_seed_pairs(results, ("hf3", "hf1"), ("hf4", "hf2"))
    return RowValue(
        f"(hf3 − hf1) − (hf4 − hf2): {interval(ds)}",
        direction_verdict([side(ds)]),
        f"Δ at equal Φ (relative rule, S − S_null): small patches {interval(small)}, large patches {interval(large)}",
    )


def by_seed_pairs(results: dict[str, dict], first: tuple[str, str], second: tuple[str, str]) -> np.ndarray:
    """Per seed, the equal-Φ difference of ``first`` minus that of ``second`` (S − S_null, relative rule)."""
    from aca_warp.analysis.measures import equal_prevalence_difference

    ts = {n: tables(results.get(n), "relative") for n in (*first, *second)}
    seeds = [s for s in sorted(ts[first[0]]) if all(s in ts[n] for n in ts)]
    if not seeds:
        return np.array([])
    d1 = equal_prevalence_difference([ts[first[0]][s] for s in seeds], [ts[first[1]][s] for s in seeds]).difference
    d2 = equal_prevalence_difference([ts[second[0]][s] for s in seeds], [ts[second[1]][s] for s in seeds]).difference
    return d1 - d2


def larger_peaks_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """HF2 vs HF1 and HF4 vs HF3: ln height ratio > 0, ln width ratio < 0, frequency ratio < 1 (velocity spectrum)."""
    texts, sides = [], []
    for big, small in (("hf2", "hf1"), ("hf4", "hf3")):
        parts = {}
        for key, sign in (("peak_height", 1.0), ("peak_width", -1.0), ("f1", -1.0)):
            d = paired(
                by_seed(results.get(big), lambda p, k=key: math.log(_get(p, k))),
                by_seed(results.get(small), lambda p, k=key: math.log(_get(p, k))),
            )
            parts[key] = d
            sides.append(side(d, sign))
        texts.append(
            f"{big}/{small}: height ×{_exp_interval(parts['peak_height'])}, "
            f"width ×{_exp_interval(parts['peak_width'])}, frequency ×{_exp_interval(parts['f1'])}"
        )
    rel = [f"{n}: {interval(values(results.get(n), 'peak_relative_width'), '.2g')}" for n in PRESETS]
    return RowValue(
        "; ".join(texts),
        direction_verdict(sides),
        "peak of the velocity spectrum at f1, FWHM of the amplitude; relative width Δf/f " + "; ".join(rel),
    )


def _exp_interval(d: np.ndarray) -> str:
    m, lo, hi = ci(d)
    if not math.isfinite(m):
        return "–"
    return f"{math.exp(m):.3g} [{math.exp(lo):.3g}, {math.exp(hi):.3g}]" if math.isfinite(lo) else f"{math.exp(m):.3g}"


def spread_row(results: dict[str, dict], cfg: Config) -> RowValue:
    texts, sides, notes = [], [], []
    for key, label in (("spread", "spread"), ("prevalence", "mean Φ")):
        d = paired(*(by_seed(results.get(n), lambda p, k=key: _get(p, f"sync_relative.{k}")) for n in ("hf2", "hf1")))
        texts.append(f"Δ {label} hf2 − hf1: {interval(d)}")
        sides.append(side(d))
        snr = paired(*(by_seed(results.get(n), lambda p, k=key: _get(p, f"sync_snr.{k}")) for n in ("hf2", "hf1")))
        notes.append(f"{label} (snr rule) {interval(snr)}")
    return RowValue(
        "; ".join(texts),
        direction_verdict(sides),
        "spread = share of the bins in [f1/8, 2 f1] with S − S_null > 0.05; mean Φ over that band; " + "; ".join(notes),
    )


def patterns_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """HF2 vs HF1: the size of the co-moving groups (where C(d) of the directions of motion falls to 0: larger) and
    C among coupled neighbours (better defined); the same of the spectral phases at f1 beside them."""
    parts = []
    for key in ("corr", "corr_f1"):
        d_size = paired(*(by_seed(results.get(n), lambda p, k=key: _get(p, f"{k}_zero")) for n in ("hf2", "hf1")))
        d_near = paired(*(by_seed(results.get(n), lambda p, k=key: _get(p, f"{k}_near")) for n in ("hf2", "hf1")))
        each = "; ".join(
            f"{n}: C near {interval(values(results.get(n), f'{key}_near'))}, zero at "
            f"{interval(values(results.get(n), f'{key}_zero'), '.3g', 1e3, 'mm')}"
            for n in ("hf1", "hf2")
        )
        parts.append((d_size, d_near, each))
    (d_size, d_near, each), (f_size, f_near, f_each) = parts
    return RowValue(
        f"Δ group size hf2 − hf1: {interval(d_size, '.3g', 1e3, 'mm')}; Δ C of coupled neighbours: {interval(d_near)}",
        direction_verdict([side(d_size), side(d_near)]),
        f"C(d) = ⟨s_i s_j⟩ of the directions of motion s = sign(u̇) at {SNAPSHOTS} instants (Figs. 4/6); "
        f"{each}; spectral phases at f1 (amplitude-weighted): Δ size {interval(f_size, '.3g', 1e3, 'mm')}, "
        f"Δ C near {interval(f_near)}; {f_each}",
    )


def hf1_hf2_row(results: dict[str, dict], cfg: Config) -> RowValue:
    d, classes = equal_phi(results, "hf2", "hf1")
    snr = equal_phi(results, "hf2", "hf1", rule="snr")[0]
    return RowValue(
        f"Δ(S − S_null) at equal Φ hf2 − hf1: {interval(d)}",
        equal_verdict(d, EQUAL_MARGIN),
        f"{classes}; snr rule {interval(snr)}",
    )


def agreement_row(results: dict[str, dict], cfg: Config) -> RowValue:
    rho = {n: by_seed(results.get(n), lambda p: _get(p, "sync_relative.agreement")) for n in PRESETS}
    diffs = {n: paired(rho["hf4"], rho[n]) for n in ("hf1", "hf2", "hf3")}
    snr = {n: by_seed(results.get(n), lambda p: _get(p, "sync_snr.agreement")) for n in PRESETS}
    return RowValue(
        "; ".join(f"ρ {n}: {interval(np.array(list(rho[n].values())))}" for n in PRESETS),
        direction_verdict([side(d) for d in diffs.values()]),
        "ρ = Spearman(S·Φ, |μ(f)|/μ̄) over 20–80 kHz; paired hf4 − other: "
        + "; ".join(f"{n} {interval(d)}" for n, d in diffs.items())
        + "; snr rule ρ "
        + "; ".join(f"{n} {interval(np.array(list(snr[n].values())))}" for n in PRESETS),
    )


def combination_row(results: dict[str, dict], cfg: Config) -> RowValue:
    spread = paired(*(by_seed(results.get(n), lambda p: _get(p, "sync_relative.spread")) for n in ("hf4", "hf1")))
    high, classes = equal_phi(results, "hf4", "hf1", which="table_high")
    whole, _ = equal_phi(results, "hf4", "hf1")
    return RowValue(
        f"Δ spread hf4 − hf1: {interval(spread)}; Δ(S − S_null) at equal Φ above f1: {interval(high)}",
        direction_verdict([side(spread), side(high), side(high - whole)]),
        f'the whole band: {interval(whole)}; above f1 minus whole band ("especially at higher frequencies"): '
        f"{interval(high - whole)}; {classes}",
    )


for _row in (
    Row("§3.1, Fig. 9", "lower M raises S significantly for small patches (HF3 vs HF1)", "S(HF3) > S(HF1)",
        "direction", ("hf1", "hf3"), lower_m_row("hf3", "hf1"), "Δ > 0", uses=("sync",)),
    Row("§3.1, Fig. 9", "lower M raises S for large patches too (HF4 vs HF2)", "S(HF4) > S(HF2)", "direction",
        ("hf2", "hf4"), lower_m_row("hf4", "hf2"), "Δ > 0", uses=("sync",)),
    Row("§3.1, Fig. 9", "the rise with lower M is not as substantial for the larger patches",
        "Δ(HF3 − HF1) > Δ(HF4 − HF2)", "direction", PRESETS, less_for_large_row, "difference > 0", uses=("sync",)),
    Row("§3.1, Fig. 8", "larger patches: peaks higher, narrower, at lower frequencies (HF2 vs HF1, HF4 vs HF3)",
        "yes", "direction", PRESETS, larger_peaks_row, "height ×>1, width ×<1, frequency ×<1 in both pairs"),
    Row("§3.1, Fig. 9", "larger patches spread S over more frequencies with higher prevalence Φ (HF2 vs HF1)", "yes",
        "direction", ("hf1", "hf2"), spread_row, "both Δ > 0", uses=("sync",)),
    Row("§3.1, Figs. 4/6", "larger patches: larger, better-defined synchronisation patterns (HF2 vs HF1)", "yes",
        "direction", ("hf1", "hf2"), patterns_row, "both Δ > 0"),
    Row("§3.1, Fig. 9", "HF1 vs HF2: the size increase does not significantly affect the synchronisation quality",
        "no significant difference", "equal", ("hf1", "hf2"), hf1_hf2_row, f"margin ± {EQUAL_MARGIN:g}",
        uses=("sync",)),
    Row("§3.1, Figs. 8/9", "HF4 shows the best agreement of S with the friction spectrum", "HF4 highest", "direction",
        PRESETS, agreement_row, "ρ(hf4) − ρ(other) > 0 for all three", uses=("sync",)),
    Row("§3.1, Fig. 9", "HF4 vs HF1: S more spread out, greater, especially at higher frequencies", "yes",
        "direction", ("hf1", "hf4"), combination_row, "three Δ > 0", uses=("sync",)),
):  # fmt: skip
    register_row(_row)


# ------------------------------------------------------------------------------------------------ §3.2, §3.3, causes

validation_area.register()
validation_multiscale.register()
validation_causes.register()
validation_area.register_variants()
validation_multiscale.register_variants()


def _range(v: list[float | None], scale: float = 1.0, spec: str = ".3g") -> str:
    x = np.array([np.nan if a is None else a for a in v], dtype=np.float64) * scale + 0.0  # no "-0"
    x = x[np.isfinite(x)]
    if x.size == 0:
        return "–"
    return format(np.mean(x), spec) + (f" ({format(x.min(), spec)}–{format(x.max(), spec)})" if x.size > 1 else "")


def experiment_rows(results: dict[str, dict]) -> list[list[str]]:
    """One line per experiment: what, pads used, run, predicted against measured growth, saturation, segment."""
    rows = []
    for name, exp in EXPERIMENTS.items():
        res = results.get(name)
        if not res or "plan" not in res:
            rows.append([name, exp.description, res.get("status", "not run") if res else "not run", *["–"] * 7])
            continue
        pads, plan, run = res.get("pads", []), res["plan"], res.get("run") or {}
        ok = usable(res)
        grow = np.array([p["growth_rate"] for p in ok if p.get("growth_rate") is not None])
        seg = res.get("segment") or {}
        rows.append(
            [
                name,
                exp.description,
                f"{len(ok)} / {len(pads)}" + ("" if res.get("status") == "done" else f" ({res.get('status')})"),
                _contact_text(pads),
                _run_text(exp, res),
                f"{plan['steps']:,}; {fmt(run.get('wall_s'), '.0f')} s, {fmt(run.get('us_per_step'), '.3g')} µs/step",
                " / ".join(
                    _range([p[k] for p in pads], spec=".0f") for k in ("sigma_min", "sigma_median", "sigma_max")
                ),
                interval(grow, ".0f"),
                f"{_range([p.get('t_s_sum_abs_velocity') for p in pads], 1e3)} / "
                f"{_range([p.get('t_s_mu') for p in pads], 1e3)}",
                f"{fmt((seg.get('seconds') or 0) * 1e3, '.2f')} ms, {fmt(seg.get('resolution_hz'), '.0f')} Hz"
                if seg.get("samples")
                else "–",
            ]
        )
    return rows


def _contact_text(pads: list[dict[str, Any]]) -> str:
    """Patches per pad (the range where they differ) and how many are in contact."""
    if not pads:
        return "–"
    n = [p.get("patches", 0) for p in pads]
    c = [p.get("in_contact", 0) for p in pads]
    if all(a == b for a, b in zip(c, n, strict=True)):
        where = "all in contact"
    else:
        where = f"at least {min(b / max(a, 1) for a, b in zip(n, c, strict=True)) * 100:.0f} % in contact"
    size = f"{max(n)}" if min(n) == max(n) else f"{min(n)}–{max(n)}"
    return f"{size} ({where})"


def _run_text(exp: Experiment, res: dict[str, Any]) -> str:
    """Start and run length: predicted settling + window, a fixed window, or a growth run."""
    plan = res["plan"]
    dur = f"{plan['duration_s'] * 1e3:.1f} ms"
    if exp.kind == "window":
        return f"{exp.initial}; {dur} fixed, per-patch window from {plan['window_start_s'] * 1e3:.2f} ms"
    if exp.kind == "growth":
        return f"{exp.initial}; {dur} of growth (first saturation predicted at {plan['settle_s'] * 1e3:.1f} ms)"
    members = f", {len(exp.members)} state{'s' if len(exp.members) > 1 else ''}" if exp.members else ""
    settle = plan["window_start_s"]  # the planned settling: the predicted one, at least one window
    predicted = "" if abs(settle - plan["settle_s"]) < 1e-4 else f"; predicted {plan['settle_s'] * 1e3:.1f}"
    return f"{exp.initial}; {dur} ({settle * 1e3:.1f} + window{members}{predicted})"


EXPERIMENT_HEADER = [
    "experiment",
    "what",
    "pads used / seeds",
    "patches per pad",
    "start; run (predicted settling + window)",
    "steps; wall",
    "predicted σ_i min / median / max [1/s] (mean over pads)",
    "measured σ on Σ|u̇| [1/s]",
    "t_s Σ|u̇| / μ [ms], mean (range)",
    "analysed segment, Δf",
]


def pad_notes(results: dict[str, dict]) -> list[str]:
    """Every pad that is not used, with the reason (the detector's verdict)."""
    lines = []
    for name, res in results.items():
        for p in res.get("pads", []):
            st = p.get("status")
            if st is not None and not (st in USABLE and "measures" in p):
                who = f"{name}, {p['member'] + ', ' if p.get('member') else ''}seed {p.get('seed')}"
                lines.append(f"* {who}: **{st}** — Σ|u̇|: {p.get('verdict_sum_abs_velocity')}")
    return lines or ["* none: every pad of every experiment run was analysed (saturated, or over its fixed window)."]


def initial_state_rows(results: dict[str, dict]) -> list[list[str]]:
    """hf1 from equilibrium + perturbation against hf1 from rest: saturation and the main measures."""
    out = []
    for key, label, scale, unit in (
        ("t_s_sum_abs_velocity", "t_s of Σ|u̇|", 1e3, "ms"),
        ("t_s_mu", "t_s of μ", 1e3, "ms"),
        ("growth_rate", "fitted growth rate of Σ|u̇|", 1.0, "1/s"),
    ):
        out.append(
            [label, *(interval(_pad_values(results.get(n), key), ".3g", scale, unit) for n in ("hf1", "hf1_rest"))]
        )
    for key, label, scale, unit in (
        ("f1", "first velocity peak", 1e-3, "kHz"),
        ("sync_relative.median_excess_phi10", "median S − S_null (Φ ≥ 10)", 1.0, ""),
        ("corr_near", "C of the directions of motion of coupled neighbours (≤ 5 mm)", 1.0, ""),
        ("corr_zero", "distance where that C falls to 0", 1e3, "mm"),
        ("corr_f1_near", "C of the phases at f1 of coupled neighbours", 1.0, ""),
    ):
        out.append([label, *(interval(values(results.get(n), key), ".3g", scale, unit) for n in ("hf1", "hf1_rest"))])
    return out


def _pad_values(res: dict[str, Any] | None, key: str) -> np.ndarray:
    v = [p.get(key) for p in usable(res)]
    return np.array([x for x in v if x is not None], dtype=np.float64)


def stft_lines(results: dict[str, dict]) -> list[str]:
    """Largest STFT amplitude of μ/μ̄ per window length, per §3.1 experiment (mean over pads)."""
    lines = []
    for name, res in results.items():
        if name not in EXPERIMENTS or EXPERIMENTS[name].section != "§3.1" or EXPERIMENTS[name].kind != "saturated":
            continue
        per: dict[str, list[tuple[float, float]]] = {}
        for p in usable(res):
            for w in p["measures"].get("stft", []):
                per.setdefault(w["window"], []).append((w["amplitude"], w["frequency"]))
        for window, v in per.items():
            a, f = np.array(v).T
            lines.append(f"* {name}, {window}: {interval(a, '.3g')} at {interval(f, '.1f', 1e-3, 'kHz')}")
    return lines or ["* no saturated segment holds a window of 2^12 samples."]


def cause_lines(causes: list[dict[str, Any]]) -> list[str]:
    """The summary of the variants of the open rows and, folded, every variant's value."""
    if not causes:
        return ["No open verdict, or no variant of one was run."]
    header, rows = validation_causes.cause_summary(causes)
    moved = [c for c in causes if c["moved"]]
    lines = [
        "Each open statement (main verdict ✗ not reproduced or ~ partly) evaluated again with one change (a "
        "variant); a cell gives the variant and its verdict (✓ reproduced, ~ partly, ✗ not reproduced, · not "
        "measured), **bold** where the verdict moved. Variants whose experiments were not run are left out.",
        "",
        *md_table(header, rows),
        "",
        f"Verdicts moved by a variant: {len(moved)} of {len(causes)}"
        + (
            ": "
            + "; ".join(
                f"{c['statement']} — {c['cause']} ({c['variant']}): {c['main_verdict']} → {c['verdict']}" for c in moved
            )
            if moved
            else ""
        )
        + ".",  # fmt: skip
        "",
        "<details><summary>Every variant's value</summary>",
        "",
        *md_table(
            ["statement", "cause", "variant", "experiments", "value", "verdict"],
            [
                [c["statement"], c["cause"], c["variant"], ", ".join(c["experiments"]), c["value"], c["verdict"]]
                for c in causes
            ],
        ),  # fmt: skip
        "",
        "</details>",
    ]
    return lines


def render(
    results: dict[str, dict],
    rows: list[dict[str, Any]],
    meta: dict[str, Any],
    causes: list[dict[str, Any]] | None = None,
) -> list[str]:
    """The generated part of docs/validation.md."""
    lines = [
        *_header_lines(meta),
        "",
        "### The paper's statements",
        "",
        *md_table(
            [
                "§",
                "statement",
                "ours: mean [95 % interval] (n seeds)",
                "paper",
                "verdict (criterion)",
                "experiments",
                "notes",
            ],
            [
                [
                    r["section"],
                    r["statement"],
                    r["value"],
                    r["paper"],
                    f"**{r['verdict']}** ({r['kind']}: {r['criterion']})",
                    ", ".join(r["experiments"]),
                    r["notes"],
                ]
                for r in rows
            ],
        ),  # fmt: skip
        "",
        "### Which change moves which verdict",
        "",
        *cause_lines(causes or []),
        "",
        "### §3.2: the growth runs (means over the analysed pads)",
        "",
        *md_table(*validation_area.growth_table(results)),
        "",
        "### §3.3: the LF states (means over the seeds' pads; equilibrium start)",
        "",
        *md_table(*validation_multiscale.state_table(results)),
        "",
        "### Experiments",
        "",
        *md_table(EXPERIMENT_HEADER, experiment_rows(results)),
        "",
        "Pads not used:",
        "",
        *pad_notes(results),
        "",
        "### Initial state: equilibrium + perturbation (hf1) against rest (hf1_rest)",
        "",
        *md_table(["measure", "hf1 (equilibrium)", "hf1_rest (rest)"], initial_state_rows(results)),
        "",
        "### §3.1: STFT maximum of μ/μ̄ over the saturated segment (Fig. 10's normalisation; the paper gives "
        "≈ 0.004 at 69.1 kHz for §3.2 only)",
        "",
        *stft_lines(results),
    ]
    return lines


def _header_lines(meta: dict[str, Any]) -> list[str]:
    """The opening of the generated page: the variant (quick or full), the command, machine, versions and wall
    time that produced it, and the settings of its runs."""
    cfg = meta["config"]
    variant = (
        "**QUICK variant (reduced CPU smoke check: small pads, short windows, few seeds, a coarser step) — not the "
        "validation itself.**"
        if cfg["quick"]
        else "Full variant."
    )
    dtp = cfg["sample_dt"] * cfg["decimation"]
    cut = cfg.get("state_patches") or cfg["patches"]
    return [
        variant,
        "",
        f"Produced by `{meta['command']}` on {meta['created']}, {meta['machine']}; "
        f"Warp {meta['versions'].get('warp-lang')}, aca-warp {meta['versions'].get('aca-warp')}; "
        f"wall time {meta['wall_s']:.0f} s (the experiments' runs and analyses, from their checkpoints: "
        f"{meta.get('experiments_s', 0.0):.0f} s).",
        "",
        f"Settings: {cfg['seeds']} seeds from {cfg['first_seed']}; {cfg['patches'] or 'the preset’s'} patches per pad; "
        f"strang, dt = {cfg['dt']:g} s, {cfg['precision']}; global outputs every {cfg['sample_dt']:g} s, per-patch "
        f"velocities every {dtp:g} s (Nyquist {0.5 / dtp / 1e3:.0f} kHz) over the last {cfg['window'] * 1e3:g} ms; "
        f"initial velocity perturbation {cfg['perturbation']:g} m/s; settling factor {cfg['settle_safety']:g}; "
        f"S(f) over {cfg['sync_band'][0] / 1e3:g}–{cfg['sync_band'][1] / 1e3:g} kHz. §3.2: the varying-area "
        f"growth compressed × {cfg['growth_speedup']:g} ({0.36 / cfg['growth_speedup'] * 1e3:g} ms; `va_full` at "
        f"the paper's 0.36 s only with --full-varying-area, and then the rows' source). §3.3: the LF "
        f"{'quick ' if cfg['quick'] else ''}schedule per seed on the CPU, every state "
        f"{f'cut to about {cut} patches' if cut else 'whole'}, a window of half the above.",
    ]


# ------------------------------------------------------------------------------------------------ command line


def build_parser() -> argparse.ArgumentParser:
    """The command line (``scripts/validation.py``)."""
    p = argparse.ArgumentParser(
        prog="validation.py",
        description="Seed ensembles of saturated HF runs against the paper's statements; writes everything under "
        "--out and, with --page, the generated table of a docs page.",
        epilog="Full variant (GPU): python3 scripts/validation.py --device cuda:0 --seeds 8 --out DIR --page "
        "docs/validation.md. Quick CPU smoke check: --quick. Checkpoints: each experiment's result is saved under "
        "DIR/<experiment>/ when done and reused by a rerun with the same settings (--rerun: run again).",
    )
    p.add_argument("--out", type=Path, default=Path("out/validation"), help="output folder (created)")
    p.add_argument("--page", type=Path, default=None, help="docs page whose generated section is rewritten")
    p.add_argument("--device", default="auto", help="Warp device: cpu, cuda:0, or auto (cuda:0 when present)")
    p.add_argument("--precision", choices=("fp64", "fp32"), default=None, help="precision (default fp64)")
    p.add_argument("--engine", choices=("auto", "general", "onchip"), default="auto", help="HF engine")
    p.add_argument("--quick", action="store_true", help="the reduced CPU variant (small pads, short windows)")
    p.add_argument("--seeds", type=int, default=None, help=f"pads per experiment ({FULL.seeds}; quick {QUICK.seeds})")
    p.add_argument("--first-seed", type=int, default=None, help="seed of pad 0 (1: the presets' layout)")
    p.add_argument("--patches", type=int, default=None, help=f"patches per pad (preset's; quick {QUICK.patches})")
    p.add_argument("--dt", type=float, default=None, help=f"time step [s] ({FULL.dt:g}; quick {QUICK.dt:g})")
    p.add_argument("--window", type=float, default=None, help=f"window [s] ({FULL.window:g}; quick {QUICK.window:g})")
    p.add_argument("--perturbation", type=float, default=None, help=f"initial velocity σ [m/s] ({FULL.perturbation:g})")
    p.add_argument("--settle-safety", type=float, default=None, help=f"factor on the predicted settling time "
                   f"({FULL.settle_safety:g})")  # fmt: skip
    p.add_argument("--only", nargs="+", default=None, metavar="EXPERIMENT", help="run only these experiments "
                   "(the table still uses the saved results of the others)")  # fmt: skip
    p.add_argument("--max-wall", type=float, default=None, help="wall-time budget [s]: an experiment whose estimate "
                   "no longer fits is not started")  # fmt: skip
    p.add_argument("--full-varying-area", action="store_true", help="also run va_full: the varying-area ensemble "
                   "at the paper's clock (0.36 s, 3.6e7 steps; about 140 s on an H100 for 8 pads)")  # fmt: skip
    p.add_argument("--growth-speedup", type=float, default=None, help=f"compression of the varying-area growth "
                   f"({FULL.growth_speedup:g}; quick {QUICK.growth_speedup:g})")  # fmt: skip
    p.add_argument("--state-patches", type=int, default=None, help=f"patches per LF state of the multi-timescale "
                   f"experiments (a sector; the whole state; quick {QUICK.state_patches})")  # fmt: skip
    p.add_argument("--workers", type=int, default=None, help="processes that analyse the pads of an experiment "
                   "(default: the CPU count less one, at most 8)")  # fmt: skip
    p.add_argument("--rerun", action="store_true", help="run again even where a saved result fits")
    p.add_argument("--keep-records", action="store_true", help="also keep each run's records (globals and per-patch "
                   "velocities, DIR/<experiment>/records.npz: the per-patch record's size per experiment)")  # fmt: skip
    p.add_argument("--reanalyse", action="store_true", help="analyse kept records again instead of reusing the "
                   "saved results (experiments without records are run)")  # fmt: skip
    p.add_argument("--list", action="store_true", help="list the experiments and rows, then exit")
    p.add_argument("--dry-run", action="store_true", help="plan the experiments (run lengths, steps, memory, the "
                   "time estimate for --device and --precision), then exit; runs nothing, needs no GPU")  # fmt: skip
    return p


COMPILE_S = 4.0  # s per experiment on CUDA: one on-chip module per tile shape (1.7–4.5 s, docs/benchmarks/onchip_h100)
LF_RUN_S = 11.0  # s per LF run of the full multiscale schedule on one CPU core (2-core AMD EPYC host; quick: 4 s)
ANALYSIS_S = 1.5  # s per analysed pad of 1758 patches × 6667 per-patch samples on one core of the same host


def dry_prepare(exp: Experiment, cfg: Config, log: Log) -> Prepared:
    """:func:`prepare` for the cost: an LF-state experiment is planned from the LF run of the first seed only
    (run here if missing; its states stand for every seed's)."""
    if exp.builder is not validation_multiscale.state_scene:
        return prepare(exp, cfg)
    one = dataclasses.replace(cfg, seeds=1)
    validation_multiscale.ensure_lf([exp.name], one, log)
    p = prepare(exp, one)
    rep = cfg.seeds
    return Prepared(
        exp, [s for s in p.scenes for _ in range(rep)], [c for c in p.contacts for _ in range(rep)],
        [s for s in p.sigma for _ in range(rep)], p.plan, [m for m in p.members for _ in range(rep)],
    )  # fmt: skip


def overheads(preps: dict[str, Prepared], cfg: Config, lf_runs: int) -> dict[str, float]:
    """Estimated wall seconds beside the stepping: kernel compilation (CUDA), LF runs and the pads' analysis
    (both spread over ``cfg.workers`` processes)."""
    pads = 0.0
    layouts = {
        (p.exp.kind == "growth", tuple((s.patches.count, round(float(s.patches.x.sum()), 12)) for s in p.scenes))
        for p in preps.values()
    }  # one on-chip module per layout of a batch (tile sizes); the cache serves the others
    for p in preps.values():
        if p.exp.kind == "growth":
            pads += 0.3 * len(p.scenes)
        else:
            pads += sum(s.patches.count for s in p.scenes) / 1758 * p.plan.patch_samples / 6667
    lf = LF_RUN_S * (4.0 / 11.0 if cfg.quick else 1.0)
    return {
        "compile": COMPILE_S * len(layouts) if cfg.device != "cpu" else 0.0,
        "lf": lf * math.ceil(lf_runs / max(cfg.workers, 1)) if lf_runs else 0.0,
        "analysis": ANALYSIS_S * pads / max(cfg.workers, 1),
    }


def dry_run(names: list[str], cfg: Config, log: Log) -> float:
    """Plan every experiment of ``names`` and print its run length, steps, memory and estimate; the total [s]
    of stepping and overheads."""
    total = 0.0
    preps: dict[str, Prepared] = {}
    lf_runs = len(validation_multiscale.lf_jobs(names, cfg))
    for name in names:
        prep = preps[name] = dry_prepare(EXPERIMENTS[name], cfg, log)
        est = prep.estimate(cfg, {})
        total += est
        p = prep.plan
        sig = np.median([np.percentile(s, [0, 50, 100]) for s in prep.sigma], axis=0)
        sizes = sorted({s.patches.count for s in prep.scenes})
        log(
            f"{name}: {len(prep.scenes)} pads × {'/'.join(map(str, sizes))} patches; {prep.exp.kind}; σ_i "
            f"min/median/max {sig[0]:.0f}/{sig[1]:.0f}/{sig[2]:.0f} 1/s, σ_25 {p.sigma_q25:.0f} 1/s; v0 {p.v0:.3g} "
            f"m/s; run {p.duration * 1e3:.1f} ms (settle {p.settle * 1e3:.1f}); {p.steps:,} steps; per-patch record "
            f"{p.velocity_bytes / 2**20:.0f} MiB; estimated {est:.0f} s on {cfg.device} ({cfg.precision})"
        )
    extra = overheads(preps, cfg, lf_runs)
    log(f"total: estimated {total:.0f} s of stepping ({total / 60:.1f} min) for {len(names)} experiment(s)")
    log(
        f"beside it (estimates): kernel compilation {extra['compile']:.0f} s, {lf_runs} LF run(s) "
        f"{extra['lf']:.0f} s, analysis {extra['analysis']:.0f} s with {cfg.workers} worker(s); in all "
        f"{total + sum(extra.values()):.0f} s ({(total + sum(extra.values())) / 60:.1f} min)"
    )
    return total + sum(extra.values())


def default_workers() -> int:
    """Analysis processes by default: the CPU count less one (the run loop's), at most 8."""
    import os

    return max(1, min(8, (os.cpu_count() or 1) - 1))


def default_experiments(quick: bool, full_varying_area: bool = False) -> list[str]:
    """The experiments a run without --only runs: every registered one except the opt-in ones (unless switched
    on: ``va_full`` with ``full_varying_area``) and, in the quick variant, those marked full-variant only."""
    out = []
    for name, exp in EXPERIMENTS.items():
        if exp.opt_in and not (full_varying_area and name == "va_full"):
            continue  # va_full, hf3_equal, hf4_equal: --only NAME
        if quick and not exp.quick:
            continue
        out.append(name)
    return out


def config_from(args: argparse.Namespace, device: str) -> Config:
    """The settings: the quick or the full defaults, with the options given."""
    base = QUICK if args.quick else FULL
    over = {
        "seeds": args.seeds,
        "first_seed": args.first_seed,
        "patches": args.patches,
        "dt": args.dt,
        "window": args.window,
        "perturbation": args.perturbation,
        "settle_safety": args.settle_safety,
        "precision": args.precision,
        "growth_speedup": args.growth_speedup,
        "state_patches": args.state_patches,
        "workers": args.workers if args.workers is not None else default_workers(),
    }
    return dataclasses.replace(
        base, device=device, engine=args.engine, **{k: v for k, v in over.items() if v is not None}
    )


def _list(log: Log) -> None:
    for name, exp in EXPERIMENTS.items():
        print(f"experiment {name:12} {exp.section:6} {exp.description}")
    for row in ROWS:
        print(f"row {row.section:16} {row.statement}  [{', '.join(row.experiments)}]")


def run_all(names: list[str], cfg: Config, out: Path, log: Log, args: argparse.Namespace) -> dict:
    """Reuse, analyse again or run every experiment of ``names`` (estimates first); failures are logged and
    recorded (``args``: rerun, reanalyse, keep_records, max_wall)."""
    results: dict[str, dict] = {}
    preps: dict[str, Prepared] = {}
    calibration: dict[str, float] = {}
    todo = []
    for name in names:
        saved = None if args.rerun or args.reanalyse else load_result(out / name, EXPERIMENTS[name], cfg)
        if saved is not None:
            results[name] = saved
            log(f"{name}: reusing the saved result in {out / name}")
        else:
            todo.append(name)
    try:
        validation_multiscale.ensure_lf(todo, cfg, log)
    except Exception as e:  # noqa: BLE001 (the experiments that need the LF runs fail below, the others go on)
        log(f"LF runs: FAILED: {type(e).__name__}: {e}")
    for name in todo:
        exp = EXPERIMENTS[name]
        try:
            prep = prepare(exp, cfg)
            again = reanalyse(prep, cfg, out, log) if args.reanalyse else None
            if again is not None:
                results[name] = again
            else:
                preps[name] = prep
        except Exception as e:  # noqa: BLE001 (one experiment must not stop the others)
            results[name] = _failed(out, name, e, log)
    total = sum(p.estimate(cfg, calibration) for p in preps.values())
    steps = sum(p.plan.steps for p in preps.values())
    log(f"{len(preps)} experiment(s) to run: {steps:,} steps, estimated {total:.0f} s of stepping on {cfg.device}")
    for name, prep in preps.items():
        budget = None if args.max_wall is None else args.max_wall - log.elapsed()
        try:
            results[name] = run_experiment(prep, cfg, out, log, calibration, budget, args.keep_records)
        except Exception as e:  # noqa: BLE001
            results[name] = _failed(out, name, e, log)
    return results


def _failed(out: Path, name: str, e: Exception, log: Log) -> dict[str, Any]:
    import traceback

    (out / name).mkdir(parents=True, exist_ok=True)
    (out / name / "error.txt").write_text(traceback.format_exc())
    log(f"{name}: FAILED: {type(e).__name__}: {e} (traceback in {out / name / 'error.txt'})")
    return {"status": f"failed: {type(e).__name__}: {e}", "pads": []}


def main(argv: list[str] | None = None) -> int:
    """Run the selected experiments, build the table, write ``--out`` and ``--page``; 0 unless the input is bad."""
    from aca_warp.common.files import machine, versions
    from aca_warp.studies.report import init_warp, write_json

    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)
    log = Log()
    if args.list:
        _list(log)
        return 0
    names = args.only or default_experiments(args.quick, args.full_varying_area)
    unknown = [n for n in names if n not in EXPERIMENTS]
    if unknown:
        print(f"validation.py: unknown experiment(s) {', '.join(unknown)}; see --list", file=sys.stderr)
        return 2
    if args.dry_run:
        cfg = config_from(args, "cpu" if args.device == "auto" else args.device)
        dry_run(names, dataclasses.replace(cfg, lf_dir=str(args.out / "lf")), log)
        return 0
    wp = init_warp()
    device = ("cuda:0" if wp.is_cuda_available() else "cpu") if args.device == "auto" else args.device
    cfg = dataclasses.replace(config_from(args, device), lf_dir=str(args.out / "lf"))
    args.out.mkdir(parents=True, exist_ok=True)
    log(f"validation ({'quick' if cfg.quick else 'full'}): {', '.join(names)} on {device} -> {args.out}")
    results = run_all(names, cfg, args.out, log, args)
    for name, exp in EXPERIMENTS.items():  # the table uses every saved result that fits these settings
        if name not in results:
            saved = load_result(args.out / name, exp, cfg)
            if saved is not None:
                results[name] = saved
    view, aliases = validation_area.full_view(results)
    rows = evaluate_rows(view, cfg)
    for r in rows:
        r["experiments"] = [aliases.get(n, n) for n in r["experiments"]]
    causes = validation_causes.evaluate_causes(view, cfg, rows)
    meta = {
        "command": command_line("validation.py", argv),
        "created": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": machine(wp.get_device(device))["device_name"],
        "versions": versions(),
        "config": cfg.run_key(),
        "wall_s": log.elapsed(),
        "experiments_s": sum((r.get("total_s") or 0.0) + (r.get("analysis_s") or 0.0) for r in results.values()),
    }
    body = render(results, rows, meta, causes)
    (args.out / "validation.md").write_text("# Validation\n\n" + "\n".join(body) + "\n")
    write_json(args.out / "validation.json", clean({"meta": meta, "rows": rows, "causes": causes}), indent=1)
    if args.page is not None:
        replace_generated(args.page, body, generated_markers(MARKER), "Validation")
    for r in rows:
        print(f"  {r['verdict']:15} {r['statement']}")
    log(f"wrote {args.out / 'validation.md'}" + (f" and {args.page}" if args.page else ""))
    close_pools()
    return 0


if __name__ == "__main__":
    sys.exit(main())
