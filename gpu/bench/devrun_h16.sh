#!/usr/bin/env bash
# Issue 16 device run of 2026-11-27 14:40 UTC (the sky-rate stacks on the device): unpacks pkg.tar.xz (new binaries, base/synthtrack-cli = the commit before, lib/)
# and runs the steps named: tests memcheck prep fits demo
set -uo pipefail
D=$(cd "$(dirname "$0")" && pwd)
W=/tmp/h16
mkdir -p $W && tar -xJf "$D/pkg.tar.xz" -C $W
export LD_LIBRARY_PATH=$W/lib
O=/tmp/h16out
mkdir -p "$O"
trap 'tar -czf "${OUT:-/tmp}/h16logs.tar.gz" -C /tmp h16out 2>/dev/null' EXIT
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader
date -u
NEW=$W/synthtrack-cli
OLD=$W/base/synthtrack-cli
MID=$W/mid/synthtrack-cli  # optional: an intermediate build (BINS="OLD MID NEW")
for step in "$@"; do
  echo "=== $step $(date -u +%H:%M:%S)"
  case $step in
    tests) for t in ${TESTS:-$W/st_gpu_test_*}; do
             timeout 200 "$t" >"$O/$(basename "$t").log" 2>&1; echo "$(basename "$t") rc=$?"
             grep -E "^\[ +(FAILED|PASSED|SKIPPED) |Failure|Expected|Which|actual|first at" "$O/$(basename "$t").log" | head -30
           done ;;
    memcheck) for t in ${MC_TESTS:-st_gpu_test_gpu_preprocess st_gpu_test_gpu_zero_bias}; do
                timeout 240 compute-sanitizer --tool memcheck --leak-check full "$W/$t" --gtest_filter=-*LongCube* \
                  >"$O/memcheck_$t.log" 2>&1; echo "memcheck $t rc=$?"
                grep -E "ERROR SUMMARY|LEAK SUMMARY|PASSED|FAILED" "$O/memcheck_$t.log" | head -4
              done ;;
    prep) for r in ${PREP_ROUNDS:-1}; do
            for b in ${BINS:-OLD NEW}; do
              bin=${!b}
              "$bin" bench preprocess --frames 1500 --backend cuda 2>"$O/prep_${b}_$r.err" >"$O/prep_${b}_$r.log"
              echo "--- $b round $r"; grep -vE "^note: (stars subtracted|sky rate|registration)" "$O/prep_${b}_$r.log" | head -40
            done
          done ;;
    prepcpu) for b in OLD NEW; do
               bin=${!b}
               "$bin" bench preprocess --frames 1500 --backend cpu >"$O/prep_cpu_$b.log" 2>/dev/null
               echo "--- CPU $b"; grep -vE "^note: (stars subtracted|sky rate|registration)" "$O/prep_cpu_$b.log" | head -30
             done ;;
    fits) "$NEW" demo --frames 1500 --backend cuda --fits 0 --out /tmp/d1500 >"$O/d1500.log" 2>&1
          cat /tmp/d1500/observation.fits >/dev/null
          for b in ${FITS_BINS:-OLD NEW NEW OLD}; do
            bin=${!b}
            /usr/bin/time -f "$b fits to candidates wall %e s" "$bin" search /tmp/d1500/observation.fits \
              --backend cuda --out /tmp/s1500_$b.csv >"$O/s1500_$b.log" 2>"$O/s1500_$b.err"
            grep -E "wall|pre-process|search" "$O/s1500_$b.err" | tail -4
          done
          grep -vE "^\s*$" "$O/s1500_NEW.err" | tr '\r' '\n' | grep -vE "%|^\s*$" | tail -40
          head -3 /tmp/s1500_OLD.csv; head -3 /tmp/s1500_NEW.csv ;;
    demo) for b in OLD NEW OLD NEW; do
            bin=${!b}
            /usr/bin/time -f "$b demo wall %e s" "$bin" demo --backend cuda --out /tmp/demo_$b >"$O/demo_$b.log" 2>"$O/demo_$b.err"
            grep -E "demo wall|warning" "$O/demo_$b.err" | head -3; grep -iE "pre-processing|search:" "$O/demo_$b.log" | head -3
          done ;;
  esac
done
echo "=== done $(date -u +%H:%M:%S)"
