#!/usr/bin/env bash
# Runs the GPU tests, compute-sanitizer memcheck and the benchmark on a machine with a GPU, from binaries
# built elsewhere (build-gpu/, Debian 12: they need only glibc and libstdc++). Logs go to $OUT (or /tmp).
# Usage: gpu/bench/run_device.sh [test|memcheck|bench|treebench|exactbench|sass]...   (default: test memcheck bench)
set -uo pipefail
out=${OUT:-/tmp/st_gpu_out}
mkdir -p "$out"
bin=build-gpu
steps=("$@")
[ ${#steps[@]} -eq 0 ] && steps=(test memcheck bench)
nvidia-smi --query-gpu=index,name,driver_version,memory.total,clocks.sm,clocks.max.sm --format=csv
for s in "${steps[@]}"; do
  case $s in
    test) for t in "$bin"/tests/st_gpu_test_*; do [ -x "$t" ] || continue
            "$t" 2>&1 | tee "$out/test_$(basename "$t").log" | grep -E "^\[ +(OK|FAILED|SKIPPED|PASSED) |Failure|Expected|Which|actual" | head -60
          done ;;
    memcheck) for t in "$bin"/tests/st_gpu_test_*; do [ -x "$t" ] || continue
                timeout 240 compute-sanitizer --tool memcheck --leak-check full "$t" --gtest_filter=-*LongCube* \
                  >"$out/memcheck_$(basename "$t").log" 2>&1; echo "memcheck $(basename "$t") rc=$?"
                tail -4 "$out/memcheck_$(basename "$t").log"
              done ;;
    treebench) "$bin/gpu/st_gpu_bench" 1500 512 100 12 500 tree 2>&1 | tee "$out/treebench.log" ;;
    bench) "$bin/gpu/st_gpu_bench" 2>&1 | tee "$out/bench.log" ;;
    exactbench) "$bin/gpu/st_gpu_bench" 1500 512 100 12 500 exact 2>&1 | tee "$out/exactbench.log" ;;
    sass) cuobjdump -sass "$bin/gpu/st_gpu_bench" >"$out/bench.sass" 2>&1; grep -c LDS "$out/bench.sass" ;;
  esac
done
