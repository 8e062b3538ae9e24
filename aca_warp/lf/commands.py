"""``aca-warp lf SCENE -o LF.h5 [--duration S]``: run the LF automaton over a load schedule into an LF run file."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from aca_warp.argtypes import positive

EPILOG = """\
SCENE is the preset multiscale (paper §3.3: 10 s applications at 10/30/5/15 bar, 5 s pauses, 10 m/s, M = 0.8)
or an LF TOML scene file (docs/lf_model.md). The run file holds /global/time, mu, torque, friction_radius,
patch_count, coverage, temperatures (one row per 0.01 s step) and /snapshots/NAME (start and end of every
application); run HF on one with:  aca-warp hf LF.h5 --snapshot app2_end -o hf.h5
Example:  aca-warp lf multiscale -o lf.h5
"""


def run_lf(
    scene: Any,
    output: str | Path,
    *,
    duration: float | None = None,
    device: str = "cpu",
    overwrite: bool = False,
    progress: bool = False,
    graph: bool | None = None,
) -> Any:
    """Run an LF scene over its schedule (or ``duration`` [s]) into ``output``; returns the simulation."""
    from aca_warp.io import check_output_path
    from aca_warp.lf.io import LFRunWriter
    from aca_warp.lf.solver import LFSimulation

    check_output_path(output, overwrite=overwrite)
    sim = LFSimulation(scene, device=device, duration=duration, graph=graph)
    writer = LFRunWriter(output, sim, overwrite=overwrite)
    try:
        wall = sim.run(on_snapshot=writer.snapshot, progress=progress)
    except KeyboardInterrupt:
        writer.close(complete=False, status="interrupted by the user")
        raise
    except BaseException:
        writer.close(complete=False, status="failed")
        raise
    writer.close(complete=True, status="complete", attrs={"wall_time": wall, "steps_per_second": sim.step_index / wall})
    sim.wall_time = wall
    return sim


def _cmd_lf(args: argparse.Namespace) -> int:
    import dataclasses

    import numpy as np

    from aca_warp.lf.scene import load_lf_scene

    scene = load_lf_scene(args.scene)
    if args.coulomb:
        scene = scene.replace(lf=dataclasses.replace(scene.lf, coulomb=1))
    if args.seed is not None:
        scene = scene.replace(lf=dataclasses.replace(scene.lf, seed=args.seed))
    sim = run_lf(
        scene, args.output, duration=args.duration, device=args.device, overwrite=args.overwrite,
        progress=not args.no_progress, graph=False if args.eager else None,
    )  # fmt: skip
    h = sim.history()
    loaded = h["normal_force"] > 0
    mu = float(np.mean(h["mu"][loaded])) if loaded.any() else 0.0
    print(
        f"{args.output}: {sim.step_index} LF steps over {sim.step_index * scene.lf.dt:.4g} s, "
        f"{len(sim.table.snapshots)} snapshots, mean mu (loaded) {mu:.4f}, final patches "
        f"{int(h['patch_count'][-1])}, coverage {h['coverage'][-1]:.4f}, {sim.step_index / sim.wall_time:.3g} steps/s"
    )
    return 0


def add_parsers(sub: Any) -> None:
    """Register ``aca-warp lf``."""
    p = sub.add_parser(
        "lf",
        help="simulate the low-frequency automaton (patches, wear, temperatures) over a load schedule",
        description="Run the LF automaton (0.01 s steps; docs/lf_model.md) over the scene's schedule of brake "
        "applications and pauses, writing global time series and patch-state snapshots to an HDF5 file.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=EPILOG,
    )
    p.add_argument("scene", metavar="SCENE", help="preset name (multiscale) or LF TOML scene file")
    p.add_argument("-o", "--output", required=True, metavar="LF.h5", help="LF run file to write")
    p.add_argument("--duration", type=positive, metavar="S", help="simulated time [s] (default: the whole schedule)")
    p.add_argument("--device", default="cpu", help="Warp device: cpu (default) or cuda:0, ...")
    p.add_argument("--coulomb", action="store_true", help="constant patch friction (lf.mu_coulomb) for a TEI check")
    p.add_argument("--seed", type=int, help="seed of the random numbers (default: the scene's lf.seed)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    p.add_argument("--no-progress", action="store_true", help="no progress lines")
    p.add_argument("--eager", action="store_true", help="no graph capture of the step (debugging)")
    p.set_defaults(handler=_cmd_lf)


if __name__ == "__main__":  # pragma: no cover
    from aca_warp.cli import main

    sys.exit(main(["lf", *sys.argv[1:]]))
