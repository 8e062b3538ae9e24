#!/usr/bin/env python3
"""One hf1 pad on the CPU (on chip), strang at 2.5e-7 s from its start: DURATION [s], PRECISIONS (fp32,fp64),
CROSSING (point or mean). Prints per precision a digest of the recorded globals (equal digests: the same bits) and
the stepping's wall time [s]. Run it with the package of the code to time first on sys.path (README.md)."""

import hashlib
import sys

import numpy as np
import warp as wp

wp.config.quiet = True
from aca_warp.hf.loop import run_hf  # noqa: E402
from aca_warp.hf.model import build_model  # noqa: E402
from aca_warp.hf.options import RunOptions  # noqa: E402
from aca_warp.hf.state import initial_state  # noqa: E402
from aca_warp.scene import preset  # noqa: E402

duration, precisions, crossing = float(sys.argv[1]), sys.argv[2].split(","), sys.argv[3]
scene = preset("hf1")
for precision in precisions:
    model = build_model([scene], device="cpu", precision=precision)
    options = RunOptions(engine="onchip", integrator="strang", dt=2.5e-7, crossing=crossing, duration=duration)
    res = run_hf(model, initial_state(model), options)
    digest = hashlib.sha256(np.ascontiguousarray(res.collect().globals).tobytes()).hexdigest()[:16]
    print(f"{precision} {crossing} {duration:g} s: globals {digest}, stepping {res.wall_time:.2f} s", flush=True)
