#!/usr/bin/env bash
# Issue 16, 2026-11-28, fifth stop: old = the fourth stop's code (+ bench --fingerprint), new = this stop's
# build. GPU tests, A/B of bench preprocess and of the FITS search alternating on one machine, the two
# pre-processings' fingerprints (results to every digit, hashes of the zero-biased and filtered cubes), the
# demo. Usage: devrun_h28e.sh PKG_DIR [all|tests|ab]; PKG_DIR holds pkg.tar.xz (scripts/devrun-pack.sh BUILD
# pkg, the old CLI as pkg/synthtrack-cli-old). Logs come back as logs.tar.gz (o/).
set -uo pipefail
D=$(cd "$1" && pwd)
W=/tmp/w; mkdir -p $W && [ -x $W/pkg/synthtrack-cli ] || tar -xJf "$D/pkg.tar.xz" -C $W
export LD_LIBRARY_PATH=$W/pkg/lib
B=$W/pkg/synthtrack-cli; OLD=$W/pkg/synthtrack-cli-old
O=/tmp/o; mkdir -p $O; trap 'tar -czf ${OUT:-/tmp}/logs.tar.gz -C /tmp o' EXIT
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; lscpu | grep "Model name"
MODE=${2:-all}
if [ "$MODE" = all ] || [ "$MODE" = tests ]; then
for t in $W/pkg/st_gpu_test_*; do timeout 300 $t > $O/$(basename $t).log 2>&1; echo "$(basename $t) rc=$? $(grep -E '^\[  (PASSED|FAILED) ' $O/$(basename $t).log | tr '\n' ' ')"; done
grep -h "FAILED\|Failure" $O/st_gpu_test_*.log | head -20
fi
[ "$MODE" = tests ] && exit 0
for r in 1 2 3 4 5 6; do for v in old new; do X=$B; [ $v = old ] && X=$OLD; FP=; [ $r = 6 ] && FP=--fingerprint
  $X bench preprocess --frames 1500 --backend cuda $FP >$O/$v$r.log 2>&1; echo "$v $(grep -E '^preprocess:' $O/$v$r.log | cut -c1-40)"; done; done
grep -h "^fingerprint" $O/old6.log $O/new6.log
for v in old new; do echo "$v: $(grep -E '^  [a-z]' $O/${v}5.log | tr -s ' ' | tr '\n' '|')"; done
F=/tmp/d1500/observation.fits; [ -f $F ] || $B demo --frames 1500 --backend cuda --fits 0 --out /tmp/d1500 >/dev/null 2>&1; cat $F >/dev/null
A="--vmax-px-s 0.5565 --centre-px-s 15.8,0.3"
for r in 1 2 3 4 5; do for v in old new; do X=$B; [ $v = old ] && X=$OLD
  /usr/bin/time -f "$v wall %e s" $X search $F --backend cuda --timings $A --out /tmp/$v$r.csv >$O/s$v$r.log 2>$O/s$v$r.err
  tr '\r' '\n' < $O/s$v$r.err | grep -E "wall|timings: (loaded)" | sed 's/timings: //; s/  */ /g' | tr '\n' '|'; echo; done; done
head -2 /tmp/new5.csv | cut -c1-70; head -2 /tmp/old5.csv | cut -c1-70
for r in 1 2; do /usr/bin/time -f "demo wall %e s" $B demo --backend cuda --timings --out /tmp/demo$r >$O/demo$r.log 2>$O/demo$r.err
  tr '\r' '\n' < $O/demo$r.err | grep -E "after the simulation|wall|warning"; grep -iE "FOUND" $O/demo$r.log | head -1; done
date -u
