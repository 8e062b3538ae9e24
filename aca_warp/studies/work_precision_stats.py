"""Statistical work-precision: how coarse may the integrator be before the validation's statistics move?

The validation judges the paper's statements from seed ensembles of saturated runs; what matters there is not the
pointwise error of one chaotic trajectory but the error of an ensemble's statistics. For every measure the
validation rests on (μ mean and std, the velocity-sum peak of Fig. 8, the per-patch first peak f1, the μ and
velocity-sum spectra, S − S_null, Φ, the 5 mm neighbour correlation, growth rates; and for the growing pads μ's
rise, the falling line, the STFT maximum and the tonality), this study measures the error of the ensemble mean
against a tight reference ensemble (the same seeds, the same pads) as a function of integrator, step or tolerance
and precision, relative to the standard deviation between seeds, with the stepping wall time of each setting.

A **regime** is an experiment of the validation (the same scenes, initial states, run lengths and analysis): hf1–hf4
(equilibrium + 0.01 m/s velocity perturbation, run into saturation, analysed over the last window), ``va``
(varying_area, growth compressed) and the LF states of §3.3 (``ms_fast``, ``ms_short``, ``ms_mid``, ``ms_app3``:
groups of LF snapshots; their LF runs are made once in ``OUT/lf``). Every pad of a regime is analysed over the
same per-patch window by the validation's own per-pad analysis, whether its detector calls it saturated or not,
so that every setting is measured on the same samples.

A **setting** is ``INTEGRATOR@PRECISIONS[:dt=STEPS][:tol=TOLERANCES][:growth_dt=SPACINGS][:solve_tol=TOLS][:fast]
[:mean]`` (a product), e.g. ``strang@fp32:dt=1e-8,5e-7``, ``adaptive@fp64:tol=1e-4``,
``implicit-friction@fp32,fp64:dt=1e-7``, ``strang@fp32:dt=1e-7:fast`` (the on-chip kernel compiled with CUDA
fast math: ``aca-warp hf --fast-math``), ``strang@fp32:dt=2.5e-7:mean`` (strang's steps that cross zero slip averaged
along their slip segment, and μ read at an instant of the sub-step a crossing patch's sample reads: ``aca-warp hf
--crossing mean``), ``strang@fp32:dt=1e-7:growth_dt=1e-6`` (a growing pad's growth events every 1 µs, the
increment scaled to keep the growth rate: ``aca-warp hf --growth-dt``; refused in regimes that do not grow),
``strang@fp32:dt=1e-8:solve_tol=1e-7`` (the per-patch friction solve stopped at 1e-7 of the scale of its velocity
change instead of the precision's default: ``aca-warp hf --solve-tol``); without
dt or tol the integrator's defaults (``tol``: the tolerance of ``adaptive``, the split tolerance of ``controlled``
and ``auto``, :func:`~aca_warp.hf.options.tolerance_keyword`). Fixed steps run forced (past the spring bound
too). Any name of ``aca_warp.hf.options.INTEGRATORS`` is accepted, and a name that the default grid does not list
runs at its defaults in fp32 and fp64. The **reference** (``--reference``; strang fp64 at 1e-8 s, --quick 2e-8 s,
capped at 0.9 × the regime's friction step, h γ_max = 4) runs first, then the grid, cheapest first.

The statistics and the rule (a setting's bias within ± ``--rule`` × the standard deviation between seeds for every
measure, as ``--criterion`` counts it: proven by the 95 % interval, or within the resolution of the ensemble; the
cheapest such setting per regime) are in
:mod:`aca_warp.studies.work_precision_stats_rule`
(:func:`~aca_warp.studies.work_precision_stats_rule.settings_for`); the figure and the page in
:mod:`aca_warp.studies.work_precision_stats_report`. Results: one file per regime,
``OUT/wps_<device>[_quick]_<regime>.json``, rewritten after every run (per pad and measure the values, per setting
the stepping wall time, the digest of the kernels it ran on); a later call with the same settings continues it
(runs kept, missing ones added: another integrator, or what a time limit cut off; ``--again`` runs the grid's
settings again whose rows were made on other kernels, replacing their rows). A regime too long for one call is
measured in parts over disjoint seeds (``--seeds K --first-seed S``, e.g. one process per GPU) and the parts joined
by ``--merge``
(:mod:`aca_warp.studies.work_precision_stats_merge`). Examples::

    python3 scripts/work_precision_stats.py --quick --out out/wps_quick                     # the CPU variant
    python3 scripts/work_precision_stats.py --device cuda:0 --seeds 32 --out wps --regimes hf1 hf2
    python3 scripts/work_precision_stats.py --report wps/wps_cuda0_*.json                       # figure + page
    python3 scripts/work_precision_stats.py --merge part*/wps_cuda*_ms_app3.json --out wps     # parts into one
    python3 scripts/work_precision_stats.py --by-part wps/wps_cuda0_hf3.json --measures sync_excess  # part by part
    python3 scripts/work_precision_stats.py --by-pad wps/wps_cuda0_va.json --measures stft_amplitude  # tonal pads
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import math
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.common.argtypes import int_at_least, nonneg, positive
from aca_warp.common.errors import SceneError
from aca_warp.common.files import kernels_digest
from aca_warp.hf.options import INTEGRATORS, check_crossing, check_solve_tol, fast_math_unfit, tolerance_keyword
from aca_warp.studies.report import Log, add_device, add_page_options, clean, command_line, write_json
from aca_warp.studies.validation.analysis import analyse_batch
from aca_warp.studies.validation.area import analyse_growth
from aca_warp.studies.validation.base import EXPERIMENTS, FULL, QUICK, close_pools, without_stepping
from aca_warp.studies.validation.cli import default_workers
from aca_warp.studies.validation.experiments import Collector, prepare
from aca_warp.studies.validation.multiscale import ensure_lf
from aca_warp.studies.work_precision_stats_pads import DEFAULT_FACTOR
from aca_warp.studies.work_precision_stats_rule import (
    CRITERIA,
    DEFAULT_CRITERION,
    DEFAULT_RULE,
    MEASURES,
    load_results,
    measures_of,
    pad_values,
)

PRECISIONS = ("fp32", "fp64")
REFERENCE_MARGIN = 0.9  # the reference step: at most this × the regime's friction step (h γ_max = 4)
REFERENCE = {False: "strang@fp64:dt=1e-8", True: "strang@fp64:dt=2e-8"}
GRID = {
    False: (
        "strang@fp32:dt=1e-8,2e-8,4e-8,8e-8,1.43e-7,2.5e-7,5e-7",
        "strang@fp64:dt=8e-8,2.5e-7",
        "adaptive@fp64:tol=1e-3,1e-4",
        "implicit-friction@fp32:dt=1e-7,2.5e-7,5e-7",
    ),
    True: (
        "strang@fp64:dt=5e-8,1e-7,2.5e-7,5e-7",
        "strang@fp32:dt=1e-7,5e-7",
        "adaptive@fp64:tol=1e-3,1e-4",
        "implicit-friction@fp64:dt=1e-7,2.5e-7",
    ),
}
LEFT_OUT = ("symplectic-euler",)  # not in the default grid: explicit friction, bounded by the friction step
REGIMES = {
    False: ("hf1", "hf2", "hf3", "hf4", "va", "ms_fast", "ms_short", "ms_mid", "ms_app3"),
    True: ("hf1", "hf2", "va", "ms_fast"),
}
QUICK_CONFIG = {"seeds": 4, "patches": 60, "state_patches": 60, "window": 4.0e-3}
PROGRESS_S = 30.0  # s of wall time between progress lines of one run
PROBE_S = 10.0  # s of wall time after a run's first chunk before its end is projected against --max-wall


# ------------------------------------------------------------------------------------------------ settings


@dataclass(frozen=True)
class Setting:
    """One point of the grid: integrator, precision, fixed step [s] and/or tolerance (None: the defaults), whether
    the on-chip strang kernel is compiled with CUDA fast math (``RunOptions.fast_math``), and the spacing of a
    growing pad's growth events [s] (``RunOptions.growth_dt``; None: the scenes' growth interval) and strang's
    treatment of steps that cross zero slip (``RunOptions.crossing``) and the friction solve's tolerance
    (``RunOptions.solve_tol``; None: the precision's)."""

    integrator: str
    precision: str
    dt: float | None = None
    tolerance: float | None = None
    fast_math: bool = False
    growth_dt: float | None = None
    crossing: str = "point"
    solve_tol: float | None = None

    @property
    def label(self) -> str:
        """``integrator@precision[:dt=…][:tol=…][:growth_dt=…][:solve_tol=…][:fast][:mean]`` (parses back to this
        setting)."""
        parts = [f"dt={self.dt:g}"] if self.dt is not None else []
        parts += [f"tol={self.tolerance:g}"] if self.tolerance is not None else []
        parts += [f"growth_dt={self.growth_dt:g}"] if self.growth_dt is not None else []
        parts += [f"solve_tol={self.solve_tol:g}"] if self.solve_tol is not None else []
        parts += ["fast"] if self.fast_math else []
        parts += [self.crossing] if self.crossing != "point" else []
        return ":".join([f"{self.integrator}@{self.precision}", *parts])

    def cost(self, duration: float) -> float:
        """Steps a fixed-step run of ``duration`` [s] takes (inf when the step is chosen by error control or is
        the integrator's default: unknown, run last)."""
        return duration / self.dt if self.dt is not None and self.tolerance is None else math.inf


def parse_setting(spec: str) -> list[Setting]:
    """The settings of one spec ``NAME@P1[,P2][:dt=V[,V…]][:tol=V[,V…]][:growth_dt=V[,V…]][:solve_tol=V[,V…]][:fast]
    [:mean]`` (module docstring); ValueError names what is wrong."""
    head, *params = spec.split(":")
    name, _, precs = head.partition("@")
    if name not in INTEGRATORS:
        raise ValueError(f"unknown integrator {name!r} in {spec!r}; choose from {', '.join(INTEGRATORS)}")
    precisions = precs.split(",") if precs else list(PRECISIONS)
    bad = [p for p in precisions if p not in PRECISIONS]
    if bad:
        raise ValueError(f"unknown precision {', '.join(bad)} in {spec!r}; choose from {', '.join(PRECISIONS)}")
    axes: dict[str, list[float | None]] = {"dt": [None], "tol": [None], "growth_dt": [None], "solve_tol": [None]}
    fast = "fast" in params
    unfit = [why for p in precisions if (why := fast_math_unfit(name, p))] if fast else []
    if unfit:
        raise ValueError(f"fast math in {spec!r}: {unfit[0]} (strang@fp32:…:fast)")
    crossing = "mean" if "mean" in params else "point"
    try:
        check_crossing(crossing, name)
    except SceneError as e:
        raise ValueError(f"{crossing!r} in {spec!r}: {e} (strang@…:mean)") from None
    for p in (p for p in params if p not in ("fast", "mean")):
        key, _, vals = p.partition("=")
        if key not in axes or not vals:
            raise ValueError(
                f"bad parameter {p!r} in {spec!r}: use dt=V[,V…], tol=V[,V…], growth_dt=V[,V…], solve_tol=V[,V…], "
                "fast or mean"
            )
        try:
            nums = [float(v) for v in vals.split(",")]
        except ValueError:
            raise ValueError(f"bad number in {p!r} of {spec!r}") from None
        if not all(v > 0 and math.isfinite(v) for v in nums):
            raise ValueError(f"{key} must be positive in {spec!r}")
        if key == "solve_tol":
            try:
                for v in nums:
                    check_solve_tol(v, crossing)
            except SceneError as e:
                raise ValueError(f"{e} ({spec!r})") from None
        axes[key] = list(nums)
    combos = itertools.product(precisions, axes["dt"], axes["tol"], axes["growth_dt"], axes["solve_tol"])
    return [Setting(name, pr, dt, tol, fast, growth, crossing, solve) for pr, dt, tol, growth, solve in combos]


def grid(specs: list[str], integrators: list[str] | None, precisions: list[str] | None) -> list[Setting]:
    """The settings of ``specs`` (duplicates once), filtered to ``integrators`` and ``precisions`` if given."""
    out = dict.fromkeys(s for spec in specs for s in parse_setting(spec))
    return [
        s
        for s in out
        if (not integrators or s.integrator in integrators) and (not precisions or s.precision in precisions)
    ]


def default_grid(quick: bool) -> list[str]:
    """The default specs: :data:`GRID`, and every other integrator of ``INTEGRATORS`` (but :data:`LEFT_OUT`) at its
    defaults in both precisions, so that a new integrator enters the study without a change here."""
    named = {spec.split("@")[0] for spec in GRID[quick]}
    return [*GRID[quick], *(f"{n}@fp32,fp64" for n in INTEGRATORS if n not in named and n not in LEFT_OUT)]


# ------------------------------------------------------------------------------------------------ the validation


def regime_config(args: argparse.Namespace) -> Any:
    """The validation ``Config`` of the study: the validation's full or quick defaults with ``--seeds``,
    ``--patches``, ``--window`` and the quick variant's smaller sizes (:data:`QUICK_CONFIG`)."""
    base = dataclasses.replace(QUICK, **QUICK_CONFIG) if args.quick else FULL
    over = {"seeds": args.seeds, "first_seed": args.first_seed, "patches": args.patches, "window": args.window}
    over |= {"state_patches": args.patches} if args.patches is not None and args.quick else {}
    lf = str(Path(args.lf_dir or Path(args.out) / "lf"))
    workers = args.workers or (1 if args.device == "cpu" else default_workers())
    over = {k: x for k, x in over.items() if x is not None}
    return dataclasses.replace(base, device=args.device, engine=args.engine, lf_dir=lf, workers=workers, **over)


def prepare_regime(name: str, cfg: Any, duration: float | None, log: Log) -> Any:
    """The validation's preparation of experiment ``name`` (scenes, contact solves, plan), its LF runs made first
    when it needs them; a saturated experiment's run lasts ``duration`` [s] when given."""
    exp = EXPERIMENTS[name]
    if duration is not None and exp.kind == "saturated":
        exp = dataclasses.replace(exp, duration=duration)
    ensure_lf([name], cfg, log)
    return prepare(exp, cfg)


def analyse(prep: Any, cfg: Any, records: tuple[np.ndarray, ...]) -> tuple[list[dict], list[dict | None]]:
    """Per pad: the validation's analysis (growing pads: ``analyse_growth``; others: ``analyse_batch`` over the
    whole per-patch window, saturated or not) and its global spectra {"freq", "mu", "velocity"} (None for a growing
    pad or one not analysed)."""
    t, g, pt, vel = records
    if prep.exp.kind == "growth":
        pads, _, _ = analyse_growth(prep.scenes, t, g, prep.plan, cfg)
        return pads, [None] * len(pads)
    every_pad = dataclasses.replace(prep, exp=dataclasses.replace(prep.exp, kind="window"))  # saturated or not
    pads, arrays, seg = analyse_batch(every_pad, t, g, pt, vel, cfg)
    spectra: list[dict | None] = [None] * len(pads)
    if "pad" in arrays:
        freq = np.fft.rfftfreq(seg["samples"] * cfg.decimation, cfg.sample_dt)
        for row, p in enumerate(arrays["pad"]):
            spectra[int(p)] = {
                "freq": freq, "mu": arrays["spectrum_mu"][row], "velocity": arrays["spectrum_velocity"][row]
            }  # fmt: skip
    return pads, spectra


# ------------------------------------------------------------------------------------------------ runs


class PastBudget(Exception):
    """A run stopped because its projected end lies past ``--max-wall``: ``done`` the share of its simulated time
    run, ``end`` the call's wall time [s] it would have ended at, ``rate`` [wall s per simulated s] since its first
    chunk."""

    def __init__(self, done: float, end: float, rate: float) -> None:
        super().__init__(f"stopped at {100 * done:.0f} % of its run, projected to end at {end:.0f} s")
        self.done, self.end, self.rate = done, end, rate


class Progress:
    """Sink of a run: the validation's collector, a progress line every :data:`PROGRESS_S` seconds and, with a
    ``deadline`` (the call's wall time [s] by which the run's stepping must end, ``log``'s clock), a stop
    (:class:`PastBudget`) as soon as the rate since the run's first chunk, measured over at least :data:`PROBE_S`,
    projects its end past it: a run that cannot finish inside ``--max-wall`` gives its time back to the runs after
    it instead of running until an outer time limit kills it."""

    def __init__(self, collector: Any, what: str, duration: float, log: Log, deadline: float | None = None) -> None:
        self.collector, self.what, self.duration, self.log = collector, what, duration, log
        self.deadline = deadline
        self.t0 = self.last = time.perf_counter()
        self.first: tuple[float, float] | None = None  # (wall clock, simulated time) at the first chunk

    def __call__(self, chunk: Any) -> None:
        self.collector(chunk)
        if not len(chunk.time):
            return
        now, t = time.perf_counter(), float(chunk.time[-1])
        if now - self.last >= PROGRESS_S:
            self.last = now
            self.log(f"  {self.what}: {t * 1e3:.1f} of {self.duration * 1e3:.1f} ms simulated "
                     f"({100 * t / self.duration:.0f} %, {now - self.t0:.0f} s)")  # fmt: skip
        if self.first is None:
            self.first = (now, t)
            return
        wall, sim = now - self.first[0], t - self.first[1]
        if self.deadline is not None and wall >= PROBE_S and sim > 0:
            rate = wall / sim
            end = self.log.elapsed() + rate * (self.duration - t)
            if end > self.deadline:
                raise PastBudget(t / self.duration, end, rate)


def reference_setting(spec: str, model: Any, capped: bool = True, log: Any = None) -> Setting:
    """The reference of a regime: ``spec`` (one setting). ``capped``: a strang step capped at
    :data:`REFERENCE_MARGIN` × the model's friction step (:func:`~aca_warp.hf.solver.friction_step`, h γ_max = 4),
    the default reference's rule; otherwise the step as given (an explicit ``--reference``, e.g. the fp64 setting
    of a precision pair), with a line to ``log`` when it is past that margin."""
    from aca_warp.hf.solver import friction_step, stable_step

    (s,) = parse_setting(spec)
    if s.integrator == "strang" and s.dt is not None:
        bound = REFERENCE_MARGIN * friction_step(stable_step(model))
        if capped:
            s = dataclasses.replace(s, dt=float(f"{min(s.dt, bound):.3g}"))
        elif s.dt > bound and log is not None:
            log(
                f"reference {s.label}: its step is past the reference margin, {REFERENCE_MARGIN:g} × the friction "
                f"step = {bound:.3g} s: run as given"
            )
    return s


def run_setting(
    prep: Any, cfg: Any, setting: Setting, role: str, names: list[str], log: Log, deadline: float | None = None
) -> dict[str, Any]:
    """One run of the regime's batch with ``setting``, analysed; the row of the result file (``role``: "reference"
    or "grid"). ``deadline``: the call's wall time [s] by which its stepping must end (:class:`Progress`); a run
    stopped for it gives a row "not run: --max-wall (…)", with its ``rate`` [wall s per simulated s], which a
    later call runs again."""
    from aca_warp.studies.runs import batch_at_start, run_engine

    row: dict[str, Any] = {"label": setting.label, "role": role, **dataclasses.asdict(setting)}
    try:
        model, state = batch_at_start(prep.scenes, cfg.device, setting.precision)
        sink = Progress(Collector(), f"{prep.exp.name} {setting.label}", prep.plan.duration, log, deadline)
        res = run_engine(
            model, state, engine=cfg.engine, duration=prep.plan.duration, integrator=setting.integrator,
            dt=setting.dt, record=prep.plan.record(cfg), sink=sink, force=setting.dt is not None,
            fast_math=setting.fast_math, growth_dt=setting.growth_dt, crossing=setting.crossing,
            solve_tol=setting.solve_tol,
            **{tolerance_keyword(setting.integrator): setting.tolerance},
        )  # fmt: skip
    except (SceneError, ValueError) as e:  # a setting the integrator refuses (e.g. an fp32 tolerance too tight)
        log(f"  {setting.label}: refused: {e}")
        return {**row, "complete": False, "fault": f"refused: {e}", "wall_s": None}
    except PastBudget as e:
        log(f"  {setting.label}: {e}, past --max-wall: not run")
        return {**row, "complete": False, "fault": f"not run: --max-wall ({e})", "wall_s": None, "rate": e.rate}
    row.update(
        complete=bool(res.complete), fault=None if res.fault is None else str(res.fault), wall_s=res.wall_time,
        compile_s=res.compile_time, steps=int(res.steps), rejected=int(res.rejected), dt_used=res.dt,
        engine=res.engine,
    )  # fmt: skip
    del model, state
    if res.complete:
        pads, spectra = analyse(prep, cfg, sink.collector.arrays())
        row["values"] = _rounded(pad_values(pads, spectra, names))
        row["saturated"] = sum(p.get("detector_status", p.get("status")) == "saturated" for p in pads)
    return row


def _rounded(values: dict[str, list[Any]]) -> dict[str, list[Any]]:
    """The per-pad values to 7 significant digits (the file stays small; far below any difference measured)."""

    def r(x: Any) -> Any:
        if isinstance(x, list):
            return [r(y) for y in x]
        return float(f"{x:.7g}") if isinstance(x, float) and math.isfinite(x) else None

    return {k: r(v) for k, v in values.items()}


def measure_regime(
    name: str, args: argparse.Namespace, cfg: Any, settings: list[Setting], head: dict[str, Any], log: Log
) -> Path:
    """Every setting of one regime (the reference first, then the grid cheapest first) into its result file
    ``OUT/wps_<tag>_<regime>.json``, rewritten after each run. A file of the same regime, pads, settings and
    reference is continued: its runs are kept, the missing ones added (a run skipped by --max-wall is run again;
    with ``--again`` the grid's settings whose rows were not made on the current kernels are run again, each new row
    replacing the earlier one as it is written: a call cut short keeps the rows it did not reach, and the same call
    again finishes it; the reference's row is kept), on the same kind of device
    (:data:`CONTINUED`; another host with it is accepted, each run records its host; the file keeps the machine and
    tag it was begun on, so a part begun on ``cuda:3`` and continued on ``cuda:0`` from a copy named
    ``wps_cuda0_<regime>.json`` is still the part of ``cuda:3``).
    Raises FileExistsError when the file holds another configuration or device."""
    from aca_warp.studies.runs import batch_at_start

    prep = prepare_regime(name, cfg, args.duration, log)
    names = measures_of(prep.exp.kind)
    model, _ = batch_at_start(prep.scenes, cfg.device, "fp64")
    ref = reference_setting(args.reference, model, capped=args.reference_capped, log=log)
    del model
    plan = prep.plan
    reg: dict[str, Any] = {
        "name": name, "description": prep.exp.description, "kind": prep.exp.kind,
        "config": without_stepping(cfg.run_key()),
        "duration_s": plan.duration, "settle_s": plan.settle, "window_start_s": plan.window_start,
        "pads": [{"seed": s.initial.seed, "member": m, "patches": s.patches.count}
                 for s, m in zip(prep.scenes, prep.members, strict=True)],
        "measures": names, "reference": ref.label, "settings": [],
    }  # fmt: skip
    path = Path(args.out) / f"wps_{head['tag']}_{name}.json"
    before = 0.0  # s of wall time earlier calls spent on this file
    redo: set[tuple[str, str]] = set()  # (label, role) of the continued file's rows that --again runs again
    doc = {**{k: v for k, v in head.items() if k not in ("command", "kernels")}, "commands": [head["command"]],
           "regimes": {name: reg}}  # fmt: skip
    if path.exists():
        old = load_results(path)
        oreg = old["regimes"][name]
        if old["machine"]["device_name"] != head["machine"]["device_name"] or any(
            (without_stepping(oreg.get(k)) if k == "config" else oreg.get(k)) != reg[k] for k in CONTINUED
        ):
            raise FileExistsError(f"{path} holds another run of {name} (device, pads, settings or reference "
                                  "differ): choose another --out")  # fmt: skip
        doc["machine"], doc["tag"] = old["machine"], old.get("tag", doc["tag"])  # the device it was begun on
        if doc["tag"] != head["tag"]:
            log(f"{name}: {path.name} was begun on {doc['machine']['device']}: it keeps that tag, {doc['tag']}")
        reg["settings"] = [r for r in oreg["settings"] if not str(r.get("fault")).startswith("not run")]
        if args.again:  # the grid's rows not made on these kernels (so a call cut short is finished by the same call)
            redo = {(s.label, "grid") for s in settings} & {
                (r["label"], r["role"]) for r in reg["settings"] if r.get("kernels") != head["kernels"]
            }
            log(f"{name}: running again on kernels {head['kernels']}: "
                f"{', '.join(sorted(label for label, _ in redo)) or 'nothing'}")  # fmt: skip
        doc["commands"] = [*old["commands"], head["command"]]
        before = old.get("regime_wall_s") or 0.0
        log(f"{name}: continuing {path} ({len(reg['settings'])} runs in it)")
    done = {(r["label"], r["role"]) for r in reg["settings"]} - redo
    grid_rows = sorted((s for s in settings if s != ref), key=lambda s: s.cost(plan.duration))
    todo = [(s, role) for s, role in [(ref, "reference"), *((s, "grid") for s in grid_rows)] if (s.label, role)
            not in done]  # fmt: skip
    span = "growing" if prep.exp.kind == "growth" else f"window from {plan.window_start * 1e3:.1f} ms"
    log(f"{name}: {len(prep.scenes)} pads × {sorted({s.patches.count for s in prep.scenes})} patches, "
        f"{plan.duration * 1e3:.1f} ms ({span}); {len(todo)} runs; "
        f"reference {ref.label}")  # fmt: skip
    rref = [r for r in reg["settings"] if r["role"] == "reference" and r.get("steps")]
    per_step = rref[0]["wall_s"] / rref[0]["steps"] if rref else model_step(prep.scenes, ref, prep.exp.kind, cfg)
    overheads: list[float] = []  # s of each run of this call besides its stepping (set-up, analysis)
    t0 = log.elapsed()
    for k, (s, role) in enumerate(todo, 1):
        est = run_estimate(s.cost(plan.duration), per_step, overheads)
        if args.max_wall is not None and log.elapsed() + est > args.max_wall:
            if (s.label, role) in redo:
                log(f"  {s.label}: not run again (--max-wall {args.max_wall:g} s): its earlier row kept")
                continue
            log(f"  {s.label}: not run (--max-wall {args.max_wall:g} s)")
            reg["settings"].append({"label": s.label, "role": role, **dataclasses.asdict(s), "complete": False,
                                    "fault": "not run: --max-wall", "wall_s": None})  # fmt: skip
            continue
        t_run = log.elapsed()
        deadline = None if args.max_wall is None else args.max_wall - run_estimate(0.0, 0.0, overheads)
        row = run_setting(prep, cfg, s, role, names, log, deadline) | {
            "host": head["machine"]["host"],
            "kernels": head["kernels"],
        }
        if row.get("wall_s") is not None:
            overheads.append(max(log.elapsed() - t_run - row["wall_s"], 0.0))
        if role == "reference" and row.get("rate") and s.dt:  # stopped: the rate it ran at, for the estimates
            per_step = row["rate"] * s.dt
        if str(row.get("fault")).startswith("not run") and (s.label, role) in redo:
            log(f"  {s.label}: its earlier row kept")
            continue
        reg["settings"] = [r for r in reg["settings"] if (r["label"], r["role"]) != (s.label, role)] + [row]
        if role == "reference" and row.get("steps"):
            per_step = row["wall_s"] / row["steps"]
        _write(path, doc, before + log.elapsed() - t0)
        state = "complete" if row.get("complete") else f"stopped: {row.get('fault')}"
        wall = "–" if row.get("wall_s") is None else f"{row['wall_s']:.3g} s"
        log(f"{name} [{k}/{len(todo)}] {role} {s.label}: {wall} stepping, {row.get('steps', 0):,} steps, "
            f"{state}, {row.get('saturated', 0)}/{len(prep.scenes)} pads saturated")  # fmt: skip
    _write(path, doc, before + log.elapsed() - t0)
    return path


def model_step(scenes: list[Any], setting: Setting, kind: str, cfg: Any) -> float:
    """Seconds per step of a batch of ``scenes`` at ``setting`` by the validation's cost model
    (:func:`~aca_warp.studies.validation.cost.batch_step_seconds`: the largest pad's patches and links; a growing regime
    at the paper's clock, whose events come every few steps, at least the model's floor): what ``--max-wall``
    reckons a regime's first run with, before the call has timed any (nan for a step chosen by error control). The
    model is the validation's bare stepping, calibrated on an H100: hf1's first reference over 32 pads (fp64 at
    1e-8 s on an H200, with the recorder of that time) ran 11.5 µs per step against 5.95 µs modelled, so a run the
    model lets start can still outlast the budget."""
    from aca_warp.studies.validation.cost import batch_step_seconds

    if setting.dt is None or setting.tolerance is not None:
        return math.nan
    frequent = kind == "growth" and setting.growth_dt is None
    return batch_step_seconds(scenes, setting.precision, frequent, cfg.device)


def run_estimate(steps: float, per_step: float, overheads: list[float]) -> float:
    """Estimated wall time [s] of a run for ``--max-wall``: its ``steps`` at the reference's stepping time per step
    ``per_step`` [s] (the cost model's before the reference has run, :func:`model_step`; 0 when either is unknown:
    a step chosen by error control), plus the mean
    of ``overheads``, the time [s] each earlier run of the call spent besides its stepping (the batch's set-up and
    the analysis of its pads, which at 32 pads of 4000 patches is ≈ 50 s a run)."""
    stepping = steps * per_step
    extra = sum(overheads) / len(overheads) if overheads else 0.0
    return (stepping if math.isfinite(stepping) else 0.0) + extra


CONTINUED = ("config", "pads", "duration_s", "measures", "reference")
"""The regime fields that must match for a result file to be continued (with the device's name: the GPU model, or
on the CPU the host)."""


def _write(path: Path, doc: dict[str, Any], seconds: float) -> None:
    """Write the result file (through a temporary file); ``seconds``: the wall time spent on the regime so far, by
    every call that wrote the file."""
    doc["regime_wall_s"] = seconds
    tmp = path.with_suffix(".json.tmp")
    write_json(tmp, clean(doc), indent=None)
    tmp.replace(path)


def measure(args: argparse.Namespace, argv: list[str]) -> list[Path]:
    """Run the study; returns the result files (one per regime)."""
    import scipy
    import warp as wp

    from aca_warp.common.files import machine

    log = Log()
    cfg = regime_config(args)
    settings = grid(args.grid or default_grid(args.quick), args.integrators, args.precisions)
    Path(args.out).mkdir(parents=True, exist_ok=True)
    head: dict[str, Any] = {
        "tag": re.sub(r"[^A-Za-z0-9]+", "", args.device) + ("_quick" if args.quick else ""),
        "machine": machine(wp.get_device(args.device)),
        "versions": {"warp": wp.__version__, "numpy": np.__version__, "scipy": scipy.__version__},
        "python": sys.version.split()[0],
        "quick": bool(args.quick),
        "command": command_line("work_precision_stats.py", argv),
        "rule": DEFAULT_RULE,
        "kernels": kernels_digest(),
    }
    try:
        paths = [measure_regime(name, args, cfg, settings, head, log) for name in args.regimes]
    finally:
        close_pools()
    log(f"wrote {', '.join(str(p) for p in paths)}")
    return paths


# ------------------------------------------------------------------------------------------------ command line


def build_parser() -> argparse.ArgumentParser:
    """The command line of the study."""
    regimes = [k for k, e in EXPERIMENTS.items() if e.kind in ("saturated", "growth")]
    ap = argparse.ArgumentParser(
        description=__doc__.split("Examples::")[0].rstrip() + "\n\nExamples::" + __doc__.split("Examples::")[1],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_device(ap)
    ap.add_argument("--quick", action="store_true", help=f"CPU variant: {QUICK_CONFIG['seeds']} seeds, "
                    f"{QUICK_CONFIG['patches']}-patch sectors, {QUICK_CONFIG['window'] * 1e3:g} ms window, "
                    f"regimes {' '.join(REGIMES[True])}, a smaller grid")  # fmt: skip
    ap.add_argument("--out", default="wps_results", help="folder of the result JSON (and the LF runs, OUT/lf)")
    ap.add_argument("--regimes", nargs="+", choices=regimes, metavar="REGIME",
                    help=f"validation experiments to measure (default {' '.join(REGIMES[False])}; --quick "
                    f"{' '.join(REGIMES[True])}); any of: {' '.join(regimes)}")  # fmt: skip
    ap.add_argument("--seeds", type=int_at_least(2), help="pads (seeds) per regime (validation default 8; --quick 4)")
    ap.add_argument("--first-seed", type=int_at_least(0), help="seed of the first pad (1)")
    ap.add_argument("--patches", type=int_at_least(2), help="patches per pad: a sector (default all; --quick 60)")
    ap.add_argument("--window", type=positive, help="analysis window at the end of a saturated run [s] (20e-3; "
                    "--quick 4e-3)")  # fmt: skip
    ap.add_argument("--duration", type=positive, help="run length of the saturated regimes [s] (default: the "
                    "validation's plan, the predicted time to saturation + the window)")  # fmt: skip
    ap.add_argument(
        "--grid",
        nargs="+",
        metavar="SPEC",
        help="settings INTEGRATOR@P1[,P2][:dt=V,…][:tol=V,…][:growth_dt=V,…][:solve_tol=V,…][:fast][:mean] "
        f"(default: {' '.join(default_grid(False))}; --quick: {' '.join(default_grid(True))})",
    )
    ap.add_argument("--integrators", nargs="+", choices=INTEGRATORS, help="only these integrators of the grid")
    ap.add_argument("--precisions", nargs="+", choices=PRECISIONS, help="only these precisions of the grid")
    ap.add_argument(
        "--reference",
        help=f"the reference setting (default {REFERENCE[False]}; --quick {REFERENCE[True]}; the default's step is "
        f"capped at {REFERENCE_MARGIN:g} × the regime's friction step, a setting named here runs as given, e.g. "
        "the fp64 side of a precision pair)",
    )
    ap.add_argument("--engine", default="auto", choices=["auto", "general", "onchip"], help="HF engine (auto)")
    ap.add_argument("--workers", type=int_at_least(1), help="processes that analyse the pads of a run (default: 1 "
                    "on the CPU, else the CPU count less one, at most 8)")  # fmt: skip
    ap.add_argument("--lf-dir", help="folder of the LF runs of the LF-state regimes (default OUT/lf)")
    ap.add_argument("--max-wall", type=nonneg, help="start no run that would end past this wall time [s] (the "
                    "estimate: the reference's time per step × the steps, the validation's cost model's before the "
                    "reference has run, plus the mean time the call's earlier runs spent besides stepping), and stop "
                    "one whose rate, measured over its first 10 s, projects its end past it; written as not run, "
                    "for a later call")  # fmt: skip
    ap.add_argument("--again", action="store_true", help="in a continued result file, run the grid's settings "
                    "again whose rows were made on other kernels (each row records the digest of the kernels it "
                    "ran on) and replace their rows; the reference's row is kept; a call cut short is finished by "
                    "the same call")  # fmt: skip
    ap.add_argument("--report", nargs="+", metavar="JSON", help="only write the figure(s) and the page from "
                    "result files")  # fmt: skip
    ap.add_argument(
        "--merge",
        nargs="+",
        metavar="JSON",
        help="only join the result files of one regime measured "
        "in parts over disjoint seeds (e.g. a process per GPU) into OUT/wps_<tag>_<regime>.json",
    )
    ap.add_argument(
        "--by-part",
        metavar="JSON",
        help="only print (Markdown) each setting's error in units of σ "
        "over all pads and over each part's pads alone, for a merged result file (--measures: which)",
    )
    ap.add_argument(
        "--by-pad",
        metavar="JSON",
        help="only print (Markdown), for a result file of one regime, per setting the pads' median of each measure "
        "with positive values and every pad at --factor × that median or more (seed, value / median, difference from "
        "the reference's value of the pad in units of σ): the few pads that decide a heavy-tailed measure such as a "
        "growing pad's STFT maximum (--measures: which)",
    )
    ap.add_argument("--factor", type=positive, default=None, help="with --by-pad: how many times the pads' "
                    f"median a pad's value must reach to be listed ({DEFAULT_FACTOR:g})")  # fmt: skip
    ap.add_argument(
        "--steps",
        metavar="JSON",
        help="only print (Markdown) each fixed-step setting's error ± its 95 %% half-width in units of σ, family by "
        "family and step by step (signed for a scalar measure), and draw them against the step into "
        "wps_<tag>_<regime>_steps.png beside JSON, or in --figures where given (--regimes: which regime of the file, "
        "--measures: which measures)",
    )
    ap.add_argument(
        "--precision-pairs",
        action="store_true",
        help="with --steps: each fp32 setting against the fp64 setting of its step and variant instead of the "
        "reference (what the precision alone moves, step by step; figure wps_<tag>_<regime>_fp32_fp64.png)",
    )
    ap.add_argument("--rule", type=positive, default=DEFAULT_RULE, help="the report's rule: a setting's bias within "
                    f"± RULE × σ between seeds ({DEFAULT_RULE:g})")  # fmt: skip
    ap.add_argument("--criterion", default=DEFAULT_CRITERION, choices=list(CRITERIA), help="what the report's rule "
                    f"counts as keeping a measure (default {DEFAULT_CRITERION}): "
                    + "; ".join(f"{k}: {v}" for k, v in CRITERIA.items()).replace("%", "%%"))  # fmt: skip
    ap.add_argument("--measures", nargs="+", choices=list(MEASURES), metavar="MEASURE", help="measures the "
                    f"report's rule uses (default every one of a regime; any of: {' '.join(MEASURES)})")  # fmt: skip
    add_page_options(ap, "docs/work_precision_statistics.md", "docs/figures/work_precision_statistics")
    return ap


def merge_parts(paths: list[Path], out: Path) -> int:
    """``--merge``: the parts' result files joined into ``out``/wps_<tag>_<regime>.json (never over an existing
    file); returns 0, or 2 after one line on stderr."""
    from aca_warp.studies.work_precision_stats_merge import merge

    try:
        doc = merge(paths)
        (name,) = doc["regimes"]
        path = out / f"wps_{doc['tag']}_{name}.json"
        if path.exists():
            raise FileExistsError(f"{path} exists: choose another --out or remove it")
        out.mkdir(parents=True, exist_ok=True)
        _write(path, doc, doc["regime_wall_s"])
    except (OSError, ValueError, KeyError) as e:
        print(f"work_precision_stats: {e}", file=sys.stderr)
        return 2
    reg = doc["regimes"][name]
    print(f"wrote {path}: {name}, {len(reg['pads'])} pads from {len(paths)} parts, {len(reg['settings'])} settings")
    return 0


def steps_report(args: argparse.Namespace) -> int:
    """``--steps``: the errors against the step of one regime of a result file (``--precision-pairs``: fp32 against
    fp64 step by step), as Markdown on stdout and as a figure in ``--figures`` (where not given: beside the result
    file); returns 0, or 2 after one line on stderr."""
    from aca_warp.studies.work_precision_stats_rule import load_results
    from aca_warp.studies.work_precision_stats_steps import collect, errors_by_step, step_figure

    try:
        if args.regimes and len(args.regimes) > 1:
            raise ValueError(f"--steps takes one regime, not {' '.join(args.regimes)}")
        name = args.regimes[0] if args.regimes else None
        steps = collect(load_results(Path(args.steps)), name, args.measures, args.precision_pairs)
        path = step_figure(steps, Path(args.figures or Path(args.steps).parent), args.rule)
    except (OSError, ValueError, KeyError) as e:
        print(f"work_precision_stats: {e}", file=sys.stderr)
        return 2
    print(errors_by_step(steps), end="")
    print(f"wrote {path}", file=sys.stderr)
    return 0


def main(argv: list[str] | None = None) -> int:
    """Measure (or, with --report, only report); returns 0, or 2 after one line on stderr for bad input."""
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = build_parser()
    figures = ap.get_default("figures")
    ap.set_defaults(figures=None)  # --steps puts its figure beside the result file unless --figures names a folder
    args = ap.parse_args(argv)
    if args.precision_pairs and not args.steps:
        ap.error("--precision-pairs goes with --steps FILE")
    if args.factor is not None and not args.by_pad:
        ap.error("--factor goes with --by-pad FILE")
    only = [flag for flag, given in (("--report", args.report), ("--merge", args.merge), ("--by-part", args.by_part),
                                     ("--by-pad", args.by_pad), ("--steps", args.steps)) if given]  # fmt: skip
    if len(only) > 1:
        ap.error(f"{' and '.join(only)} each do one thing alone: give one of them")
    if args.again and only:
        ap.error(f"--again goes with a call that measures (not with {only[0]})")
    if args.report:
        from aca_warp.common.errors import AcaError
        from aca_warp.common.files import check_output_path
        from aca_warp.studies.work_precision_stats_report import report

        try:
            check_output_path(args.page, overwrite=True)  # before the figures: nothing written for a bad page
            report([Path(p) for p in args.report], Path(args.page), Path(args.figures or figures), args.rule,
                   args.measures, args.criterion)  # fmt: skip
        except (AcaError, OSError, ValueError, KeyError) as e:
            print(f"work_precision_stats: {e}", file=sys.stderr)
            return 2
        return 0
    if args.merge:
        return merge_parts([Path(p) for p in args.merge], Path(args.out))
    if args.by_part:
        from aca_warp.studies.work_precision_stats_merge import errors_by_part
        from aca_warp.studies.work_precision_stats_rule import load_results

        try:
            print(errors_by_part(load_results(Path(args.by_part)), args.measures), end="")
        except (OSError, ValueError, KeyError) as e:
            print(f"work_precision_stats: {e}", file=sys.stderr)
            return 2
        return 0
    if args.by_pad:
        from aca_warp.studies.work_precision_stats_pads import pads_far_from_median
        from aca_warp.studies.work_precision_stats_rule import load_results

        try:
            factor = DEFAULT_FACTOR if args.factor is None else args.factor
            print(pads_far_from_median(load_results(Path(args.by_pad)), args.measures, factor), end="")
        except (OSError, ValueError, KeyError) as e:
            print(f"work_precision_stats: {e}", file=sys.stderr)
            return 2
        return 0
    if args.steps:
        return steps_report(args)
    args.regimes = args.regimes or list(REGIMES[args.quick])
    args.reference_capped = args.reference is None
    args.reference = args.reference or REFERENCE[args.quick]
    try:
        refs = parse_setting(args.reference)
        if len(refs) != 1:
            raise ValueError(f"--reference {args.reference!r} names more than one setting")
        if refs[0].fast_math:
            raise ValueError(f"--reference {args.reference!r}: the reference runs the exact kernel (drop :fast)")
        grid(args.grid or [], None, None)
    except ValueError as e:
        ap.error(str(e))
    from aca_warp.common.devices import get_device
    from aca_warp.common.errors import AcaError
    from aca_warp.common.files import check_output_folder

    try:
        get_device(args.device)
        for folder in (args.out, args.lf_dir):
            if folder:
                check_output_folder(folder)
    except AcaError as e:
        ap.error(str(e))
    try:
        measure(args, argv)
    except FileExistsError as e:
        print(f"work_precision_stats: {e}", file=sys.stderr)
        return 2
    return 0
