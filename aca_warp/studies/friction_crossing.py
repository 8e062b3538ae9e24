"""Zero-slip crossings at large steps: where the step error of Φ arises.

The statistical work-precision (docs/work_precision_statistics.md) finds Φ, the number of patches the relative rule
counts as oscillating at a frequency, the measure that binds `strang`'s step on the whole hf1 pad: it grows with
the step (+0.6, +4, +19 and +67 patches at 1e-7, 2.5e-7, 5e-7 and 1e-6 s over a mean of 153), while μ and the
velocity-sum spectrum stay within a quarter of their spread between seeds up to 2.5e-7 s. This study runs full
pads of the validation's hf1 experiment (equilibrium + a velocity perturbation, into saturation, the validation's
run length and window) on the CPU and compares, per seed,

* the package's `strang` at a fine reference step and at the steps asked for, and
* the NumPy prototype (:mod:`aca_warp.studies.friction_schemes`) with the kernels' sub-step (``forced-thmid``) and
  with ``forced-thmean``, which integrates the friction along a step that crosses zero slip instead of sampling it
  at the midpoint,

by μ mean and std, Σ|u̇| mean, Φ (relative rule, η = 0.1, mean over [f1/8, 2 f1] of the per-patch spectra as the
validation counts it), the first peak f1 and the per-patch spectra's floor: the median over the patches of their
mean amplitude in [f1/8, f1/2] (the unnormalised Hann-windowed rfft of the velocity, in m/s), where Φ counts the
patches that stand above a tenth of the largest amplitude. Each result file's run length and window follow its
seeds (the validation's plan), so files of other seeds join run by run.

Results: one JSON (per run and seed the measures, wall time and steps) and a Markdown table of the ensemble mean
differences against the reference with their 95 % half-widths (``--report``). ``--step-errors`` measures single
steps instead (:func:`step_errors`): the velocity error of one step of each sub-step against fine steps, for the
patches that cross zero slip inside it and for the others. The page is docs/friction_step.md §8.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.common.argtypes import int_at_least, positive
from aca_warp.common.files import host_cpu
from aca_warp.studies.report import Log, command_line, write_json

PROTOTYPE = ("thmid", "thmean")  # the prototype's sub-steps (forced kicks)
SETTLE_DT = 1.0e-7  # s: the step that runs a pad into saturation before the step errors are measured
INSTANT_SPACING = 5.0e-6  # s: between the instants at which single steps are measured
ETA = 0.1  # the relative rule of Φ
READINGS = ("point", "segment", "instant", "applied")  # the prototype's μ: Record.mu, .mu_segment, .mu_instant, …
MEASURES = ("mu_mean", "mu_std", "abs_velocity_mean", "phi", "f1", "floor")
LABELS = {
    "mu_mean": ("μ mean", "1"), "mu_std": ("μ std", "1"), "abs_velocity_mean": ("Σ\\|u̇\\| mean", "m/s"),
    "phi": ("Φ", "patches"), "f1": ("f1", "Hz"), "floor": ("floor", "m/s"),
}  # fmt: skip


@dataclasses.dataclass(frozen=True)
class Window:
    """The measured span of every run: global samples from ``start`` [s], per-patch samples every ``dt`` [s]."""

    start: float
    dt: float


def pad_measures(time_s: np.ndarray, mu: np.ndarray, abs_v: np.ndarray, ptime: np.ndarray, vel: np.ndarray,
                 win: Window) -> dict[str, float]:  # fmt: skip
    """The measures of one pad over the window: global series (N,) at ``time_s`` [s]; per-patch velocities
    ``vel`` (M, n) [m/s] at ``ptime`` [s], already at the window's per-patch interval. ``floor`` is in m/s (the
    unnormalised Hann-windowed rfft amplitude)."""
    from aca_warp.analysis.measures import first_peak
    from aca_warp.analysis.sync import sync_index_from_signals

    g = time_s >= win.start - 1e-12
    p = ptime >= win.start - 1e-12
    v = np.asarray(vel[p], dtype=np.float64)
    v = v - v.mean(axis=0)
    amp = np.abs(np.fft.rfft(v * np.hanning(len(v))[:, None], axis=0))
    freq = np.fft.rfftfreq(len(v), win.dt)
    f1 = first_peak(freq[1:], amp[1:].mean(axis=1), fraction=0.1)[0]
    sync = sync_index_from_signals(v.astype(np.float32), win.dt, freq_range=(f1 / 8, 2 * f1), null_trials=0,
                                   rule="relative", eta=ETA, workers=1)  # fmt: skip
    low = (freq >= f1 / 8) & (freq <= f1 / 2)
    return {
        "mu_mean": float(mu[g].mean()), "mu_std": float(mu[g].std()), "abs_velocity_mean": float(abs_v[g].mean()),
        "phi": float(np.mean(sync.Phi)), "f1": float(f1), "floor": float(np.median(amp[low].mean(axis=0))),
    }  # fmt: skip


def package_runs(prep: Any, cfg: Any, dt: float, win: Window, log: Log) -> tuple[list[dict], float, int]:
    """The package's `strang` (fp32, the default engine) at ``dt`` [s] over the experiment's plan, every pad in one
    batch: per pad its measures, the stepping wall time [s] and the steps."""
    from aca_warp.studies.runs import batch_at_start, run_engine
    from aca_warp.studies.validation.experiments import Collector

    model, state = batch_at_start(prep.scenes, "cpu", "fp32")
    col = Collector()
    res = run_engine(model, state, engine="auto", duration=prep.plan.duration, integrator="strang", dt=dt,
                     record=prep.plan.record(cfg), sink=col, force=True)  # fmt: skip
    if not res.complete:
        raise RuntimeError(f"strang at {dt:g} s stopped: {res.fault}")
    t, g, pt, vel = col.arrays()
    start = np.concatenate([[0], np.cumsum([s.patches.count for s in prep.scenes])])
    out = [pad_measures(t, g[:, p, 0], g[:, p, 4], pt, vel[:, start[p]:start[p + 1]], win)
           for p in range(len(prep.scenes))]  # fmt: skip
    log(f"  strang {dt:g} s: {res.wall_time:.1f} s, {res.steps} steps")
    return out, float(res.wall_time), int(res.steps)


def prototype_runs(
    prep: Any, cfg: Any, method: str, dt: float, win: Window, log: Log, *, corrected: bool = False
) -> tuple[list[dict], float, int]:
    """The prototype's ``forced-<method>`` (fp64) at ``dt`` [s] over the experiment's plan: per pad its measures
    (with the other readings of μ: :data:`READINGS`), the wall time [s] and the steps. ``corrected``: with the
    stiffness pre-corrected for the leapfrog's dispersion at the step the run takes (``dt`` fitted to the sample
    interval: :meth:`~aca_warp.studies.friction_schemes.Pads.dispersion_corrected`)."""
    from aca_warp.studies import friction_schemes as fs

    pads = fs.load_pads(prep.scenes)
    if corrected:
        pads = pads.dispersion_corrected(fs.fixed_step(dt, cfg.sample_dt)[1])  # for the step the run takes
    t0 = time.perf_counter()
    r = fs.run_fixed(pads, fs.Scheme.parse(f"forced-{method}"), dt, prep.plan.duration, cfg.sample_dt,
                     patch_window=prep.plan.duration - win.start, readings=True)  # fmt: skip
    wall = time.perf_counter() - t0
    rec = r["record"]
    if not r["finite"] or rec.velocity is None:
        raise RuntimeError(f"forced-{method} at {dt:g} s did not stay finite")
    ptime = rec.time[rec.patch_first :][:: cfg.decimation]
    vel = rec.velocity[:: cfg.decimation]
    g = rec.time >= win.start - 1e-12
    assert rec.mu_segment is not None and rec.mu_instant is not None and rec.mu_applied is not None
    out = [pad_measures(rec.time, rec.mu[:, p], rec.sum_abs_velocity[:, p], ptime,
                        vel[:, pads.start[p]:pads.start[p + 1]], win)
           | {"mu_segment_mean": float(rec.mu_segment[g, p].mean()),
              "mu_segment_std": float(rec.mu_segment[g, p].std()),
              "mu_instant_mean": float(rec.mu_instant[g, p].mean()),
              "mu_instant_std": float(rec.mu_instant[g, p].std()),
              "mu_applied_mean": float(rec.mu_applied[g, p].mean())}
           for p in range(pads.pads)]  # fmt: skip
    log(f"  forced-{method}{' (K_c)' if corrected else ''} {dt:g} s: {wall:.1f} s, {r['steps']} steps")
    return out, wall, int(r["steps"])


def prepared(args: argparse.Namespace, log: Log) -> tuple[Any, Any]:
    """The validation's configuration and its prepared hf1 experiment for the seeds asked for."""
    from aca_warp.studies.validation.base import FULL
    from aca_warp.studies.work_precision_stats import prepare_regime

    cfg = dataclasses.replace(FULL, device="cpu", engine="auto", lf_dir=str(Path(args.out) / "lf"), workers=1,
                              seeds=args.seeds, first_seed=args.first_seed)  # fmt: skip
    return cfg, prepare_regime("hf1", cfg, None, log)


def patch_scales(prep: Any, steps: list[float]) -> list[str]:
    """Per pad the medians over its patches of k_diag = k_T + Σ_j k_ij [N/m], F_N [N], the mass [kg] and the disc
    speed v_d [m/s], and the change of a patch's spring force over one step while it moves with the disc,
    k_diag v_d h [N], against its largest friction force F_N max|f| [N] (Eq. 4's maximum)."""
    from aca_warp.studies import friction_schemes as fs

    lines = []
    for scene in prep.scenes:
        p = fs.load_pads([scene])
        kd, fn, vd = np.median(p.K.diagonal()), np.median(p.fn), np.median(p.vd)
        s = np.linspace(1e-4, 2.0, 20001)
        fmax = float(fn) * float(fs.friction(p, s).max())
        moves = ", ".join(f"{kd * vd * h:.3g} N at {h:g} s" for h in steps)
        lines.append(f"seed {scene.initial.seed}: k_diag {kd:.4g} N/m, F_N {fn:.4g} N, m {np.median(p.m):.4g} kg, "
                     f"v_d {vd:.4g} m/s; F_N max|f| {fmax:.3g} N; k_diag v_d h: {moves}")  # fmt: skip
    return lines


def step_errors(pads: Any, h: float, fine: int, settle: float, instants: int, every: float, log: Log) -> dict[str, Any]:
    """The error of one step h [s] of ``forced-thmid`` and ``forced-thmean`` from a synchronous state to the next
    (opening half sub-step, drift, closing half sub-step) against the same interval followed by ``forced-thmid`` at
    h/``fine``: at ``instants`` instants ``every`` [s] apart along that fine trajectory, which starts from the pads'
    start state run ``settle`` [s] into saturation by ``forced-thmid`` at SETTLE_DT.

    A patch crosses zero slip in the interval when its slip, sampled at every fine step, changes sign; its time held
    is the fine steps' time with |slip| < 1/slope. Per sub-step and class of patch (crossing or not) the mean and the
    rms of the velocity error v − v_ref [m/s] at the interval's end, over every patch and instant."""
    from aca_warp.studies import friction_schemes as fs

    ref = fs.SplitStepper(pads, fs.Scheme.parse("forced-thmid"))
    hs = np.full(pads.n, SETTLE_DT)
    for k in range(round(settle / SETTLE_DT)):
        ref.step(hs)
        if (k + 1) % 50000 == 0:
            log(f"  settling: {(k + 1) * SETTLE_DT * 1e3:.1f} of {settle * 1e3:.1f} ms")
    ref.synchronise()
    hf = np.full(pads.n, h / fine)
    per = max(1, round(every / h)) * fine
    width = 1.0 / pads.slope
    errs: dict[str, list[np.ndarray]] = {m: [] for m in PROTOTYPE}
    cross, held = [], []
    for k in range(instants):
        u0, v0 = ref.u.copy(), ref.velocity()
        s_min, s_max, t_held = pads.vd - v0, pads.vd - v0, np.zeros(pads.n)
        for _ in range(fine):
            ref.step(hf)
            s = pads.vd - ref.w
            s_min, s_max = np.minimum(s_min, s), np.maximum(s_max, s)
            t_held += (np.abs(s) < width) * (h / fine)
        v_ref = ref.velocity()
        c = (s_min < 0.0) & (s_max > 0.0)
        cross.append(c)
        held.append(t_held)
        at = dataclasses.replace(pads, u0=u0, v0=v0)  # the fine trajectory's synchronous state as a start state
        for m in PROTOTYPE:
            st = fs.SplitStepper(at, fs.Scheme.parse(f"forced-{m}"))
            st.step(np.full(pads.n, h))
            errs[m].append(st.velocity() - v_ref)
        for _ in range(per - fine):
            ref.step(hf)
        if (k + 1) % 10 == 0:
            log(f"  {k + 1} of {instants} instants")
    c = np.concatenate(cross)
    t = np.concatenate(held)[c]
    out: dict[str, Any] = {"h_s": h, "fine": fine, "instants": instants, "every_s": every, "settle_s": settle,
                           "patch_steps": int(c.size), "crossing": int(c.sum()),
                           "held_s_median": float(np.median(t)) if t.size else None,
                           "held_s_p90": float(np.quantile(t, 0.9)) if t.size else None}  # fmt: skip
    for m in PROTOTYPE:
        e = np.concatenate(errs[m])
        for name, sel in (("crossing", c), ("other", ~c)):
            out[f"{m}_{name}_mean"] = float(e[sel].mean()) if sel.any() else float("nan")
            out[f"{m}_{name}_rms"] = float(np.sqrt(np.mean(e[sel] ** 2))) if sel.any() else float("nan")
    return out


def measure(args: argparse.Namespace, log: Log) -> dict[str, Any]:
    """Every run of the study; the result document."""
    cfg, prep = prepared(args, log)
    win = Window(prep.plan.window_start, cfg.sample_dt * cfg.decimation)
    log(f"hf1, seeds {args.first_seed}…{args.first_seed + args.seeds - 1}: {prep.plan.duration * 1e3:.1f} ms, "
        f"window from {win.start * 1e3:.1f} ms, per-patch samples every {win.dt * 1e6:g} µs")  # fmt: skip
    runs: list[dict[str, Any]] = []

    def add(kind: str, method: str, dt: float, res: tuple[list[dict], float, int]) -> None:
        pads, wall, steps = res
        runs.append({"kind": kind, "method": method, "dt": dt, "wall_s": wall, "steps": steps, "pads": pads})

    add("reference", "strang", args.reference_dt, package_runs(prep, cfg, args.reference_dt, win, log))
    for dt in args.dt:
        add("package", "strang", dt, package_runs(prep, cfg, dt, win, log))
        for m in PROTOTYPE:
            add("prototype", m, dt, prototype_runs(prep, cfg, m, dt, win, log, corrected=args.corrected_stiffness))
    return {
        "what": "hf1 pads saturated: the package's strang and the prototype's sub-steps against a fine strang step",
        "seeds": list(range(args.first_seed, args.first_seed + args.seeds)),
        "duration_s": prep.plan.duration, "window_start_s": win.start, "patch_dt_s": win.dt,
        "machine": {"host": host_cpu(), "platform": platform.platform(), "python": platform.python_version()},
        "command": command_line("friction_crossing.py", args.argv), "runs": runs,
        "corrected_stiffness": bool(args.corrected_stiffness),
    }  # fmt: skip


def joined(docs: list[dict[str, Any]]) -> dict[str, Any]:
    """Result files of the same runs over disjoint seeds as one (pads concatenated run by run, wall times summed)."""
    keys = [[(r["kind"], r["method"], r["dt"]) for r in d["runs"]] for d in docs]
    if any(k != keys[0] for k in keys):
        raise ValueError("the result files hold different runs; join files of the same command with other seeds")
    if len({bool(d.get("corrected_stiffness")) for d in docs}) > 1:
        raise ValueError("the result files mix the prototype's stiffness with its dispersion-corrected one")
    spans = [(round(d["duration_s"] - d["window_start_s"], 9), d["patch_dt_s"]) for d in docs]
    if any(sp != spans[0] for sp in spans):
        raise ValueError(f"the result files analyse different windows (length [s], per-patch interval [s]): {spans}")
    runs = [
        dict(r, pads=[p for d in docs for p in d["runs"][j]["pads"]], wall_s=sum(d["runs"][j]["wall_s"] for d in docs))
        for j, r in enumerate(docs[0]["runs"])
    ]
    return dict(docs[0], runs=runs, seeds=[s for d in docs for s in d["seeds"]])


def t95(n: int) -> float:
    """Student's t quantile of a 95 % two-sided interval for the mean of n paired differences (NaN for n < 2)."""
    from aca_warp.analysis.measures.ensemble import t_quantile

    return t_quantile(0.975, n - 1) if n > 1 else math.nan


def paired_cell(values: np.ndarray, ref: np.ndarray, t: float, relative: bool = True) -> str:
    """A table cell: the mean of the paired differences ``values − ref`` (per seed) ± its half-width with the
    quantile t, and the mean difference relative to the reference's mean."""
    d = values - ref
    half = t * d.std(ddof=1) / math.sqrt(d.size) if d.size > 1 else math.nan
    rel = f" ({100 * d.mean() / ref.mean():+.2f} %)" if relative else ""
    return f"{d.mean():+.3g} ± {half:.2g}{rel}"


def table(doc: dict[str, Any]) -> list[str]:
    """Markdown: per run the ensemble mean of each measure's difference to the reference (± the 95 % half-width of
    the paired differences over the seeds), and the reference's own mean and spread between seeds."""
    ref = next(r for r in doc["runs"] if r["kind"] == "reference")
    n = len(ref["pads"])
    t = t95(n)
    head = "| run | step [s] | wall [s] | " + " | ".join(f"{LABELS[m][0]} [{LABELS[m][1]}]" for m in MEASURES) + " |"
    lines = [head, "|" + "---|" * (3 + len(MEASURES))]
    refvals = {m: np.array([p[m] for p in ref["pads"]]) for m in MEASURES}
    cells = [f"{refvals[m].mean():.5g} (σ {refvals[m].std(ddof=1):.2g})" if n > 1 else f"{refvals[m].mean():.5g}"
             for m in MEASURES]  # fmt: skip
    lines.append(f"| reference: strang (package) | {ref['dt']:g} | {ref['wall_s']:.0f} | " + " | ".join(cells) + " |")
    kc = ", K_c" if doc.get("corrected_stiffness") else ""
    for r in doc["runs"]:
        if r is ref:
            continue
        name = "strang (package)" if r["kind"] == "package" else f"forced-{r['method']} (prototype{kc})"
        cells = [paired_cell(np.array([p[m] for p in r["pads"]]), refvals[m], t, relative=m != "phi")
                 for m in MEASURES]  # fmt: skip
        lines.append(f"| {name} | {r['dt']:g} | {r['wall_s']:.0f} | " + " | ".join(cells) + " |")
    return lines


def readings_table(doc: dict[str, Any]) -> list[str]:
    """Markdown: per prototype run (those that recorded them) μ mean by each reading (:data:`READINGS`) and μ std by
    each instantaneous one, as ensemble mean differences to the reference's μ (± 95 % half-width)."""
    ref = next(r for r in doc["runs"] if r["kind"] == "reference")
    runs = [r for r in doc["runs"] if r["kind"] == "prototype" and "mu_applied_mean" in r["pads"][0]]
    if not runs:
        return []
    t = t95(len(ref["pads"]))
    mean, std = (np.array([p[k] for p in ref["pads"]]) for k in ("mu_mean", "mu_std"))
    cols = [("mu_mean", mean, "μ mean, point [1]"), ("mu_segment_mean", mean, "μ mean, segment [1]"),
            ("mu_instant_mean", mean, "μ mean, instant [1]"), ("mu_applied_mean", mean, "μ mean, applied [1]"),
            ("mu_std", std, "μ std, point [1]"), ("mu_segment_std", std, "μ std, segment [1]"),
            ("mu_instant_std", std, "μ std, instant [1]")]  # fmt: skip
    cols = [c for c in cols if c[0] in runs[0]["pads"][0]]  # files from before the instant reading lack it
    lines = ["| run | step [s] | " + " | ".join(c[2] for c in cols) + " |", "|" + "---|" * (2 + len(cols))]
    kc = ", K_c" if doc.get("corrected_stiffness") else ""
    for r in runs:
        cells = [paired_cell(np.array([p[key] for p in r["pads"]]), refv, t) for key, refv, _ in cols]
        lines.append(f"| forced-{r['method']} (prototype{kc}) | {r['dt']:g} | " + " | ".join(cells) + " |")
    return lines


def report_lines(doc: dict[str, Any]) -> list[str]:
    """The measures' table and, where the prototype's runs recorded them, the readings of μ."""
    more = readings_table(doc)
    return table(doc) + (["", *more] if more else [])


def run_step_errors(args: argparse.Namespace) -> int:
    """``--step-errors``: one pad, the JSON ``OUT/step_errors.json`` and its lines on stdout."""
    from aca_warp.studies import friction_schemes as fs

    log = Log()
    args.seeds = 1
    _, prep = prepared(args, log)
    pads = fs.load_pads(prep.scenes)
    doc = step_errors(pads, args.dt[0], args.fine, args.settle, args.instants, INSTANT_SPACING, log)
    doc |= {"seed": args.first_seed, "machine": {"host": host_cpu(), "python": platform.python_version()},
            "command": command_line("friction_crossing.py", args.argv)}  # fmt: skip
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "step_errors.json", doc)
    print("\n".join(step_error_lines(doc)))
    return 0


def step_error_lines(doc: dict[str, Any]) -> list[str]:
    """Markdown: per sub-step the mean and rms velocity error of one step, crossing patches and the others."""
    held = ("none crosses" if doc["held_s_median"] is None else
            f"median {doc['held_s_median'] * 1e9:.0f} ns, 90 % {doc['held_s_p90'] * 1e9:.0f} ns")  # fmt: skip
    lines = [f"hf1 seed {doc['seed']}, one step of {doc['h_s']:g} s against {doc['fine']} steps of thmid, "
             f"{doc['instants']} instants {doc['every_s'] * 1e6:g} µs apart: {doc['crossing']} of {doc['patch_steps']} "
             f"patch-steps cross zero slip; time held (|slip| < 1/a) of a crossing patch: {held}", "",
             "| sub-step | crossing: mean [m/s] | crossing: rms [m/s] | other: mean [m/s] | other: rms [m/s] |",
             "|---|---|---|---|---|"]  # fmt: skip
    for m in PROTOTYPE:
        lines.append(f"| {m} | {doc[f'{m}_crossing_mean']:+.3g} | {doc[f'{m}_crossing_rms']:.3g} | "
                     f"{doc[f'{m}_other_mean']:+.3g} | {doc[f'{m}_other_rms']:.3g} |")  # fmt: skip
    return lines


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="friction_crossing.py", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--out", default="friction_crossing", help="folder of the result JSON and table")
    ap.add_argument("--seeds", type=int_at_least(1), default=4, help="pads (seeds) of the hf1 experiment (4)")
    ap.add_argument("--first-seed", type=int_at_least(1), default=1, help="seed of the first pad (1)")
    ap.add_argument("--reference-dt", type=positive, default=5e-8, help="reference step of strang [s] (5e-8)")
    ap.add_argument("--dt", type=positive, nargs="+", default=[2.5e-7, 5e-7], help="steps compared [s]")
    ap.add_argument("--scales", action="store_true", help="print the patches' scales per seed (no runs)")
    ap.add_argument(
        "--corrected-stiffness", action="store_true",
        help="run the prototype with its stiffness pre-corrected for the leapfrog's dispersion at each step, "
             "K − (h²/12) K M⁻¹ K (the package's runs unchanged)",
    )  # fmt: skip
    ap.add_argument(
        "--step-errors", action="store_true",
        help="one pad (--first-seed): the error of single steps (--dt, the first) of thmid and thmean against a fine "
             "thmid step, for patches that cross zero slip inside the step and for the others (JSON in --out)",
    )  # fmt: skip
    ap.add_argument("--fine", type=int_at_least(2), default=250, help="--step-errors: fine steps per step (250)")
    ap.add_argument("--instants", type=int_at_least(1), default=100, help="--step-errors: instants (100)")
    ap.add_argument("--settle", type=positive, default=25e-3, help="--step-errors: time into saturation [s] (0.025)")
    ap.add_argument(
        "--report",
        metavar="JSON",
        nargs="+",
        help="print the table of result files (the same runs over disjoint seeds, joined), or of --step-errors files "
        "(one each), instead of running",
    )
    return ap


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)
    args.argv = argv
    if args.step_errors:
        return run_step_errors(args)
    if args.scales:
        print("\n".join(patch_scales(prepared(args, lambda _m: None)[1], args.dt)))
        return 0
    if args.report:
        docs = [json.loads(Path(p).read_text()) for p in args.report]
        if all("h_s" in d for d in docs):  # --step-errors files: one table each
            print("\n\n".join("\n".join(step_error_lines(d)) for d in docs))
        else:
            print("\n".join(report_lines(joined(docs))))
        return 0
    log = Log()
    t0 = time.perf_counter()
    doc = measure(args, log)
    doc["wall_s"] = time.perf_counter() - t0
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "friction_crossing.json"
    write_json(path, doc)
    (out / "friction_crossing.md").write_text("\n".join(report_lines(doc)) + "\n")
    print("\n".join(report_lines(doc)))
    log(f"wrote {path} ({doc['wall_s']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
