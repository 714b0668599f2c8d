#!/usr/bin/env bash
# Issue 16, 2026-11-28, third stop: old = d7007a3 (the second stop), new = 2b0cb46. GPU tests, memcheck,
# A/B bench preprocess and FITS search alternating on one machine, the demo, --method exact, a perf profile.
# Package beside this script: pkg.tar.xz (scripts/devrun-pack.sh BUILD pkg, the unstripped CLI copied over the
# stripped one so that perf names our functions, the old build's CLI as pkg/synthtrack-cli-old) and perf.tar.xz
# (perf and the libraries it needs, from the dev VM). The profile comes back as o55/g.txt.xz (perf script:
# tid, time, ip, symbol, with call chains).
set -uo pipefail
D=$(cd "$(dirname "$0")" && pwd)
W=/tmp/w55; mkdir -p $W && [ -x $W/pkg/synthtrack-cli ] || tar -xJf "$D/pkg.tar.xz" -C $W
[ -x $W/perf/perf ] || tar -xJf "$D/perf.tar.xz" -C $W
export LD_LIBRARY_PATH=$W/pkg/lib
B=$W/pkg/synthtrack-cli; OLD=$W/pkg/synthtrack-cli-old
O=/tmp/o55; mkdir -p $O; trap 'tar -czf ${OUT:-/tmp}/logs.tar.gz -C /tmp o55' EXIT
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; lscpu | grep "Model name"
for t in $W/pkg/st_gpu_test_*; do timeout 300 $t > $O/$(basename $t).log 2>&1; echo "$(basename $t) rc=$? $(grep -E '^\[  (PASSED|FAILED) ' $O/$(basename $t).log | tr '\n' ' ')"; done
for t in st_gpu_test_gpu_preprocess st_gpu_test_cuda_tree; do
  timeout 280 compute-sanitizer --tool memcheck --leak-check full $W/pkg/$t --gtest_filter=-*LongCube* > $O/memcheck_$t.log 2>&1; echo "memcheck $t rc=$?"; grep -E "ERROR SUMMARY|LEAK SUMMARY" $O/memcheck_$t.log | head -2; done
for r in 1 2 3 4; do for v in old new; do X=$B; [ $v = old ] && X=$OLD
  $X bench preprocess --frames 1500 --backend cuda >$O/$v$r.log 2>&1; echo "$v $(grep -E '^preprocess:' $O/$v$r.log | cut -c1-40)"; done; done
grep -E "^(sigma_n|stars|cosmic-ray pixels)" $O/old4.log $O/new4.log | cut -c1-120
cat $O/new4.log | head -20
F=/tmp/d1500/observation.fits; [ -f $F ] || $B demo --frames 1500 --backend cuda --fits 0 --out /tmp/d1500 >/dev/null 2>&1; cat $F >/dev/null
A="--vmax-px-s 0.5565 --centre-px-s 15.8,0.3"
for r in 1 2 3 4 5; do for v in old new; do X=$B; [ $v = old ] && X=$OLD
  /usr/bin/time -f "$v wall %e s" $X search $F --backend cuda --timings $A --out /tmp/$v$r.csv >$O/s$v$r.log 2>$O/s$v$r.err
  tr '\r' '\n' < $O/s$v$r.err | grep -E "wall|timings: (loaded)" | sed 's/timings: //; s/  */ /g' | tr '\n' '|'; echo; done; done
head -2 /tmp/new5.csv | cut -c1-70; head -2 /tmp/old5.csv | cut -c1-70
tr '\r' '\n' < $O/snew5.err | grep -E "timings" > $O/timings_new5.txt
/usr/bin/time -f "exact wall %e s" $B search $F --backend cuda --method exact --timings $A --out /tmp/e1.csv >$O/e1.log 2>$O/e1.err; tr '\r' '\n' < $O/e1.err | grep -E "wall"; head -2 /tmp/e1.csv | cut -c1-70
for r in 1 2 3; do /usr/bin/time -f "demo wall %e s" $B demo --backend cuda --timings --out /tmp/demo$r >$O/demo$r.log 2>$O/demo$r.err
  tr '\r' '\n' < $O/demo$r.err | grep -E "after the simulation|wall|warning"; grep -iE "FOUND" $O/demo$r.log | head -1; done
echo 0 > /proc/sys/kernel/perf_event_paranoid; echo 0 > /proc/sys/kernel/kptr_restrict
P="env LD_LIBRARY_PATH=$W/perf/lib:$LD_LIBRARY_PATH $W/perf/perf"
$P record -F 2999 -g -o $O/g.data -- $B bench preprocess --frames 1500 --backend cuda >$O/g.log 2>$O/g.err
$P script -i $O/g.data -F tid,time,ip,sym 2>/dev/null | xz -T8 > $O/g.txt.xz; rm -f $O/g.data
date -u
