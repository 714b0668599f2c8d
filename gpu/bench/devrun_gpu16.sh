#!/usr/bin/env bash
# Issue 16's search kernels on the GPU machine, from binaries packed by scripts/devrun-pack.sh into this
# script's folder (gpu16.tar.xz carried in out/): the tree and exact benchmarks, Float16 against Float32,
# ncu profiles of the tree and stair kernels, the SASS, GPU tests and memcheck.
# Usage: devrun_gpu16.sh STEP...   steps: tools sass tree half exact ncutree ncustair tests memcheck
set -uo pipefail
D=$(cd "$(dirname "$0")" && pwd)
export LD_LIBRARY_PATH=$D/lib
O=${OUT:-/tmp/st_out}
mkdir -p "$O"
nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm --format=csv,noheader
date -u
B="$D/st_gpu_bench"
for step in "$@"; do
  echo "=== $step $(date -u +%H:%M:%S)"
  case $step in
    tools) which nsys ncu compute-sanitizer cuobjdump nvdisasm; ncu --version | tail -1 ;;
    sass) cuobjdump -sass "$B" >"$O/bench.sass" 2>&1; ls -la "$O/bench.sass"; xz -T0 "$O/bench.sass" ;;
    sassstair) cuobjdump -sass -fun regex:stairSearchKernelILi8ELb1ELb0ELb[01]E "$B" >"$O/stair.sass" 2>&1
               grep -cE "BRX" "$O/stair.sass"; xz -T0 "$O/stair.sass" ;;
    tree) "$B" 1500 512 100 12 500 tree 2>&1 | tee "$O/treebench.log" | grep -vE "^  (device 0: cube|host)" |
            sed -E 's/^  device 0: tree: .*top 4 levels in registers; /  /' ;;
    half) "$B" 1500 512 100 12 500 half 2>&1 | tee "$O/halfbench.log" | grep -E "search|Float16" ;;
    exact) "$B" 1500 512 100 12 500 exact 2>&1 | tee "$O/exactbench.log" | grep -E "search|Float16" ;;
    ncutree) timeout 300 ncu -k regex:treeRootKernel -c 1 --set full "$B" 1500 512 100 12 500 treeonly \
               >"$O/ncu_root.txt" 2>&1; echo "ncu root rc=$?"
             timeout 200 ncu -k regex:treeLevelKernel -c 10 --section SpeedOfLight --section MemoryWorkloadAnalysis \
               --section LaunchStats --section Occupancy "$B" 1500 512 100 12 500 treeonly >"$O/ncu_levels.txt" 2>&1
             echo "ncu levels rc=$?" ;;
    ncustair) timeout 300 ncu -k regex:stairSearchKernel -s 6 -c 1 --set full "$B" 1500 512 100 12 500 exact \
                >"$O/ncu_stair.txt" 2>&1; echo "ncu stair rc=$?" ;;
    ncuhalf) timeout 300 ncu --kernel-name-base mangled -k regex:stairSearchKernelILi8ELb1ELb0ELb1E -s 6 -c 1 --set full "$B" 1500 512 100 12 500 half \
               >"$O/ncu_half.txt" 2>&1; echo "ncu half rc=$?" ;;
    tests) for t in "$D"/st_gpu_test_*; do
             timeout 200 "$t" >"$O/t.log" 2>&1; echo "$(basename "$t") rc=$?"
             cat "$O/t.log" >>"$O/tests.log"
             grep -E "^\[ +(FAILED|PASSED|SKIPPED) |Failure|Expected|Which|actual" "$O/t.log" | head -30
           done; rm -f "$O/t.log" ;;
    memcheck) for t in "$D"/st_gpu_test_*; do
                timeout 240 compute-sanitizer --tool memcheck --leak-check full "$t" --gtest_filter=-*LongCube* \
                  >"$O/m.log" 2>&1; echo "memcheck $(basename "$t") rc=$?"
                cat "$O/m.log" >>"$O/memcheck.log"
                grep -E "ERROR SUMMARY|LEAK SUMMARY|PASSED|FAILED" "$O/m.log" | head -4
              done; rm -f "$O/m.log" ;;
  esac
done
echo "=== done $(date -u +%H:%M:%S)"
