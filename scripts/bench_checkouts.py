#!/usr/bin/env python3
"""Time the HF engines of two checkouts of aca_warp in one run: a restructuring of the kernels must keep their speed.

Per case (engine: on-chip or general; integrator: strang or adaptive; precision; pads of the hf1 preset) each checkout
runs in its own Python process (its own package view and kernel cache, as in ``scripts/compare_checkouts.py``): a
warm-up run of two sample intervals (compile, graph capture), then ``--repeats`` timed runs over ``--window`` [s] of
simulated time, strang with the point treatment of zero-slip crossings where the checkout has the choice (the one
treatment before it; the presets' default since averages them). The checkouts alternate case by case (first, second,
first, …), so drifts of the machine's clock or load hit both alike. Reported per case and checkout: the best and the
median wall time of the stepping loop [s] (``RunResult.wall_time``, graph captures excluded), µs per accepted step, the
launch layout (``blocks_per_pad``, ``block_dim``: None for the general engine and in checkouts that do not report it)
and the ratio second/first of the best times. JSON into ``--out``, rewritten after every row (a run stopped at a time
limit keeps the rows it finished); ``--cache`` keeps the two checkouts' kernel caches for a later call (e.g. the cases
split over two calls). Examples::

    python scripts/bench_checkouts.py OLD NEW --out $OUT/bench --device cuda:0 --cache /tmp/bench_cache
    python scripts/bench_checkouts.py OLD NEW --out /tmp/bench --device cpu --pads 1 --window 2e-6 --repeats 1
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

from compare_checkouts import package_view, run_in_view

# (engine, integrator, extra RunOptions) of every case
CASES = {
    "onchip_strang": ("onchip", "strang", {"dt": 1e-8}),
    "onchip_adaptive": ("onchip", "adaptive", {"tolerance": 1e-5}),
    "general_strang": ("general", "strang", {"dt": 1e-8}),
    "general_adaptive": ("general", "adaptive", {"tolerance": 1e-5}),
    "general_euler": ("general", "symplectic-euler", {"dt": 2e-10}),  # explicit friction: a short step
}
DEFAULT_CASES = ["onchip_strang", "onchip_adaptive", "general_strang", "general_adaptive"]

# runs one case inside a checkout's package view; prints one JSON line
CHILD = """
import json, statistics
import warp as wp
wp.config.quiet = True
from aca_warp.common.files import machine
from aca_warp.hf.loop import run_hf
from aca_warp.hf.model import build_model
from aca_warp.hf.options import RunOptions
from aca_warp.hf.state import initial_state
from aca_warp.scene import preset
a = json.loads(sys.argv[2])
scene = preset(a["scene"])
model = build_model([scene] * a["pads"], device=a["device"], precision=a["precision"])
point = {"crossing": "point"} if "crossing" in RunOptions.__dataclass_fields__ else {}  # the one treatment before
options = RunOptions(engine=a["engine"], integrator=a["integrator"], **{**point, **a["options"]})
run_hf(model, initial_state(model), options.with_duration(2 * scene.record.sample_dt))
walls, steps = [], 0
for _ in range(a["repeats"]):
    res = run_hf(model, initial_state(model), options.with_duration(a["window"]))
    walls.append(res.wall_time)
    steps = res.steps
print(json.dumps({"wall_best": min(walls), "wall_median": statistics.median(walls), "walls": walls,
                  "steps": steps, "us_per_step": 1e6 * min(walls) / max(steps, 1), "machine": machine(model.device),
                  "blocks_per_pad": res.blocks_per_pad, "block_dim": getattr(res, "block_dim", None)}))
"""


def run_case(view: Path, cache: Path, case: dict) -> dict:
    """One case in the checkout of ``view``: the child's JSON line as a dict; raise on failure."""
    try:
        out = run_in_view(view, CHILD, [json.dumps(case)], cache)
    except RuntimeError as e:
        raise RuntimeError(f"{case} failed ({e})") from None
    return json.loads(out.strip().splitlines()[-1])


def growth_refusal(scene: str, growth_dt: float | None, cases: list[str]) -> str | None:
    """Why ``--scene SCENE`` with ``--growth-dt`` cannot be run (an unknown preset; a spacing of growth events for a
    scene that does not grow, or for a choice of cases without ``strang``), or None."""
    from aca_warp.common.errors import AcaError
    from aca_warp.scene import preset

    try:
        grows = preset(scene).growth is not None
    except AcaError as e:
        return f"--scene: {e}"
    if growth_dt is None:
        return None
    if not grows:
        return f"--growth-dt: scene {scene!r} does not grow"
    if not any(CASES[c][1] == "strang" for c in cases):
        return "--growth-dt applies to the strang cases, and none is asked for (--cases)"
    return None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("first", type=Path, help="first checkout (e.g. a worktree of the old commit)")
    ap.add_argument("second", type=Path, help="second checkout")
    ap.add_argument("--out", type=Path, required=True, help="folder for bench_checkouts.json")
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--cases", nargs="+", choices=sorted(CASES), default=DEFAULT_CASES)
    ap.add_argument("--precisions", nargs="+", choices=["fp32", "fp64"], default=["fp32", "fp64"])
    ap.add_argument("--pads", nargs="+", type=int, default=[1, 1024])
    ap.add_argument("--scene", default="hf1")
    ap.add_argument("--window", type=float, default=2e-5, help="timed simulated time per run [s]")
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per case and checkout")
    ap.add_argument(
        "--dt", type=float, default=None, help="step of the fixed-step cases [s] (default: each case's, CASES)"
    )
    ap.add_argument(
        "--growth-dt",
        type=float,
        default=None,
        help="simulated time between the growth events of a growing scene [s] (RunOptions.growth_dt of the strang "
        "cases; default: the scene's own interval)",
    )
    ap.add_argument("--cache", type=Path, default=None, help="kernel caches kept here (default: a temporary folder)")
    args = ap.parse_args(argv)
    for flag, value in (("--dt", args.dt), ("--growth-dt", args.growth_dt)):
        if value is not None and not 0 < value < float("inf"):
            print(f"bench_checkouts: {flag} must be a step > 0 [s], got {value}", file=sys.stderr)
            return 2
    if (why := growth_refusal(args.scene, args.growth_dt, args.cases)) is not None:
        print(f"bench_checkouts: {why}", file=sys.stderr)
        return 2
    for c in (args.first, args.second):
        if not (c / "aca_warp").is_dir() or not (c / "kernels").is_dir():
            print(f"bench_checkouts: {c} is not a checkout of aca_warp (no aca_warp/ and kernels/)", file=sys.stderr)
            return 2
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        views = [package_view(c.resolve(), Path(tmp) / f"v{i}") for i, c in enumerate((args.first, args.second))]
        for name in args.cases:
            engine, integrator, options = CASES[name]
            if args.dt is not None and "dt" in options:
                options = {**options, "dt": args.dt}
            if args.growth_dt is not None and integrator == "strang":
                options = {**options, "growth_dt": args.growth_dt}
            for precision in args.precisions:
                for pads in args.pads:
                    case = {"scene": args.scene, "pads": pads, "device": args.device, "precision": precision}
                    case |= {"engine": engine, "integrator": integrator, "options": options}
                    case |= {"window": args.window, "repeats": args.repeats}
                    got = [run_case(v, (args.cache or Path(tmp)) / f"cache{i}", case) for i, v in enumerate(views)]
                    row = {"case": name, "options": options, "precision": precision, "pads": pads}
                    row |= {"first": got[0], "second": got[1]}
                    row["ratio"] = got[1]["wall_best"] / got[0]["wall_best"]
                    rows.append(row)
                    report = {"first": str(args.first.resolve()), "second": str(args.second.resolve()), "rows": rows}
                    (args.out / "bench_checkouts.json").write_text(json.dumps(report, indent=1))  # after every row
                    print(
                        f"{name:17s} {precision} pads={pads:5d}: {got[0]['us_per_step']:9.3f} -> "
                        f"{got[1]['us_per_step']:9.3f} us/step (second/first {row['ratio']:.3f})",
                        flush=True,
                    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
