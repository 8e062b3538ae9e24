#!/usr/bin/env bash
set -uo pipefail
mkdir -p /tmp/vv $OUT/var
python3 - <<'PY'
import sys; sys.path.insert(0, "scripts")
from pathlib import Path
from compare_checkouts import package_view
for v in ["base", "v1", "v2", "v12"]:
    if not Path("/tmp/vv/" + v).exists():
        package_view(Path("build/" + v).resolve(), Path("/tmp/vv/" + v))
PY
B="--device cuda:0 --scene hf1 --pads 64 --integrator strang --precision fp32 --no-reference --no-stages --duration 0.03"
for R in a b; do
for c in "mean_2.5e-7:--dt 2.5e-7 --crossing mean" "mean_1e-7:--dt 1e-7 --crossing mean"; do
  name=${c%%:*}; opts=${c#*:}
  for v in base v1 v2 v12; do
    (cd /tmp/vv/$v && PYTHONPATH=/tmp/vv/$v:/tmp/site python3 -c "import sys, aca_warp; assert aca_warp.__file__.startswith('/tmp/vv/$v'); from aca_warp.cli import run; sys.argv[0]='aca-warp'; run()" bench $B $opts --json $OUT/var/${name}_${v}_${R}.json > $OUT/var/${name}_${v}_${R}.log 2>&1)
    python3 -c "import json; d=json.load(open('$OUT/var/${name}_${v}_${R}.json')); r=d['results'][0]; print('$name $v $R', r.get('wall_s'))" 2>&1 | tail -1
  done
done
done
cd $OUT && tar czf var.tgz var && rm -rf var
