#!/usr/bin/env bash
# Issue 16, 2026-12-05 (twenty-first stop): memcheck of the one-stream host copies' test, then ROUNDS rounds
# of `bench preprocess --frames 1500 --backend cuda` with knob variants alternating in one binary (no GPU
# tests, no FITS search: devrun_d14.sh ran those in the same session). Usage: devrun_d21.sh PKG_DIR ROUNDS
# [VARIANT ...]; logs come back as o.tar.gz in $OUT.
set -uo pipefail
D=$(cd "$1" && pwd); ROUNDS=${2:-10}; shift 2; VARIANTS=("ST_NONE=1" "$@")
W=/tmp/w; mkdir -p $W && [ -x $W/pkg/synthtrack-cli ] || tar -xJf "$D/pkg.tar.xz" -C $W
export LD_LIBRARY_PATH=$W/pkg/lib
P=$W/pkg; B=$P/synthtrack-cli; O=/tmp/o; mkdir -p $O
trap 'tar -czf ${OUT:-/tmp}/o.tar.gz -C /tmp o' EXIT
date -u; nvidia-smi --query-gpu=name --format=csv,noheader
timeout 200 compute-sanitizer --tool memcheck --leak-check full $P/st_gpu_test_gpu_downloads >$O/memcheck.log 2>&1
echo "memcheck gpu_downloads rc=$? $(grep -E 'ERROR SUMMARY|LEAK SUMMARY|  PASSED|  FAILED' $O/memcheck.log | tr '\n' ' ')"
for r in $(seq 1 $ROUNDS); do for v in "${VARIANTS[@]}"; do n=${v//[=\/,-]/_}
  env ${v//,/ } $B bench preprocess --frames 1500 --backend cuda > $O/bp_${n}_$r.log 2>&1
  echo "$r $n $(grep '^preprocess:' $O/bp_${n}_$r.log | cut -c13-22) $(grep -E '^  (sky rate|matched)' $O/bp_${n}_$r.log | tr -s ' ' | cut -c1-24 | tr '\n' ' ')"
done; done
date -u
