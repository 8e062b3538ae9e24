#!/usr/bin/env bash
# A/B of the on-chip crossing queue on one GPU: 64 saturated hf1 pads x 30 ms, the code before (build/base) and this
# checkout in turn, three cases per round; with ROUND "moon", the paper's record length (0.36 s) at the default once
# each. usage: OUT=FOLDER bash run.sh ROUND, from the repository root with the code before in build/base (README.md)
# (writes $OUT/ab/<case>_<base|new>_<ROUND>.json and .log; the harness is ../restructured/run.sh)
set -uo pipefail
C="mean_2.5e-7:--dt 2.5e-7 --crossing mean|point_2.5e-7:--dt 2.5e-7 --crossing point|mean_1e-7:--dt 1e-7 --crossing mean"
[ "$1" = moon ] && C="default_360ms:--duration 0.36 --dt default"
CASES="$C" bash "$(dirname "$0")/../restructured/run.sh" "$1"
