#pragma once
// Internal to core/io: a bounds-checked dry run of CFITSIO's RICE_1 decoder over every tile of a tile-
// compressed image, done before CFITSIO decompresses it. CFITSIO 4.2's fits_rdecomp_* read past the end of a
// corrupt tile's buffer (an unbounded scan for a non-zero byte), which crashes the process; found by fuzzing
// (tests/fuzz). The dry run mirrors ricecomp.c's bit reading exactly, so valid tiles always pass.
#include <cstddef>
#include <cstdint>
#include <string>

#include "fits_file.hpp"

namespace st::io::detail {

/// True when a RICE stream of `length` bytes decodes `pixels` pixels of `bytePix` bytes (1, 2 or 4) in blocks
/// of `blockSize` without reading beyond its end.
bool riceStreamIsSafe(const std::uint8_t* data, std::size_t length, std::size_t pixels, int bytePix,
                      int blockSize);

/// For a tile-compressed image in the current HDU, checks that every tile lies inside the heap and, for
/// RICE_1, that its stream is safe to decode; throws st::InputError naming the file, HDU and tile when one is
/// corrupt. Does nothing for other HDUs.
void checkRiceTiles(const FitsFile& file);

}  // namespace st::io::detail
