#!/usr/bin/env bash
# Issue 16, 2026-12-02 (eleventh stop): GPU tests, then `bench preprocess --frames 1500 --backend cuda` with
# variants alternating in one binary: "base" (this build), "NAME=VALUE" words (an environment knob) and
# "--flag" words (a `bench preprocess` flag, e.g. --chain-remeasure; "A=1,B=1" sets both knobs); each variant's stages, notes and
# fingerprint; then the FITS search and the demo (base only). Usage: devrun_d02.sh PKG_DIR [all|tests|ab]
# [VARIANT ...]; PKG_DIR holds pkg.tar.xz (scripts/devrun-pack.sh BUILD pkg). Logs come back as logs.tar.gz.
set -uo pipefail
D=$(cd "$1" && pwd)
W=/tmp/w; mkdir -p $W && [ -x $W/pkg/synthtrack-cli ] || tar -xJf "$D/pkg.tar.xz" -C $W
export LD_LIBRARY_PATH=$W/pkg/lib
B=$W/pkg/synthtrack-cli
O=/tmp/o; mkdir -p $O; trap 'tar -czf ${OUT:-/tmp}/logs.tar.gz -C /tmp o' EXIT
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; lscpu | grep "Model name"
MODE=${2:-all}; shift 2 2>/dev/null; VARIANTS=("base" "$@")
run() { local k=$1; shift; case "$k" in base) $B "$@";; --*) $B "$@" "$k";; *) env ${k//,/ } $B "$@";; esac; }
if [ "$MODE" = all ] || [ "$MODE" = tests ]; then
for t in $W/pkg/st_gpu_test_*; do timeout 300 $t > $O/$(basename $t).log 2>&1; echo "$(basename $t) rc=$? $(grep -E '^\[  (PASSED|FAILED) ' $O/$(basename $t).log | tr '\n' ' ')"; done
grep -h "FAILED\|Failure" $O/st_gpu_test_*.log | head -20
IFS=';' read -ra MC <<< "${MEMCHECK:-}"
for t in "${MC[@]}"; do
  timeout 200 compute-sanitizer --tool memcheck --leak-check full $W/pkg/$t > $O/memcheck_${t%% *}.log 2>&1
  echo "memcheck ${t} rc=$? $(grep -E 'ERROR SUMMARY|LEAK SUMMARY' $O/memcheck_${t%% *}.log | tr '\n' ' ')"; done
fi
[ "$MODE" = tests ] && exit 0
ROUNDS=${ROUNDS:-6}
for r in $(seq 1 $ROUNDS); do for k in "${VARIANTS[@]}"; do FP=; [ $r = 2 ] && FP=--fingerprint
  L=$O/bp_${k//[=\/,-]/_}_$r.log
  if [ -n "$FP" ]; then run $k bench preprocess --frames 1500 --backend cuda $FP >$L 2>&1
  else run $k bench preprocess --frames 1500 --backend cuda >$L 2>&1; fi
  echo "$r $k $(grep -E '^preprocess:' $L | cut -c1-40) | $(grep -E '^  sky rate ' $L | tr -s ' ')"; done; done
for k in "${VARIANTS[@]}"; do echo "== $k"; L=$O/bp_${k//[=\/,-]/_}_3.log; grep -E '^  [A-Za-z]' $L | tr -s ' '; grep -vE '^  [A-Za-z]|^\s*$' $L | cut -c1-600 | head -60; grep -h "^fingerprint" $O/bp_${k//[=\/,-]/_}_2.log; done
[ "$MODE" = ab ] && exit 0
F=/tmp/d1500/observation.fits; [ -f $F ] || $B demo --frames 1500 --backend cuda --fits 0 --out /tmp/d1500 >/dev/null 2>&1; cat $F >/dev/null
A="--vmax-px-s 0.5565 --centre-px-s 15.8,0.3"
for r in 1 2 3; do
  /usr/bin/time -f "wall %e s" $B search $F --backend cuda --timings $A --out /tmp/s$r.csv >$O/s$r.log 2>$O/s$r.err
  tr '\r' '\n' < $O/s$r.err | grep -E "wall|timings: (loaded)" | sed 's/timings: //; s/  */ /g' | tr '\n' '|'; echo; done
head -2 /tmp/s3.csv | tail -1 | cut -c1-70
for r in 1 2; do /usr/bin/time -f "demo wall %e s" $B demo --backend cuda --timings --out /tmp/demo$r >$O/demo$r.log 2>$O/demo$r.err
  tr '\r' '\n' < $O/demo$r.err | grep -E "after the simulation|wall|warning"; grep -iE "FOUND" $O/demo$r.log | head -1; done
date -u
