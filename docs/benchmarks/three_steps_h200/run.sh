#!/usr/bin/env bash
# A/B of strang's default step by regime (this checkout: 1e-6/3 s for hf1) against the code before (build/base:
# 2.5e-7 s for every measured regime) on one GPU: 64 saturated hf1 pads x 30 ms at the default stepping of each code,
# base and new in turn; with ROUND "moon", the paper's record length (0.36 s) once each.
# usage: OUT=FOLDER bash run.sh ROUND, from the repository root (writes $OUT/ab/<case>_<base|new>_<ROUND>.json and
# .log; the harness is ../crossing_h200/restructured/run.sh)
set -uo pipefail
C="default:--dt default"
[ "$1" = moon ] && C="default_360ms:--duration 0.36 --dt default"
CASES="$C" bash "$(dirname "$0")/../crossing_h200/restructured/run.sh" "$1"
