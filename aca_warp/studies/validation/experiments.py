"""Running experiments (stages 3, 4 and 6 of :mod:`aca_warp.studies.validation`): their preparation (scenes, host
contact solves, predicted growth rates, plan), batches of experiments run as one, the run in segments through the
one run loop with a sink that keeps the records, the saturation of every pad, the analysis of the common segment
(and of the track windows), and the checkpoints (``result.json``, ``arrays.npz``) that a rerun with the same
settings reuses.
"""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.studies.report import Log, clean
from aca_warp.studies.validation.base import USABLE, Config, Experiment, pad_member, same_settings
from aca_warp.studies.validation.plan import Plan, experiment_scene, plan_run, predicted_sigma

# ------------------------------------------------------------------------------------------------ running


class Collector:
    """Sink of the run loop over the segments of a run: keeps the global outputs (float64) and the per-patch
    velocities (float32) with times from the run's start (:meth:`segment` sets the offset of the next segment)."""

    def __init__(self) -> None:
        self.time: list[np.ndarray] = []
        self.globals: list[np.ndarray] = []
        self.patch_time: list[np.ndarray] = []
        self.velocity: list[np.ndarray] = []
        self.offset = 0.0
        self.skip = 0

    def segment(self, start: float) -> None:
        """The next chunks belong to a segment starting at ``start`` [s]; its first global sample repeats the last
        one of the segment before (every run records its start) and is dropped."""
        self.offset, self.skip = start, int(bool(self.time))

    def __call__(self, chunk: Any) -> None:
        k, self.skip = self.skip, 0 if len(chunk.time) else self.skip
        self.time.append(chunk.time[k:] + self.offset)
        self.globals.append(np.asarray(chunk.globals[k:], dtype=np.float64))
        if chunk.velocity is not None and len(chunk.patch_time):
            self.patch_time.append(chunk.patch_time + self.offset)
            self.velocity.append(np.asarray(chunk.velocity, dtype=np.float32))

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(time (N,), globals (N, pads, 6), patch time (M,), velocity (M, patches))."""

        def cat(parts: list[np.ndarray], empty: tuple[int, ...]) -> np.ndarray:
            return np.concatenate(parts) if parts else np.zeros(empty)

        v = cat(self.velocity, (0, 0)).astype(np.float32, copy=False)
        self.velocity.clear()
        return cat(self.time, (0,)), cat(self.globals, (0, 0, 6)), cat(self.patch_time, (0,)), v


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

    def replanned(self, duration: float, cfg: Config) -> Prepared:
        """The same experiment planned for ``duration`` [s] (the length of the batch it runs in)."""
        plan = plan_run(self.exp, self.scenes, self.contacts, self.sigma, cfg, self.members, duration=duration)
        return dataclasses.replace(self, plan=plan)


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


@dataclass
class Batch:
    """Experiments run as one batch of pads: one model, one run as long as the longest member's plan (each member
    replanned to it) at the fixed step of the members' stepping; each member is analysed and saved on its own."""

    name: str
    members: list[Prepared]

    @property
    def scenes(self) -> list[Any]:
        return [s for p in self.members for s in p.scenes]

    @property
    def plan(self) -> Plan:
        """The run's plan (every member's covers the same run; the segments are the union of the members')."""
        return self.members[0].plan

    @property
    def stepping_kind(self) -> str:
        return self.members[0].exp.stepping

    @property
    def growth(self) -> bool:
        return self.members[0].exp.kind == "growth"


def make_batch(name: str, preps: list[Prepared], cfg: Config) -> Batch:
    """The batch of ``preps``: every member replanned to the longest duration. Members must share their kind,
    stepping and per-patch windows, and a growing batch runs as one segment, since each run counts its growth
    events from its start (ValueError otherwise: a batch is one run)."""
    if len({(p.exp.kind, p.exp.stepping, p.exp.tracks, p.exp.window_scale) for p in preps}) > 1:
        raise ValueError(f"batch {name}: its experiments differ in kind, stepping, tracks or window")
    duration = max(p.plan.duration for p in preps)
    members = [p if p.plan.duration == duration else p.replanned(duration, cfg) for p in preps]
    batch = Batch(name, members)
    if batch.growth and len(batch.plan.segments) != 1:
        raise ValueError(f"batch {name}: a growing batch runs as one segment, planned {len(batch.plan.segments)}")
    return batch


def run_segments(
    model: Any, state: Any, plan: Plan, cfg: Config, step: Any, dt: float, sink: Collector,
    probe: Any = None,
) -> tuple[Any, list[Any]]:  # fmt: skip
    """Step ``model`` from ``state`` through the plan's segments (``run_engine`` per segment, per-patch velocities
    recorded where the segment says), every chunk to ``sink``. ``probe(result) -> bool``, called after the first
    segment when others follow, may stop the run (False). Returns (the last segment's result, every segment's
    result). Each segment starts its integrator afresh, so the segments are part of the arithmetic: the same plan
    gives the same numbers, another cut of it numbers that differ in the last bits (and then, in stick-slip, in
    every measure)."""
    from aca_warp.scene import Record
    from aca_warp.studies.runs import run_engine

    results = []
    for k, (a, b, patches) in enumerate(plan.segments):
        record = Record(
            sample_dt=cfg.sample_dt, patches=("velocity",) if patches else (), decimation=cfg.decimation
        )  # fmt: skip
        sink.segment(a)
        res = run_engine(
            model, state, engine=cfg.engine, duration=b - a, integrator=step.integrator, dt=dt, record=record,
            sink=sink, force=step.force, growth_dt=step.growth_dt,
        )  # fmt: skip
        results.append(res)
        if not res.complete or (probe is not None and k == 0 and k + 1 < len(plan.segments) and not probe(res)):
            break
    return results[-1], results


def warm_up(model: Any, cfg: Config, step: Any, dt: float) -> float:
    """Run ``model`` for one sample interval from a spare initial state, discarded, and return the wall time [s]: a
    batch's first launches carry one-off costs (on an H200 the first 5000 steps of 88 full pads took 2.18 s, about
    50 times their steady cost), which would otherwise enter the probe of its step time. The batch's own state, and
    so every number of its run, is left as it is (a run writes its state and its recorder, not the model; a growing
    batch, whose events write the model, is not warmed up)."""
    from aca_warp.hf.state import initial_state
    from aca_warp.scene import Record
    from aca_warp.studies.runs import run_engine

    t0 = time.perf_counter()
    run_engine(
        model, initial_state(model), engine=cfg.engine, duration=cfg.sample_dt, integrator=step.integrator, dt=dt,
        record=Record(sample_dt=cfg.sample_dt), sink=lambda chunk: None, force=step.force,
    )  # fmt: skip
    return time.perf_counter() - t0


def split_segments(plan: Plan, first: float) -> Plan:
    """The plan with its first segment cut at ``first`` [s] (a probe of the step time), when it is longer."""
    a, b, patches = plan.segments[0]
    if b - a <= 2.0 * first:
        return plan
    return dataclasses.replace(plan, segments=((a, a + first, patches), (a + first, b, patches), *plan.segments[1:]))


@dataclass
class BudgetProbe:
    """The probe of a batch's step time (``run_segments``' ``probe``): the probe segment's wall time per step,
    projected over the batch's ``steps``, against what the ``budget`` [s] (None: none) leaves since ``t0``
    (``time.perf_counter``); ``stopped``: it did not fit."""

    name: str
    steps: int
    budget: float | None
    t0: float
    log: Log
    per_step: float = float("nan")  # [s] per step
    stopped: bool = False

    def __call__(self, res: Any) -> bool:
        self.per_step = res.wall_time / max(res.steps, 1)
        total = self.per_step * self.steps
        self.log(
            f"{self.name}: probe {res.steps:,} steps at {self.per_step * 1e6:.2f} µs/step: {total:.0f} s projected"
        )
        self.stopped = self.budget is not None and total > self.budget - (time.perf_counter() - self.t0)
        return not self.stopped


def run_batch(
    batch: Batch,
    cfg: Config,
    out: Path,
    log: Log,
    costs: Any,
    budget: float | None,
    keep_records: bool = False,
) -> dict[str, dict[str, Any]]:
    """Run, analyse and save one batch; returns its members' result dicts by name.

    A batch the ``budget`` [s of wall time left] cannot hold by its estimate is not started; a batch whose first
    segment (a probe of its step time, on a non-growing batch, after :func:`warm_up` has taken the first launches'
    one-off costs) projects beyond the budget is stopped there. Its members' results say so.
    """
    from aca_warp.hf.solver import friction_step, stable_step
    from aca_warp.studies.runs import batch_at_start

    t0 = time.perf_counter()
    scenes, plan = batch.scenes, batch.plan
    step = cfg.stepping(batch.stepping_kind)
    model, state = batch_at_start(scenes, cfg.device, step.precision)
    bound = friction_step(stable_step(model))
    dt = step.dt
    steps = plan.steps(dt, cfg.sample_dt)
    est = costs.estimate(batch, cfg)
    sizes = sorted({s.patches.count for s in scenes})
    names = ", ".join(p.exp.name for p in batch.members)
    log(
        f"{batch.name} ({names}): {len(scenes)} pads × {'/'.join(map(str, sizes))} patches, run "
        f"{plan.duration * 1e3:.1f} ms in {len(plan.segments)} segment(s), {len(plan.tracks)} track window(s); "
        f"per-patch record {sum(p.plan.velocity_bytes for p in batch.members) / 2**20:.0f} MiB; {step.describe()}: "
        f"dt {dt:.3g} s (friction step {bound:.3g} s), {steps:,} steps, estimated {est:.0f} s"
    )
    heads = {p.exp.name: _result_head(p, cfg, est) for p in batch.members}
    if budget is not None and est > budget:
        log(f"{batch.name}: not run: estimated {est:.0f} s exceeds the {budget:.0f} s left of the budget")
        return {n: {**h, "status": "skipped (budget)"} for n, h in heads.items()}
    probe = None if batch.growth else BudgetProbe(batch.name, steps, budget, t0, log)
    if probe is not None:
        log(f"{batch.name}: warm-up {warm_up(model, cfg, step, dt):.2f} s (one sample from a spare state)")
    probe_s = cfg.sample_dt * max(1, round(min(5.0e-4, 0.05 * plan.duration) / cfg.sample_dt))  # whole samples
    run_plan = plan if batch.growth else split_segments(plan, probe_s)
    sink = Collector()
    last, parts = run_segments(model, state, run_plan, cfg, step, dt, sink, probe)
    if probe is not None and probe.stopped:
        log(f"{batch.name}: stopped after the probe: {probe.per_step * steps:.0f} s projected exceeds the budget")
        return {n: {**h, "status": "skipped (budget)", "probe_us_per_step": 1e6 * probe.per_step}
                for n, h in heads.items()}  # fmt: skip
    facts = _run_facts(parts, model, cfg, step, bound)
    costs.calibrate(batch, cfg, facts["us_per_step"] * 1e-6)
    del model, state
    log(
        f"{batch.name}: {'complete' if facts['complete'] else 'stopped: ' + str(facts['fault'])} in "
        f"{facts['wall_s']:.1f} s ({facts['us_per_step']:.2f} µs/step at dt = {facts['dt']:.3g} s, compile "
        f"{facts['compile_s']:.1f} s; per segment: "
        + ", ".join(f"{r.steps:,} steps in {r.wall_time:.2f} s + {r.compile_time:.2f} s set-up" for r in parts)
        + ")"
    )
    records = sink.arrays()
    del sink
    out_results, pad0, patch0 = {}, 0, 0
    share = (time.perf_counter() - t0) / len(batch.members)  # the batch's setup and run, shared by its members
    for prep in batch.members:
        n, m = len(prep.scenes), prep.patch_count
        t, g, pt, v = records
        mine = (t, g[:, pad0 : pad0 + n], pt, v[:, patch0 : patch0 + m])
        result = {**heads[prep.exp.name], "run": facts, "total_s": share}
        out_results[prep.exp.name] = finish_experiment(prep, cfg, out, log, result, mine, keep_records)
        pad0, patch0 = pad0 + n, patch0 + m
    return out_results


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
    from aca_warp.studies.validation.analysis import analyse_batch

    t, g, pt, v = records
    name = prep.exp.name
    ta = time.perf_counter()
    if prep.exp.kind == "growth":
        from aca_warp.studies.validation.area import analyse_growth

        pads, arrays, segment = analyse_growth(prep.scenes, t, g, prep.plan, cfg)
    else:
        pads, arrays, segment = analyse_batch(prep, t, g, pt, v, cfg)
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
    """Analyse again the kept records of a saved run of ``prep`` (same settings and LF runs, :func:`fits`); None when
    there are none."""
    folder = out / prep.exp.name
    path, res = folder / "records.npz", folder / "result.json"
    if not (path.is_file() and res.is_file()):
        return None
    result = json.loads(res.read_text())
    if not fits(result, prep.exp, cfg):
        return None
    duration = (result.get("plan") or {}).get("duration_s")
    if duration is not None and abs(duration - prep.plan.duration) > 1e-12:
        prep = prep.replanned(duration, cfg)  # it ran in a batch as long as its longest member
    with np.load(path) as d:
        records = (d["time"], d["globals"], d["patch_time"], d["velocity"])
    log(f"{prep.exp.name}: analysing the kept records again")
    return finish_experiment(prep, cfg, out, log, result, records, keep_records=False)


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


def _result_head(prep: Prepared, cfg: Config, est: float) -> dict[str, Any]:
    from aca_warp.studies.validation.multiscale import lf_runs

    plan = prep.plan
    return {
        "experiment": prep.exp.key(),
        "config": cfg.run_key(),
        **({"lf_runs": runs} if (runs := lf_runs(prep.exp, cfg)) else {}),
        "plan": {
            "duration_s": plan.duration,
            "settle_s": plan.settle,
            "v0_m_s": plan.v0,
            "v_sat_m_s": plan.v_sat,
            "sigma_q25": plan.sigma_q25,
            "window_start_s": plan.window_start,
            "patch_samples": plan.patch_samples,
            "tracks_s": [list(w) for w in plan.tracks],
            "velocity_bytes": plan.velocity_bytes,
            "estimate_s": est,
        },
        "pads": pad_facts(prep.scenes, prep.contacts, prep.sigma),
    }


def _run_facts(parts: list[Any], model: Any, cfg: Config, step: Any, bound: float) -> dict[str, Any]:
    """What the segments of a run did together: completeness, steps, wall and compile time, the step."""
    from aca_warp.common.files import machine

    last = parts[-1]
    steps = sum(int(r.steps) for r in parts)
    wall = sum(float(r.wall_time) for r in parts)
    return {
        "complete": bool(last.complete),
        "fault": None if last.fault is None else str(last.fault),
        "steps": steps,
        "wall_s": wall,
        "compile_s": sum(float(r.compile_time) for r in parts),
        "us_per_step": 1e6 * wall / max(steps, 1),
        "dt": float(last.dt),
        "friction_step": float(bound),
        "stepping": dataclasses.asdict(step),
        "segments": len(parts),
        "blocks_per_pad": int(last.blocks_per_pad),
        "stages": list(last.stages),
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


def same_definition(res: dict[str, Any], exp: Experiment) -> bool:
    """Whether the saved result ``res`` was made with the current definition of ``exp``."""
    return res.get("experiment") == clean(exp.key())


def fits(res: dict[str, Any], exp: Experiment, cfg: Config) -> bool:
    """Whether the saved result ``res`` was made with the definition of ``exp`` and the settings ``cfg`` (and, for a
    §3.3 experiment, from the same LF run files as those in ``cfg.lf_dir``)."""
    from aca_warp.studies.validation.multiscale import lf_runs

    same = same_definition(res, exp) and same_settings(res.get("config") or {}, cfg.run_key(), exp.stepping)
    return same and res.get("lf_runs", {}) == lf_runs(exp, cfg)


def load_result(folder: Path, exp: Experiment, cfg: Config) -> dict[str, Any] | None:
    """The saved result of ``exp`` if it :func:`fits` and is finished, else None."""
    path = folder / "result.json"
    if not path.is_file():
        return None
    try:
        res = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return res if fits(res, exp, cfg) and res.get("status") in ("done", "stopped") else None
