"""The command line of the validation study (``scripts/validation.py``): the options, the listing, the dry run
(every experiment planned and its cost estimated, nothing run), running the selected experiments (reusing their
checkpoints), evaluating the rows and the candidate causes, and writing ``validation.md``, ``validation.json`` and
the page's generated section.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as _dt
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.studies.report import Log, clean, command_line, generated_markers, replace_generated
from aca_warp.studies.validation import area as validation_area
from aca_warp.studies.validation import causes as validation_causes
from aca_warp.studies.validation import multiscale as validation_multiscale
from aca_warp.studies.validation.base import (
    EXPERIMENTS,
    FULL,
    QUICK,
    ROWS,
    Config,
    Experiment,
    close_pools,
    evaluate_rows,
)
from aca_warp.studies.validation.experiments import Prepared, load_result, prepare, reanalyse, run_experiment
from aca_warp.studies.validation.page import render

MARKER = "scripts/validation.py"  # the generated section's marker on the page


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
