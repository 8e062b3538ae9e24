#!/usr/bin/env bash
# A/B of the samples' warp sums reduce-scattered (this checkout) against Warp's warp reduction into the first lane
# (the code before, build/base) on one GPU: 64 saturated hf1 pads x 30 ms at the default stepping, base and new in
# turn; with ROUND "moon", the paper's record length (0.36 s) once each.
# usage: OUT=FOLDER bash run.sh ROUND, from the repository root (writes $OUT/ab/<case>_<base|new>_<ROUND>.json and
# .log; the harness is ../crossing_h200/restructured/run.sh)
set -uo pipefail
C="default:--dt default"
[ "$1" = moon ] && C="default_360ms:--duration 0.36 --dt default"
CASES="$C" bash "$(dirname "$0")/../crossing_h200/restructured/run.sh" "$1"
