#!/usr/bin/env python3
"""Is Warp's CPU runtime safe for two threads at once? The measurement behind the sweep's device turns.

Two threads of this process do what two shard tasks of an overlapped sweep would do on the CPU: one builds models
(``build_model``: device arrays, the neighbour search's hash grid and kernels) again and again, the other runs them
(``run_hf``, the general engine, which captures its steps in a CPU graph). Every build is compared with the same
build done alone before (every model array, bit for bit), every run with its lone run (every recorded global
sample); an exception, a difference or a fault counts as a failure. Run twice: ``free`` (the threads call Warp
whenever they like, as a sweep did when the build was outside the device's turn) and ``turns`` (one lock around
each build and each run, as ``aca_warp.sweep.overlap.KernelTurn`` holds it now). The pads are those of the
overlapped-sweep test (hf1, 20 patches, 400 µs at 1 µs samples, fp32, eight seeds × M).

    python scripts/warp_cpu_threads.py --seconds 90 --md warp_cpu_threads.md

Prints one Markdown line per mode (builds, runs, failures by kind) with the machine and date; ``--md`` writes them.
"""

from __future__ import annotations

import argparse
import collections
import datetime
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import warp as wp

from aca_warp.common.argtypes import positive
from aca_warp.common.errors import AcaError
from aca_warp.common.files import check_output_path, machine
from aca_warp.hf.loop import run_hf
from aca_warp.hf.model import build_model
from aca_warp.hf.options import RunOptions
from aca_warp.hf.state import initial_state
from aca_warp.sweep import load_spec

SPEC = {
    "sweep": {"base": "hf1", "shard_size": 3, "name": "threads"},
    "run": {"duration": 4e-4, "precision": "fp32", "sample_dt": 1e-6},
    "base": {"patches": {"count": 20}},
    "parameters": {"friction.M": [0.6, 0.9], "patches.seed": {"range": [1, 5]}},
}


class Work:
    """The pads, their lone builds and runs, and the two operations the threads repeat."""

    def __init__(self) -> None:
        self.spec = load_spec(SPEC, base_dir=Path.cwd())
        self.scenes = self.spec.scenes(range(self.spec.pad_count))
        s = self.spec
        self.options = RunOptions(duration=s.duration, integrator=s.integrator, dt=s.dt, tolerance=s.tolerance)
        self.built = [self.build(i) for i in range(len(self.scenes))]
        self.ran = [self.run(i)[0] for i in range(len(self.scenes))]

    def build(self, i: int) -> dict[str, np.ndarray]:
        """Pad ``i``'s model arrays, read back."""
        m = build_model([self.scenes[i]], device="cpu", precision=self.spec.precision)
        return {k: a.numpy().copy() for k, a in m.arrays.items()}

    def run(self, i: int) -> tuple[np.ndarray, Any]:
        """Pad ``i`` built and run: its recorded globals (samples, 1, outputs) and its fault (None)."""
        m = build_model([self.scenes[i]], device="cpu", precision=self.spec.precision)
        r = run_hf(m, initial_state(m), self.options, record=self.spec.base.record)
        return np.concatenate([c.globals for c in r.chunks]), r.fault


def trial(work: Work, seconds: float, turns: bool) -> dict[str, Any]:
    """Both threads for ``seconds``; returns counts and failures by kind."""
    lock = threading.Lock() if turns else None
    end = time.monotonic() + seconds
    failures: collections.Counter[str] = collections.Counter()
    counts = {"builds": 0, "runs": 0}
    n = len(work.scenes)

    def guarded(f: Any, i: int) -> Any:
        if lock is None:
            return f(i)
        with lock:
            return f(i)

    def builder() -> None:
        k = 0
        while time.monotonic() < end:
            i, k = k % n, k + 1
            try:
                got = guarded(work.build, i)
                if any(not np.array_equal(got[key], work.built[i][key]) for key in got):
                    failures["build differs"] += 1
            except Exception as e:  # noqa: BLE001  (what a concurrent build raises is the measurement)
                failures[f"build raised {type(e).__name__}: {e}"[:120]] += 1
            counts["builds"] += 1

    def runner() -> None:
        k = 0
        while time.monotonic() < end:
            i, k = k % n, k + 1
            try:
                g, fault = guarded(work.run, i)
                if fault is not None or not np.array_equal(g, work.ran[i], equal_nan=True):
                    failures["run differs or faulted"] += 1
            except Exception as e:  # noqa: BLE001
                failures[f"run raised {type(e).__name__}: {e}"[:120]] += 1
            counts["runs"] += 1

    threads = [threading.Thread(target=builder), threading.Thread(target=runner)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return {**counts, "failures": dict(failures)}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=positive, default=90.0, help="time per mode [s] (default 90)")
    ap.add_argument("--md", type=Path, help="also write the Markdown lines to this file")
    a = ap.parse_args(argv)
    if a.md is not None:
        try:
            check_output_path(a.md, overwrite=True)
        except AcaError as e:
            ap.error(str(e))
    wp.config.log_level = wp.LOG_WARNING
    work = Work()
    m = machine(wp.get_device("cpu"))
    day = datetime.date.today().isoformat()
    lines = []
    for mode, turns in (("free", False), ("turns", True)):
        r = trial(work, a.seconds, turns)
        total = sum(r["failures"].values())
        kinds = "; ".join(f"{v} × {k}" for k, v in sorted(r["failures"].items())) or "none"
        lines.append(
            f"> {day}, {m['device_name']}, Warp {wp.config.version}: {mode} ({a.seconds:g} s): {r['builds']} builds, "
            f"{r['runs']} runs, **{total} failed** ({kinds})"
        )
        print(lines[-1], flush=True)
    if a.md is not None:
        a.md.write_text("\n\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
