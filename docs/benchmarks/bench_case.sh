# Sourced by the run.sh of the benchmark folders beside it, after `set -uo pipefail`, with OUT set: D, N, T, L (the
# device, pads, the short and the long duration [s]; DEVICE, PADS, DUR, MOON override cuda:0, 64, 0.03 and 0.36 for
# a dry run) and the folder OUT; the caller then sets B, the options common to its cases.
D=${DEVICE:-cuda:0}; N=${PADS:-64}; T=${DUR:-0.03}; L=${MOON:-0.36}
mkdir -p "$OUT"

# bench NAME DURATION OPTIONS...: one `aca-warp bench` into $OUT/NAME.json and .log, and a line per result (wall
# [s], steps, step [s], crossing treatment, fast math)
bench() {
  local name=$1 dur=$2; shift 2
  aca-warp bench $B --duration $dur "$@" --json $OUT/$name.json > $OUT/$name.log 2>&1
  python3 -c "import json; [print('$name', r['wall_s'], r['steps'], r['dt'], r['crossing'], r.get('fast_math')) for r in json.load(open('$OUT/$name.json'))['results']]"
}

# the machine and the code, beside the results
machine_and_commit() {
  nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv > $OUT/gpu.txt 2>/dev/null || true
  git log -1 --format=%H > $OUT/commit.txt 2>/dev/null || true
}
