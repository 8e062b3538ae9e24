"""The analysis of one experiment's records (stage 5 of :mod:`aca_warp.studies.validation`): the saturation of every
pad, the common segment, the measures of each usable pad and, for a tracked run, the measures of every track window.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aca_warp.studies.validation.base import USABLE, Config, map_pads

REST_GROWTH_R2 = 0.9
"""Least R² of the Σ|u̇| growth fit of a pad released from rest, in an experiment analysed once saturated, that
counts as exponential growth: hf1, hf3 and hf4 from rest fit at 0.977 and above; HF2's release transient (a few
windows) followed by a slow drift fits at 0.04-0.29 over the paper's length, and its σ of a few 1/s would hold the
settled windows to a slope no fluctuation keeps. The linear phases (kind "window") keep every fit: their growth
rate is a measure."""


def growth_r2_floor(exp: Any) -> float:
    """``min_growth_r2`` of the pads of experiment ``exp``: ``REST_GROWTH_R2`` from rest in an experiment analysed
    once saturated, 0 (every fit) otherwise."""
    return REST_GROWTH_R2 if exp.initial == "rest" and exp.kind != "window" else 0.0


def pad_saturation(
    time: np.ndarray,
    glob: np.ndarray,
    window_end: float,
    window: float,
    from_rest: bool = False,
    min_growth_r2: float = 0.0,
) -> dict[str, Any]:
    """Saturation of one pad (``record_saturation``: Σ|u̇| by window means, μ by standard deviations over N/64
    windows) as plain figures. ``status``: "saturated" (Σ|u̇| grows, then settles early enough: the analysed part
    starts at least half a window before ``window_end``), "not saturated", "no growth phase" (settled without
    growing: not the instability's saturated state) or "saturated too late".

    A pad released from rest (``from_rest``) starts at an amplitude near its saturated one (every patch released
    into the full friction force), so its Σ|u̇| need not rise by the e-fold of a growth phase: it counts as
    saturated once Σ|u̇| (and μ, where it settles) have settled. A rise of Σ|u̇| whose fit is not exponential (R²
    below ``min_growth_r2``; ``REST_GROWTH_R2`` for such pads of an experiment analysed once saturated) is such a
    release, not a growth phase.
    """
    from aca_warp.analysis.saturation import record_saturation

    out = record_saturation(time, glob[:, 0], glob[:, 4], min_growth_r2).figures()
    if from_rest and out["status"] == "no growth phase":
        ts = out["t_s_sum_abs_velocity"]
        out.update(status="saturated", t_start=max(ts, out["t_s_mu"]) if out["mu_saturated"] else ts)
    if out["status"] == "saturated" and out["t_start"] > window_end - 0.5 * window:
        out["status"] = "saturated too late"
    return out


def analysis_segment(sat: list[dict[str, Any]], patch_time: np.ndarray, window_start: float) -> int | None:
    """First per-patch sample of the common analysis segment: the latest saturated start of the usable pads, no
    earlier than the final window's start; None when no pad is usable."""
    starts = [s["t_start"] for s in sat if s["status"] == "saturated"]
    if not starts or patch_time.size == 0:
        return None
    return int(np.searchsorted(patch_time, max(*starts, window_start) - 1e-12))


def _geometry(scene: Any) -> dict[str, np.ndarray]:
    p = scene.patches
    return {"x": p.x, "y": p.y, "r": p.friction_radius}


def analyse_batch(
    prep: Any, time: np.ndarray, glob: np.ndarray, ptime: np.ndarray, vel: np.ndarray, cfg: Config
) -> tuple[list[dict[str, Any]], dict[str, np.ndarray], dict[str, Any]]:
    """Saturation of every pad of the prepared experiment ``prep``, the common segment, the measures of each
    usable pad and its track windows.

    Kind "saturated": the segment starts at the latest saturated start of the usable pads (within the final
    per-patch window), the others are not analysed; a pad started from rest counts without a growth phase
    (``pad_saturation``). "window": every pad is analysed over the whole per-patch record, saturated or not (status
    "linear phase"; the detector's verdict is kept as ``detector_status``). Each pad's global measures use its own
    saturated span (from its saturated start to the end). Pads are analysed in ``cfg.workers`` processes.
    Returns (pads, arrays, segment): one dict per pad (seed, member, status, saturation figures, measures, tracks),
    the arrays for ``arrays.npz`` (stacked over the analysed pads, their indices in "pad"), and the segment's
    start, length and resolution.
    """
    scenes, plan, kind = prep.scenes, prep.plan, prep.exp.kind
    window = plan.patch_samples * cfg.sample_dt * cfg.decimation
    rest = prep.exp.initial == "rest"
    r2 = growth_r2_floor(prep.exp)
    sat = [pad_saturation(time, glob[:, p], plan.duration, window, rest, r2) for p in range(len(scenes))]
    final = ptime >= plan.window_start - 1e-12
    if kind == "window":
        for s in sat:
            s.update(detector_status=s["status"], status="linear phase", t_start=plan.window_start)
        k0 = int(np.argmax(final)) if final.any() else None
    else:
        k0 = analysis_segment(sat, ptime, plan.window_start)
    pads: list[dict[str, Any]] = []
    segment: dict[str, Any] = {"start_s": None, "samples": 0}
    jobs: list[tuple[int, tuple]] = []
    start = np.concatenate([[0], np.cumsum([s.patches.count for s in scenes])])
    if k0 is not None:
        m = ptime.size - k0 - 1  # one short: the global segment (m·decimation samples) must end inside the record
        j0 = int(np.searchsorted(time, ptime[k0] - 0.5 * cfg.sample_dt))
        segment = {"start_s": float(ptime[k0]), "samples": m, "seconds": m * cfg.sample_dt * cfg.decimation}
        segment["resolution_hz"] = 1.0 / segment["seconds"]
    for p, s in enumerate(scenes):
        a, b = int(start[p]), int(start[p + 1])
        entry: dict[str, Any] = {"seed": s.initial.seed, "patches": b - a, **sat[p]}
        if prep.members[p] is not None:
            entry["member"] = prep.members[p]
        pads.append(entry)
        if sat[p]["status"] in USABLE and k0 is not None:
            ks = int(np.searchsorted(time, sat[p]["t_start"] - 0.5 * cfg.sample_dt))
            gsat = glob[min(ks, j0) :, p]
            gseg = glob[j0 : j0 + m * cfg.decimation, p]
            jobs.append((p, (gsat, gseg, vel[k0 : k0 + m, a:b], _geometry(s), cfg)))
    arrays: dict[str, list] = {}
    for (p, _), (scal, arr) in zip(jobs, map_pads(_pad_job, [j for _, j in jobs], cfg.workers), strict=True):
        if isinstance(scal, str):  # the pad is reported, never silently used
            pads[p]["status"] = f"analysis failed: {scal}"
            continue
        pads[p]["measures"] = scal
        for k, v in arr.items():
            arrays.setdefault(k, []).append(v)
        arrays.setdefault("pad", []).append(p)
    if plan.tracks:
        for p, tracks in enumerate(analyse_tracks(prep, time, glob, ptime, vel, cfg)):
            pads[p]["tracks"] = tracks
    return pads, {k: np.asarray(v) for k, v in arrays.items()}, segment


def analyse_tracks(
    prep: Any, time: np.ndarray, glob: np.ndarray, ptime: np.ndarray, vel: np.ndarray, cfg: Config
) -> list[list[dict[str, Any]]]:
    """Per pad, the compact measures (``track_measures``) of every track window of the plan (and of the final
    window), each with its start and end [s]; a window whose analysis fails says why."""
    start = np.concatenate([[0], np.cumsum([s.patches.count for s in prep.scenes])])
    windows = [*prep.plan.tracks, (prep.plan.window_start, prep.plan.duration)]
    jobs, where = [], []
    for p, s in enumerate(prep.scenes):
        for a, b in windows:
            rows = np.flatnonzero((ptime >= a - 1e-12) & (ptime <= b + 1e-12))
            if rows.size < 16:
                continue
            g0 = int(np.searchsorted(time, ptime[rows[0]] - 0.5 * cfg.sample_dt))
            n = (rows.size - 1) * cfg.decimation
            vw = vel[rows[0] : rows[-1], int(start[p]) : int(start[p + 1])]
            jobs.append((glob[g0 : g0 + n, p], vw, _geometry(s), cfg))
            where.append((p, a, b))
    out: list[list[dict[str, Any]]] = [[] for _ in prep.scenes]
    for (p, a, b), m in zip(where, map_pads(_track_job, jobs, cfg.workers), strict=True):
        out[p].append({"start_s": a, "end_s": b, **m})
    return out


def pad_measures(
    gsat: np.ndarray, gseg: np.ndarray, vseg: np.ndarray, geometry: dict[str, np.ndarray], cfg: Config
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Every measure of one saturated pad.

    Args:
        gsat: Global outputs over the pad's own saturated span, shape (N, 6), every ``cfg.sample_dt``.
        gseg: Global outputs over the experiment's common per-patch segment, shape (decimation·M, 6).
        vseg: Patch velocities over that segment, shape (M, n) float32, every ``cfg.sample_dt·decimation``.
        geometry: Patch centres "x", "y" and friction radii "r" [m], each (n,).
        cfg: Settings.

    Returns:
        (scalars, arrays): JSON-ready numbers, and the spectra and S(f) for the arrays file.
    """
    from aca_warp.studies.validation.measures import global_measures
    from aca_warp.studies.validation.sync_measures import patch_measures

    out = global_measures(gsat, cfg)
    scalars, arrays = patch_measures(gseg, vseg, geometry, out["f1"], cfg)
    out.update(scalars)
    return out, arrays


def _pad_job(args: tuple) -> tuple[Any, Any]:
    """:func:`pad_measures` of one pad; ("ErrorType: message", None) when its analysis fails."""
    try:
        return pad_measures(*args)
    except (ValueError, FloatingPointError, IndexError) as e:
        return f"{type(e).__name__}: {e}", None


def _track_job(args: tuple) -> dict[str, Any]:
    """``track_measures`` of one window; {"failed": "ErrorType: message"} when it fails."""
    from aca_warp.studies.validation.sync_measures import track_measures

    try:
        return track_measures(*args)
    except (ValueError, FloatingPointError, IndexError) as e:
        return {"failed": f"{type(e).__name__}: {e}"}
