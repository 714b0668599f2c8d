#pragma once
// The velocity-search contract shared by every backend (CPU exact, CPU tree, CUDA). The CPU exact backend
// is the reference the others are tested against (ARCHITECTURE.md, "Interfaces that matter").
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/progress.hpp"
#include "st/common/units.hpp"
#include "st/search/search_method.hpp"

namespace st::search {

/// Frames ready for the search: zero-biased, static sources and cosmic rays zeroed, matched-filtered.
struct FilteredCube {
  FrameCube frames;        ///< filtered frames, masked pixels already 0
  double sigmaF = 0.0;     ///< noise of one filtered frame, measured robustly from the data
  Velocity skyRate;        ///< motion of the stars, px/s (zero for a tracked telescope)
  double psfFwhmPx = 0.0;  ///< FWHM of the PSF used for the matched filter
  /// Identity of these frames' pixels for a device that keeps them between searches (issue 16): set by
  /// whoever makes the cube (nextCubeRevision()), never reused for other pixels. 0 = unknown: every search
  /// uploads the frames. Code that changes `frames` after a revision was set must set a new one (or 0).
  std::uint64_t revision = 0;
};

/// A process-wide unique, non-zero FilteredCube::revision.
inline std::uint64_t nextCubeRevision() {
  static std::atomic<std::uint64_t> next{1};
  return next.fetch_add(1);
}

/// A regular 2-D grid of trial velocities (px/s), nvx x nvy points, index (ix, iy) at
/// centre + ((ix - (nvx-1)/2) * step, (iy - (nvy-1)/2) * step).
struct VelocityGrid {
  Velocity centre;
  double stepPxS = 0.0;
  int nvx = 0;
  int nvy = 0;

  [[nodiscard]] std::size_t count() const noexcept {
    return static_cast<std::size_t>(nvx) * static_cast<std::size_t>(nvy);
  }
  [[nodiscard]] Velocity at(int ix, int iy) const noexcept {
    return {centre.vx + (ix - 0.5 * (nvx - 1)) * stepPxS, centre.vy + (iy - 0.5 * (nvy - 1)) * stepPxS};
  }
};

/// Search thresholds and limits.
struct SearchParams {
  double snrThreshold = 7.0;        ///< paper §4.4: SNR 7 (FAP ~0.34% for 512^2 x 100^2 trials)
  std::optional<double> targetFap;  ///< when set, the SNR threshold is derived from it and the trials
  /// Cells above threshold kept before clustering (highest SNR first), a bound on memory (~30 bytes each).
  /// Generous on purpose: the skirts of one bright star residual light up 1e5-1e6 cells, and a small cap
  /// silently drops every fainter object (SearchResult::cellsAboveThreshold shows when it was reached).
  std::size_t maxCandidates = 2'000'000;
  double minFrameFraction = 0.5;  ///< cells whose N_in is below this fraction of N_f are ignored
  /// Exact (IPSA at every frame) or Tree (hierarchical, tree_search.hpp); Auto is resolved to one of them
  /// by searchWithMethod (method_choice.hpp) before a backend sees it. Named "exact", "tree", "auto" in
  /// files.
  SearchMethod method = SearchMethod::Exact;
  /// Search buffers of all threads together (the tree's partial stacks), bytes; 0 = the default
  /// (kTreeBuffersBytes, tree_search.hpp). Sized from the memory budget (issue 20); no effect on results.
  std::size_t bufferBytes = 0;
  /// Threads the CPU tree search runs on at most (0: st::workerCount()). The out-of-core plan lowers it
  /// when every thread's partial stacks would not fit the memory budget beside a tile (issue 20); the tile
  /// rows stay those of workerCount() threads, so the results do not change.
  unsigned treeThreads = 0;
};

/// One detection, at its best cell after clustering in (x, y, vx, vy).
struct Candidate {
  int x = 0;             ///< column at t_ref, 0-based
  int y = 0;             ///< row at t_ref, 0-based
  Velocity v;            ///< grid velocity, px/s
  int ivx = 0;           ///< grid index along vx
  int ivy = 0;           ///< grid index along vy
  double sum = 0.0;      ///< IPSA statistic S at the cell
  int nIn = 0;           ///< frames that contributed (boundary-aware)
  double snr = 0.0;      ///< S / (sigma_F sqrt(N_in))
  double fap = 1.0;      ///< detection false-alarm probability (paper \label{Prob_false})
  int clusterCells = 1;  ///< cells above threshold merged into this candidate
};

/// The trial counts that enter the false-alarm probability.
struct TrialCounts {
  std::int64_t nx = 0, ny = 0, nvx = 0, nvy = 0;
  [[nodiscard]] double total() const noexcept {
    return static_cast<double>(nx) * static_cast<double>(ny) * static_cast<double>(nvx) *
           static_cast<double>(nvy);
  }
};

/// For every grid velocity: the highest SNR over all pixels, and where it was.
struct VelocityMap {
  int nvx = 0;
  int nvy = 0;
  std::vector<float> maxSnr;  ///< nvy rows of nvx, index iy * nvx + ix
  std::vector<int> argX;      ///< column of the maximum
  std::vector<int> argY;      ///< row of the maximum
};

/// What the static-source rule reads of a cube: the frames' t - t_ref (s), the whole image's size (px) and
/// the frames' registration offsets (empty = all 0).
struct TrackFrames {
  std::vector<double> dtS;
  int width = 0;
  int height = 0;
  std::vector<PixelOffset> offsets;
};

/// The search statistic's spread measured on the cube (st/search/statistic_noise.hpp); the paper's unit until
/// measured.
struct StatisticNoise {
  double scale = 1.0;          ///< the statistic's standard deviation at random cells (1 = the paper's unit)
  double standardError = 0.0;  ///< of `scale` (scale / sqrt(2 cells))
  double mean = 0.0;           ///< the statistic's mean there (0 when the background is removed)
  int cells = 0;               ///< random cells measured (0 = not measured: scale is the unit)
  [[nodiscard]] bool measured() const noexcept { return cells > 0; }
};

struct SearchResult {
  VelocityGrid grid;
  VelocityMap map;
  std::vector<Candidate> candidates;  ///< clustered, sorted by decreasing SNR; movers only
  /// Candidates whose velocity relative to the stars (FilteredCube::skyRate) moves them less than one PSF
  /// FWHM over the span (search::staticRateLimitPxS): static sources that pre-processing left (a star's
  /// residual, a pair of faint stars), which no search can tell from a star. Set aside, sorted by SNR, not
  /// counted as detections; a mover that slow is below the method's documented limit.
  std::vector<Candidate> staticSources;
  TrialCounts trials;
  double snrThreshold = 0.0;  ///< the threshold actually used
  double tRefMjd = 0.0;
  std::string backend;       ///< e.g. "cpu", "cuda: NVIDIA H100 80GB HBM3"
  SearchMethod method;       ///< Exact or Tree (named "exact", "tree" in files)
  std::string methodReason;  ///< why that method: "requested", or "auto: ..." (method_choice.hpp)
  double elapsedS = 0.0;
  std::int64_t cellsAboveThreshold = 0;  ///< every (x, y, v) cell above threshold, before capping/clustering
  int minFrames = 0;                     ///< N_in below this was ignored (minFrameFraction x N_f, rounded up)
  std::int64_t sidelobesMerged =
      0;  ///< candidates merged into a brighter one as its sidelobes (sidelobes.hpp)
  /// How the backend ran the search, for the log: memory tiling, devices, time per phase (CUDA); may be
  /// empty.
  std::string backendNote;
  /// What the user must see: e.g. the GPU failed and the CPU searched instead (fallback_backend.hpp).
  std::vector<std::string> warnings;
  /// The statistic's noise on this cube, when measured (searchWithChoice); a measurement for the user.
  StatisticNoise statisticNoise;
};

enum class StackMode { Ipsa, Csa };

/// A search implementation. Implementations are not required to be thread-safe; one search at a time.
class SearchBackend {
 public:
  virtual ~SearchBackend() = default;
  /// Short human-readable name, e.g. "cpu (2 threads)" or "cuda: NVIDIA H100".
  [[nodiscard]] virtual std::string name() const = 0;
  /// Runs the velocity search over the whole grid. Throws st::Cancelled when cancelled.
  virtual SearchResult search(const FilteredCube& cube, const VelocityGrid& grid, const SearchParams& params,
                              ProgressSink& progress, CancelToken& cancel) = 0;
  /// The stack of the cube at one velocity (sum over frames, out-of-frame samples excluded), for live
  /// scrubbing in the GUI.
  virtual Image stackAt(const FilteredCube& cube, Velocity v, StackMode mode) = 0;
  /// Whether search() implements the SearchParams::method named `method` ("exact", "tree"). A backend that
  /// does not say supports the exact search only. (Keyed by name: the CUDA backend overrides it.)
  [[nodiscard]] virtual bool supportsMethod(const std::string& method) const { return method == "exact"; }
  /// supportsMethod() for a typed method.
  [[nodiscard]] bool supports(SearchMethod method) const {
    return supportsMethod(std::string(method.name()));
  }
};

}  // namespace st::search
