#!/usr/bin/env bash
# The crossing treatment's cost where no patch crosses: 1024 hf1 pads sliding at 1e-8 s (the throughput benchmark's
# case), fp32 on chip, the point treatment and mean in turn, two rounds. From the repository root, aca_warp installed:
#   OUT=FOLDER bash docs/benchmarks/default_mean_h200/sliding_1024/run.sh
set -uo pipefail
mkdir -p $OUT
for r in a b; do
  for c in point mean; do
    aca-warp bench --device ${DEVICE:-cuda:0} --precision fp32 --pads ${PADS:-1024} --engine onchip --no-reference \
      --no-stages --duration ${DUR:-2e-5} --crossing $c --json $OUT/bench_${c}_$r.json > $OUT/bench_${c}_$r.log 2>&1
    python3 -c "import json; r=json.load(open('$OUT/bench_${c}_$r.json'))['results'][0]; print('$c $r', r['wall_s'], r['steps'], r['patch_steps_per_s'], r['crossing'])"
  done
done
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv > $OUT/gpu.txt 2>/dev/null || true
