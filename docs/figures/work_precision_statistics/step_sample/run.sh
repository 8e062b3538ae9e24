#!/usr/bin/env bash
# strang's default stepping (2.5e-7 s, crossings averaged; growth every 5 us) on the current kernels, whose samples
# read the solve of the step that follows them: every regime's parts of ../fast_mean/ continued on their seeds and
# references with that one setting, its row made on other kernels run again and replaced (--again).
# FROM, STEP and AGAIN (default: ../fast_mean/, 2.5e-7 s, --again) continue other parts with another step as a new
# row (../three_steps/run.sh).
# usage, from the repository root on a GPU: OUT=FOLDER LF=FOLDER bash run.sh GROUP...
#   GROUP: hf (hf1-hf4), va, equal (hf1_equal-hf4_equal, va_equal), ms_mid, ms_app3; LF: where the LF states' runs
#   are made (ms_mid, ms_app3); WORKERS: analysis processes (default 15)
# Writes OUT/<regime>/[s<first seed>/]<the part's own file name> and log.txt beside it.
set -uo pipefail
F=${FROM:-docs/figures/work_precision_statistics/fast_mean}
S=${STEP:-2.5e-7}
W="python3 scripts/work_precision_stats.py --device cuda:0 --workers ${WORKERS:-15} ${AGAIN---again}"
D="--duration 30e-3 --window 10e-3"
G="--grid strang@fp32:dt=$S:mean"
GV="--reference strang@fp32:dt=1e-8 --grid strang@fp32:dt=$S:growth_dt=5e-6:mean"

# part REGIME PART OPTIONS...: continue F/REGIME/PART (copied as the device's file, renamed back after)
part() {
  local r=$1 p=$2; shift 2
  local dir=$OUT/$r/$(dirname "$p") name=$(basename "$p")
  mkdir -p "$dir"
  cp "$F/$r/$p" "$dir/wps_cuda0_$r.json"
  $W --regimes "$r" "$@" --out "$dir" > "$dir/log.txt" 2>&1
  echo "$r $p: rc $?, $(tail -n 2 "$dir/log.txt" | head -n 1)"
  [ "$name" = "wps_cuda0_$r.json" ] || mv "$dir/wps_cuda0_$r.json" "$dir/$name"
}

for group in "$@"; do
  case $group in
    hf)
      part hf1 s1/wps_cuda0_hf1.json $D --seeds 32 --first-seed 1 $G
      part hf1 s33/wps_cuda0_hf1.json $D --seeds 64 --first-seed 33 $G
      part hf1 s97/wps_cuda0_hf1.json $D --seeds 64 --first-seed 97 $G
      part hf2 s1/wps_cuda0_hf2.json $D --seeds 32 --first-seed 1 $G
      part hf2 s33/wps_cuda0_hf2.json $D --seeds 64 --first-seed 33 $G
      part hf3 s1/wps_cuda0_hf3.json $D --seeds 32 --first-seed 1 $G
      part hf3 s33/wps_cuda0_hf3.json $D --seeds 64 --first-seed 33 $G
      part hf3 s97/wps_cuda0_hf3.json $D --seeds 32 --first-seed 97 $G
      part hf4 wps_cuda0_hf4.json $D --seeds 32 $G ;;
    va)
      for s in 1 33 65 97; do part va s$s/wps_cuda0_va.json --seeds 32 --first-seed $s $GV; done ;;
    equal)
      part hf1_equal s1/wps_cuda0_hf1_equal.json $D --seeds 64 --first-seed 1 $G
      part hf1_equal s65/wps_cuda1_hf1_equal.json $D --seeds 64 --first-seed 65 $G
      part hf2_equal s1/wps_cuda1_hf2_equal.json $D --seeds 64 --first-seed 1 $G
      part hf2_equal s65/wps_cuda1_hf2_equal.json $D --seeds 64 --first-seed 65 $G
      part hf3_equal wps_cuda0_hf3_equal.json $D --seeds 64 $G
      part hf4_equal wps_cuda1_hf4_equal.json $D --seeds 64 $G
      for s in 1 65; do part va_equal s$s/wps_cuda0_va_equal.json --seeds 64 --first-seed $s $GV; done ;;
    ms_mid)
      part ms_mid s1/wps_cuda0_ms_mid.json --lf-dir "$LF" --seeds 16 --first-seed 1 $G
      part ms_mid s17/wps_cuda1_ms_mid.json --lf-dir "$LF" --seeds 16 --first-seed 17 $G ;;
    ms_app3)
      for s in 1 5 9 13 17 21 25 29; do
        part ms_app3 "$(cd $F/ms_app3 && ls s$s/wps_*_ms_app3.json)" --lf-dir "$LF" --seeds 4 --first-seed $s $G
      done ;;
    *) echo "unknown group $group (hf, va, equal, ms_mid, ms_app3)"; exit 2 ;;
  esac
done
