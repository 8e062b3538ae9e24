"""Friction sub-steps at large steps and an error-controlled default: the measurements behind
docs/friction_step.md (a NumPy prototype on the package's own equations; nothing here runs in the kernels).

Parts (``--parts``, each writes ``OUT/<part>.json``):

* ``single`` — one patch: the sub-steps' stability functions; a sticking patch held under a frozen spring force at
  hγ = 1, 4, 40, 1000 (:func:`~aca_warp.studies.friction_analysis.hold`); the stick-slip cycle of an isolated patch
  at 0.5 m/s against SciPy Radau at rtol 1e-11 for every scheme of ``--schemes`` and step; the held case
  (:data:`HELD_SCENE`, every patch held at hγ = 46).
* ``fixed`` — hf1 sectors (``--seeds`` pads of ``--patches`` patches, the validation's ``reduced_pad``; ``--speed``
  another disc speed) from equilibrium + 0.01 m/s over ``--duration``: every fixed-step run of ``--runs``
  (SCHEME:DT), the statistics of the last ``--window`` against the package's ``strang`` at ``--ref-dt`` (fp64),
  beside the same reference from another draw of the initial velocities (the twin: the floor of a window's
  statistics) and the spread between the seeds.
* ``stability`` — the schemes at 0.95 × the exact spring bound on the sectors and on one whole hf1 pad.
* ``controlled`` — the composite (:class:`~aca_warp.studies.friction_control.Composite`) on the same pads, pad by
  pad, for every setting of ``--controlled`` (:func:`parse_job`): steps, spring and friction evaluations, the same
  statistics errors.
* ``sliding`` — hf1 (the whole pad, from its default start) over 1 ms: μ(t) of the composite (mode E with landing
  and with dense output) and of SciPy DOP853 at rtol 1e-6 against SciPy DOP853 at rtol 1e-11, with their
  evaluation counts.

The references are cached as ``OUT/ref_*.npz``, the fixed-step runs in ``OUT/fixed/`` and the composite's settings
in ``OUT/ctl/``: a rerun redoes only what is missing. ``--report`` prints the tables of OUT's JSONs
(:mod:`aca_warp.studies.friction_report`; with ``--page`` into docs/friction_step.md). Examples::

    python3 scripts/friction_schemes.py --out OUT                  # everything, 4 seeds × 150 patches × 30 ms
    python3 scripts/friction_schemes.py --quick --out OUT          # CPU smoke run (2 seeds × 60 patches × 4 ms)
    python3 scripts/friction_schemes.py --parts single --out OUT
    python3 scripts/friction_schemes.py --report --out docs/figures/friction_step --page docs/friction_step.md
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.common.argtypes import int_at_least, positive
from aca_warp.studies import friction_analysis as fa
from aca_warp.studies import friction_schemes as fs
from aca_warp.studies.friction_stats import (
    SAMPLE_DT,
    compare,
    reference_run,
    sector_scenes,
    seed_spread,
    statistics,
    twin_scenes,
)
from aca_warp.studies.report import Log, clean, command_line, write_json

SETTINGS = ("seeds", "patches", "duration", "window", "ref_dt", "quick", "speed")  # recorded with every result
PARTS = ("single", "fixed", "stability", "controlled", "sliding")
SCHEMES = ("strang-mid", "strang-sdirk2", "forced-mid", "forced-thmid", "forced-be", "forced-sdirk2", "forced-trbdf2")
FEW_SCHEMES = ("strang-mid", "forced-mid", "forced-thmid", "forced-sdirk2")
GRID = ((1e-6, SCHEMES), (5e-7, FEW_SCHEMES), (2.5e-7, SCHEMES), (1e-7, FEW_SCHEMES))  # fixed steps [s], schemes
RUNS = tuple(
    f"{name}:{dt:g}" for dt, names in GRID for name in names
)  # fmt: skip
HGAMMA = (1.0, 4.0, 40.0, 1000.0)
CYCLE_STEPS = (5e-8, 2e-7, 5e-7, 2e-6)
CYCLE_SPEED = 0.5  # m/s: the isolated patch's disc speed (the package's stickslip scene)
CONTROLLED = (
    "I:thmid:rms:f:1e-2",
    "I:thmid:rms:f:3e-3",
    "I:thmid:rms:f:1e-3",
    "I:sdirk2:rms:f:3e-3",
    "EI:thmid:rms:f:1e-2",
)
QUICK = {"seeds": 2, "patches": 60, "duration": 4e-3, "window": 2e-3, "runs": ("strang-mid:1e-6", "forced-thmid:1e-6"),
         "controlled": ("I:thmid:rms:f:1e-2",)}  # fmt: skip


def part_single(args: argparse.Namespace, log: Log) -> dict[str, Any]:
    """Stability functions, the hold test and the isolated patch's cycle (module docstring)."""
    pads = fs.load_pads(sector_scenes(1, args.patches))
    i = int(np.argsort(pads.m)[pads.n // 2])  # the median patch
    p1 = fa.isolated(pads, i)
    out: dict[str, Any] = {
        "patch": {"index": i, "m": p1.m[0], "k_t": p1.kt[0], "normal_force": p1.fn[0], "gamma": p1.gamma_max()[0]},
        "R": {m: {str(z): fs.stability_function(m, -z).real for z in HGAMMA} for m in fs.METHODS},
        "hold": [fa.hold(p1, m, z) for m in fs.METHODS for z in HGAMMA],
    }
    pc = fa.isolated(pads, i, speed=CYCLE_SPEED)
    duration = 2e-4 if not args.quick else 6e-5
    t0 = time.perf_counter()
    ref = fa.cycle_reference(pc, duration, 1e-8)
    mref = fa.cycle_measures(pc, ref, duration / 4)
    log(f"isolated patch at {CYCLE_SPEED} m/s: Radau reference in {time.perf_counter() - t0:.1f} s: {mref}")
    rows = []
    for name in args.schemes:
        for h in CYCLE_STEPS if not args.quick else CYCLE_STEPS[1:]:
            r = fa.limit_cycle(pc, fs.Scheme.parse(name), h, duration)
            m = fa.cycle_measures(pc, r, duration / 4)
            rows.append(
                {
                    "scheme": name,
                    "h": h,
                    "hgamma": h * pc.gamma_max()[0],
                    "period": m["period"] / mref["period"] - 1.0,
                    "amplitude": m["amplitude"] / mref["amplitude"] - 1.0,
                    "mu_mean": m["mu_mean"] - mref["mu_mean"],
                    "stick_share": m["stick_share"],
                    "chatter": r["chatter"],
                    "evals_per_step": r["evals_per_step"],
                }
            )
    out["cycle"] = {"speed": CYCLE_SPEED, "duration": duration, "reference": mref, "rows": rows}
    out["held"] = part_held(args, log)
    return out


# The stated case of tests/test_sanity.py: 40 patches, 20 N, M = 100 (every patch holds to the disc; hγ = 46 at 1e-8 s),
# a stress test of the friction sub-step beyond any real friction coefficient (allow_implausible)
HELD_SCENE = """
[scene]
name = "m100"
allow_implausible = true
[load]
normal_force = 20.0
[disc]
sliding_speed = 10.0
[patches]
count = 40
area_min = 2.0e-8
area_max = 8.0e-8
seed = 4
height = 3.0e-6
[initial]
perturbation = 1.0e-3
seed = 2
[friction]
M = 100.0
"""
HELD_STEPS = (1e-8, 1e-9, 2.5e-10)


def part_held(args: argparse.Namespace, log: Log) -> dict[str, Any]:
    """Mean μ over 20 µs (samples every 0.1 µs) of the held case (:data:`HELD_SCENE`) for every scheme and step;
    the reference is forced-sdirk2 at 2.5e-10 s (the package's implicit-friction gives 55.24, the test's figure)."""
    import tempfile

    from aca_warp.scene import load_scene

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "m100.toml"
        path.write_text(HELD_SCENE)
        pads = fs.load_pads([load_scene(path)])
    rows = []
    for name in args.schemes:
        for h in HELD_STEPS if not args.quick else HELD_STEPS[:1]:
            r = fs.run_fixed(pads, fs.Scheme.parse(name), h, 2e-5, 1e-7)
            rows.append({"scheme": name, "h": h, "hgamma": h * float(pads.gamma_max().max()),
                         "mu_mean": float(np.mean(r["record"].mu))})  # fmt: skip
    log(f"held case: {len(rows)} runs")
    return {"rows": rows}


def references(args: argparse.Namespace, scenes: list[Any], log: Log) -> tuple[dict, dict, dict]:
    """Statistics of the reference run and of its twin (another start of the same pads), and run information."""
    from aca_warp.analysis.saturation import saturation

    out = Path(args.out)
    main, info = reference_run(scenes, args.ref_dt, args.duration, args.window, cache=out / "ref_main.npz", log=log)
    twin, tinfo = reference_run(
        twin_scenes(scenes), args.ref_dt, args.duration, args.window, cache=out / "ref_twin.npz", log=log
    )
    sat = [saturation(main.time, main.sum_abs_velocity[:, p], statistic="mean").t_s for p in range(len(scenes))]
    vd, start = vd_start(scenes)
    s_main, s_twin = statistics(main, args.window, vd, start), statistics(twin, args.window, vd, start)
    info = {**info, "saturated_from_s": sat, "twin_wall_s": tinfo["wall_s"], "twin_seeds": tinfo["seeds"]}
    return s_main, s_twin, info


def vd_start(scenes: list[Any]) -> tuple[np.ndarray, np.ndarray]:
    """Disc speed at every patch [m/s] and the pads' patch offsets of a batch of scenes."""
    pads = fs.load_pads(scenes)
    return pads.vd, pads.start


def part_fixed(args: argparse.Namespace, log: Log) -> dict[str, Any]:
    """Every scheme at every fixed step on the sectors, statistics errors against the reference."""
    scenes = sector_scenes(args.seeds, args.patches, speed=args.speed)
    s_ref, s_twin, info = references(args, scenes, log)
    pads = fs.load_pads(scenes)
    folder = Path(args.out) / "fixed"
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    for name, dt in (parse_run(r) for r in args.runs):
        path = folder / f"{name}_{dt:g}.json"
        if path.exists() and json.loads(path.read_text()).get("duration", args.duration) == args.duration:
            doc = json.loads(path.read_text())
        else:
            t0 = time.perf_counter()
            r = fs.run_fixed(pads, fs.Scheme.parse(name), dt, args.duration, SAMPLE_DT, patch_window=args.window)
            doc = {k: v for k, v in r.items() if k != "record"}
            doc |= {"scheme": name, "wall_s": time.perf_counter() - t0, "duration": args.duration}
            doc["stats"] = statistics(r["record"], args.window, pads.vd, pads.start)
            write_json(path, clean(doc))
            doc = json.loads(path.read_text())
        errors = compare(doc["stats"], s_ref)
        log(f"{name} at {dt:g} s: {fmt_errors(errors)} ({doc['wall_s']:.0f} s)")
        rows.append({k: doc[k] for k in ("scheme", "dt", "steps", "evals_per_step", "chatter", "wall_s")} | errors)
    return {
        "reference": info,
        "reference_stats": s_ref,
        "floor": compare(s_twin, s_ref),
        "seed_spread": seed_spread(s_ref),
        "rows": rows,
    }


def part_stability(args: argparse.Namespace, log: Log) -> dict[str, Any]:
    """The split schemes at 0.95 × the exact spring bound 2/ω_max on the sectors and on one whole hf1 pad: bounded or
    not, the largest patch speed over the disc speed, μ mean and standard deviation of the last window, chatter."""
    rows = []
    sectors = sector_scenes(args.seeds, args.patches, speed=args.speed)
    for what, scenes in (("sector", sectors), ("pad", sector_scenes(1, None, speed=args.speed))):
        if what == "pad" and args.quick:
            continue
        pads = fs.load_pads(scenes)
        bound = 2.0 / pads.omega_max()
        h = 0.95 * bound
        for name in STABILITY_SCHEMES:
            t0 = time.perf_counter()
            r = fs.run_fixed(pads, fs.Scheme.parse(name), h, args.duration, h)
            rec, n = r["record"], round(args.window / h)
            vmax = float(np.nanmax(np.abs(rec.sum_abs_velocity[-n:]))) if r["finite"] else math.inf
            rows.append(
                {
                    "what": what, "patches": pads.n, "scheme": name, "spring_bound": bound, "h": r["dt"],
                    "hgamma_max": float(r["dt"] * pads.gamma_max().max()), "finite": r["finite"],
                    "mu_mean": rec.mu[-n:].mean(axis=0) if r["finite"] else None,
                    "mu_std": rec.mu[-n:].std(axis=0) if r["finite"] else None,
                    "sum_abs_velocity_max_over_n_vd": vmax / float(np.abs(pads.vd).max() * pads.n / pads.pads),
                    "chatter": r["chatter"], "evals_per_step": r["evals_per_step"],
                    "wall_s": time.perf_counter() - t0,
                }
            )  # fmt: skip
            log(f"stability {what} {name} at {h:.3g} s (0.95 × 2/ω_max): finite {r['finite']}")
    return {"rows": rows}


STABILITY_SCHEMES = ("strang-mid", "forced-mid", "forced-thmid", "forced-sdirk2")


def parse_run(run: str) -> tuple[str, float]:
    """``SCHEME:DT`` (e.g. ``forced-thmid:2.5e-7``) as (scheme, step [s])."""
    name, _, dt = run.partition(":")
    fs.Scheme.parse(name)
    try:
        h = float(dt)
    except ValueError:
        raise ValueError(f"bad fixed run {run!r}: SCHEME:DT, e.g. forced-thmid:2.5e-7") from None
    if not h > 0:
        raise ValueError(f"bad fixed run {run!r}: the step must be > 0 s")
    return name, h


def fmt_errors(e: dict[str, Any]) -> str:
    """One line of the main statistics errors."""
    if not e.get("finite", False):
        return "not finite"
    return (
        f"mu mean {e['mu_mean']:+.2%}, mu std {e['mu_std']:+.1%}, sum|v| {e['abs_velocity_mean']:+.2%}, "
        f"peak {e['ensemble_velocity_peak_hz']:+.2%}, spectra {e['mu_bands']:.3f}/{e['velocity_bands']:.3f}"
    )


def parse_job(job: str) -> dict[str, Any]:
    """A composite setting ``MODES:METHOD:NORM:ERRORS:TOL_I`` (e.g. ``I:sdirk2:rms:f:3e-3``): modes (EI
    switching, I only), mode I's sub-step (sdirk2, mid, thmid), pad norm (rms, max), error parts (f: spring and
    friction, s: spring only), tol_i."""
    modes, method, norm, parts, tol = job.split(":")
    if (
        modes not in ("EI", "I")
        or method not in ("sdirk2", "mid", "thmid")
        or norm not in ("rms", "max")
        or parts not in "fs"
    ):
        raise ValueError(f"bad composite setting {job!r}: MODES:METHOD:NORM:ERRORS:TOL_I, e.g. I:sdirk2:rms:f:3e-3")
    return {"modes": modes, "method": method, "norm": norm, "friction_error": parts == "f", "tol_i": float(tol)}


def part_controlled(args: argparse.Namespace, log: Log) -> dict[str, Any]:
    """The composite on every pad of the sectors for every setting of ``--controlled``; statistics errors and work
    (each setting cached as OUT/ctl/<setting>.json)."""
    from aca_warp.studies.friction_control import Composite

    scenes = sector_scenes(args.seeds, args.patches, speed=args.speed)
    s_ref, _, info = references(args, scenes, log)
    pads = fs.load_pads(scenes)
    rows = []
    for job in args.controlled:
        path = Path(args.out) / "ctl" / f"{job.replace(':', '_')}.json"
        if not path.exists():
            kw = parse_job(job)
            recs, counts, t0 = [], [], time.perf_counter()
            for p in range(pads.pads):
                c = Composite(pads.subset([p]), tol_e=args.tol_e, patch_window=args.window, **kw)
                recs.append(c.run(args.duration))
                counts.append(dataclasses.asdict(c.counts))
            rec = fs.Record(
                recs[0].time, *(np.concatenate([getattr(r, k) for r in recs], axis=1) for k in
                                ("mu", "sum_velocity", "sum_abs_velocity", "velocity")), recs[0].patch_first,
            )  # fmt: skip
            errors = compare(statistics(rec, args.window, pads.vd, pads.start), s_ref)
            path.parent.mkdir(parents=True, exist_ok=True)
            doc = {"job": job, "counts": counts, "errors": errors, "wall_s": time.perf_counter() - t0}
            write_json(path, clean(doc))
        doc = json.loads(path.read_text())
        mean = lambda f, c=doc["counts"]: float(np.mean([f(x) for x in c]))  # noqa: E731
        row = {
            "job": job,
            **parse_job(job),
            "steps_per_pad": mean(lambda x: x["accepted"]["E"] + x["accepted"]["I"]),
            "rejected_per_pad": mean(lambda x: x["rejected"]["E"] + x["rejected"]["I"]),
            "accepted_E": mean(lambda x: x["accepted"]["E"]),
            "accepted_I": mean(lambda x: x["accepted"]["I"]),
            "gathers_per_pad": mean(lambda x: x["gathers"]),
            "evals_per_patch": mean(lambda x: x["evals"]),
            "mean_step_I": mean(lambda x: x["time"]["I"] / max(x["accepted"]["I"], 1)),
            "wall_s": doc["wall_s"],
            "strang_steps": round(args.duration / args.ref_dt),
        } | doc["errors"]
        log(f"composite {job}: {row['steps_per_pad']:.0f} steps/pad, {row['gathers_per_pad']:.0f} gathers/pad; "
            f"{fmt_errors(doc['errors'])}")  # fmt: skip
        rows.append(row)
    return {"reference": info, "rows": rows}


def part_sliding(args: argparse.Namespace, log: Log) -> dict[str, Any]:
    """hf1 over 1 ms from its default start: μ errors and evaluation counts (module docstring)."""
    from aca_warp.hf.reference import ReferenceODE
    from aca_warp.studies.friction_control import Composite
    from aca_warp.studies.runs import batch_at_start
    from aca_warp.studies.time_to_solution import make_scene

    duration = 1e-3 if not args.quick else 2e-4
    scene = make_scene("hf1")
    pads = fs.load_pads([scene])
    model, _ = batch_at_start([scene], "cpu", "fp64")
    ode = ReferenceODE(model)
    times = np.arange(round(duration / SAMPLE_DT) + 1) * SAMPLE_DT
    ref = ode.solve(times, method="DOP853", rtol=1e-11, u0=pads.u0, v0=pads.v0)
    mu_ref = ode.globals(ref.u, ref.v)["mu"]
    log(f"hf1 sliding: DOP853 rtol 1e-11 reference in {ref.wall_time:.1f} s")
    rows = []
    for rtol in (1e-6,):
        sol = ode.solve(times, method="DOP853", rtol=rtol, u0=pads.u0, v0=pads.v0)
        err = float(np.abs(ode.globals(sol.u, sol.v)["mu"] - mu_ref).max())
        rows.append({"solver": f"SciPy DOP853 rtol {rtol:g}", "evaluations": sol.nfev, "mu_error": err,
                     "wall_s": sol.wall_time})  # fmt: skip
    for dense in (False, True):
        for tol in (1e-5, 3e-5):
            c = Composite(pads, tol_e=tol, tol_i=parse_job(args.controlled[0])["tol_i"], dense=dense)
            t0 = time.perf_counter()
            rec = c.run(duration)
            rows.append(
                {
                    "solver": f"composite, DP5 tol {tol:g}, {'dense output' if dense else 'landing on samples'}",
                    "evaluations": c.counts.gathers,
                    "mu_error": float(np.abs(rec.mu[:, 0] - mu_ref).max()),
                    "accepted": c.counts.accepted,
                    "rejected": c.counts.rejected,
                    "switches": c.counts.switches,
                    "wall_s": time.perf_counter() - t0,
                }
            )
            log(f"{rows[-1]['solver']}: {rows[-1]['evaluations']} evaluations, μ error {rows[-1]['mu_error']:.2g}")
    return {"duration": duration, "patches": pads.n, "rows": rows}


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="friction_schemes.py",
        description="Friction sub-steps at large steps and an error-controlled default: a NumPy prototype on the "
        "package's HF equations (docs/friction_step.md). Writes OUT/<part>.json.",
    )
    ap.add_argument("--out", required=True, help="result folder (JSON, cached reference runs)")
    ap.add_argument("--report", action="store_true", help="print the markdown tables of OUT's JSONs, run nothing")
    ap.add_argument("--page", help="with --report: rewrite this page's generated section from OUT/{study,hf1,ss}")
    ap.add_argument("--parts", nargs="+", default=list(PARTS), choices=PARTS, help="what to measure (default all)")
    ap.add_argument("--quick", action="store_true", help=f"a CPU smoke run: {QUICK}")
    ap.add_argument(
        "--seeds", type=int_at_least(1), default=4, help="pads (seeds 1 …) of the sector ensemble (default 4)"
    )
    ap.add_argument("--patches", type=int_at_least(2), default=150, help="patches per sector (default 150)")
    ap.add_argument("--duration", type=positive, default=30e-3, help="simulated time [s] (default 0.03)")
    ap.add_argument("--window", type=positive, default=10e-3, help="statistics over the last WINDOW s (default 0.01)")
    ap.add_argument("--ref-dt", type=positive, default=1e-8, help="step of the strang reference [s] (default 1e-8)")
    ap.add_argument("--schemes", nargs="+", default=list(SCHEMES), help="split schemes: strang-<m> / forced-<m>")
    ap.add_argument("--runs", nargs="+", default=list(RUNS), help="fixed-step runs SCHEME:DT (default: the grid)")
    ap.add_argument("--tol-e", type=positive, default=1e-5, help="mode E (DP5) tolerance (default 1e-5)")
    ap.add_argument("--controlled", nargs="+", default=list(CONTROLLED),
                    help="composite settings MODES:METHOD:NORM:ERRORS:TOL_I (parse_job)")  # fmt: skip
    ap.add_argument("--speed", type=positive, help="disc speed at the mean radius [m/s] (default: the preset's)")
    return ap


def _check(args: argparse.Namespace) -> None:
    """Refuse, before anything runs or is written (ValueError or AcaError): with --report, an --out that is no
    folder or a --page that cannot be written; else an unknown scheme, setting or run, a window longer than the run,
    an --out that cannot be made."""
    from aca_warp.common.files import check_output_folder, check_output_path

    if args.report:
        if not Path(args.out).is_dir():
            raise ValueError(f"--out {args.out}: no folder of results")
        if args.page:
            check_output_path(args.page, overwrite=True)
        return
    for name in args.schemes:
        fs.Scheme.parse(name)
    for job in args.controlled:
        parse_job(job)
    for run in args.runs:
        parse_run(run)
    if not args.window <= args.duration:
        raise ValueError("need --window <= --duration")
    check_output_folder(args.out)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    args = build_parser().parse_args(argv)
    if args.quick:
        for k, v in QUICK.items():
            setattr(args, k, v)
    from aca_warp.common.errors import AcaError

    try:
        _check(args)
    except (AcaError, ValueError) as e:
        print(f"friction_schemes.py: error: {e}", file=sys.stderr)
        return 2
    if args.report:
        from aca_warp.studies.friction_report import report, write_page

        if args.page:
            write_page(Path(args.out), Path(args.page))
        else:
            print("\n".join(report(Path(args.out))))
        return 0
    from aca_warp.studies.report import init_warp

    wp = init_warp()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    log = Log()
    parts = {"single": part_single, "fixed": part_fixed, "stability": part_stability, "controlled": part_controlled,
             "sliding": part_sliding}  # fmt: skip
    from aca_warp.common.files import machine

    for name in args.parts:
        t0 = time.perf_counter()
        doc = parts[name](args, log)
        doc |= {
            "command": command_line("friction_schemes.py", argv),
            "machine": machine(wp.get_device("cpu")),
            "wall_s": time.perf_counter() - t0,
            "settings": {k: getattr(args, k) for k in SETTINGS},
        }
        write_json(out / f"{name}.json", clean(doc))
        log(f"{name}: {out / (name + '.json')} ({doc['wall_s']:.0f} s)")
    return 0 if math.isfinite(log.elapsed()) else 1
