#!/usr/bin/env python3
"""What a CPU kernel launch costs through ``wp.launch`` and replayed by ``aca_warp.common.launches.Launcher``.

Two measurements on one pad of a preset (default hf1), fp64, on the CPU, each the least over ``--repeat`` rounds of
``--launches`` calls, in turn: the launch alone (``spring_forces`` over one thread: packing and dispatch, next to no
kernel work) and one strang step (``strang_advance`` and ``spring_forces`` over every patch, as ``HFSolver.step``
launches them), each through ``wp.launch`` and through a ``Launcher``. Prints one line per measurement [µs] and,
with ``--json``, writes them with the machine and the date.

    python3 scripts/launch_cost.py --json docs/benchmarks/launch_cost_cpu.json
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

from aca_warp.common.argtypes import int_at_least


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="hf1", help="preset (default hf1)")
    ap.add_argument("--launches", type=int_at_least(1), default=2000, help="calls per round (default 2000)")
    ap.add_argument(
        "--repeat", type=int_at_least(1), default=3, help="rounds per way, in turn; the least is kept (default 3)"
    )
    ap.add_argument("--json", type=Path, help="write the results there (JSON)")
    args = ap.parse_args(argv)

    from aca_warp.common.devices import init_warp

    init_warp()
    import warp as wp
    from aca_warp.kernels import hf as K

    from aca_warp import RunOptions, build_model, initial_state, preset
    from aca_warp.common.errors import AcaError
    from aca_warp.common.files import check_output_path, host_cpu
    from aca_warp.common.launches import Launcher
    from aca_warp.hf.solver import HFSolver
    from aca_warp.studies.report import command_line, write_json

    try:  # every refusal before the first launch: nothing run, nothing written
        scene = preset(args.scene)
        if args.json:
            check_output_path(args.json, overwrite=True)
    except AcaError as e:
        ap.error(str(e))
    model = build_model([scene], device="cpu")
    state = initial_state(model)
    solver = HFSolver.for_run(model, RunOptions(duration=1e-5, integrator="strang"))
    km, n, h = solver.kernel_model, model.patch_count, solver.T(solver.dt)
    step = [(K.strang_advance, n, [km, h, solver.newton_tol, 0, state.force, state.u, state.v])]
    step.append((K.spring_forces, n, [km, state.u, state.force]))
    cases = {"launch": [(K.spring_forces, 1, [km, state.u, state.force])], "strang step": step}
    launcher = Launcher(model.device)
    ways = {
        "wp.launch": lambda k, d, i: wp.launch(k, dim=d, inputs=i, device=model.device),
        "Launcher": launcher,
    }

    def per_call(way, launches) -> float:
        t = time.perf_counter()
        for _ in range(args.launches):
            for kernel, dim, inputs in launches:
                way(kernel, dim, inputs)
        return (time.perf_counter() - t) / args.launches

    result: dict[str, dict[str, float]] = {}
    for case, launches in cases.items():
        for way in ways.values():
            per_call(way, launches)  # kernels loaded, the launcher's records made
        best = {name: min(per_call(way, launches) for _ in range(args.repeat)) for name, way in ways.items()}
        result[case] = {name: 1e6 * s for name, s in best.items()}
        print(f"{case}: " + ", ".join(f"{name} {us:.1f} µs" for name, us in result[case].items()))
    if args.json:
        doc = {
            "date": time.strftime("%Y-%m-%d"),
            "machine": f"{host_cpu()}, {platform.platform()}",
            "scene": args.scene,
            "patches": n,
            "command": command_line("launch_cost.py", sys.argv[1:] if argv is None else argv),
            "microseconds": result,
        }
        write_json(args.json, doc)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
