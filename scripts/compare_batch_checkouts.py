#!/usr/bin/env python3
"""Compare two checkouts of aca_warp on a batch of saturating hf1 pads: globals, per-patch velocities, final state.

``scripts/compare_checkouts.py`` compares what the commands write (a sweep's shards hold the global outputs only); this
runs one batch of ``--pads`` hf1 pads (initial perturbation 0.01 m/s, seed = the pad's index) on the on-chip engine with
``strang`` at ``--dt`` with the point treatment of zero-slip crossings (where the checkout has the choice), samples
every 1 µs and the per-patch velocities of the second half, once per checkout, each in its own Python process with its
own package view (kernels/ as aca_warp/kernels), and reports the launch layout each took (blocks per pad, threads per
block) and per array whether the two are bit-identical, else how many entries differ and by how much (against the
array's largest value). A kernel change that leaves the arithmetic of the steps alone keeps the
final state (u, u̇) to the bit; one that changes how the compiler rounds a step shows there first. Example (GPU
machine)::

    python3 scripts/compare_batch_checkouts.py build/base . --device cuda:0 --precisions fp32 fp64 --out cmp.txt
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
from compare_checkouts import largest_relative, package_view, refuse_bad_checkouts, run_in_view

from aca_warp.common.argtypes import int_at_least, positive

CHILD = """
import json
import numpy as np
import warp as wp
wp.config.quiet = True
from aca_warp.hf.loop import run_hf
from aca_warp.hf.model import build_model
from aca_warp.hf.options import RunOptions
from aca_warp.hf.state import initial_state
from aca_warp.scene import Initial, Record, preset
a = json.loads(sys.argv[2])
record = Record(sample_dt=1e-6, patches=("velocity",), window=(a["duration"] / 2, a["duration"]))
scenes = [preset("hf1").replace(initial=Initial(perturbation=0.01, seed=k), record=record) for k in range(a["pads"])]
model = build_model(scenes, device=a["device"], precision=a["precision"])
state = initial_state(model)
point = {"crossing": "point"} if "crossing" in RunOptions.__dataclass_fields__ else {}  # the one treatment before
options = RunOptions(integrator="strang", engine="onchip", duration=a["duration"], dt=a["dt"], **point)
res = run_hf(model, state, options)
c = res.collect()
u, v = state.numpy()
np.savez(a["out"], globals=c.globals, velocity=c.velocity, u=u, v=v)
# the launch layout (block_dim: None in checkouts that do not report it)
print(json.dumps({"blocks_per_pad": res.blocks_per_pad, "block_dim": getattr(res, "block_dim", None)}))
"""


def run(checkout: Path, args: argparse.Namespace, precision: str, out: Path, work: Path) -> str:
    """Run the batch with ``checkout``'s package into ``out`` (an .npz); returns its launch layout in words."""
    view = package_view(checkout, Path(tempfile.mkdtemp(dir=work)))
    a = {"pads": args.pads, "device": args.device, "precision": precision, "duration": args.duration}
    a |= {"dt": args.dt, "out": str(out)}
    try:
        out = run_in_view(view, CHILD, [json.dumps(a)])
    except RuntimeError as e:
        raise SystemExit(f"{checkout}: the run failed ({e})") from None
    layout = json.loads(out.strip().splitlines()[-1])
    return f"{layout['blocks_per_pad']} block(s) per pad of {layout['block_dim'] or '?'} threads"


def differences(a: np.ndarray, b: np.ndarray) -> str:
    """'identical', or how many entries differ and their largest difference relative to the first array's largest
    value (``compare_checkouts.largest_relative``)."""
    if np.array_equal(a, b, equal_nan=True):
        return "identical"
    return f"differ: {np.count_nonzero(a != b)} of {a.size}, ≤ {largest_relative(a, b):.2g} relative"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("first", type=Path, help="first checkout (a folder with aca_warp/ and kernels/)")
    ap.add_argument("second", type=Path, help="second checkout")
    ap.add_argument("--device", default="cuda:0", help="Warp device (default cuda:0)")
    ap.add_argument("--precisions", nargs="+", choices=["fp32", "fp64"], default=["fp32", "fp64"])
    ap.add_argument("--pads", type=int_at_least(1), default=64, help="hf1 pads of the batch (default 64)")
    ap.add_argument("--duration", type=positive, default=1e-4, help="simulated time [s] (default 1e-4)")
    ap.add_argument("--dt", type=positive, default=1e-7, help="step [s] (default 1e-7)")
    ap.add_argument("--out", type=Path, default=None, help="also write the report here (text)")
    args = ap.parse_args(argv)
    refuse_bad_checkouts(ap, [args.first, args.second])
    lines = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for precision in args.precisions:
            files = [work / f"{k}_{precision}.npz" for k in (0, 1)]
            layouts = [
                run(checkout, args, precision, out, work)
                for checkout, out in zip((args.first, args.second), files, strict=True)
            ]
            a, b = (np.load(f) for f in files)
            lines.append(f"{precision} layout: {layouts[0]} against {layouts[1]}")
            lines += [f"{precision} {name} {differences(a[name], b[name])}" for name in a.files]
    text = (
        f"{args.pads} hf1 pads, strang at {args.dt:g} s, {args.duration:g} s, device {args.device}: "
        f"{args.first} against {args.second}\n" + "\n".join(lines) + "\n"
    )
    print(text, end="")
    if args.out is not None:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
