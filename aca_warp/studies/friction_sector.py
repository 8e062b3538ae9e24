"""The package's integrators on saturated hf1 sectors: statistics and wall time against a fixed fine step
(docs/friction_step.md, "The kernels on a saturated sector").

The pads are the validation's ``reduced_pad`` sectors of hf1 (``--seeds`` pads of ``--patches`` patches, from
equilibrium + N(0, (0.01 m/s)²) velocities, :func:`~aca_warp.studies.friction_stats.sector_scenes`), run as one
batch on the CPU over ``--duration`` on ``--engine`` (default the general engine; ``auto``: the engine a run of
``aca-warp hf`` takes, on-chip; both give the same bits, the wall times differ). Every setting of ``--runs``
(``INTEGRATOR:DT`` for a fixed step, forced past the stable-step estimate; ``INTEGRATOR:tol=TOL``, the tolerance of
``adaptive`` or the split tolerance of ``controlled`` and ``auto``; or ``INTEGRATOR`` at its default step or
tolerances; each in ``--precision``, fp64 unless asked, unless it ends in ``@fp32`` or ``@fp64``: ``strang@fp32`` is
``strang`` at both its defaults; a run ending in ``/general``, ``/onchip`` or ``/auto`` on that engine, so that the
default on one engine and the reference on another compare within one call) is
compared with ``--reference`` over the last ``--window``: the ensemble means of μ mean, μ std, mean Σ|u̇| and the
velocity-sum peak (:func:`~aca_warp.studies.friction_stats.statistics`, ``compare``), the steps and the wall time of
the stepping loop. Examples::

    python3 scripts/friction_step_sector.py --out docs/figures/friction_step/sector_cpu.json
    python3 scripts/friction_step_sector.py --quick --out OUT/quick.json          # a smoke run of a minute
    python3 scripts/friction_step_sector.py --runs controlled controlled:tol=3e-3 auto adaptive strang:1e-7 \
        --out docs/figures/friction_step/sector_controlled_cpu.json
    python3 scripts/friction_step_sector.py --runs strang@fp32 --engine auto --out OUT/sector_default.json
    python3 scripts/friction_step_sector.py --engine auto --reference strang:1e-8/general \
        --runs strang@fp32 strang:1e-8 --out OUT/sector_default_vs_general.json
    python3 scripts/friction_step_sector.py --report docs/figures/friction_step/sector_cpu.json \
        docs/figures/friction_step/sector_controlled_cpu.json --page docs/friction_step.md
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.common.argtypes import int_at_least, positive
from aca_warp.hf.options import ENGINES, ONCHIP_INTEGRATORS
from aca_warp.studies.report import Log, command_line, generated_markers, md_table, replace_generated, write_json

SCRIPT = "friction_step_sector.py"
RUNS = ("strang:1e-7", "strang:2.5e-7", "strang:5e-7", "strang:1e-6")
REFERENCE = "strang:1e-8"
MEASURES = ("mu_mean", "mu_std", "abs_velocity_mean", "velocity_peak_hz")
ENGINE_TEXT = {"general": "general engine", "onchip": "on-chip engine", "auto": "`auto`'s engine (on chip for strang)"}
LABELS = {"mu_mean": "μ mean", "mu_std": "μ std", "abs_velocity_mean": "Σ|u̇| mean", "velocity_peak_hz": "Σu̇ peak"}


def parse_run(spec: str) -> dict[str, Any]:
    """``INTEGRATOR``, ``INTEGRATOR:DT`` [s] or ``INTEGRATOR:tol=TOL``, each with an optional ``@fp32`` or
    ``@fp64`` and then an optional ``/ENGINE`` (the run's own engine, so that settings on two engines compare within
    one call), as package_run's keywords (TOL: the ``tolerance`` of ``adaptive``, the ``split_tolerance`` of
    ``controlled`` and ``auto``; ``precision`` and ``engine`` only where the spec names them)."""
    from aca_warp.hf.options import INTEGRATORS, tolerance_keyword

    spec_only, slash, engine = spec.partition("/")
    if slash and engine not in ENGINES:
        raise ValueError(f"unknown engine {engine!r} in {spec!r}; choose from {', '.join(ENGINES)}")
    setting, at, precision = spec_only.partition("@")
    if at and precision not in ("fp32", "fp64"):
        raise ValueError(f"unknown precision {precision!r} in {spec!r}; choose fp32 or fp64")
    out: dict[str, Any] = {"precision": precision} if at else {}
    if slash:
        out["engine"] = engine
    name, _, rest = setting.partition(":")
    if name not in INTEGRATORS:
        raise ValueError(f"unknown integrator {name!r} in {spec!r}; choose from {', '.join(INTEGRATORS)}")
    if rest.startswith("tol="):
        out[tolerance_keyword(name)] = float(rest[4:])
    elif rest:
        out["dt"] = float(rest)
    return {"integrator": name, **out}


def run_all(args: argparse.Namespace, log: Log) -> dict[str, Any]:
    """The reference and every run of ``args.runs`` on the sectors; their statistics and errors."""
    from aca_warp.studies.friction_stats import compare, package_run, sector_scenes, statistics

    scenes = sector_scenes(args.seeds, args.patches)
    rows = []
    ref_stats: dict[str, Any] | None = None
    for spec in [args.reference, *args.runs]:
        log(f"{spec}: {len(scenes)} pads × {args.patches} patches, {args.duration * 1e3:g} ms")
        run = {"precision": args.precision, "engine": args.engine, **parse_run(spec)}
        rec, info = package_run(scenes, duration=args.duration, window=0.0, **run)
        stats = statistics(rec, args.window, np.zeros(0), np.zeros(0, dtype=int))
        ref_stats = stats if ref_stats is None else ref_stats
        row = {"run": spec, "wall_s": info["wall_s"], "steps": info["steps"]}
        row |= {"stats": {k: np.asarray(stats[k]).tolist() for k in MEASURES} if stats["finite"] else None}
        row |= {"errors": compare(stats, ref_stats)}
        log(f"  {info['wall_s']:.1f} s, {info['steps']} steps; errors " + _errors_line(row["errors"]))
        rows.append(row)
    return {"reference": args.reference, "runs": rows}


def _errors_line(err: dict[str, Any]) -> str:
    if not err.get("finite", False):
        return "not finite"
    return ", ".join(f"{LABELS[k]} {100 * err[k]:+.2f} %" for k in MEASURES)


def report(doc: dict[str, Any]) -> list[str]:
    """The page's table of a result file."""
    ref = doc["runs"][0]
    head = ["run", "steps", "wall [s]", "× faster", *(LABELS[k] for k in MEASURES)]
    rows = []
    for r in doc["runs"]:
        e = r["errors"]
        errs = [f"{100 * e[k]:+.2f} %" if e.get("finite") else "–" for k in MEASURES]
        rows.append(
            [f"`{r['run']}`", f"{r['steps']:,}", f"{r['wall_s']:.1f}", f"{ref['wall_s'] / r['wall_s']:.1f}", *errs]
        )
    s = doc["setup"]
    lines = [
        f"{s['seeds']} hf1 sector(s) × {s['patches']} patches (the validation's reduced pad, seeds from 1), "
        f"{s['duration'] * 1e3:g} ms from equilibrium + 0.01 m/s, {s['precision']}"
        f"{' (a run ending in @fp32 or @fp64: that precision)' if any('@' in r['run'] for r in doc['runs']) else ''}, "
        f"{ENGINE_TEXT[s.get('engine', 'general')]} on the CPU; "
        f"statistics of the last {s['window'] * 1e3:g} ms against `{doc['reference']}` (ensemble means; the "
        "velocity-sum peak above 20 kHz):",
        "",
        *md_table(head, rows),
        "",
        f"(`{s['command']}`; {s['machine']})",
    ]
    return lines


def _check(args: argparse.Namespace) -> None:
    """Refuse, before anything runs or is written (ValueError or AcaError): a --report file that is not there, a
    --page that cannot be written; without --report, no --out, an unknown run, a run the on-chip engine does not
    implement with ``--engine onchip``, an --out that cannot be written."""
    from aca_warp.common.files import check_output_folder, check_output_path

    if args.report is not None:
        for path in args.report:
            if not path.is_file():
                raise ValueError(f"--report: no result file {path}")
        if args.page is not None:
            check_output_path(args.page, overwrite=True)
        return
    if args.out is None:
        raise ValueError("--out is required (or --report)")
    for spec in [args.reference, *args.runs]:
        run = parse_run(spec)
        if run["integrator"] not in ONCHIP_INTEGRATORS and run.get("engine", args.engine) == "onchip":
            raise ValueError(f"the on-chip engine runs {' and '.join(ONCHIP_INTEGRATORS)} only, not {spec!r}")
    if args.out.is_dir():
        raise ValueError(f"--out {args.out} is a folder; give a file name such as {args.out / 'sector.json'}")
    check_output_folder(args.out.parent)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int_at_least(1), default=1, help="pads (seeds 1 …; default 1)")
    ap.add_argument("--patches", type=int_at_least(1), default=150, help="patches per sector (default 150)")
    ap.add_argument("--duration", type=positive, default=30e-3, help="run length [s] (default 30e-3)")
    ap.add_argument("--window", type=positive, default=10e-3, help="statistics over the last WINDOW [s] (10e-3)")
    ap.add_argument(
        "--precision", choices=("fp32", "fp64"), default="fp64", help="of the runs that name none (default fp64)"
    )
    ap.add_argument(
        "--engine",
        choices=ENGINES,
        default="general",
        help="the engine of every run that names none (default general; auto: on-chip, as aca-warp hf runs; the "
        "same bits)",
    )
    ap.add_argument("--reference", default=REFERENCE, help=f"the reference run (default {REFERENCE})")
    ap.add_argument(
        "--runs",
        nargs="+",
        default=list(RUNS),
        help="INTEGRATOR[:DT | :tol=TOL][@fp32 | @fp64][/ENGINE] (default the grid)",
    )
    ap.add_argument("--quick", action="store_true", help="1 pad × 60 patches × 4 ms, window 2 ms: a smoke run")
    ap.add_argument("--out", type=Path, help="result JSON")
    ap.add_argument(
        "--report", type=Path, nargs="+", help="print the tables of these result JSONs (with --page: into the page)"
    )
    ap.add_argument("--page", type=Path, help="docs page whose generated section --report rewrites")
    args = ap.parse_args(argv)
    from aca_warp.common.errors import AcaError

    try:
        _check(args)
    except (AcaError, ValueError) as e:
        print(f"{SCRIPT}: error: {e}", file=sys.stderr)
        return 2
    if args.report is not None:
        try:
            lines = [line for path in args.report for line in [*report(json.loads(path.read_text())), ""]][:-1]
        except (ValueError, KeyError, TypeError, IndexError) as e:  # JSON that is not this study's results
            print(f"{SCRIPT}: error: --report: not a result file of this study ({type(e).__name__}: {e})",
                  file=sys.stderr)  # fmt: skip
            return 2
        if args.page is not None:
            replace_generated(args.page, lines, generated_markers(f"scripts/{SCRIPT} --report"), "Friction step")
        print("\n".join(lines))
        return 0
    if args.quick:
        args.patches, args.duration, args.window = 60, 4e-3, 2e-3
    from aca_warp.common.files import machine
    from aca_warp.studies.report import init_warp

    wp = init_warp()
    log = Log()
    doc = run_all(args, log)
    setup = {k: getattr(args, k) for k in ("seeds", "patches", "duration", "window", "precision", "engine")}
    setup |= {"command": command_line(SCRIPT, sys.argv[1:] if argv is None else argv)}
    setup |= {"machine": machine(wp.get_device("cpu"))["host"] + " (shared with other jobs)"}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_json(args.out, {"setup": setup, **doc})
    print("\n".join(report({"setup": setup, **doc})))
    return 0
