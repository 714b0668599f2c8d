#!/usr/bin/env bash
# Issue 16 device run of 2026-11-28 (H200): unpacks pkg.tar.xz (scripts/devrun-pack.sh BUILD DEST, then tar -cJf
# pkg.tar.xz pkg) and runs the steps named: fits (FITS to candidates, the paper problem 101^2 x 4 and --method
# exact), demo (x3, --timings), prep (bench preprocess x2), tests (every GPU test), memcheck (tree, pre-processing).
set -uo pipefail
D=$(cd "$(dirname "$0")" && pwd)
W=/tmp/h28; mkdir -p $W && tar -xJf "$D/pkg.tar.xz" -C $W
export LD_LIBRARY_PATH=$W/pkg/lib
B=$W/pkg/synthtrack-cli
O=/tmp/h28out; mkdir -p $O; trap 'tar -czf ${OUT:-/tmp}/logs.tar.gz -C /tmp h28out' EXIT
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader; date -u; nproc
for step in "$@"; do
  echo "=== $step $(date -u +%H:%M:%S)"
  case $step in
    tests) for t in $W/pkg/st_gpu_test_*; do timeout 300 $t > $O/$(basename $t).log 2>&1; echo "$(basename $t) rc=$?"; grep -E "^\[ +(FAILED|PASSED|SKIPPED) |Failure" $O/$(basename $t).log | head -8; done ;;
    memcheck) for t in st_gpu_test_cuda_tree st_gpu_test_gpu_preprocess; do
                timeout 280 compute-sanitizer --tool memcheck --leak-check full $W/pkg/$t --gtest_filter=-*LongCube* > $O/memcheck_$t.log 2>&1; echo "memcheck $t rc=$?"
                grep -E "ERROR SUMMARY|LEAK SUMMARY|PASSED|FAILED" $O/memcheck_$t.log | head -4; done ;;
    fits) [ -f /tmp/d1500/observation.fits ] || $B demo --frames 1500 --backend cuda --fits 0 --out /tmp/d1500 >$O/d1500.log 2>&1
          cat /tmp/d1500/observation.fits >/dev/null
          for r in 1 2 3 4; do
            /usr/bin/time -f "paper problem (101^2) FITS to candidates wall %e s" $B search /tmp/d1500/observation.fits --backend cuda --timings --vmax-px-s 0.5565 --centre-px-s 15.8,0.3 --out /tmp/s$r.csv >$O/s$r.log 2>$O/s$r.err
            tr '\r' '\n' < $O/s$r.err | grep -E "timings: [a-z]|wall|host:"; done
          /usr/bin/time -f "paper problem, --method exact, wall %e s" $B search /tmp/d1500/observation.fits --backend cuda --method exact --timings --vmax-px-s 0.5565 --centre-px-s 15.8,0.3 --out /tmp/e1.csv >$O/e1.log 2>$O/e1.err
          tr '\r' '\n' < $O/e1.err | grep -E "timings: (loaded|searched)|wall|host:"
          tr '\r' '\n' < $O/s4.err | grep -vE "timings|%|^\s*$" | tail -14; head -2 /tmp/s4.csv; head -2 /tmp/e1.csv ;;
    demo) for r in 1 2 3; do /usr/bin/time -f "demo wall %e s" $B demo --backend cuda --timings --out /tmp/demo$r >$O/demo$r.log 2>$O/demo$r.err
            tr '\r' '\n' < $O/demo$r.err | grep -E "timings: [a-z]|wall|warning"; grep -iE "FOUND" $O/demo$r.log; done ;;
    prep) for r in 1 2; do $B bench preprocess --frames 1500 --backend cuda >$O/prep$r.log 2>$O/prep$r.err
            echo "--- prep $r"; grep -E "preprocess:|  [a-z]|sigma_n|stars" $O/prep$r.log | head -22; done ;;
  esac
done
echo "=== done $(date -u +%H:%M:%S)"
