#!/usr/bin/env bash
# Issue 16 device run of 2026-11-27 evening (SEP's frame backgrounds on the device): unpacks pkg.tar.xz (the
# new binaries of scripts/devrun-pack.sh, base/synthtrack-cli = a build before the change, lib/) and runs the
# steps named: tests memcheck prep fits demo. In `prep`, NEW is also run with ST_GPU_SEP_ON_CPU=1 (the frame
# backgrounds on the CPU, as before) and ST_GPU_SEP_NO_REUSE=1 (on the device, but their frames not reused:
# the global background, hot pixels and prefetch as before), so each change's share shows in one run.
set -uo pipefail
D=$(cd "$(dirname "$0")" && pwd)
W=/tmp/sep16
mkdir -p $W && tar -xJf "$D/pkg.tar.xz" -C $W
export LD_LIBRARY_PATH=$W/lib
O=/tmp/sep16out
mkdir -p "$O"
trap 'tar -czf "${OUT:-/tmp}/sep16logs_$$.tar.gz" -C /tmp sep16out 2>/dev/null' EXIT
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader
nproc
date -u
NEW=$W/synthtrack-cli
OLD=$W/base/synthtrack-cli
MID=$W/mid/synthtrack-cli  # optional: an intermediate build (BINS="OLD MID NEW")
summary() { grep -E "^(preprocess:|  [a-z]|sigma_n|stars [0-9]|sky rate \(|cosmic-ray pixels)|frame backgrounds on|stacks at the sky rate|block stacks" "$1" | cut -c1-260 | head -${2:-40}; grep -oE "upload (prefetched|none)[^)]*\)" "$1"; }
for step in "$@"; do
  echo "=== $step $(date -u +%H:%M:%S)"
  case $step in
    tests) for t in ${TESTS:-$W/st_gpu_test_*}; do
             timeout 240 "$t" >"$O/$(basename "$t").log" 2>&1; echo "$(basename "$t") rc=$?"
             grep -E "^\[ +(FAILED|PASSED|SKIPPED) |Failure|Expected|Which|actual|pixels equal|frame backgrounds on" \
               "$O/$(basename "$t").log" | head -30
           done ;;
    memcheck) for t in ${MC_TESTS:-st_gpu_test_gpu_frame_backgrounds}; do
                timeout 240 compute-sanitizer --tool memcheck --leak-check full "$W/$t" >"$O/memcheck_$t.log" 2>&1
                echo "memcheck $t rc=$?"
                grep -E "ERROR SUMMARY|LEAK SUMMARY|PASSED|FAILED" "$O/memcheck_$t.log" | head -4
              done ;;
    prep) for r in ${PREP_ROUNDS:-1 2}; do
            for b in ${BINS:-OLD NEW CPUSEP NOREUSE}; do
              case $b in
                OLD) cmd=("$OLD") ;;
                MID) cmd=("$MID") ;;
                NEW) cmd=("$NEW") ;;
                CPUSEP) cmd=(env ST_GPU_SEP_ON_CPU=1 "$NEW") ;;
                NOREUSE) cmd=(env ST_GPU_SEP_NO_REUSE=1 "$NEW") ;;
              esac
              "${cmd[@]}" bench preprocess --frames 1500 --backend cuda 2>"$O/prep_${b}_$r.err" >"$O/prep_${b}_$r.log"
              echo "--- $b round $r"; summary "$O/prep_${b}_$r.log" 45
            done
          done ;;
    fits) "$NEW" demo --frames 1500 --backend cuda --fits 0 --out /tmp/d1500 >"$O/d1500.log" 2>&1
          cat /tmp/d1500/observation.fits >/dev/null
          for b in ${FITS_BINS:-OLD NEW OLD NEW}; do
            bin=${!b}
            /usr/bin/time -f "$b fits to candidates wall %e s" "$bin" search /tmp/d1500/observation.fits \
              --backend cuda --out /tmp/s1500_$b.csv >"$O/s1500_$b.log" 2>"$O/s1500_$b.err"
            grep -E "wall|pre-process|search" "$O/s1500_$b.err" | tail -4
          done
          head -3 /tmp/s1500_OLD.csv; head -3 /tmp/s1500_NEW.csv ;;
    demo) for b in OLD NEW OLD NEW; do
            bin=${!b}
            /usr/bin/time -f "$b demo wall %e s" "$bin" demo --backend cuda --out /tmp/demo_$b >"$O/demo_$b.log" 2>"$O/demo_$b.err"
            grep -E "demo wall|warning" "$O/demo_$b.err" | head -3; grep -iE "pre-processing|search:" "$O/demo_$b.log" | head -3
          done ;;
  esac
done
echo "=== done $(date -u +%H:%M:%S)"
