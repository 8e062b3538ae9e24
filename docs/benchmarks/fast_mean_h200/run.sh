#!/usr/bin/env bash
# strang's default stepping for the presets' physics (2.5e-7 s, crossings averaged) on the exact kernel and with CUDA
# fast math, in one call on one GPU: 64 saturated hf1 pads x 30 ms in rounds a and b (each `--math exact fast`, the
# two kernels in turn), the same at samples 4 and 10 us apart (what the 1 us samples cost), then the paper's record
# length (0.36 s) once. From the repository root, with aca_warp installed:
#   OUT=FOLDER bash docs/benchmarks/fast_mean_h200/run.sh
# (DEVICE, PADS, DUR, MOON override cuda:0, 64, 0.03 and 0.36 for a dry run)
set -uo pipefail
source "$(dirname "$0")/../bench_case.sh"
B="--device $D --scene hf1 --pads $N --integrator strang --precision fp32 --no-reference --no-stages --dt default"
for r in a b; do
  bench math_30ms_$r $T --math exact fast
  bench samples4us_30ms_$r $T --sample-dt 4e-6
  bench samples10us_30ms_$r $T --sample-dt 1e-5
done
bench math_360ms $L --math exact fast
machine_and_commit
