#!/usr/bin/env python3
"""What the recorder's hand-over to the host costs in a saturated-regime batch, with the package's flush and with the
whole-buffer copy it replaced, side by side on one device.

One batch of a validation experiment (default hf1: ``--seeds`` pads, ``--duration`` into saturation, per-patch
velocities over the last ``--window``, as the statistical work-precision runs it) is run ``--repeat`` times each
way, the two ways in turn, after a short untimed run that loads the kernels:

* ``rows`` — the package's flush (``aca_warp.hf.recorder.rows_to_host``): after every launch only the rows the
  launch filled are copied to the host;
* ``whole`` — the flush before it: every launch copied each whole device buffer (``buffer.numpy()``) and cut the
  filled rows out on the host, also before the window, where no per-patch row is filled.

The samples go to a sink that only counts them. Prints the wall time of each run [s] and, with ``--json``, writes
them with the least per way, the bytes handed over, the machine and the command.

    python3 scripts/recorder_flush_cost.py --device cuda:0 --seeds 32 \
        --json docs/benchmarks/recorder/recorder_flush_32hf1_h200.json
"""

from __future__ import annotations

import argparse
import dataclasses
import platform
import sys
import time
from pathlib import Path
from typing import Any

WAYS = ("rows", "whole")


def whole_buffer(buffer: Any, rows: int) -> Any:
    """The hand-over before the package's: the whole buffer to the host, the filled rows cut out there."""
    return buffer.numpy()[:rows].copy()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--device", default="cpu", help="Warp device (default cpu)")
    ap.add_argument("--experiment", default="hf1", help="validation experiment whose batch is run (default hf1)")
    ap.add_argument("--seeds", type=int, default=32, help="pads (seeds 1 …) (default 32)")
    ap.add_argument("--patches", type=int, default=None, help="patches per pad: a sector (default: the preset's)")
    ap.add_argument("--duration", type=float, default=30e-3, help="run length [s] (default 30e-3)")
    ap.add_argument("--window", type=float, default=10e-3, help="per-patch window at the end [s] (default 10e-3)")
    ap.add_argument("--dt", type=float, default=5e-8, help="strang's step [s] (default 5e-8)")
    ap.add_argument("--precision", default="fp32", choices=("fp32", "fp64"), help="precision (default fp32)")
    ap.add_argument("--repeat", type=int, default=2, help="runs per way, the ways in turn (default 2)")
    ap.add_argument("--json", type=Path, help="write the results there (JSON)")
    args = ap.parse_args(argv)
    if args.seeds < 1 or args.repeat < 1 or not 0 < args.window < args.duration or args.dt <= 0:
        ap.error("--seeds and --repeat must be at least 1, 0 < --window < --duration, --dt > 0")

    from aca_warp.common.devices import get_device
    from aca_warp.common.errors import SceneError

    try:
        get_device(args.device)
    except SceneError as e:
        ap.error(str(e))
    import aca_warp.hf.recorder as recorder
    from aca_warp.common.files import host_cpu, machine
    from aca_warp.studies.report import command_line, write_json
    from aca_warp.studies.runs import batch_at_start, run_engine
    from aca_warp.studies.validation.base import EXPERIMENTS, FULL
    from aca_warp.studies.validation.experiments import prepare

    if args.experiment not in EXPERIMENTS or EXPERIMENTS[args.experiment].kind != "saturated":
        ap.error(f"--experiment must be a saturated validation experiment, got {args.experiment!r}")
    cfg = dataclasses.replace(FULL, device=args.device, seeds=args.seeds, patches=args.patches, window=args.window)
    prep = prepare(dataclasses.replace(EXPERIMENTS[args.experiment], duration=args.duration), cfg)
    record = prep.plan.record(cfg)
    package = recorder.rows_to_host
    flushes = {"rows": package, "whole": whole_buffer}
    runs: dict[str, list[dict[str, float]]] = {w: [] for w in WAYS}
    model, state = batch_at_start(prep.scenes, args.device, args.precision)  # a short untimed run loads the kernels
    name = machine(model.device)["device_name"]
    warm = min(args.duration, 20 * record.sample_dt)
    run_engine(model, state, engine="auto", duration=warm, integrator="strang", dt=args.dt, record=record)
    del model, state
    try:
        for k in range(args.repeat):
            for way in WAYS:
                recorder.rows_to_host = flushes[way]
                handed = [0]

                def sink(chunk: Any, handed: list[int] = handed) -> None:
                    handed[0] += sum(a.nbytes for a in (chunk.globals, chunk.velocity) if a is not None)

                model, state = batch_at_start(prep.scenes, args.device, args.precision)
                t = time.perf_counter()
                res = run_engine(
                    model, state, engine="auto", duration=args.duration, integrator="strang", dt=args.dt,
                    record=record, sink=sink,
                )  # fmt: skip
                wall = time.perf_counter() - t
                if not res.complete:
                    print(f"recorder_flush_cost.py: run stopped: {res.fault}", file=sys.stderr)
                    return 3
                runs[way].append({"wall_s": wall, "run_wall_s": res.wall_time, "compile_s": res.compile_time,
                                  "bytes": handed[0], "steps": int(res.steps)})  # fmt: skip
                print(f"{way:5} run {k + 1}: {wall:.3f} s ({res.steps:,} steps, {handed[0] / 1e6:.3g} MB handed over, "
                      f"engine {res.engine})")  # fmt: skip
                del model, state
    finally:
        recorder.rows_to_host = package
    least = {w: min(r["wall_s"] for r in runs[w]) for w in WAYS}
    print(f"least: rows {least['rows']:.3f} s, whole {least['whole']:.3f} s ({least['whole'] / least['rows']:.2f}×)")
    if args.json:
        doc = {
            "date": time.strftime("%Y-%m-%d"),
            "machine": f"{name}; host {host_cpu()}, {platform.platform()}",
            "command": command_line("recorder_flush_cost.py", sys.argv[1:] if argv is None else argv),
            "pads": len(prep.scenes),
            "patches": sorted({s.patches.count for s in prep.scenes}),
            "record": {"sample_dt_s": record.sample_dt, "window_s": list(record.window), "every": record.decimation},
            "least_wall_s": least,
            "runs": runs,
        }
        args.json.parent.mkdir(parents=True, exist_ok=True)
        write_json(args.json, doc)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
