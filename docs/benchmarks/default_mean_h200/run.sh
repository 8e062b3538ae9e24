#!/usr/bin/env bash
# strang's default for the shipped presets' physics (2.5e-7 s, crossings averaged) beside the default before it
# (1e-7 s, point treatment), in one call on one GPU: 64 saturated hf1 pads x 30 ms in rounds a and b, then the
# paper's record length (0.36 s) once each. From the repository root, with aca_warp installed:
#   OUT=FOLDER bash docs/benchmarks/default_mean_h200/run.sh
# (DEVICE, PADS, DUR, MOON override cuda:0, 64, 0.03 and 0.36 for a dry run on the CPU)
set -uo pipefail
source "$(dirname "$0")/../bench_case.sh"
B="--device $D --scene hf1 --pads $N --integrator strang --precision fp32 --no-reference --no-stages"
for r in a b; do
  bench default_30ms_$r $T --dt default
  bench before_30ms_$r $T --dt 1e-7 --crossing point
done
bench default_360ms $L --dt default
bench before_360ms $L --dt 1e-7 --crossing point
machine_and_commit
