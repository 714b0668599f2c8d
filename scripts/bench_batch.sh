#!/usr/bin/env bash
# Throughput of `synthtrack-cli batch` on CPU ranks (issue 17's scale model), all in one run so that the
# ratios are comparable on a shared machine.
# usage: scripts/bench_batch.sh BUILD_DIR [N_OBS=12] [PAPER_OBS=2]
#   1. N_OBS small simulated observations (128^2 x 64, +-40 deg/day, fits) through: one process, and
#      `mpirun -np 2, 3, 4` (1, 2, 3 worker ranks), every worker one thread (ST_THREADS=1): observations/h
#      in all, per worker rank, and the ratio to one worker rank.
#   2. PAPER_OBS paper-neo observations (500 x 512^2, the paper's +-12 deg/day grid, fits) on one worker
#      rank of one thread: observations/h per CPU rank at the paper's size (0: skip).
#   WORK (default /tmp/st-bench-batch) holds the inputs and outputs. Needs an MPI build for step 1's mpirun
#   rows (they are skipped without mpirun).
set -euo pipefail
build="${1:?usage: $0 BUILD_DIR [N_OBS] [PAPER_OBS]}"
n="${2:-12}"
paper="${3:-2}"
cli="$build/app/synthtrack-cli"
[ -x "$cli" ] || { echo "no $cli" >&2; exit 2; }
work="${WORK:-/tmp/st-bench-batch}"
mkdir -p "$work/small" "$work/paper"
export ST_THREADS=1 OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
echo "date: $(date -u +%Y-%m-%dT%H:%M:%SZ), host: $(hostname), cores: $(nproc), load: $(cut -d' ' -f1-3 /proc/loadavg)"

for s in $(seq 1 "$n"); do
  f="$work/small/obs$s.fits"
  [ -f "$f" ] || "$cli" simulate --preset small --seed "$s" -o "$f" >/dev/null
done
small=("$work"/small/obs*.fits)

# Runs batch (prefix in "$@" before --) over the given inputs into a fresh folder; prints "seconds".
timed_batch() {
  local out="$work/out-$RANDOM-$(date +%s%N)"
  local start end
  start=$(date +%s.%N)
  "$@" --out "$out" >/dev/null 2>"$out.stderr" || { tail -n 5 "$out.stderr" >&2; return 1; }
  end=$(date +%s.%N)
  python3 -c "print('%.2f' % ($end - $start))"
}

declare -A secs
secs[one]=$(timed_batch "$cli" batch "${small[@]}" --vmax-deg-day 40 --backend cpu)
echo "one process, 1 thread: ${secs[one]} s"
if command -v mpirun >/dev/null; then
  for w in 1 2 3; do
    secs[$w]=$(timed_batch mpirun --oversubscribe -np $((w + 1)) "$cli" batch "${small[@]}" --vmax-deg-day 40 \
                 --backend cpu)
    echo "mpirun -np $((w + 1)) ($w worker ranks, 1 thread each): ${secs[$w]} s"
  done
fi
python3 - "$n" "${secs[one]}" "${secs[1]:-0}" "${secs[2]:-0}" "${secs[3]:-0}" <<'PY'
import sys
n = int(sys.argv[1]); one, w1, w2, w3 = map(float, sys.argv[2:6])
print("%d small observations (128^2 x 64, 71^2 velocities):" % n)
print("  one process          %7.0f obs/h" % (n * 3600 / one))
for w, s in ((1, w1), (2, w2), (3, w3)):
    if s > 0:
        print("  %d worker rank(s)     %7.0f obs/h in all, %6.0f per rank, ratio to 1 rank %.2f" %
              (w, n * 3600 / s, n * 3600 / s / w, w1 / s))
PY

if [ "$paper" -gt 0 ]; then
  for s in $(seq 1 "$paper"); do
    f="$work/paper/paper-neo-s$s.fits"
    [ -f "$f" ] || "$cli" simulate --preset paper-neo --seed "$s" -o "$f" >/dev/null
  done
  pobs=("$work"/paper/paper-neo-s*.fits)
  pobs=("${pobs[@]:0:$paper}")
  p=$(timed_batch "$cli" batch "${pobs[@]}" --backend cpu)
  python3 -c "print('%d paper-neo observations (500 x 512^2, +-12 deg/day) on one CPU rank of 1 thread: %s s, %.1f obs/h, %.1f s per observation' % ($paper, '$p', $paper * 3600 / $p, $p / $paper))"
fi
