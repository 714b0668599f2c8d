#pragma once
// A pre-processed cube larger than the memory budget, opened without holding it (issue 20 item 4, the GUI):
// its header, times and WCS from a small corner, and every pixel read later through CFITSIO's subset reader
// (io::loadFrames with a crop) in regions that fit the budget. The search runs out of core through the same
// core functions as `synthtrack-cli search --preprocessed` (pipeline::planTiledSearch, search::searchTiled,
// each tile filtered by pipeline::searchInputFromPrepared; a tree search's candidates re-scored on their
// tiles, search::polishTiledTreeCandidates), so its candidates equal the in-memory search's
// (search/tiled_search.hpp). Stacks for display are summed in strips of rows with the overlap of the largest
// shift, so they equal stack::stackIpsa of the cube in memory.
#include <string>
#include <vector>

#include "st/common/memory_budget.hpp"
#include "st/common/progress.hpp"
#include "st/io/fits_reader.hpp"
#include "st/pipeline/memory_plan.hpp"
#include "st/pipeline/prepared_cube.hpp"
#include "st/search/types.hpp"

namespace st::pipeline {

/// Peak of holding a cube the way the GUI holds an opened one: the loaded cube (4 bytes a sample and its
/// 1-byte mask), and for a prepared cube its matched-filtered copy (5) plus, when zero-biased, the
/// unfiltered copy the fits use (4), and kPreprocessImageBytesPerPixel per frame pixel; the search's own
/// working set comes on top (estimateSearchPeak).
[[nodiscard]] MemoryEstimate estimateOpenPeak(const CubeShape& shape, bool prepared, bool zeroBiased);

/// How an interactive front end holds inputs under a memory budget.
enum class OpenMode {
  InMemory,   ///< load them as usual
  OutOfCore,  ///< a prepared cube over the budget: openOutOfCore, stackOutOfCore, searchOutOfCore
  Refused,    ///< raw frames whose in-memory pre-processing does not fit: `reason` says what to do
};

struct OpenPlan {
  OpenMode mode = OpenMode::InMemory;
  CubeShape shape;
  bool prepared = false;  ///< the header says a cube written by `synthtrack-cli preprocess`
  /// Holding it (estimateOpenPeak) or, for raw frames, pre-processing it in memory (estimatePreprocessPeak).
  MemoryEstimate need;
  /// OutOfCore and Refused: the need, the budget and (Refused) what to run instead.
  std::string reason;
};

/// Decides how to hold `inputs` under `budgetBytes` from their headers (io::summarizeInputs) and, when they
/// do not fit as the largest prepared cube would, a 16 x 16 corner of every frame (to read the prepared
/// header): in memory when estimateOpenPeak (prepared) or estimatePreprocessPeak (raw, `threads` workers, the
/// zero-biased copy kept for the fits) fits; a prepared cube that does not fit opens out of core; raw frames
/// that do not fit are refused (the GUI has no out-of-core pre-processing: `synthtrack-cli search
/// --keep-scratch` pre-processes them out of core in strips and keeps the filtered cube, which then opens out
/// of core). Throws st::FitsError / st::InputError from the reader, st::Cancelled.
[[nodiscard]] OpenPlan planOpen(const std::vector<std::string>& inputs, const io::LoadOptions& load,
                                std::size_t budgetBytes, unsigned threads, CancelToken& cancel);

struct OutOfCoreCube {
  std::vector<std::string> inputs;
  io::LoadOptions load;
  CubeShape shape;
  PreparedHeader header;
  /// A 16 x 16 corner of every frame (header, times, registration offsets, WCS of the image's origin) with
  /// the search's sigma_F, sky rate and PSF FWHM: what the grid, the estimates and the reports need.
  search::FilteredCube meta;
  int filterHalfSize = 0;  ///< the matched filter's reach, added to a tile's overlap for a zero-biased cube
  std::vector<std::string> notes;
};

/// Opens a prepared cube (written by `synthtrack-cli preprocess`, header STPREP/STFILT) out of core:
/// io::summarizeInputs, the corner, sigma_F from the header (a filtered cube's SIGMAF) or measured on a
/// central region of at most 256 x 256 px (said in notes). Throws st::InputError when the input is not a
/// prepared cube (naming the missing keyword), when a zero-biased cube has no PSFFWHM; st::Cancelled.
[[nodiscard]] OutOfCoreCube openOutOfCore(const std::vector<std::string>& inputs, const io::LoadOptions& load,
                                          ProgressSink& progress, CancelToken& cancel);

/// The frames of `rect` (image pixels) of every frame, as stored (CFITSIO subset reads).
[[nodiscard]] FrameCube loadOutOfCoreRegion(const OutOfCoreCube& cube, const search::TileRect& rect,
                                            CancelToken& cancel);

/// The IPSA sum at `v` (px/s) of the cube as stored, over all frames: strips of whole rows, each read with
/// the overlap of the largest shift round(o_n + v dt_n), as many rows as fit `budgetBytes` (at least one).
/// Equal to stack::stackIpsa(cube in memory, v).sum. Polls `cancel` between strips.
[[nodiscard]] Image stackOutOfCore(const OutOfCoreCube& cube, Velocity v, std::size_t budgetBytes,
                                   ProgressSink& progress, CancelToken& cancel);

/// What searchOutOfCore did, in words and numbers.
struct OutOfCoreSearch {
  search::SearchResult result;
  std::size_t tiles = 0;
  int overlapPx = 0;
  MemoryEstimate perTile;
};

/// The search of the whole cube out of core on the CPU: the method resolved from the estimate
/// (chooseMethod; the exact kernel when the tree's buffers do not fit beside a tile), tiles from
/// planTiledSearch under `budgetBytes` (the search's overlap plus the filter's reach for a zero-biased cube),
/// search::searchTiled with each tile made by searchInputFromPrepared. Throws st::InputError naming the need
/// and the budget when not even one tile fits; st::Cancelled.
[[nodiscard]] OutOfCoreSearch searchOutOfCore(const OutOfCoreCube& cube, const search::VelocityGrid& grid,
                                              search::SearchParams params, std::size_t budgetBytes,
                                              ProgressSink& progress, CancelToken& cancel);

}  // namespace st::pipeline
