#!/usr/bin/env bash
# Issue 16 on the GPU machine, from binaries packed by scripts/devrun-pack.sh into this script's folder:
# GPU tests (preprocess, backend, tree), memcheck of the pre-processing tests, the paper problem's
# pre-processing per stage on the GPU, the search benchmark (exact + tree, PSF source), the demo.
# Usage: devrun_issue16.sh [tests] [apptests] [memcheck] [prep] [prepstage] [bench] [demo] [demo16] [fits1500] [prepcpu] [prepcpu2]
# (MC_TESTS: the test binaries memcheck runs, default every st_gpu_test_*)
set -uo pipefail
D=$(cd "$(dirname "$0")" && pwd)
export LD_LIBRARY_PATH=$D/lib
O=${OUT:-/tmp/st_out}
mkdir -p "$O"
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader
date -u
for step in "$@"; do
  echo "=== $step $(date -u +%H:%M:%S)"
  case $step in
    tests) for t in "$D"/st_gpu_test_*; do
             timeout 150 "$t" >"$O/$(basename "$t").log" 2>&1; echo "$(basename "$t") rc=$?"
             grep -E "^\[ +(FAILED|PASSED|SKIPPED) |Failure|Expected|Which|actual|worst| on cuda" "$O/$(basename "$t").log" | head -40
           done ;;
    memcheck) for t in ${MC_TESTS:-"$D"/st_gpu_test_*}; do
                case $t in /*) ;; *) t=$D/$t ;; esac
                timeout 200 compute-sanitizer --tool memcheck --leak-check full "$t" --gtest_filter=-*LongCube* \
                  >"$O/memcheck_$(basename "$t").log" 2>&1; echo "memcheck $(basename "$t") rc=$?"
                grep -E "ERROR SUMMARY|LEAK SUMMARY|PASSED|FAILED" "$O/memcheck_$(basename "$t").log" | head -4
              done ;;
    prep) "$D/synthtrack-cli" bench preprocess --frames 1500 --backend cuda 2>"$O/prep_gpu.err" | tee "$O/prep_gpu.log" ;;
    prepstage) # the stage-by-stage device path of before the resident zero-biased cube (ST_GPU_STAGEWISE)
               ST_GPU_STAGEWISE=1 "$D/synthtrack-cli" bench preprocess --frames 1500 --backend cuda 2>"$O/prep_gpu_stagewise.err" | tee "$O/prep_gpu_stagewise.log" ;;
    prepcpu2) ST_THREADS=2 taskset -c 0,1 "$D/synthtrack-cli" bench preprocess --frames 1500 --backend cpu 2>/dev/null | tee "$O/prep_cpu2.log" ;;
    prepcpu) "$D/synthtrack-cli" bench preprocess --frames 1500 --backend cpu 2>/dev/null | tee "$O/prep_cpu16.log" ;;
    bench) "$D/st_gpu_bench" 1500 512 100 12 500 tree 2>&1 | tee "$O/treebench.log" | grep -vE "^  device 0: tree" ;;
    apptests) for t in "$D"/st_app_test_*; do [ -x "$t" ] || continue
                timeout 150 "$t" >"$O/$(basename "$t").log" 2>&1; echo "$(basename "$t") rc=$?"
                grep -E "^\[ +(FAILED|PASSED|SKIPPED) |Failure|Expected" "$O/$(basename "$t").log" | head -20
              done ;;
    demo16) /usr/bin/time -f "demo fp16 wall %e s" "$D/synthtrack-cli" demo --backend cuda --frame-precision fp16 \
              --out /tmp/demo16 2>"$O/demo16.err" | tee "$O/demo16.log"
            grep -E "warning|demo fp16 wall|GPU" "$O/demo16.err" | head ;;
    fits1500) # FITS files (one 1500-frame cube written by the demo) to candidates, paper-neo 1500 x 512^2
              "$D/synthtrack-cli" demo --frames 1500 --backend cuda --fits 0 --out /tmp/d1500 >"$O/d1500.log" 2>&1
              grep -E "pre-processing|search:" "$O/d1500.log"
              cat /tmp/d1500/observation.fits >/dev/null  # in the page cache
              /usr/bin/time -f "fits to candidates wall %e s" "$D/synthtrack-cli" search /tmp/d1500/observation.fits \
                --backend cuda --out /tmp/s1500.csv >"$O/s1500.log" 2>"$O/s1500.err"
              tail -25 "$O/s1500.err"; head -5 "$O/s1500.log" ;;
    demo) /usr/bin/time -f "demo wall %e s" "$D/synthtrack-cli" demo --backend cuda --out /tmp/demo 2>"$O/demo.err" | tee "$O/demo.log"
          grep -E "warning|demo wall|GPU" "$O/demo.err" | head ;;
  esac
done
echo "=== done $(date -u +%H:%M:%S)"
