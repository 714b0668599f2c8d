#!/usr/bin/env bash
# A perf profile with frame pointers (build with -DST_FRAME_POINTERS=ON): bench preprocess --frames 1500 --backend
# cuda, every thread's call chains; comes back as g.txt.xz (perf script: tid, time, ip, symbol).
set -uo pipefail
D=$(cd "$(dirname "$0")" && pwd); W=/tmp/w; mkdir -p $W; tar -xJf "$D/pkg.tar.xz" -C $W; tar -xJf "$D/perf.tar.xz" -C $W
export LD_LIBRARY_PATH=$W/pkg/lib; B=$W/pkg/synthtrack-cli
date -u; nvidia-smi --query-gpu=name --format=csv,noheader
echo 0 > /proc/sys/kernel/perf_event_paranoid; echo 0 > /proc/sys/kernel/kptr_restrict
P="env LD_LIBRARY_PATH=$W/perf/lib:$LD_LIBRARY_PATH $W/perf/perf"
$B bench preprocess --frames 1500 --backend cuda 2>&1 | grep -E "^preprocess:"
$P record -F 2999 --call-graph fp -o /tmp/g.data -- $B bench preprocess --frames 1500 --backend cuda > $OUT/g.log 2>/tmp/g.err
grep -E "^preprocess:" $OUT/g.log
$P script -i /tmp/g.data -F tid,time,ip,sym 2>/dev/null | xz -T8 > $OUT/g.txt.xz
ls -la $OUT; date -u
