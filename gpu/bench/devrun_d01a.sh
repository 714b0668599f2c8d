#!/usr/bin/env bash
# Issue 16, 2026-12-01: GPU tests, `bench preprocess --frames 1500 --backend cuda` (its notes: each device
# stage's upload, kernels and download) with variants alternating on one machine: "base" (this build),
# "old" (pkg/synthtrack-cli-old, when packed) and knobs given as "NAME=VALUE" words (A/B in one binary); the
# FITS search and the demo. Usage: devrun_d01a.sh PKG_DIR [all|tests|ab] [KNOB ...]; PKG_DIR holds
# pkg.tar.xz (scripts/devrun-pack.sh BUILD pkg). Logs come back as logs.tar.gz.
set -uo pipefail
D=$(cd "$1" && pwd)
W=/tmp/w; mkdir -p $W && [ -x $W/pkg/synthtrack-cli ] || tar -xJf "$D/pkg.tar.xz" -C $W
export LD_LIBRARY_PATH=$W/pkg/lib
B=$W/pkg/synthtrack-cli
O=/tmp/o; mkdir -p $O; trap 'tar -czf ${OUT:-/tmp}/logs.tar.gz -C /tmp o' EXIT
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; lscpu | grep "Model name"
MODE=${2:-all}; shift 2 2>/dev/null; KNOBS=("base" "$@"); [ -x $W/pkg/synthtrack-cli-old ] && KNOBS=("old" "${KNOBS[@]}")
run() { local k=$1; shift; if [ "$k" = old ]; then $W/pkg/synthtrack-cli-old "$@"; elif [ "$k" = base ]; then $B "$@"; else env "$k" $B "$@"; fi; }
if [ "$MODE" = all ] || [ "$MODE" = tests ]; then
for t in $W/pkg/st_gpu_test_*; do timeout 300 $t > $O/$(basename $t).log 2>&1; echo "$(basename $t) rc=$? $(grep -E '^\[  (PASSED|FAILED) ' $O/$(basename $t).log | tr '\n' ' ')"; done
grep -h "FAILED\|Failure" $O/st_gpu_test_*.log | head -20
# This stop's kernels under memcheck: the cosmic rays' pre-test, the calibration with the frame backgrounds.
# MEMCHECK (words separated by ';') overrides the list, e.g. MEMCHECK="st_gpu_test_gpu_zero_bias --gtest_filter=*Failed*".
IFS=';' read -ra MC <<< "${MEMCHECK:-st_gpu_test_gpu_cosmic_rays;st_gpu_test_gpu_frame_backgrounds --gtest_filter=*Calibrated*}"
for t in "${MC[@]}"; do
  timeout 200 compute-sanitizer --tool memcheck --leak-check full $W/pkg/$t > $O/memcheck_${t%% *}.log 2>&1
  echo "memcheck ${t} rc=$? $(grep -E 'ERROR SUMMARY|LEAK SUMMARY' $O/memcheck_${t%% *}.log | tr '\n' ' ')"; done
fi
[ "$MODE" = tests ] && exit 0
for r in 1 2 3 4 5 6; do for k in "${KNOBS[@]}"; do FP=; [ $r = 5 ] && FP=--fingerprint
  run $k bench preprocess --frames 1500 --backend cuda $FP >$O/bp_${k//[=\/]/_}_$r.log 2>&1
  echo "$k $(grep -E '^preprocess:' $O/bp_${k//[=\/]/_}_$r.log | cut -c1-40)"; done; done
for k in "${KNOBS[@]}"; do echo "== $k"; L=$O/bp_${k//[=\/]/_}_4.log; grep -E '^  [A-Za-z]' $L | tr -s ' ' | tr '\n' '|'; echo; grep -iE "on cuda|ms" $L | cut -c1-400 | head -30; grep -h "^fingerprint" $O/bp_${k//[=\/]/_}_5.log; done
F=/tmp/d1500/observation.fits; [ -f $F ] || $B demo --frames 1500 --backend cuda --fits 0 --out /tmp/d1500 >/dev/null 2>&1; cat $F >/dev/null
A="--vmax-px-s 0.5565 --centre-px-s 15.8,0.3"
for r in 1 2 3; do for k in "${KNOBS[@]}"; do
  /usr/bin/time -f "$k wall %e s" bash -c "$(declare -f run); W=$W B=$B; run $k search $F --backend cuda --timings $A --out /tmp/s$r$k.csv" >$O/s$r.log 2>$O/s$r.err
  tr '\r' '\n' < $O/s$r.err | grep -E "wall|timings: (loaded)" | sed 's/timings: //; s/  */ /g' | tr '\n' '|'; echo; done; done
for k in "${KNOBS[@]}"; do head -2 /tmp/s3$k.csv | tail -1 | cut -c1-70; done
for r in 1 2; do /usr/bin/time -f "demo wall %e s" $B demo --backend cuda --timings --out /tmp/demo$r >$O/demo$r.log 2>$O/demo$r.err
  tr '\r' '\n' < $O/demo$r.err | grep -E "after the simulation|wall|warning"; grep -iE "FOUND" $O/demo$r.log | head -1; done
date -u
