#!/usr/bin/env python3
"""Where a trial of the on-chip adaptive kernel spends its time: ablation profile on one hf1 pad (or a batch).

Runs the on-chip ``adaptive`` engine (``aca_warp.hf.onchip_adaptive``, its default layout unless ``--cluster`` /
``--block``) on hf1 from rest over ``--duration`` at ``--tolerance`` (fp64, samples every 1 µs), whole and with
parts of the kernel left out — ``gather``: the neighbour sums of the stage evaluations when they use lanes (the
CUDA layout of one pad); ``record``: the samples' global outputs; ``sync``: the barriers between stages; and all
three (an ablated run is wrong and only its time counts) — and the general engine for comparison. Each case: a
warm-up run that compiles, then the best of ``--repeats`` timed runs (the stepping loop's wall time). µs per
trial = wall / (accepted + rejected trials); the difference between the whole kernel and an ablated row is about
the cost of the part left out (an ablated run may take a different number of trials, hence per trial). Writes a
JSON list and a Markdown table.

    python3 scripts/profile_onchip_adaptive.py --device cuda:0 --json $OUT/prof.json --markdown $OUT/prof.md
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

from aca_warp.common.argtypes import int_at_least, positive
from aca_warp.common.devices import get_device
from aca_warp.common.errors import SceneError

CASES = [("whole kernel", ()), ("no gather", ("gather",)), ("no record", ("record",)), ("no stage barriers", ("sync",))]
CASES.append(("none of the three", ("gather", "record", "sync")))


def _parse(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--device", default="cuda:0", help="Warp device (default cuda:0)")
    ap.add_argument("--pads", type=int_at_least(1), default=1, help="identical hf1 pads in the batch (default 1)")
    ap.add_argument("--duration", type=positive, default=1e-3, help="simulated time per timed run [s] (default 1e-3)")
    ap.add_argument("--tolerance", type=positive, default=1e-5, help="adaptive tolerance (default 1e-5)")
    ap.add_argument("--cluster", type=int, default=None, help="blocks per pad (default: the engine's)")
    ap.add_argument("--block", type=int, default=None, help="threads per block (default: the engine's)")
    ap.add_argument(
        "--lanes", type=int, default=None, help="threads per patch of a stage evaluation on CUDA (default: the engine)"
    )
    ap.add_argument("--repeats", type=int_at_least(1), default=2, help="timed runs per case, best kept (default 2)")
    ap.add_argument("--json", type=Path, default=None, help="write the rows here")
    ap.add_argument("--markdown", type=Path, default=None, help="write a table here")
    args = ap.parse_args(argv)
    try:
        get_device(args.device)
    except SceneError as e:
        ap.error(str(e))
    return args


def _time(model, options, tuning, repeats: int) -> dict:
    """Warm-up, then the best of ``repeats`` runs: wall [s], trials, µs per trial, the layout used."""
    from aca_warp.hf.loop import run_hf
    from aca_warp.hf.state import initial_state

    run_hf(model, initial_state(model), options.with_duration(20 * 1e-6), tuning=tuning)
    best = None
    for _ in range(repeats):
        res = run_hf(model, initial_state(model), options, tuning=tuning)
        best = res.wall_time if best is None else min(best, res.wall_time)
    trials = res.steps + res.rejected
    return {"wall_s": best, "trials": trials, "us_per_trial": 1e6 * best / trials, "stages": res.stages}


def main(argv: list[str] | None = None) -> int:
    args = _parse(argv)
    import warp as wp

    wp.config.quiet = True
    from aca_warp.common.files import machine
    from aca_warp.hf import onchip_adaptive
    from aca_warp.hf.loop import EngineTuning
    from aca_warp.hf.model import build_model
    from aca_warp.hf.onchip_adaptive import layout
    from aca_warp.hf.options import RunOptions
    from aca_warp.scene import Record, preset

    if args.lanes is not None:  # the engine's rule with another lane count
        onchip_adaptive.EVAL_LANES = args.lanes
    scene = preset("hf1").replace(record=Record(sample_dt=1e-6))
    model = build_model([scene] * args.pads, device=args.device, precision="fp64")
    options = RunOptions(duration=args.duration, integrator="adaptive", tolerance=args.tolerance)
    info = {**machine(model.device), "warp_version": wp.__version__, "command": " ".join(sys.argv)}
    rows = []
    for label, abl in CASES:
        tuning = EngineTuning(cluster=args.cluster, block_dim=args.block, ablate=frozenset(abl))
        k, lanes, block, _ = layout(model, tuning)
        t0 = time.perf_counter()
        row = {"case": label, "engine": "onchip", "cluster": k, "lanes": lanes, "block": block}
        row.update(_time(model, dataclasses.replace(options, engine="onchip"), tuning, args.repeats))
        print(f"{label}: {row['us_per_trial']:.1f} µs/trial ({row['trials']} trials, {time.perf_counter() - t0:.0f} s)")
        rows.append(row)
    row = {"case": "general engine", "engine": "general", "cluster": 1, "lanes": None, "block": None}
    row.update(_time(model, dataclasses.replace(options, engine="general"), EngineTuning(), args.repeats))
    print(f"general engine: {row['us_per_trial']:.1f} µs/trial")
    rows.append(row)
    doc = {"machine": info, "pads": args.pads, "duration_s": args.duration, "tolerance": args.tolerance, "rows": rows}
    if args.json:
        args.json.write_text(json.dumps(doc, indent=1))
    lines = [
        f"On-chip adaptive profile: {args.pads} hf1 pad(s), fp64, {args.duration:g} s at tol {args.tolerance:g}, "
        f"{info['device_name']}, Warp {info['warp_version']}",
        "",
        "| case | engine | blocks per pad | lanes | threads | trials | wall [s] | µs per trial |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['case']} | {r['engine']} | {r['cluster']} | {r['lanes'] or '–'} | {r['block'] or '–'} | "
            f"{r['trials']} | {r['wall_s']:.3g} | {r['us_per_trial']:.3g} |"
        )
    text = "\n".join(lines) + "\n"
    print(text)
    if args.markdown:
        args.markdown.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
