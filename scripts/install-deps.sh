#!/usr/bin/env bash
# Installs the Debian 12 packages synthtrack needs to build, test and run. Idempotent: packages that are
# already installed are skipped, and apt is not touched at all when nothing is missing.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config clang libclang-rt-14-dev
  libcfitsio-dev wcslib-dev libeigen3-dev libfftw3-dev
  libopencv-core-dev libopencv-imgproc-dev nlohmann-json3-dev libsep-dev
  qt6-base-dev qt6-svg-dev libqcustomplot-dev libgl-dev
  libgtest-dev libgmock-dev
  libopenmpi-dev openmpi-bin
  python3-astropy python3-numpy
  xvfb xauth saods9
  libxml2-utils
  # Plate solving (synthtrack-cli solve, preprocess --plate-solve; optional at run time). The Tycho-2 index
  # of 22'-30' quads (88 MB) is the densest Debian packages: its stars around the pointing also make the
  # small index files built for each field (core/astro/field_index.hpp), which solve the shared 26' Lowell
  # frames; -08 (30'-44'), -09 and -10-19 are for wider fields and left out to keep the download modest.
  astrometry.net astrometry-data-tycho2-07-littleendian
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages already installed"
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
