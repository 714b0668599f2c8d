#!/usr/bin/env bash
# Issue 16, 2026-12-03 (fourteenth stop): every GPU test, then `bench preprocess --frames 1500 --backend cuda`
# with knob variants alternating in one binary ("NAME=VALUE" words; ST_NONE=1 is the default build), each
# round traced (ST_TRACE, scripts/trace_summary.py), the fingerprints compared, then the FITS search and the
# demo. Usage: devrun_d14.sh PKG_DIR ROUNDS [VARIANT ...]; PKG_DIR holds pkg.tar.xz (scripts/devrun-pack.sh).
# Logs and traces come back as o.tar.gz in $OUT.
set -uo pipefail
D=$(cd "$1" && pwd); ROUNDS=${2:-3}; shift 2; VARIANTS=("ST_NONE=1" "$@")
W=/tmp/w; mkdir -p $W && [ -x $W/pkg/synthtrack-cli ] || tar -xJf "$D/pkg.tar.xz" -C $W
export LD_LIBRARY_PATH=$W/pkg/lib
P=$W/pkg; B=$P/synthtrack-cli; O=/tmp/o; mkdir -p $O
trap 'tar -czf ${OUT:-/tmp}/o.tar.gz -C /tmp o' EXIT
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; lscpu | grep "Model name"
for t in $P/st_gpu_test_*; do n=$(basename $t); timeout 300 $t > $O/$n.log 2>&1
  echo "$n rc=$? $(grep -E '^\[  (PASSED|FAILED) ' $O/$n.log | tr '\n' ' ')"; done
grep -h "FAILED\|Failure" $O/st_gpu_test_*.log | head -20
for r in $(seq 1 $ROUNDS); do for v in "${VARIANTS[@]}"; do n=${v//[=\/,-]/_}; FP=; [ $r = 2 ] && FP=--fingerprint
  env ${v//,/ } ST_TRACE=$O/tr_${n}_$r.json $B bench preprocess --frames 1500 --backend cuda $FP > $O/bp_${n}_$r.log 2>&1
  echo "$r $n $(grep '^preprocess:' $O/bp_${n}_$r.log | cut -c1-32) $(grep -E '^  (sky rate|registration|cosmic|residual|matched)' $O/bp_${n}_$r.log | tr -s ' ' | cut -c1-30 | tr '\n' ' ')"
done; done
grep -h '^fingerprint' $O/bp_*_2.log | sort | uniq -c
F=/tmp/d1500/observation.fits; [ -f $F ] || $B demo --frames 1500 --backend cuda --fits 0 --out /tmp/d1500 >/dev/null 2>&1; cat $F >/dev/null
A="--vmax-px-s 0.5565 --centre-px-s 15.8,0.3"
for r in 1 2 3; do /usr/bin/time -f "wall %e s" $B search $F --backend cuda --timings $A --out /tmp/s$r.csv >$O/s$r.log 2>$O/s$r.err
  tr '\r' '\n' < $O/s$r.err | grep -E "wall|timings: (loaded)" | sed 's/timings: //; s/  */ /g' | tr '\n' '|'; echo; done
head -2 /tmp/s3.csv | tail -1 | cut -c1-70
for r in 1 2; do /usr/bin/time -f "demo wall %e s" $B demo --backend cuda --timings --out /tmp/demo$r >$O/demo$r.log 2>$O/demo$r.err
  tr '\r' '\n' < $O/demo$r.err | grep -E "after the simulation|wall|warning"; grep -iE "FOUND" $O/demo$r.log | head -1; done
date -u
