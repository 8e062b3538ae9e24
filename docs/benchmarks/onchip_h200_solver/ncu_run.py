"""The program Nsight Compute profiled for ncu_cluster8_* and ncu_va_cluster8_*: scripts/profile_onchip.py with Warp's
kernels compiled with line information, run from the repository root as ``python3
docs/benchmarks/onchip_h200_solver/ncu_run.py "full, cluster 8 [fp32]"`` (the case label; any further arguments go
to the script, e.g. ``--growth --growth-dt 5e-6`` for the varying-area pad's cases)."""

import runpy
import sys

import warp as wp

wp.config.lineinfo = True
case, extra = sys.argv[1], sys.argv[2:]
sys.argv = ["profile_onchip.py", "--device", "cuda:0", "--dt", "5e-8", "--window", "2e-4", "--sample-dt", "1e-6",
            "--only", case, *extra]  # fmt: skip
runpy.run_path("scripts/profile_onchip.py", run_name="__main__")
