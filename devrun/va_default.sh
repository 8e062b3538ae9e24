#!/usr/bin/env bash
set -u
export PYTHONPATH=/tmp/site NCCL_NVLS_ENABLE=0
python3 -m pip install -q --no-deps --no-build-isolation --no-index -e . 2>&1 | tail -2
if ! command -v aca-warp >/dev/null; then
  mkdir -p /tmp/bin
  cat > /tmp/bin/aca-warp <<'W'
#!/bin/sh
exec python3 -c 'import sys; from aca_warp.cli import run; sys.argv[0] = "aca-warp"; run()' "$@"
W
  chmod +x /tmp/bin/aca-warp
  export PATH=/tmp/bin:$PATH
fi
command -v aca-warp
nvidia-smi --query-gpu=name,driver_version --format=csv > "$OUT/gpu.txt"
python3 scripts/time_varying_area.py --device cuda:0 --steps 5e-8 --growth-dt default 2.02e-7 --out "$OUT/va" 2>&1 | tail -8
rm -f "$OUT"/va/*.h5
ls "$OUT/va"
