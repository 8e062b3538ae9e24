#!/usr/bin/env bash
# A/B of strang's samples read from the solve of the step that follows them (this checkout) against a separate
# closing solve per sample (the code before, in build/base) on one GPU: 64 saturated hf1 pads x 30 ms at the default
# stepping and with the point treatment at the same step, base and new in turn; with ROUND "moon", the paper's
# record length (0.36 s) at the default once each. usage: OUT=FOLDER bash run.sh ROUND, from the repository root
# (writes $OUT/ab/<case>_<base|new>_<ROUND>.json and .log; the harness is ../crossing_h200/restructured/run.sh)
set -uo pipefail
C="default:--dt default|point_2.5e-7:--dt 2.5e-7 --crossing point"
[ "$1" = moon ] && C="default_360ms:--duration 0.36 --dt default"
CASES="$C" bash "$(dirname "$0")/../crossing_h200/restructured/run.sh" "$1"
