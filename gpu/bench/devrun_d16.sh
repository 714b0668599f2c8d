#!/usr/bin/env bash
# 2026-12-04 (seventeenth stop): every GPU test, the FITS search and the demo with --backend cuda (the tree's
# candidates now re-scored by the exact search on the CPU), then the pipeline-seeds campaign over paper-neo
# seeds ST_SEEDS (CPU path, every core). Usage: devrun_d16.sh PKG_DIR SEEDS; logs come back as o.tar.gz in $OUT.
set -uo pipefail
D=$(cd "$1" && pwd); SEEDS=${2:-41-130}
W=/tmp/w; mkdir -p $W && [ -x $W/pkg/synthtrack-cli ] || tar -xJf "$D/pkg.tar.xz" -C $W
export LD_LIBRARY_PATH=$W/pkg/lib
P=$W/pkg; B=$P/synthtrack-cli; O=/tmp/o; mkdir -p $O
trap 'tar -czf ${OUT:-/tmp}/o.tar.gz -C /tmp o' EXIT
date -u; nvidia-smi --query-gpu=name --format=csv,noheader
for t in $P/st_gpu_test_*; do n=$(basename $t); timeout 300 $t > $O/$n.log 2>&1
  echo "$n rc=$? $(grep -E '^\[  (PASSED|FAILED) ' $O/$n.log | tr '\n' ' ')"; done
grep -h "FAILED\|Failure" $O/st_gpu_test_*.log | head -20
F=/tmp/d1500/observation.fits; [ -f $F ] || $B demo --frames 1500 --backend cuda --fits 0 --out /tmp/d1500 >/dev/null 2>&1; cat $F >/dev/null
A="--vmax-px-s 0.5565 --centre-px-s 15.8,0.3"
for r in 1 2 3; do /usr/bin/time -f "wall %e s" $B search $F --backend cuda --timings $A --out /tmp/s$r.csv >$O/s$r.log 2>$O/s$r.err
  tr '\r' '\n' < $O/s$r.err | grep -E "wall|timings: (loaded)|re-scored" | sed 's/timings: //; s/  */ /g' | tr '\n' '|'; echo; done
head -2 /tmp/s3.csv | tail -1 | cut -c1-70
for r in 1 2; do /usr/bin/time -f "demo wall %e s" $B demo --backend cuda --timings --out /tmp/demo$r >$O/demo$r.log 2>$O/demo$r.err
  tr '\r' '\n' < $O/demo$r.err | grep -E "after the simulation|wall|warning|re-scored"; grep -iE "FOUND" $O/demo$r.log | head -1; done
date -u
ST_SEEDS=$SEEDS timeout 420 $P/seeds > $O/seeds.log 2>&1; echo "seeds rc=$?"
grep -E "^found|other candidate|per-frame|MISSED" $O/seeds.log | cut -c1-220 | tail -12
grep -E "^seed [0-9]+: sky rate" $O/seeds.log | grep -vE "\((-?[01]\.[0-9]), (-?[01]\.[0-9]) steps\)" | cut -c1-200 | head
date -u
