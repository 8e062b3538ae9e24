"""Saturated statistics of the friction-step study (:mod:`aca_warp.studies.friction_study`): scenes, the package's
``strang`` reference runs and the statistics of a record.

Scenes: hf1 sectors as the validation ensembles use them (``aca_warp.studies.validation.experiment_scene`` with
``patches`` patches: the preset's density and pressure on a sector, seed k for pad k, equilibrium + N(0, (0.01
m/s)²) velocities). Statistics over the last ``window`` of a record, per pad: mean and standard deviation of μ, the
mean of Σ|u̇|, the frequency of the largest peak of the Σu̇ spectrum, and from per-patch velocities the share of
patch-samples on the static branch of Eq. 4 and the Synchronization Index S(f); per ensemble: the mean-normalised μ
spectrum, the Σu̇ amplitude spectrum and the patches' mean velocity spectrum, averaged over the pads in bands and
compared by the rms of log10 of their ratio.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.analysis.spectra import amplitude_spectrum, peak
from aca_warp.studies.friction_schemes import Record

SAMPLE_DT = 1.0e-6  # s
BAND = (1.0e3, 200.0e3)  # Hz, spectra compared and peaks searched in this band
BAND_WIDTH = 2.0e3  # Hz, spectra averaged over bands of this width before they are compared
TWIN_SEED = 1000  # the twin reference draws its initial velocities with seed + this (same patch layout)
SYNC_BAND = (1.0e3, 150.0e3)  # Hz, the Synchronization Index's band (the validation's sync_band)
PEAK_FMIN = 20.0e3  # Hz, the velocity-sum peak is searched above this (below it the slow drift of Σu̇)


def sector_scenes(
    seeds: int, patches: int | None, first_seed: int = 1, preset: str = "hf1", speed: float | None = None
) -> list[Any]:
    """``seeds`` pads of the validation experiment ``preset`` (seeds first_seed …), on a sector of ``patches``
    patches (None: the whole pad), from equilibrium + 0.01 m/s velocities; ``speed``: the disc speed at the mean
    radius [m/s] instead of the preset's (the equilibrium is then that of this speed)."""
    from aca_warp.studies.validation.base import EXPERIMENTS, Config
    from aca_warp.studies.validation.plan import experiment_scene

    cfg = Config(patches=patches, first_seed=first_seed)
    scenes = [experiment_scene(EXPERIMENTS[preset], k, cfg) for k in range(seeds)]
    if speed is None:
        return scenes
    return [s.replace(name=f"{s.name}_{speed:g}mps", angular_velocity=speed / s.pad.mean_radius) for s in scenes]


def twin_scenes(scenes: list[Any]) -> list[Any]:
    """The scenes with their initial velocities drawn from seed + TWIN_SEED: the same pads (layouts, loads), another
    start from the same distribution, so another exact trajectory of the same saturated state."""
    import dataclasses

    return [s.replace(initial=dataclasses.replace(s.initial, seed=s.initial.seed + TWIN_SEED)) for s in scenes]


def reference_run(
    scenes: list[Any], dt: float, duration: float, window: float, *, cache: Path | None, log: Any = print
) -> tuple[Record, dict[str, Any]]:
    """The package's ``strang`` (fp64, general engine on the CPU) at the fixed step ``dt`` [s] over ``duration``
    [s], samples every SAMPLE_DT, per-patch velocities over the last ``window`` [s]. Cached as ``cache`` (npz)."""
    key = {"scenes": [s.name for s in scenes], "seeds": [s.initial.seed for s in scenes], "dt": dt}
    key |= {"duration": duration, "window": window}
    if cache is not None and cache.exists():
        d = np.load(cache, allow_pickle=False)
        if json.loads(str(d["key"])) == key:
            log(f"reference from {cache}")
            rec = Record(d["time"], d["mu"], d["sum_velocity"], d["sum_abs_velocity"], d["velocity"], int(d["first"]))
            return rec, json.loads(str(d["info"]))
    log(f"package strang at {dt:g} s over {duration * 1e3:g} ms, {len(scenes)} pads (seeds {key['seeds']})")
    rec, info = package_run(scenes, "strang", duration, window, dt=dt)
    info["seeds"] = key["seeds"]
    if cache is not None:
        cache.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(
            cache, key=json.dumps(key), info=json.dumps(info), time=rec.time, mu=rec.mu,
            sum_velocity=rec.sum_velocity, sum_abs_velocity=rec.sum_abs_velocity, velocity=rec.velocity,
            first=rec.patch_first,
        )  # fmt: skip
    return rec, info


def package_run(
    scenes: list[Any],
    integrator: str,
    duration: float,
    window: float,
    *,
    dt: float | None = None,
    tolerance: float | None = None,
    split_tolerance: float | None = None,
    precision: str = "fp64",
    engine: str = "general",
) -> tuple[Record, dict[str, Any]]:
    """A run of the package (on ``engine``, on the CPU) of ``scenes`` as one batch with ``integrator`` at step
    ``dt`` [s] (forced past the stable-step estimate) or ``tolerance``/``split_tolerance`` (None: the defaults)
    over ``duration`` [s]:
    samples every SAMPLE_DT, per-patch velocities over the last ``window`` [s] (0: none). Returns the record and
    {wall_s (stepping), steps, dt, integrator}."""
    from aca_warp.scene import Record as SceneRecord
    from aca_warp.studies.runs import batch_at_start, run_engine

    model, state = batch_at_start(scenes, "cpu", precision)
    patches = ("velocity",) if window > 0 else ()
    record = SceneRecord(SAMPLE_DT, patches=patches, window=(duration - window - 0.5 * SAMPLE_DT, math.inf))
    res = run_engine(
        model, state, engine=engine, duration=duration, integrator=integrator, dt=dt, record=record,
        force=dt is not None, tolerance=tolerance, split_tolerance=split_tolerance,
    )  # fmt: skip
    if not res.complete:
        raise RuntimeError(f"{integrator} run stopped: {res.fault}")
    g = res.collect()
    first = len(g.time) - len(g.patch_time)
    velocity = g.velocity.astype(np.float64) if window > 0 else None
    sums = (g.globals[:, :, j].astype(np.float64) for j in (0, 3, 4))
    rec = Record(g.time.astype(np.float64), *sums, velocity, first)
    info = {"wall_s": res.wall_time, "steps": res.steps, "dt": dt, "integrator": integrator}
    return rec, info


def _bands(f: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Amplitudes a (F, P) averaged over BAND_WIDTH bands of BAND, (B, P)."""
    edges = np.arange(BAND[0], BAND[1] + 0.5 * BAND_WIDTH, BAND_WIDTH)
    return np.stack([a[(f >= lo) & (f < hi)].mean(axis=0) for lo, hi in zip(edges[:-1], edges[1:], strict=True)])


def statistics(rec: Record, window: float, vd: np.ndarray, start: np.ndarray) -> dict[str, Any]:
    """Statistics of the last ``window`` [s] of a record, per pad (lists over the pads) and the band spectra; with
    per-patch velocities also the sticking share, the patches' mean velocity spectrum and the Synchronization Index
    S(f). ``vd``: disc speed at every patch [m/s] (n,); ``start``: the pads' patch offsets (P + 1,)."""
    from aca_warp.analysis.sync import sync_index_from_signals
    from aca_warp.studies.friction_schemes import STATIC_SLIP

    n = round(window / SAMPLE_DT)
    mu, vs, va = rec.mu[-n:], rec.sum_velocity[-n:], rec.sum_abs_velocity[-n:]
    if not (np.all(np.isfinite(mu)) and np.all(np.isfinite(vs))):
        return {"finite": False}
    fm, am = amplitude_spectrum(mu, SAMPLE_DT, normalise="mean", axis=0)
    fv, av = amplitude_spectrum(vs - vs.mean(axis=0), SAMPLE_DT, normalise=None, axis=0)
    peaks = [peak(fv, av[:, p], fmin=PEAK_FMIN, fmax=BAND[1])[0] for p in range(mu.shape[1])]
    out = {
        "finite": True,
        "mu_mean": mu.mean(axis=0),
        "mu_std": mu.std(axis=0),
        "abs_velocity_mean": va.mean(axis=0),
        "velocity_peak_hz": np.array(peaks),
        "ensemble_velocity_peak_hz": peak(fv, av.mean(axis=1), fmin=PEAK_FMIN, fmax=BAND[1])[0],
        "mu_bands": _bands(fm, am).mean(axis=1),
        "velocity_bands": _bands(fv, av).mean(axis=1),
    }
    if rec.velocity is None:
        return out
    v = rec.velocity[-n:]
    if not np.all(np.isfinite(v)):
        return {"finite": False}
    stick, bands, sync = [], [], []
    for a, b in zip(start[:-1], start[1:], strict=True):
        vp = v[:, a:b]
        stick.append(float((np.abs(vd[a:b] - vp) < STATIC_SLIP).mean()))
        fp, ap = amplitude_spectrum(vp - vp.mean(axis=0), SAMPLE_DT, normalise=None, axis=0)
        bands.append(_bands(fp, ap.mean(axis=1)[:, None])[:, 0])
        r = sync_index_from_signals(vp.astype(np.float32), SAMPLE_DT, freq_range=SYNC_BAND, null_trials=0, workers=1)
        sync.append(np.asarray(r.S, dtype=np.float64))
    out |= {"stick_share": np.array(stick), "patch_bands": np.mean(bands, axis=0), "sync": np.array(sync)}
    return out


PER_PAD = ("mu_mean", "mu_std", "abs_velocity_mean", "velocity_peak_hz")


def compare(s: dict[str, Any], ref: dict[str, Any]) -> dict[str, Any]:
    """Errors of the statistics ``s`` against ``ref``: for each per-pad measure the relative error of the ensemble
    mean and the largest relative error of one pad; the ensemble velocity-sum peak; rms of log10 of the band
    spectra's ratio."""
    if not s.get("finite", False):
        return {"finite": False}
    out: dict[str, Any] = {"finite": True}
    for k in PER_PAD:
        a, b = np.asarray(s[k]), np.asarray(ref[k])
        out[k] = float(a.mean() / b.mean() - 1.0)
        out[k + "_pad_max"] = float(np.max(np.abs(a / b - 1.0)))
    out["ensemble_velocity_peak_hz"] = float(s["ensemble_velocity_peak_hz"] / ref["ensemble_velocity_peak_hz"] - 1.0)
    for k in ("mu_bands", "velocity_bands", "patch_bands"):
        if k in s and k in ref:
            r = np.log10(np.asarray(s[k]) / np.asarray(ref[k]))
            out[k] = float(np.sqrt(np.mean(r * r)))
    if "stick_share" in s and "stick_share" in ref:
        share = float(np.mean(ref["stick_share"]))  # 0 before any patch reaches the static branch
        out["stick_share"] = float(np.mean(s["stick_share"]) / share - 1.0) if share > 0 else math.nan
        a, b = np.asarray(s["sync"], dtype=float), np.asarray(ref["sync"], dtype=float)
        both = np.isfinite(a) & np.isfinite(b)
        out["sync"] = float(np.mean(np.abs(a - b)[both])) if both.any() else math.nan
    return out


def seed_spread(ref: dict[str, Any]) -> dict[str, float]:
    """Relative standard deviation between the pads (seeds) of each per-pad measure of ``ref``, and the 95 %
    half-width of the ensemble mean relative to it (Student t)."""
    from scipy.stats import t as student

    out = {}
    for k in PER_PAD:
        a = np.asarray(ref[k])
        rel = float(a.std(ddof=1) / a.mean()) if len(a) > 1 else float("nan")
        out[k] = rel
        out[k + "_ci95"] = float(student.ppf(0.975, len(a) - 1) * rel / np.sqrt(len(a))) if len(a) > 1 else rel
    return out
