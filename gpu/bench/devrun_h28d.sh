#!/usr/bin/env bash
# Issue 16, 2026-11-28, fourth stop: old = 5e13bcc (the third stop's code), new = this stop's build. GPU
# tests, memcheck of the pre-processing tests (the downloads behind the filter, the sparse mask), A/B of
# bench preprocess and the FITS search alternating on one machine, the demo, a perf profile of the new one.
# Package beside this script: pkg.tar.xz (scripts/devrun-pack.sh BUILD pkg, the unstripped CLI copied over
# the stripped one, the old CLI as pkg/synthtrack-cli-old) and, optionally, perf.tar.xz (perf and its
# libraries). Logs come back as logs.tar.gz (o/).
set -uo pipefail
D=$(cd "$(dirname "$0")" && pwd)
W=/tmp/w; mkdir -p $W && [ -x $W/pkg/synthtrack-cli ] || tar -xJf "$D/pkg.tar.xz" -C $W
[ -f "$D/perf.tar.xz" ] && { [ -x $W/perf/perf ] || tar -xJf "$D/perf.tar.xz" -C $W; }
export LD_LIBRARY_PATH=$W/pkg/lib
B=$W/pkg/synthtrack-cli; OLD=$W/pkg/synthtrack-cli-old; MID=$W/pkg/synthtrack-cli-mid
VS="old new"; [ -x $MID ] && VS="old mid new"  # a third binary (an earlier commit of this stop) when packed
O=/tmp/o; mkdir -p $O; trap 'tar -czf ${OUT:-/tmp}/logs.tar.gz -C /tmp o' EXIT
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; lscpu | grep "Model name"
MODE=${1:-all}
if [ "$MODE" = all ] || [ "$MODE" = tests ]; then
for t in $W/pkg/st_gpu_test_*; do timeout 300 $t > $O/$(basename $t).log 2>&1; echo "$(basename $t) rc=$? $(grep -E '^\[  (PASSED|FAILED) ' $O/$(basename $t).log | tr '\n' ' ')"; done
grep -h "FAILED\|Failure" $O/st_gpu_test_*.log | head -20
for t in st_gpu_test_gpu_zero_bias st_gpu_test_gpu_preprocess; do
  timeout 280 compute-sanitizer --tool memcheck --leak-check full $W/pkg/$t --gtest_filter=-*LongCube* > $O/memcheck_$t.log 2>&1; echo "memcheck $t rc=$?"; grep -E "ERROR SUMMARY|LEAK SUMMARY" $O/memcheck_$t.log | head -2; done
fi
[ "$MODE" = tests ] && exit 0
for r in 1 2 3 4 5 6; do for v in $VS; do X=$B; [ $v = old ] && X=$OLD; [ $v = mid ] && X=$MID
  $X bench preprocess --frames 1500 --backend cuda >$O/$v$r.log 2>&1; echo "$v $(grep -E '^preprocess:' $O/$v$r.log | cut -c1-40)"; done; done
grep -E "^(sigma_n|stars|cosmic-ray pixels|sky rate)" $O/old6.log $O/new6.log | cut -c1-120
grep -E "^  [a-z]" $O/new6.log | tr -s ' ' | tr '\n' '|'; echo; grep -E "^  [a-z]" $O/old6.log | tr -s ' ' | tr '\n' '|'; echo
grep -E "^note: (sky rate: the block|matched filter on|per-pixel background to)" $O/new6.log | cut -c1-400
F=/tmp/d1500/observation.fits; [ -f $F ] || $B demo --frames 1500 --backend cuda --fits 0 --out /tmp/d1500 >/dev/null 2>&1; cat $F >/dev/null
A="--vmax-px-s 0.5565 --centre-px-s 15.8,0.3"
for r in 1 2 3 4 5; do for v in $VS; do X=$B; [ $v = old ] && X=$OLD; [ $v = mid ] && X=$MID
  /usr/bin/time -f "$v wall %e s" $X search $F --backend cuda --timings $A --out /tmp/$v$r.csv >$O/s$v$r.log 2>$O/s$v$r.err
  tr '\r' '\n' < $O/s$v$r.err | grep -E "wall|timings: (loaded)" | sed 's/timings: //; s/  */ /g' | tr '\n' '|'; echo; done; done
head -2 /tmp/new5.csv | cut -c1-70; head -2 /tmp/old5.csv | cut -c1-70
for r in 1 2; do /usr/bin/time -f "demo wall %e s" $B demo --backend cuda --timings --out /tmp/demo$r >$O/demo$r.log 2>$O/demo$r.err
  tr '\r' '\n' < $O/demo$r.err | grep -E "after the simulation|wall|warning"; grep -iE "FOUND" $O/demo$r.log | head -1; done
if [ -x $W/perf/perf ]; then
  echo 0 > /proc/sys/kernel/perf_event_paranoid; echo 0 > /proc/sys/kernel/kptr_restrict
  P="env LD_LIBRARY_PATH=$W/perf/lib:$LD_LIBRARY_PATH $W/perf/perf"
  $P record -F 2999 -g -o $O/g.data -- $B bench preprocess --frames 1500 --backend cuda >$O/g.log 2>$O/g.err
  $P script -i $O/g.data -F tid,time,ip,sym 2>/dev/null | xz -T8 > $O/g.txt.xz; rm -f $O/g.data
fi
date -u
