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

# Runs batch (prefix in "$@") over the given inputs into a fresh folder; prints "WALL CPU" seconds (CPU: user +
# system of the command and the ranks it waited for, as /usr/bin/time counts them).
timed_batch() {
  local out="$work/out-$RANDOM-$(date +%s%N)"
  /usr/bin/time -f "%e %U %S" -o "$out.time" "$@" --out "$out" >/dev/null 2>"$out.stderr" ||
    { tail -n 5 "$out.stderr" >&2; return 1; }
  python3 -c "w, u, s = map(float, open('$out.time').read().split()[-3:]); print('%.2f %.2f' % (w, u + s))"
}

declare -A secs
secs[one]=$(timed_batch "$cli" batch "${small[@]}" --vmax-deg-day 40 --backend cpu)
echo "one process, 1 thread: wall, CPU s: ${secs[one]}"
if command -v mpirun >/dev/null; then
  for w in 1 2 3; do
    secs[$w]=$(timed_batch mpirun --oversubscribe -np $((w + 1)) "$cli" batch "${small[@]}" --vmax-deg-day 40 \
                 --backend cpu)
    echo "mpirun -np $((w + 1)) ($w worker ranks, 1 thread each): wall, CPU s: ${secs[$w]}"
  done
fi
python3 - "$n" "${secs[one]}" "${secs[1]:-0 0}" "${secs[2]:-0 0}" "${secs[3]:-0 0}" <<'PY'
import sys
n = int(sys.argv[1])
runs = [("one process", 1, sys.argv[2])] + [("%d worker rank(s)" % w, w, a) for w, a in ((1, sys.argv[3]), (2, sys.argv[4]), (3, sys.argv[5]))]
base = float(sys.argv[3].split()[0]) or float(sys.argv[2].split()[0])
print("%d small observations (128^2 x 64, 71^2 velocities, fits); 'cores got' = CPU s / wall s:" % n)
for label, w, a in runs:
    wall, cpu = map(float, a.split())
    if wall <= 0:
        continue
    print("  %-18s %6.0f obs/h in all, %5.0f per rank, ratio to 1 worker %.2f; CPU %.2f s/obs, cores got %.2f" %
          (label, n * 3600 / wall, n * 3600 / wall / w, base / wall, cpu / n, cpu / wall))
PY

if [ "$paper" -gt 0 ]; then
  for s in $(seq 1 "$paper"); do
    f="$work/paper/paper-neo-s$s.fits"
    [ -f "$f" ] || "$cli" simulate --preset paper-neo --seed "$s" -o "$f" >/dev/null
  done
  pobs=("$work"/paper/paper-neo-s*.fits)
  pobs=("${pobs[@]:0:$paper}")
  p=$(timed_batch "$cli" batch "${pobs[@]}" --backend cpu)
  python3 -c "
w, c = map(float, '$p'.split()); n = $paper
print('%d paper-neo observations (500 x 512^2, +-12 deg/day, fits) on one CPU rank of 1 thread: wall %.1f s '
      '(%.1f obs/h), CPU %.1f s per observation (%.1f obs/h per fully available core)' % (n, w, n * 3600 / w, c / n, n * 3600 / c))"
fi
