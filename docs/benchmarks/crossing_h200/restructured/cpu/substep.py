#!/usr/bin/env python3
"""Time one friction sub-step (`friction_substep`, fp32, h = 1e-7 s) per patch on the CPU, compiled with the crossing
treatment off (0) and on (1), for 1758 patches that slide (none crosses zero slip): ns per sub-step, best of three
launches of 100 sub-steps each. Run it with the package of the code to time first on sys.path (README.md)."""

import time

import numpy as np
import warp as wp

wp.config.quiet = True
from aca_warp.kernels.physics import friction_substep  # noqa: E402


def kernel(crossing: int):
    C = wp.constant(crossing)

    @wp.kernel(enable_backward=False)
    def k(v: wp.array(dtype=wp.float32), vd: wp.array(dtype=wp.float32), out: wp.array(dtype=wp.float32), reps: int):
        i = wp.tid()
        x = v[i]
        for _r in range(reps):
            x = friction_substep(
                x, wp.float32(1e-7), wp.float32(1.9e-6), wp.float32(1e-3), wp.float32(0.02), wp.float32(0.01), vd[i],
                wp.float32(0.127), wp.float32(200.0), wp.float32(0.3), wp.float32(1e-6), C,
            )  # fmt: skip
        out[i] = x

    return k


n = 1758
rng = np.random.default_rng(1)
v = wp.array(rng.uniform(-0.5, 0.5, n).astype(np.float32), device="cpu")
vd = wp.array(rng.uniform(8, 12, n).astype(np.float32), device="cpu")
out = wp.zeros(n, dtype=wp.float32, device="cpu")
for crossing in (0, 1):
    k = kernel(crossing)
    wp.launch(k, n, inputs=[v, vd, out, 1], device="cpu")  # compile
    best = float("inf")
    for _ in range(3):
        t = time.perf_counter()
        wp.launch(k, n, inputs=[v, vd, out, 100], device="cpu")
        best = min(best, time.perf_counter() - t)
    print(f"crossing {crossing}: {1e9 * best / (n * 100):.1f} ns per sub-step", flush=True)
