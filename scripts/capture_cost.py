#!/usr/bin/env python3
"""Wall time of short and long HF runs on the CPU with graphs as the engine chooses them, with every chunk captured,
and with eager launches only: what a graph capture costs against what its replays save.

    python3 scripts/capture_cost.py                  # hf1, strang 2 µs and 200 µs, adaptive 20 µs
    python3 scripts/capture_cost.py --scene hf2 --repeat 3

Each case runs once to warm the kernels, then ``--repeat`` times per mode; the least wall time is printed [s].
``strang`` takes :data:`STRANG_STEP`, named so that runs of other times compare (its default step depends on the
scene and has changed).
"""

from __future__ import annotations

import argparse
import time

STRANG_STEP = 5.0e-8  # s


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="hf1", help="preset (default hf1)")
    ap.add_argument("--repeat", type=int, default=2, help="timed runs per case and mode (default 2)")
    args = ap.parse_args(argv)
    if args.repeat < 1:
        ap.error("--repeat must be at least 1")

    import warp as wp

    wp.config.quiet = True
    from aca_warp import RunOptions, build_model, initial_state, preset, run_hf
    from aca_warp.common.errors import SceneError
    from aca_warp.hf import general
    from aca_warp.hf.engine import EngineTuning

    try:
        scene = preset(args.scene)
    except SceneError as e:
        ap.error(str(e))

    def wall(mode: str, duration: float, integrator: str) -> float:
        use_graph = mode != "eager"
        general.CPU_CAPTURE_REPLAYS = 0 if mode == "always" else 8
        model = build_model([scene], device="cpu")
        state = initial_state(model)
        t = time.perf_counter()
        step = STRANG_STEP if integrator == "strang" else None
        options = RunOptions(duration=duration, integrator=integrator, dt=step)
        run_hf(model, state, options, tuning=EngineTuning(use_graph=use_graph))
        return time.perf_counter() - t

    cases = [(2e-6, "strang"), (2e-5, "adaptive"), (2e-4, "strang")]
    for duration, integrator in cases:
        wall("eager", duration, integrator)
        best = {
            m: min(wall(m, duration, integrator) for _ in range(args.repeat)) for m in ("policy", "always", "eager")
        }
        print(
            f"{args.scene} {integrator} {duration:g} s: graphs as the engine chooses {best['policy']:.3f} s, "
            f"every chunk captured {best['always']:.3f} s, eager {best['eager']:.3f} s"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
