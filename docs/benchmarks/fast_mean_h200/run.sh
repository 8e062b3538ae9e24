#!/usr/bin/env bash
# strang's default stepping for the presets' physics (2.5e-7 s, crossings averaged) on the exact kernel and with CUDA
# fast math, in one call on one GPU: 64 saturated hf1 pads x 30 ms in rounds a and b (each `--math exact fast`, the
# two kernels in turn), the same at samples 4 and 10 us apart (what the 1 us samples cost), then the paper's record
# length (0.36 s) once. From the repository root, with aca_warp installed:
#   OUT=FOLDER bash docs/benchmarks/fast_mean_h200/run.sh
# (DEVICE, PADS, DUR, MOON override cuda:0, 64, 0.03 and 0.36 for a dry run)
set -uo pipefail
D=${DEVICE:-cuda:0}; N=${PADS:-64}; T=${DUR:-0.03}; L=${MOON:-0.36}
mkdir -p $OUT
B="--device $D --scene hf1 --pads $N --integrator strang --precision fp32 --no-reference --no-stages --dt default"
bench() {  # NAME DURATION OPTIONS...
  local name=$1 dur=$2; shift 2
  aca-warp bench $B --duration $dur "$@" --json $OUT/$name.json > $OUT/$name.log 2>&1
  python3 -c "import json; [print('$name', r.get('fast_math'), r['wall_s'], r['steps'], r['dt'], r['crossing']) for r in json.load(open('$OUT/$name.json'))['results']]"
}
for r in a b; do
  bench math_30ms_$r $T --math exact fast
  bench samples4us_30ms_$r $T --sample-dt 4e-6
  bench samples10us_30ms_$r $T --sample-dt 1e-5
done
bench math_360ms $L --math exact fast
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv > $OUT/gpu.txt 2>/dev/null || true
git log -1 --format=%H > $OUT/commit.txt 2>/dev/null || true
