#!/usr/bin/env bash
# Issue 16, 2026-12-05 (twenty-second stop): devrun_d14.sh (every GPU test, ROUNDS rounds of `bench preprocess
# --frames 1500 --backend cuda` traced, the FITS search, the demo), then memcheck of the zero-bias tests (the
# per-pixel background's windows now come from core: ae679ba). Usage: devrun_d22.sh PKG_DIR ROUNDS [VARIANT ...]
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
bash "$here/devrun_d14.sh" "$@"
P=/tmp/w/pkg; export LD_LIBRARY_PATH=$P/lib
timeout 240 compute-sanitizer --tool memcheck --leak-check full $P/st_gpu_test_gpu_zero_bias >/tmp/o/memcheck_zb.log 2>&1
echo "memcheck gpu_zero_bias rc=$? $(grep -E 'ERROR SUMMARY|LEAK SUMMARY|  PASSED|  FAILED' /tmp/o/memcheck_zb.log | tr '\n' ' ')"
tar -czf ${OUT:-/tmp}/o.tar.gz -C /tmp o
