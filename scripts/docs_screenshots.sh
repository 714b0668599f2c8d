#!/usr/bin/env bash
# Makes the pictures of docs/user-guide.md with the application's own script options, offscreen (no display
# needed): the demo observation pre-processed, searched, a candidate fitted and labelled, the figure and
# report dialogs, and the paper-style figure itself. Each run simulates, pre-processes and searches the demo
# again (~40 s on 2 cores). Usage: scripts/docs_screenshots.sh [BUILD_DIR]   (default: build)
set -euo pipefail
cd "$(dirname "$0")/.."
app="$(realpath "${1:-build}")/app/synthtrack"
[ -x "$app" ] || { echo "no $app: build with -DST_BUILD_GUI=ON first" >&2; exit 1; }
out="$PWD/docs/guide"
mkdir -p "$out"
# A scratch home: the runs' settings and autosaved sessions stay out of the user's.
scratch="$(mktemp -d)"
trap 'rm -rf "$scratch"' EXIT
export QT_QPA_PLATFORM=offscreen HOME="$scratch" XDG_CONFIG_HOME="$scratch/config" XDG_DATA_HOME="$scratch/data"
cd "$scratch"
width=1200

shot() {  # NAME ARGS...: one scripted run ending in a screenshot of the window
  local name="$1"
  shift
  echo "== $name: synthtrack $*"
  "$app" --demo "$@" --screenshot "$out/$name.png" --screenshot-width "$width" --screenshot-colours 256 2>&1 | grep -v propagateSizeHints
}

shot 01_preprocessed
shot 02_search --search --select 1
shot 03_fit --search --select 1 --fit --accept-fit --label 1=real
shot 04_figure_dialog --search --select 1 --export-figure "$out/fig_sky_and_nea.png" --figure-dpi 110 \
  --dialog figure
shot 05_reports_dialog --search --select 1 --fit --accept-fit --label 1=real --export-reports "$scratch/reports" \
  --dialog reports
ls -l "$out"
