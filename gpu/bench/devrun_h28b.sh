#!/usr/bin/env bash
# Issue 16 device run of 2026-11-28, second stop (H100): A/B of FITS to candidates (old = d09a778, new = b66fc20) on one
# host, alternating; every GPU test; memcheck; the demo; bench preprocess; --method exact. Package: scripts/devrun-pack.sh
# BUILD pkg, the old build's CLI copied in as pkg/synthtrack-cli-old, tar -cJf pkg.tar.xz pkg beside this script.
# Usage: devrun_h28b.sh ab exact tests demo prep memcheck
set -uo pipefail
D=$(cd "$(dirname "$0")" && pwd)
W=/tmp/w45; mkdir -p $W && [ -x $W/pkg/synthtrack-cli ] || tar -xJf "$D/pkg.tar.xz" -C $W
export LD_LIBRARY_PATH=$W/pkg/lib
B=$W/pkg/synthtrack-cli; OLD=$W/pkg/synthtrack-cli-old
O=/tmp/o45; mkdir -p $O; trap 'tar -czf ${OUT:-/tmp}/logs.tar.gz -C /tmp o45' EXIT
nvidia-smi --query-gpu=name --format=csv,noheader; date -u; nproc
F=/tmp/d1500/observation.fits; [ -f $F ] || $B demo --frames 1500 --backend cuda --fits 0 --out /tmp/d1500 >/dev/null 2>&1; cat $F >/dev/null
A="--vmax-px-s 0.5565 --centre-px-s 15.8,0.3"
for step in "$@"; do echo "=== $step $(date -u +%H:%M:%S)"; case $step in
ab) for r in 1 2 3 4 5; do for v in old new; do X=$B; [ $v = old ] && X=$OLD
      /usr/bin/time -f "$v wall %e s" $X search $F --backend cuda --timings $A --out /tmp/$v$r.csv >$O/$v$r.log 2>$O/$v$r.err
      tr '\r' '\n' < $O/$v$r.err | grep -E "wall|timings: (backend|  read|loaded|searched|outputs)" | sed 's/timings: //; s/  */ /g' | tr '\n' '|'; echo; done; done
    tr '\r' '\n' < $O/new5.err | grep -E "timings|host:"; head -2 /tmp/new5.csv | cut -c1-70; head -2 /tmp/old5.csv | cut -c1-70 ;;
exact) /usr/bin/time -f "exact wall %e s" $B search $F --backend cuda --method exact --timings $A --out /tmp/e1.csv >$O/e1.log 2>$O/e1.err
       tr '\r' '\n' < $O/e1.err | grep -E "wall|timings: (loaded|searched)"; head -2 /tmp/e1.csv | cut -c1-70 ;;
tests) for t in $W/pkg/st_gpu_test_*; do timeout 300 $t > $O/$(basename $t).log 2>&1; echo "$(basename $t) rc=$? $(grep -E '^\[  (PASSED|FAILED) ' $O/$(basename $t).log | tr '\n' ' ')"; done ;;
memcheck) for t in st_gpu_test_cuda_tree st_gpu_test_gpu_preprocess; do
      timeout 280 compute-sanitizer --tool memcheck --leak-check full $W/pkg/$t --gtest_filter=-*LongCube* > $O/memcheck_$t.log 2>&1; echo "memcheck $t rc=$?"
      grep -E "ERROR SUMMARY|LEAK SUMMARY|PASSED|FAILED" $O/memcheck_$t.log | head -4; done ;;
demo) for r in 1 2 3; do /usr/bin/time -f "demo wall %e s" $B demo --backend cuda --timings --out /tmp/demo$r >$O/demo$r.log 2>$O/demo$r.err
        tr '\r' '\n' < $O/demo$r.err | grep -E "after the simulation|wall|warning"; grep -iE "FOUND" $O/demo$r.log | head -1; done ;;
prep) for r in 1 2; do $B bench preprocess --frames 1500 --backend cuda >$O/prep$r.log 2>$O/prep$r.err; grep -E "^preprocess:|sigma_n|^stars|cosmic-ray pixels" $O/prep$r.log | head -4; done ;;
esac; done; echo "=== done $(date -u +%H:%M:%S)"
