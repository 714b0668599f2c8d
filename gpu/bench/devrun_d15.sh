#!/usr/bin/env bash
# Issue 16, 2026-12-03 (fifteenth stop): the copy probe (st_gpu_copy_probe: DMA, staging, registered host
# memory), every GPU test, memcheck of the tests of the last stop's new device work (the kept mask's hot
# pixels, the pipelined residual means: GpuFrameBackgrounds, GpuZeroBias), then devrun_d14.sh's bench rounds
# with knob variants alternating, the FITS search and the demo.
# Usage: devrun_d15.sh PKG_DIR ROUNDS [VARIANT ...]; logs and traces come back as o.tar.gz in $OUT.
set -uo pipefail
D=$(cd "$1" && pwd)
W=/tmp/w; mkdir -p $W && [ -x $W/pkg/synthtrack-cli ] || tar -xJf "$D/pkg.tar.xz" -C $W
export LD_LIBRARY_PATH=$W/pkg/lib
O=/tmp/o; mkdir -p $O
date -u; $W/pkg/st_gpu_copy_probe 1500 512 2 2>&1 | tee $O/copy_probe.log
mc() {  # memcheck TEST_BINARY_SUFFIX GTEST_FILTER
  timeout 200 compute-sanitizer --tool memcheck --leak-check full $W/pkg/st_gpu_test_$1 --gtest_filter="$2" >$O/memcheck_$1.log 2>&1
  echo "memcheck $1 rc=$? $(grep -E 'ERROR SUMMARY|LEAK SUMMARY|  PASSED|  FAILED' $O/memcheck_$1.log | tr '\n' ' ')"
}
mc gpu_frame_backgrounds '*HotPixels*:*Prefetch*'
mc gpu_zero_bias '*StagesOnTheDevice*:*PipelineWithTheDevice*'
exec bash "$(dirname "$0")/devrun_d14.sh" "$@"
