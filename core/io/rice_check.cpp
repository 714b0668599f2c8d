#include "rice_check.hpp"

#include <algorithm>
#include <bit>
#include <cstring>
#include <filesystem>
#include <vector>

#include "st/common/error.hpp"

namespace st::io::detail {

bool riceStreamIsSafe(const std::uint8_t* data, std::size_t length, std::size_t pixels, int bytePix,
                      int blockSize) {
  int fsBits = 0;
  int fsMax = 0;
  switch (bytePix) {
    case 1:
      fsBits = 3;
      fsMax = 6;
      break;
    case 2:
      fsBits = 4;
      fsMax = 14;
      break;
    case 4:
      fsBits = 5;
      fsMax = 25;
      break;
    default:
      return true;  // CFITSIO rejects other sizes itself
  }
  const int bBits = 1 << fsBits;
  if (blockSize <= 0 || length < static_cast<std::size_t>(bytePix) + 1) return false;
  std::size_t pos = static_cast<std::size_t>(bytePix);  // the first pixel is stored raw
  bool overrun = false;
  auto next = [&]() -> std::uint64_t {
    if (pos >= length) {
      overrun = true;
      return 0;
    }
    return data[pos++];
  };
  std::uint64_t b = next();
  int nbits = 8;
  for (std::size_t i = 0; i < pixels;) {
    nbits -= fsBits;
    while (nbits < 0) {
      b = (b << 8) | next();
      nbits += 8;
    }
    const int fs = static_cast<int>(b >> nbits) - 1;
    b &= (std::uint64_t{1} << nbits) - 1;
    const std::size_t iMax = std::min(pixels, i + static_cast<std::size_t>(blockSize));
    if (fs < 0) {
      i = iMax;
    } else if (fs == fsMax) {
      for (; i < iMax && !overrun; ++i) {
        int k = bBits - nbits;
        for (k -= 8; k >= 0; k -= 8)
          b = next();
        if (nbits > 0) {
          b = next() & ((std::uint64_t{1} << nbits) - 1);
        } else {
          b = 0;
        }
      }
    } else {
      for (; i < iMax && !overrun; ++i) {
        while (b == 0) {
          nbits += 8;
          b = next();
          if (overrun) return false;
        }
        const int nzero = nbits - static_cast<int>(std::bit_width(b));
        nbits -= nzero + 1;
        if (nbits < 0) return false;
        b ^= std::uint64_t{1} << nbits;
        nbits -= fs;
        while (nbits < 0) {
          b = (b << 8) | next();
          nbits += 8;
        }
        b &= (std::uint64_t{1} << nbits) - 1;
      }
    }
    if (overrun) return false;
  }
  return true;
}

void checkRiceTiles(const FitsFile& f) {
  int status = 0;
  if (!fits_is_compressed_image(f.get(), &status)) return;
  const std::string where = f.path() + " HDU " + std::to_string(f.currentHdu());
  // The parameters exactly as CFITSIO parsed them when it opened the HDU (they drive its decoder).
  const FITSfile& p = *f.get()->Fptr;
  const bool rice = p.compress_type == RICE_1;  // other types: only the tile sizes are checked
  const int znaxis = p.zndim;
  if (znaxis < 1 || znaxis > MAX_COMPRESS_DIM) return;  // CFITSIO refuses these itself
  std::vector<long long> size(static_cast<std::size_t>(znaxis)), tile(static_cast<std::size_t>(znaxis));
  for (int a = 0; a < znaxis; ++a) {
    size[a] = p.znaxis[a];
    tile[a] = p.tilesize[a];
    if (size[a] <= 0 || tile[a] <= 0) return;
  }
  const int blockSize = p.rice_blocksize;
  const int bytePix = p.rice_bytepix;
  const int col = p.cn_compressed;
  if (col <= 0) return;
  long rows = 0;
  fits_get_num_rows(f.get(), &rows, &status);
  // A tile cannot hold more bytes than the heap (PCOUNT), nor than the file (gzip'ed files: allow for the
  // ratio).
  LONGLONG heap = 0;
  fits_read_key(f.get(), TLONGLONG, "PCOUNT", &heap, nullptr, &status);
  f.check(status, "reading PCOUNT");
  std::error_code ec;
  const auto onDisk = static_cast<LONGLONG>(std::filesystem::file_size(f.path(), ec));
  const LONGLONG maxTileBytes = ec ? heap : std::min<LONGLONG>(heap, onDisk * 64);
  std::vector<std::uint8_t> bytes;
  for (long r = 1; r <= rows; ++r) {
    LONGLONG repeat = 0;
    LONGLONG offset = 0;
    fits_read_descriptll(f.get(), col, r, &repeat, &offset, &status);
    f.check(status, "reading the descriptor of compressed tile " + std::to_string(r));
    if (repeat == 0) continue;  // the tile is stored in another column (GZIP or uncompressed)
    if (repeat < 0 || offset < 0 || repeat > maxTileBytes || offset > heap - repeat) {
      throw InputError(where + ": compressed tile " + std::to_string(r) + " claims " +
                       std::to_string(repeat) + " bytes at heap offset " + std::to_string(offset) +
                       ", outside the heap of " + std::to_string(heap) +
                       " bytes (corrupt or truncated file)");
    }
    // Pixels in tile r: tiles run fastest along axis 1; edge tiles are smaller.
    long long index = r - 1;
    long long pixels = 1;
    for (int a = 0; a < znaxis; ++a) {
      const long long count = (size[a] + tile[a] - 1) / tile[a];
      const long long t = index % count;
      index /= count;
      pixels *= std::min(tile[a], size[a] - t * tile[a]);
    }
    if (!rice) continue;
    bytes.resize(static_cast<std::size_t>(repeat));
    unsigned char nul = 0;
    int anyNull = 0;
    fits_read_col(f.get(), TBYTE, col, r, 1, repeat, &nul, bytes.data(), &anyNull, &status);
    f.check(status, "reading compressed tile " + std::to_string(r));
    if (!riceStreamIsSafe(bytes.data(), bytes.size(), static_cast<std::size_t>(pixels), bytePix, blockSize)) {
      throw InputError(where + ": RICE-compressed tile " + std::to_string(r) + " of " + std::to_string(rows) +
                       " is corrupt (its data ends before its " + std::to_string(pixels) + " pixels)");
    }
  }
}

}  // namespace st::io::detail
