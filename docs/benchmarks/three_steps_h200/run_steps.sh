#!/usr/bin/env bash
# 64 saturated hf1 pads, strang fp32 with the crossings averaged, at four steps per 1 us sample (2.5e-7 s) and at
# three (3.33e-7 s, asked as 3.34e-7 s), one case after the other in each round, one code.
# usage: OUT=FOLDER bash run_steps.sh ROUND  (ROUND "moon": the paper's record length, 0.36 s, once each)
# writes $OUT/steps/<case>_<ROUND>.json and .log
set -uo pipefail
R=$1
mkdir -p $OUT/steps
B="--device cuda:0 --scene hf1 --pads 64 --integrator strang --precision fp32 --no-reference --no-stages --duration 0.03"
[ "$R" = moon ] && B="$B --duration 0.36"
for c in "four:--dt 2.5e-7 --crossing mean" "three:--dt 3.34e-7 --crossing mean"; do
  name=${c%%:*}; opts=${c#*:}
  python3 -c "import sys; from aca_warp.cli import run; sys.argv[0]='aca-warp'; run()" bench $B $opts \
    --json $OUT/steps/${name}_${R}.json > $OUT/steps/${name}_${R}.log 2>&1
  python3 -c "import json; r=json.load(open('$OUT/steps/${name}_${R}.json'))['results'][0]; print('$name $R', r.get('wall_s'), r.get('steps'), r.get('dt'), r.get('crossing'))" 2>&1 | tail -1
done
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv > $OUT/steps/gpu.txt
