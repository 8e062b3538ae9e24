#!/usr/bin/env bash
# A/B of the crossing treatment's restructuring on one GPU: 64 saturated hf1 pads x 30 ms, base and new in turn.
# usage: OUT=FOLDER bash run.sh ROUND, from the repository root with the code before in build/base (README.md)
# (writes $OUT/ab/<case>_<base|new>_<ROUND>.json and .log; /tmp/site: where the device's Warp was installed)
set -uo pipefail
R=$1
mkdir -p /tmp/views $OUT/ab
if [ ! -d /tmp/views/base ]; then
  python3 - <<'PY'
import sys; sys.path.insert(0, "scripts")
from pathlib import Path
from compare_checkouts import package_view
package_view(Path("build/base").resolve(), Path("/tmp/views/base"))
package_view(Path(".").resolve(), Path("/tmp/views/new"))
PY
fi
B="--device cuda:0 --scene hf1 --pads 64 --integrator strang --precision fp32 --no-reference --no-stages --duration 0.03"
# CASES (name:options|name:options…, later options win over B's) replaces the four cases (../queue/run.sh)
IFS='|' read -ra LIST <<< "${CASES:-point_1e-7:--dt 1e-7|mean_1e-7:--dt 1e-7 --crossing mean|mean_2.5e-7:--dt 2.5e-7 --crossing mean|point_2.5e-7:--dt 2.5e-7}"
for c in "${LIST[@]}"; do
  name=${c%%:*}; opts=${c#*:}
  for v in base new; do
    (cd /tmp/views/$v && PYTHONPATH=/tmp/views/$v:/tmp/site python3 -c "import sys, aca_warp; assert aca_warp.__file__.startswith('/tmp/views/$v'); from aca_warp.cli import run; sys.argv[0]='aca-warp'; run()" bench $B $opts --json $OUT/ab/${name}_${v}_${R}.json > $OUT/ab/${name}_${v}_${R}.log 2>&1)
    python3 -c "import json,sys; d=json.load(open('$OUT/ab/${name}_${v}_${R}.json')); r=d['results'][0]; print('$name $v $R', r.get('wall_s'), r.get('steps'), r.get('dt'), r.get('crossing'))" 2>&1 | tail -1
  done
done
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv > $OUT/ab/gpu.txt
