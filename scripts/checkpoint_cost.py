#!/usr/bin/env python3
"""What the default, automatic checkpoints cost an HF and an LF run (``aca_warp.common.checkpoint.CheckpointClock``).

Each run is made twice into a run file, the way ``aca-warp hf`` / ``aca-warp lf`` make it: with the automatic
checkpoints (the default) and with none (``--no-checkpoint``). Reported per run: the wall time of both, the
checkpoints written, the wall time spent writing them and its share of the run (the load-independent figure: both
are measured in the same process under the same load), the mean cost of one checkpoint, and the share that cost
makes at the default spacing (one checkpoint per :data:`~aca_warp.common.checkpoint.AUTO_WALL_S`, the steady state
of a long run). ``--wall S`` spaces the automatic checkpoints S apart instead of the default (more of them in a short
run: a denser sample of their cost; the share at the default spacing is still reported). Examples::

    python3 scripts/checkpoint_cost.py                                    # CPU: hf1 for 1 ms, the LF schedule
    python3 scripts/checkpoint_cost.py --wall 1 --json docs/benchmarks/checkpoint_cost_cpu.json \\
        --markdown docs/benchmarks/checkpoint_cost_cpu.md
    python3 scripts/checkpoint_cost.py --device cuda:0 --hf-duration 0.02 --pads 1024 --wall 1  # a GPU batch
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import warp as wp

from aca_warp.common.argtypes import int_at_least, positive

wp.config.log_level = wp.LOG_WARNING


def hf_runs(args: argparse.Namespace, folder: Path) -> dict:
    """hf ``args.scene`` for ``args.hf_duration`` [s], automatic checkpoints and none; ``args.pads`` copies of it in
    one batch (the file records the first)."""
    from aca_warp.common.files import machine
    from aca_warp.hf.loop import run_hf
    from aca_warp.hf.model import build_model
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.runfile import RunWriter
    from aca_warp.hf.state import initial_state
    from aca_warp.scene import preset

    scene = preset(args.scene)
    out: dict = {"scene": args.scene, "pads": args.pads, "duration_s": args.hf_duration}
    for name, interval in (("none", 0.0), ("automatic", None)):
        model = build_model([scene] * args.pads, device=args.device, precision=args.precision)
        options = RunOptions(duration=args.hf_duration, checkpoint_interval=interval)
        writer = RunWriter(folder / f"hf_{name}.h5", model, overwrite=True)
        t = time.perf_counter()
        res = run_hf(model, initial_state(model), options, sink=writer.write, on_checkpoint=writer.checkpoint)
        writer.close(complete=res.complete, status="complete")
        out[name] = _figures(
            time.perf_counter() - t, res.wall_time, res.checkpoints, res.checkpoint_time, args.default_wall
        )
        out["machine"] = machine(model.device)
        out["steps"] = res.steps
        out["step_s"] = res.dt  # strang's default for the scene (docs/numerics.md)
    return out


def lf_runs(args: argparse.Namespace, folder: Path) -> dict:
    """lf ``multiscale`` for ``args.lf_duration`` [s] (None: its whole schedule), automatic checkpoints and none."""
    from aca_warp.lf import io
    from aca_warp.lf.commands import run_lf
    from aca_warp.lf.scene import load_lf_scene

    spent = {"n": 0, "s": 0.0}
    real = io.LFRunWriter.checkpoint

    def timed(self: io.LFRunWriter, sim: object) -> None:
        t = time.perf_counter()
        real(self, sim)
        spent["n"] += 1
        spent["s"] += time.perf_counter() - t

    io.LFRunWriter.checkpoint = timed  # type: ignore[method-assign]
    scene = load_lf_scene("multiscale")
    out: dict = {"scene": "multiscale", "duration_s": args.lf_duration}
    for name, interval in (("none", 0.0), ("automatic", None)):
        spent.update(n=0, s=0.0)
        t = time.perf_counter()
        sim = run_lf(scene, folder / f"lf_{name}.h5", duration=args.lf_duration, device=args.device, overwrite=True,
                     checkpoint_interval=interval)  # fmt: skip
        out[name] = _figures(time.perf_counter() - t, sim.wall_time, spent["n"], spent["s"], args.default_wall)
        out["steps"] = sim.step_index
    io.LFRunWriter.checkpoint = real  # type: ignore[method-assign]
    return out


def _figures(total: float, stepping: float, count: int, seconds: float, default_wall: float) -> dict:
    """The figures of one run: wall times [s], checkpoints and their wall time [s], shares."""
    each = seconds / count if count else None
    return {
        "wall_s": total,
        "stepping_wall_s": stepping,
        "checkpoints": count,
        "checkpoint_wall_s": seconds,
        "share": seconds / stepping if stepping > 0 else 0.0,
        "seconds_per_checkpoint": each,
        "share_at_default_spacing": None if each is None else each / default_wall,
    }


def markdown(doc: dict) -> str:
    rows = [
        "| run | steps | wall, none [s] | wall, automatic [s] | checkpoints | their wall [s] | share of the run | "
        f"one checkpoint [ms] | share at 1 per {doc['default_wall_s']:g} s |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for key in ("hf", "lf"):
        if key not in doc:
            continue
        r, a, n = doc[key], doc[key]["automatic"], doc[key]["none"]
        each = "–" if a["seconds_per_checkpoint"] is None else f"{1e3 * a['seconds_per_checkpoint']:.3g}"
        at10 = "–" if a["share_at_default_spacing"] is None else f"{100 * a['share_at_default_spacing']:.3g} %"
        label = f"{key} {r['scene']}" + (f" × {r['pads']} pads" if r.get("pads", 1) > 1 else "")
        rows.append(
            f"| {label}, {r['duration_s'] or 'whole schedule'} s | {r['steps']} | {n['wall_s']:.3g} | "
            f"{a['wall_s']:.3g} | {a['checkpoints']} | {a['checkpoint_wall_s']:.3g} | {100 * a['share']:.3g} % | "
            f"{each} | {at10} |"
        )
    head = (
        f"# Cost of the automatic checkpoints\n\n`{doc['command']}` on {doc['machine']}, {doc['date']}; automatic "
        f"checkpoints spaced {doc['wall_s']:g} s apart (default {doc['default_wall_s']:g} s), at most "
        f"{100 * doc['share_bound']:g} % of the run by construction. Load average during the run: {doc['load']:.3g}."
        "\n\n"
    )
    return head + "\n".join(rows) + "\n"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--device", default="cpu")
    p.add_argument("--precision", default="fp64", choices=("fp32", "fp64"))
    p.add_argument("--scene", default="hf1", help="HF preset (default hf1)")
    p.add_argument("--pads", type=int_at_least(1), default=1, help="copies of the HF scene in one batch (default 1)")
    p.add_argument("--hf-duration", type=positive, default=1e-3, help="simulated HF time [s] (default 1 ms)")
    p.add_argument("--lf-duration", type=positive, default=None, help="simulated LF time [s] (default: 55 s schedule)")
    p.add_argument("--only", choices=("hf", "lf"), help="one of the two runs")
    p.add_argument("--wall", type=positive, help="automatic checkpoints this many seconds of wall time apart")
    p.add_argument("--json", type=Path)
    p.add_argument("--markdown", type=Path)
    args = p.parse_args()

    import os

    from aca_warp.common import checkpoint
    from aca_warp.common.devices import get_device
    from aca_warp.common.errors import AcaError
    from aca_warp.common.files import check_output_path
    from aca_warp.scene import preset

    try:  # every refusal before the first run: nothing run, nothing written
        get_device(args.device)
        preset(args.scene)
        for out in (args.json, args.markdown):
            if out:
                check_output_path(out, overwrite=True)
    except AcaError as e:
        p.error(str(e))
    args.default_wall = checkpoint.AUTO_WALL_S
    if args.wall is not None:
        checkpoint.AUTO_WALL_S = args.wall
    doc: dict = {
        "command": "python3 scripts/checkpoint_cost.py " + " ".join(sys.argv[1:]),
        "date": time.strftime("%Y-%m-%d"),
        "wall_s": checkpoint.AUTO_WALL_S,
        "default_wall_s": args.default_wall,
        "share_bound": checkpoint.AUTO_SHARE,
    }
    with tempfile.TemporaryDirectory() as tmp:
        if args.only in (None, "hf"):
            doc["hf"] = hf_runs(args, Path(tmp))
            doc["machine"] = doc["hf"].pop("machine")["device_name"]
        if args.only in (None, "lf"):
            doc["lf"] = lf_runs(args, Path(tmp))
    doc.setdefault("machine", args.device)
    doc["load"] = os.getloadavg()[0]
    print(json.dumps(doc, indent=1))
    if args.json:
        args.json.write_text(json.dumps(doc, indent=1) + "\n")
    if args.markdown:
        args.markdown.write_text(markdown(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
