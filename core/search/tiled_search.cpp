#include "st/search/tiled_search.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <string>

#include "ipsa_kernel.hpp"
#include "st/common/error.hpp"
#include "st/common/memory_budget.hpp"
#include "st/search/ipsa.hpp"
#include "st/search/search_run.hpp"
#include "st/search/tree_polish.hpp"
#include "st/search/velocity_grid.hpp"
#include "tree_region.hpp"

namespace st::search {

int searchOverlapPx(const VelocityGrid& grid, const std::vector<double>& dtS, int marginPx) {
  int most = 0;
  for (const int ix : {0, grid.nvx - 1}) {
    for (const int iy : {0, grid.nvy - 1}) {
      const Velocity v = grid.at(ix, iy);
      for (const double dt : dtS)
        most = std::max({most, std::abs(ipsaShift(v.vx, dt)), std::abs(ipsaShift(v.vy, dt))});
    }
  }
  return most + std::max(0, marginPx);
}

std::vector<SearchTile> planSearchTiles(int width, int height, int overlapPx, std::size_t maxReadPixels,
                                        int minOwnedRows) {
  std::vector<SearchTile> tiles;
  if (width <= 0 || height <= 0) return tiles;
  const auto readOf = [&](const TileRect& o) {
    const int x0 = std::max(0, o.x0 - overlapPx);
    const int y0 = std::max(0, o.y0 - overlapPx);
    const int x1 = std::min(width, o.x0 + o.width + overlapPx);
    const int y1 = std::min(height, o.y0 + o.height + overlapPx);
    return TileRect{x0, y0, x1 - x0, y1 - y0};
  };
  // The whole image in one tile.
  if (static_cast<std::size_t>(width) * height <= maxReadPixels) {
    tiles.push_back({{0, 0, width, height}, {0, 0, width, height}});
    return tiles;
  }
  // Strips of whole rows: owned rows r, read rows r + 2 overlap (fewer at the image's edges).
  const long long rowsFit = static_cast<long long>(maxReadPixels / static_cast<std::size_t>(width));
  const long long strip = rowsFit - 2LL * overlapPx;
  if (strip >= std::min(minOwnedRows, height)) {
    const int n = static_cast<int>((height + strip - 1) / strip);
    const int rows = (height + n - 1) / n;  // even strips
    for (int y = 0; y < height; y += rows) {
      const TileRect owned{0, y, width, std::min(rows, height - y)};
      tiles.push_back({readOf(owned), owned});
    }
    return tiles;
  }
  // Square-ish rectangles: side s with (s + 2 overlap)^2 <= maxReadPixels.
  const double side = std::floor(std::sqrt(static_cast<double>(maxReadPixels))) - 2.0 * overlapPx;
  if (side < 8.0) return tiles;
  const int s = static_cast<int>(side);
  const int nx = (width + s - 1) / s, ny = (height + s - 1) / s;
  const int tw = (width + nx - 1) / nx, th = (height + ny - 1) / ny;
  for (int y = 0; y < height; y += th) {
    for (int x = 0; x < width; x += tw) {
      const TileRect owned{x, y, std::min(tw, width - x), std::min(th, height - y)};
      tiles.push_back({readOf(owned), owned});
    }
  }
  return tiles;
}

SearchResult searchTiled(const TileLoader& load, const std::vector<SearchTile>& tiles, int width, int height,
                         const VelocityGrid& grid, const SearchParams& params, ProgressSink& progress,
                         CancelToken& cancel) {
  if (tiles.empty()) throw InputError("the out-of-core search got no tiles");
  if (params.method != SearchMethod::Exact && params.method != SearchMethod::Tree) {
    throw InputError("search method '" + std::string(params.method.name()) + "' (expected exact or tree)");
  }
  const auto start = std::chrono::steady_clock::now();
  SearchResult result;
  std::vector<CellHit> hits;
  std::vector<double> dtS;
  std::vector<PixelOffset> offsets;  // the frames' registration offsets (FRAMES table), for the sidelobes
  double psfFwhm = 0.0;
  Velocity skyRate;
  result.map = detail::emptyVelocityMap(grid);
  VelocityMap& map = result.map;
  const HeapReuseScope reuse;  // each tile's cube and the tree's stacks land on the previous tile's pages
  for (std::size_t t = 0; t < tiles.size(); ++t) {
    cancel.throwIfCancelled();
    const SearchTile& tile = tiles[t];
    const double p0 = static_cast<double>(t) / static_cast<double>(tiles.size());
    const double p1 = static_cast<double>(t + 1) / static_cast<double>(tiles.size());
    detail::KernelOutput out;
    {
      const FilteredCube cube = load(tile.read);
      if (cube.frames.width() != tile.read.width || cube.frames.height() != tile.read.height) {
        throw InputError("out-of-core search: a tile was read as " + std::to_string(cube.frames.width()) + " x " +
                         std::to_string(cube.frames.height()) + " px instead of " +
                         std::to_string(tile.read.width) + " x " + std::to_string(tile.read.height));
      }
      if (t == 0) {
        validateSearchInput(cube, grid, params);
        result.grid = grid;
        result.trials = trialCounts(width, height, grid);
        result.snrThreshold = effectiveThreshold(params, result.trials);
        result.minFrames = minFramesFor(params, cube.frames.timeOffsetsS(), width, height, grid);
        result.tRefMjd = cube.frames.tRefMjd();
        result.backend = "cpu";
        result.method = params.method;
        dtS = cube.frames.timeOffsetsS();
        offsets = cube.frames.frameOffsets();
        psfFwhm = cube.psfFwhmPx;
        skyRate = cube.skyRate;
      } else if (cube.frames.frameCount() != dtS.size()) {
        throw InputError("out-of-core search: a tile has " + std::to_string(cube.frames.frameCount()) +
                         " frames, the first had " + std::to_string(dtS.size()));
      }
      const detail::Roi roi{tile.owned.x0 - tile.read.x0, tile.owned.y0 - tile.read.y0, tile.owned.width,
                            tile.owned.height};
      SubProgress sub(progress, p0, p1);
      if (params.method == SearchMethod::Exact) {
        detail::KernelParams kp;
        kp.sigmaF = cube.sigmaF;
        kp.snrThreshold = result.snrThreshold;
        kp.minFrames = result.minFrames;
        kp.maxHits = params.maxCandidates;
        out = detail::runIpsaKernel(cube.frames, grid, roi, kp, sub, cancel);
      } else {
        detail::TreeRegionParams tp;
        tp.sigmaF = cube.sigmaF;
        tp.snrThreshold = result.snrThreshold;
        tp.minFrames = result.minFrames;
        tp.maxHits = params.maxCandidates;
        tp.bufferBytes = params.bufferBytes;
        tp.threads = params.treeThreads;
        out = detail::treeSearchRegion(cube.frames, grid, roi, tp, sub, cancel);
      }
    }
    for (CellHit& h : out.hits) {
      h.x += tile.read.x0;
      h.y += tile.read.y0;
    }
    hits.insert(hits.end(), out.hits.begin(), out.hits.end());
    result.cellsAboveThreshold += out.hitsTotal;
    for (std::size_t iv = 0; iv < grid.count(); ++iv) {
      if (out.map.argX[iv] < 0) continue;
      const float snr = out.map.maxSnr[iv];
      const int x = out.map.argX[iv] + tile.read.x0;
      const int y = out.map.argY[iv] + tile.read.y0;
      // Ties go to the lowest (y, x), as in the in-memory search.
      const bool better = map.argX[iv] < 0 || snr > map.maxSnr[iv] ||
                          (snr == map.maxSnr[iv] && (y < map.argY[iv] || (y == map.argY[iv] && x < map.argX[iv])));
      if (better) {
        map.maxSnr[iv] = snr;
        map.argX[iv] = x;
        map.argY[iv] = y;
      }
    }
  }
  setCandidates(result, std::move(hits), psfFwhm, dtS, width, height, params, offsets, skyRate);
  result.backendNote = "out of core: " + std::to_string(tiles.size()) + " tile(s)";
  result.elapsedS = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  progress.report(1.0, params.method == SearchMethod::Tree ? "velocity search (tree)" : "velocity search");
  return result;
}

PolishSummary polishTiledTreeCandidates(const TileLoader& load, const std::vector<SearchTile>& tiles,
                                        SearchResult& result, ProgressSink& progress, CancelToken& cancel) {
  std::vector<std::optional<Candidate>> polished(std::min(kPolishedTreeCandidates, result.candidates.size()));
  const auto owns = [&](const SearchTile& tile, const Candidate& c) {
    return c.x >= tile.owned.x0 && c.y >= tile.owned.y0 && c.x < tile.owned.x0 + tile.owned.width &&
           c.y < tile.owned.y0 + tile.owned.height;
  };
  // The tiles read again, for the progress (each is a whole tile's read and pre-processing).
  std::size_t toRead = 0;
  for (const SearchTile& tile : tiles)
    toRead += std::any_of(result.candidates.begin(),
                          result.candidates.begin() + static_cast<std::ptrdiff_t>(polished.size()),
                          [&](const Candidate& c) { return owns(tile, c); });
  std::size_t read = 0;
  double psfFwhm = 0.0;
  std::vector<double> dtS;
  std::vector<PixelOffset> offsets;
  Velocity skyRate;
  for (const SearchTile& tile : tiles) {
    std::optional<FilteredCube> cube;
    for (std::size_t i = 0; i < polished.size(); ++i) {
      const Candidate& c = result.candidates[i];
      if (!owns(tile, c)) continue;
      cancel.throwIfCancelled();
      if (!cube) {
        progress.report(static_cast<double>(read) / static_cast<double>(toRead),
                        "re-scoring the tree's candidates: reading tile " + std::to_string(read + 1) +
                            " of " + std::to_string(toRead) + " again");
        cube = load(tile.read);
        ++read;
        psfFwhm = cube->psfFwhmPx;
        dtS = cube->frames.timeOffsetsS();
        offsets = cube->frames.frameOffsets();
        skyRate = cube->skyRate;
      }
      polished[i] = polishCandidate(*cube, result, c, tile.read.x0, tile.read.y0, cancel);
    }
  }
  progress.report(1.0, "re-scoring the tree's candidates");
  if (dtS.empty()) return {};  // no candidate to re-score
  // The whole image (candidates are in its pixels): the owned areas partition it.
  TrackFrames frames{std::move(dtS), 0, 0, std::move(offsets)};
  for (const SearchTile& tile : tiles) {
    frames.width = std::max(frames.width, tile.owned.x0 + tile.owned.width);
    frames.height = std::max(frames.height, tile.owned.y0 + tile.owned.height);
  }
  const PolishSummary summary = finishPolish(result, polished, psfFwhm, frames, skyRate);
  result.backendNote.append(1, '\n').append(polishNote(summary));
  return summary;
}

}  // namespace st::search
