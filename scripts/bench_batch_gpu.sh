#!/usr/bin/env bash
# Throughput of `synthtrack-cli batch` on GPU ranks (issue 17's scale model, row "per GPU rank").
# usage: scripts/bench_batch_gpu.sh BUILD_DIR [N_OBS=8] [FRAMES=500] [RANKS=0]
#   Simulates N_OBS paper-neo observations (512^2, FRAMES frames each, seeds 1..N_OBS; cached in $WORK),
#   then runs `batch --backend cuda` over them into a fresh output folder and prints observations/hour.
#   RANKS=0: one process (one GPU); RANKS=K>0: `mpirun -np K+1` (rank 0 hands out, K GPU workers, one GPU
#   each when the node has K). Search options: the paper's defaults (+-12 deg/day, fits of every candidate).
#   BACKEND: default cuda (cpu to try the script without a GPU). WORK (default /tmp/st-bench-batch-gpu)
#   holds the cubes (~0.5 GB each at 500 frames) and the outputs.
#   Prints the device, the per-observation seconds from the batch logs and the figure for the README:
#   "per GPU rank: X observations/h of FRAMES x 512^2".
set -euo pipefail
build="${1:?usage: $0 BUILD_DIR [N_OBS] [FRAMES] [RANKS]}"
n="${2:-8}"
frames="${3:-500}"
ranks="${4:-0}"
cli="$build/app/synthtrack-cli"
[ -x "$cli" ] || cli="$build/synthtrack-cli"
[ -x "$cli" ] || { echo "no synthtrack-cli under $build (app/synthtrack-cli)" >&2; exit 2; }
work="${WORK:-/tmp/st-bench-batch-gpu}"
mkdir -p "$work/obs"

command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,memory.total --format=csv,noheader || true
echo "date: $(date -u +%Y-%m-%dT%H:%M:%SZ), host: $(hostname), cores: $(nproc)"

for s in $(seq 1 "$n"); do
  f="$work/obs/paper-neo-$frames-s$s.fits"
  [ -f "$f" ] || "$cli" simulate --preset paper-neo --frames "$frames" --seed "$s" -o "$f" >/dev/null
done
obs=("$work"/obs/paper-neo-"$frames"-s*.fits)
obs=("${obs[@]:0:$n}")

out="$work/out-$(date +%s)"
cmd=("$cli" batch "${obs[@]}" --out "$out" --backend "${BACKEND:-cuda}")
if [ "$ranks" -gt 0 ]; then
  cmd=(mpirun --allow-run-as-root --oversubscribe -np $((ranks + 1)) "${cmd[@]}")
fi
echo "running: ${cmd[*]}"
start=$(date +%s.%N)
set +e
"${cmd[@]}" 2> "$out.stderr"
rc=$?
set -e
end=$(date +%s.%N)
tail -n 3 "$out.stderr"
[ "$rc" -le 1 ] || { echo "batch exited $rc (see $out.stderr)" >&2; exit "$rc"; }
python3 - "$out" "$start" "$end" "$n" "$frames" "$ranks" <<'PY'
import glob, json, os, sys
out, start, end, n, frames, ranks = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5]), int(sys.argv[6])
wall = end - start
logs = [json.load(open(p)) for p in sorted(glob.glob(os.path.join(out, "logs", "*.json")))]
done = [l for l in logs if l.get("status") == "done"]
per = [l["seconds"] for l in done]
print("observations done: %d of %d; backends: %s" % (len(done), n, sorted({l.get("backend", "?") for l in done})))
print("methods: %s" % sorted({l.get("method", "?") for l in done}))
if per:
    print("seconds per observation (worker): min %.2f median %.2f max %.2f" % (min(per), sorted(per)[len(per) // 2], max(per)))
workers = max(ranks, 1)
print("wall %.1f s for %d observations of %d x 512^2: %.0f observations/h in all, %.0f per GPU rank" %
      (wall, len(done), frames, len(done) * 3600.0 / wall, len(done) * 3600.0 / wall / workers))
if per:
    print("per GPU rank, from the worker's own seconds (excludes process start and the merge): %.0f observations/h" %
          (3600.0 / (sum(per) / len(per))))
PY
