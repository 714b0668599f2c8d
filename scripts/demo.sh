#!/usr/bin/env bash
# Sets up and runs the main job on the built-in demo observation: installs the Debian packages, builds
# Release, and opens the GUI on the demo (the paper's observation, simulated). With no display, runs the
# CLI demo instead and says where its outputs went.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build -j "$(nproc)"

if [ -n "${DISPLAY:-}${WAYLAND_DISPLAY:-}" ] && [ -x build/app/synthtrack ]; then
  exec build/app/synthtrack --demo
fi
out="${ST_DEMO_OUT:-$PWD/demo-output}"
echo "No display: running the CLI demo, outputs in $out"
exec build/app/synthtrack-cli demo --out "$out"
