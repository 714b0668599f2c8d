#!/usr/bin/env bash
# Packs the binaries a GPU-machine run needs (the GPU tests, st_gpu_bench, synthtrack-cli) and the shared
# libraries the bare device image lacks into DEST (an ignored folder of the checkout the device tool sends),
# stripped. Usage: scripts/devrun-pack.sh BUILD_DIR DEST
set -euo pipefail
build=$1
dest=$2
mkdir -p "$dest/lib"
bins=("$build"/tests/st_gpu_test_* "$build"/gpu/st_gpu_bench "$build"/gpu/st_gpu_copy_probe "$build"/app/synthtrack-cli)
for b in "${bins[@]}"; do
  [ -x "$b" ] || continue
  strip -o "$dest/$(basename "$b")" "$b"
done
# Everything outside glibc/libstdc++/libgcc (the device image has those).
for b in "${bins[@]}"; do
  [ -x "$b" ] || continue
  ldd "$b" | awk '/=> \//{print $3}'
done | sort -u | grep -vE '/(libc|libm|libpthread|libdl|librt|libstdc\+\+|libgcc_s|ld-linux[^/]*)\.so' |
  while read -r lib; do cp -L "$lib" "$dest/lib/"; strip --strip-unneeded "$dest/lib/$(basename "$lib")" 2>/dev/null || true; done
du -sh "$dest"
