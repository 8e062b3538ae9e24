#!/usr/bin/env python3
"""Time the general and the on-chip HF engine side by side on the CPU, and check that they give the same bits.

Per case (a batch of pads) and precision, the same ``strang`` run (its default step unless ``--dt``) on both engines
(``RunOptions.engine``), ``--repeats`` times in turn: a warm-up of two sample intervals (compilation), then
``--duration`` [s] timed from the scene's initial state. Every timed run's μ(t) and final state must be equal between
the engines bit for bit, else the script stops with exit code 1. Cases: ``hf1`` (the whole 1758-patch pad),
``varying_area`` (hf1's patches growing: a growth event and contact re-solve every 0.202 µs),
``sectorN`` (the validation's hf1 pad of seed 1 cut to N patches, from equilibrium + 0.01 m/s, as
``scripts/friction_step_sector.py`` runs it), ``sectorsKxN`` (K such pads, seeds 1 … K, one batch). Writes a JSON
document (``--json``) and a Markdown table (``--markdown``). Example (the figures of docs/onchip.md, "On the CPU")::

    python3 scripts/bench_cpu_engines.py --duration 2e-3 --precisions fp64 fp32 \
        --json docs/benchmarks/cpu_engines/cpu_engines.json --markdown docs/benchmarks/cpu_engines/cpu_engines.md
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.common.argtypes import int_at_least, positive
from aca_warp.common.errors import AcaError
from aca_warp.common.files import check_output_path

DEFAULT_CASES = ["hf1", "sector150", "sector60", "sectors4x150"]
ENGINES = ("general", "onchip")


def case_scenes(case: str) -> list[Any]:
    """The pads of a case name (module docstring); SceneError for a name it does not know."""
    from aca_warp.common.errors import SceneError
    from aca_warp.scene import preset
    from aca_warp.studies.friction_stats import sector_scenes

    if case in ("hf1", "varying_area"):
        return [preset(case)]
    m = re.fullmatch(r"sector(\d+)|sectors(\d+)x(\d+)", case)
    if m is None:
        raise SceneError(f"unknown case {case!r}: hf1, varying_area, sectorN or sectorsKxN")
    if m.group(1):
        return sector_scenes(1, int(m.group(1)))
    return sector_scenes(int(m.group(2)), int(m.group(3)))


def time_engine(scenes: list[Any], engine: str, precision: str, dt: float | None, duration: float) -> dict[str, Any]:
    """One warm-up and one timed run of ``scenes`` on ``engine``: wall [s], steps, μ(t) and the final state."""
    from aca_warp.hf.loop import run_hf
    from aca_warp.hf.model import build_model
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.state import initial_state

    model = build_model(scenes, device="cpu", precision=precision)
    opts = RunOptions(integrator="strang", dt=dt, engine=engine)
    run_hf(model, initial_state(model), opts.with_duration(2 * scenes[0].record.sample_dt))  # compiles
    state = initial_state(model)
    t0 = time.perf_counter()
    res = run_hf(model, state, opts.with_duration(duration))
    wall = time.perf_counter() - t0
    return {
        "wall": wall,
        "steps": res.steps,
        "step_s": res.dt,
        "patches": model.patch_count,
        "mu": res.collect().globals[:, :, 0],
        "state": [a.copy() for a in state.numpy()],
    }


def run_case(case: str, precision: str, dt: float | None, duration: float, repeats: int) -> dict[str, Any]:
    """Both engines ``repeats`` times in turn; the best wall of each and the check that they agree bit for bit."""
    scenes = case_scenes(case)
    walls: dict[str, list[float]] = {e: [] for e in ENGINES}
    ref: dict[str, Any] = {}
    for _ in range(repeats):
        for engine in ENGINES:
            r = time_engine(scenes, engine, precision, dt, duration)
            walls[engine].append(r["wall"])
            if not ref:
                ref = r
            elif not (np.array_equal(r["mu"], ref["mu"]) and all(map(np.array_equal, r["state"], ref["state"]))):
                raise AssertionError(f"{case} {precision}: the {engine} engine's run differs from the general one's")
    best = {e: min(w) for e, w in walls.items()}
    return {
        "case": case,
        "pads": len(scenes),
        "patches": ref["patches"],
        "precision": precision,
        "steps": ref["steps"],
        "step_s": ref["step_s"],
        "walls": walls,
        "us_per_step": {e: best[e] / ref["steps"] * 1e6 for e in ENGINES},
        "speedup": best["general"] / best["onchip"],
        "bit_identical": True,
    }


def _step(row: dict[str, Any]) -> str:
    """A row's step [s] (``?`` in a result file written before the rows named it)."""
    return "?" if row.get("step_s") is None else f"{row['step_s']:g}"


def markdown(doc: dict[str, Any]) -> str:
    """The result table."""
    m = doc["machine"]
    lines = [
        f"# strang on the CPU: general against on-chip engine ({m['device_name']}, Warp {doc['warp_version']})",
        "",
        f"`{doc['command']}`; {doc['duration_s']:g} s per run, best of {doc['repeats']}, step "
        f"{doc['dt_s'] if doc['dt_s'] else 'the default of each case'}; μ(t) and final state bit-identical between the "
        "engines.",
        "",
        "| case | pads | patches | precision | step [s] | steps | general [µs/step] | on chip [µs/step] "
        "| on chip speed-up |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in doc["results"]:
        us = r["us_per_step"]
        lines.append(
            f"| {r['case']} | {r['pads']} | {r['patches']} | {r['precision']} | {_step(r)} | {r['steps']} | "
            f"{us['general']:.2f} | "
            f"{us['onchip']:.2f} | {r['speedup']:.2f}× |"
        )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", nargs="+", default=DEFAULT_CASES, help=f"cases (default {' '.join(DEFAULT_CASES)})")
    ap.add_argument("--precisions", nargs="+", choices=("fp32", "fp64"), default=["fp64"], help="(default fp64)")
    ap.add_argument("--dt", type=positive, help="strang's step [s] (default: its default step)")
    ap.add_argument("--duration", type=positive, default=2e-4, help="timed simulated time per run [s] (default 2e-4)")
    ap.add_argument("--repeats", type=int_at_least(1), default=2, help="timed runs per engine (default 2)")
    ap.add_argument("--json", type=Path, help="write the results here")
    ap.add_argument("--markdown", type=Path, help="write a table here")
    args = ap.parse_args(argv)

    import warp as wp

    from aca_warp.common.devices import init_warp
    from aca_warp.common.files import machine
    from aca_warp.studies.report import command_line

    try:  # every refusal before the first run
        for case in args.cases:
            case_scenes(case)
        for out in (args.json, args.markdown):
            if out is not None:
                check_output_path(out, overwrite=True)
    except AcaError as e:
        ap.error(str(e))
    init_warp()
    results = []
    for case in args.cases:
        for prec in args.precisions:
            try:
                row = run_case(case, prec, args.dt, args.duration, args.repeats)
            except AssertionError as e:
                print(f"bench_cpu_engines.py: {e}", file=sys.stderr)
                return 1
            us = row["us_per_step"]
            print(
                f"{case:14s} {prec} {row['patches']:6d} patches: general {us['general']:8.2f}, on chip "
                f"{us['onchip']:8.2f} µs/step ({row['speedup']:.2f}×), bit-identical",
                flush=True,
            )
            results.append(row)
    doc = {
        "command": command_line("bench_cpu_engines.py", sys.argv[1:] if argv is None else argv),
        "machine": machine(wp.get_device("cpu")),
        "warp_version": wp.__version__,
        "duration_s": args.duration,
        "dt_s": args.dt,
        "repeats": args.repeats,
        "results": results,
    }
    if args.json is not None:
        args.json.write_text(json.dumps(doc, indent=1) + "\n")
    if args.markdown is not None:
        args.markdown.write_text(markdown(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
