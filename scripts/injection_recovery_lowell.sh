#!/usr/bin/env bash
# Injection-recovery on real frames, as a user runs it: synthetic movers injected into the raw Lowell
# 42-inch frames of ../shared/data/real/lowell42-5945 (15 x 300 s, README there), then pre-processed,
# searched and scored with the same commands as any observation:
#   inject -> preprocess (bias, flat, matched filter) -> search --preprocessed -> recovery
# 3 seeds x 40 movers, expected SNR 4-20 (optimal matched filter of the whole track), speeds 0.0005-0.004
# px/s in the frames (2-17 px over the 72-min span), searched +-0.2 deg/day around the sky rate in 1 px
# steps over the span (as tests/core/test_pipeline_real_slow.cpp). Each seed gets its own recovery, and all
# three are scored together in OUT/recovery (completeness.csv, completeness.svg, recovery.json, ...).
#
# usage: scripts/injection_recovery_lowell.sh [OUT_DIR]     (default: build/injection-recovery-lowell)
# env:   CLI (synthtrack-cli, default build/app/synthtrack-cli), DATA (the lowell42-5945 folder),
#        SEEDS (default "1 2 3"), N (movers per seed, default 40)
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
CLI=${CLI:-$ROOT/build/app/synthtrack-cli}
DATA=${DATA:-$ROOT/../shared/data/real/lowell42-5945}
OUT=${1:-$ROOT/build/injection-recovery-lowell}
SEEDS=${SEEDS:-"1 2 3"}
N=${N:-40}
# The headers carry no GAIN: AGAIN_01 = 4.95 e-/ADU is the gain of amplifier 1, the only one read out.
GAIN=4.95

[ -d "$DATA/science" ] || { echo "no data at $DATA" >&2; exit 1; }
pairs=()
for seed in $SEEDS; do
  d=$OUT/seed$seed
  mkdir -p "$d"
  echo "== seed $seed: inject" >&2
  "$CLI" inject "$DATA"/science/*.fits.fz -o "$d/frames" --bias "$DATA"/bias --flat "$DATA"/flat \
    --gain "$GAIN" --n "$N" --snr 4,20 --rate 0.0005,0.004 --rate-unit px-s --seed "$seed" > "$d/inject.txt"
  echo "== seed $seed: preprocess" >&2
  "$CLI" preprocess "$d"/frames/*.fits --bias "$DATA"/bias --flat "$DATA"/flat \
    -o "$d/prepared.fits" --filtered "$d/filtered.fits" > "$d/preprocess.txt"
  echo "== seed $seed: search" >&2
  "$CLI" search "$d/filtered.fits" --preprocessed --vmax-deg-day 0.2 --json > "$d/candidates.json"
  echo "== seed $seed: recovery" >&2
  "$CLI" recovery "$d/frames/truth.json" "$d/candidates.json" --out "$d/recovery" | tee "$d/recovery.txt"
  pairs+=("$d/frames/truth.json" "$d/candidates.json")
done
echo "== all seeds" >&2
"$CLI" recovery "${pairs[@]}" --out "$OUT/recovery" | tee "$OUT/recovery.txt"
