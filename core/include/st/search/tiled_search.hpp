#pragma once
// The velocity search out of core (issue 20): the image is cut into tiles, each read with an overlap of the
// largest shift of any trial velocity at any frame (|v|max x max|t - t_ref|, plus a margin), searched by the
// CPU kernels (exact or tree) over its OWNED cells only, with N_in and the out-of-frame samples of the whole
// image. For an owned cell every sample the whole-image search adds lies inside the tile's read area (the
// overlap covers every shift; tiles end where the image ends), so its sum, N_in and SNR are bit-identical to
// the in-memory search's. The cells above threshold of all tiles are then sorted, capped and clustered once
// for the whole image (setCandidates), so clusters across tile borders are merged as in memory and no
// candidate is found twice; the velocity map takes each velocity's best over the tiles (ties to the lowest
// (y, x), as in memory). The result therefore equals the in-memory one (tested, tests/core/test_out_of_core),
// except when more than SearchParams::maxCandidates cells are above threshold in a tile and equal SNRs sit
// at the cap.
#include <functional>
#include <vector>

#include "st/common/progress.hpp"
#include "st/search/tree_polish.hpp"
#include "st/search/types.hpp"

namespace st::search {

/// A rectangle of image pixels [x0, x0 + width) x [y0, y0 + height).
struct TileRect {
  int x0 = 0;
  int y0 = 0;
  int width = 0;
  int height = 0;
  [[nodiscard]] std::size_t pixels() const noexcept {
    return static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  }
  friend bool operator==(const TileRect&, const TileRect&) = default;
};

/// One tile: the pixels read (owned plus the overlap, clipped to the image) and the cells it reports.
struct SearchTile {
  TileRect read;
  TileRect owned;
};

/// The overlap a search tile needs: max |round(v dt)| over the grid's corners and the frames' offsets `dtS`
/// (t - t_ref, s), plus `marginPx` (the tree's samples deviate by up to 1 px from the exact shifts).
int searchOverlapPx(const VelocityGrid& grid, const std::vector<double>& dtS, int marginPx = 2);

/// Tiles covering width x height whose read areas have at most `maxReadPixels` pixels each: strips of whole
/// rows when a strip of at least `minOwnedRows` owned rows fits, else a grid of rectangles. Owned areas
/// partition the image. Returns an empty list when not even a tile of 8 x 8 owned pixels fits.
std::vector<SearchTile> planSearchTiles(int width, int height, int overlapPx, std::size_t maxReadPixels,
                                        int minOwnedRows = 16);

/// Gives the filtered frames of one read rectangle (all frames, in the same order for every tile), with the
/// observation's sigma_F, sky rate and PSF FWHM (the same for every tile).
using TileLoader = std::function<FilteredCube(const TileRect& read)>;

/// Searches the tiles one after the other (`params.method` "exact" or "tree"; each tile's search uses every
/// thread) and merges them as described above. `width` x `height` is the whole image. The result's backend
/// is "cpu", backendNote says how many tiles. Throws st::InputError (as the in-memory search), st::Cancelled.
SearchResult searchTiled(const TileLoader& load, const std::vector<SearchTile>& tiles, int width, int height,
                         const VelocityGrid& grid, const SearchParams& params, ProgressSink& progress,
                         CancelToken& cancel);

/// A tiled tree search's candidates re-scored by the exact search as searchWithChoice does in memory
/// (tree_polish.hpp): each of the first kPolishedTreeCandidates on the tile that owns it (its read area
/// holds every track of the window), the tiles with candidates read again (progress by tile); a line added
/// to backendNote. Throws what `load` throws and st::Cancelled.
PolishSummary polishTiledTreeCandidates(const TileLoader& load, const std::vector<SearchTile>& tiles,
                                        SearchResult& result, ProgressSink& progress, CancelToken& cancel);

}  // namespace st::search
