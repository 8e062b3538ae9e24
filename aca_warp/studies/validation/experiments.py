"""Running an experiment (stages 3, 4 and 6 of :mod:`aca_warp.studies.validation`): its preparation (scenes,
host contact solves, predicted growth rates, plan), the run through the one run loop with a sink that keeps the
records, the saturation of every pad, the analysis of the common segment, and the checkpoints (``result.json``,
``arrays.npz``) that a rerun with the same settings reuses.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.studies.report import Log, clean
from aca_warp.studies.validation.base import USABLE, Config, Experiment, map_pads, pad_member
from aca_warp.studies.validation.measures import pad_measures
from aca_warp.studies.validation.plan import Plan, experiment_scene, plan_run, predicted_sigma, step_seconds

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
    """Run, analyse and save one prepared experiment (package docstring); returns its result dict.

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
        from aca_warp.studies.validation.area import analyse_growth

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
