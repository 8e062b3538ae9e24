#!/usr/bin/env bash
# GPU check of the fp32 default (run on the device machine from the repository root).
set -u
export PYTHONPATH=/tmp/site NCCL_NVLS_ENABLE=0
python3 -m pip install -q --no-deps --no-build-isolation --no-index -e . 2>&1 | tail -2
nvidia-smi --query-gpu=name,driver_version --format=csv > "$OUT/gpu.txt"
date -u > "$OUT/date.txt"
{ /usr/bin/time -f "%e s wall" python3 -c 'import sys; from aca_warp.cli import run; sys.argv[0]="aca-warp"; run()' hf hf1 --device cuda:0 --duration 0.03 -o "$OUT/hf1_default.h5" --no-progress; } > "$OUT/cli_default.txt" 2>&1
{ /usr/bin/time -f "%e s wall" python3 -c 'import sys; from aca_warp.cli import run; sys.argv[0]="aca-warp"; run()' hf hf1 --device cuda:0 --duration 0.03 -o "$OUT/hf1_default2.h5" --no-progress; } >> "$OUT/cli_default.txt" 2>&1
{ /usr/bin/time -f "%e s wall" python3 -c 'import sys; from aca_warp.cli import run; sys.argv[0]="aca-warp"; run()' hf hf1 --device cuda:0 --duration 0.03 --fast-math -o "$OUT/hf1_fast.h5" --no-progress; } >> "$OUT/cli_default.txt" 2>&1
cat "$OUT/cli_default.txt"
python3 -c 'import sys; from aca_warp.cli import run; sys.argv[0]="aca-warp"; run()' bench --device cuda:0 --scene hf1 --pads 64 --integrator strang --dt 5e-8 --duration 0.03 --precision fp32 fp64 --no-reference --no-stages --json "$OUT/bench_64hf1_30ms_dt5e-8_h200.json" > "$OUT/bench64.txt" 2>&1
tail -5 "$OUT/bench64.txt"
python3 -c "import xdist" 2>/dev/null && X="-n 8" || X=""
echo "xdist: ${X:-none}"
ACA_WARP_TEST_DEVICES=cuda:0 timeout 330 python3 -m pytest -q $X tests -k cuda -p no:cacheprovider -rs --junitxml="$OUT/junit_cuda.xml" > "$OUT/pytest_cuda.txt" 2>&1
echo "pytest rc=$?"
tail -25 "$OUT/pytest_cuda.txt"
