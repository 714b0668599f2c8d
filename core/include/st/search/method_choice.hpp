#pragma once
// Which search method to run: "exact" (IPSA at every frame, the reference) or "tree" (hierarchical,
// tree_search.hpp), and, for method "auto", which of the two wins for this problem on this backend.
//
// Cost model (pure arithmetic, tested): both methods are priced in seconds on the backend's throughput.
// - exact: N_pix x N_f x N_v additions (velocity_grid.hpp estimateSearch) at the exact kernel's rate, plus a
//   fixed start-up time;
// - tree: treeAdditions() of the plan (tree_plan.hpp), each weighted as `treeOpsWeight` exact additions (a
//   tree addition reads and writes scattered partial stacks, an exact one streams through registers), at the
//   same rate, so that one measured throughput prices both methods (the GUI measures it from its live
//   stack), plus a fixed start-up time (plan, tile buffers, threads).
// CPU coefficients: least squares over 13 `synthtrack-cli bench search --method tree` problems from
// 30 x 128^2 x 9^2 to 1500 x 512^2 x 100^2 on the 2-core development VM (AMD EPYC, AVX2, shared, load 5-6),
// 2026-11-22 05:12-05:17 UTC, in CPU seconds: exact 1.8e10 x width / (width + 128) additions per CPU-second
// (1.44e10 at 512 px, 0.9e10 at 128 px; within 13% except the smallest problem), tree 0.013 s + 9.6
// exact-equivalent additions (at 1.35e10 per CPU-second) per tree addition (rms error 29%, worst 56%;
// per-pixel-frame and per-pixel-velocity terms did not improve the fit). The CUDA ones are the H100's
// measured end-to-end times of both methods on the paper problem (README).
//
// Decision for "auto": tree when the backend supports it (SearchBackend::supportsMethod), it is estimated at
// least kAutoTreeMinSpeedup times faster than exact AND it saves at least the model's autoTreeMinSavingS
// seconds (the CPU's kAutoTreeMinSavingS; the GPU's kCudaAutoTreeMinSavingS, issue 16) AND its SNR loss for
// the cube's PSF is at most kAutoTreeMaxSnrLoss; otherwise exact. The tree's samples stay within 1 px of the
// exact shifts and lose some SNR (median ~1%, worst ~5% on injected objects, README): exact is kept wherever
// the time saved does not pay for that.
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "st/search/types.hpp"

namespace st::search {

/// "auto" picks the tree only when it is at least this many times faster than exact (estimated)...
inline constexpr double kAutoTreeMinSpeedup = 2.0;
/// ...and saves at least this many seconds (a sub-second search is not worth any SNR loss)...
inline constexpr double kAutoTreeMinSavingS = 1.0;
/// ...on the GPU, this many: issue 16 asks the tree of the paper's problem (0.47 s exact, ~0.2 s tree with
/// the cube resident) wherever its SNR loss for the data's PSF is small (<= kAutoTreeMaxSnrLoss).
inline constexpr double kCudaAutoTreeMinSavingS = 0.1;

/// ...and loses at most this fraction of the exact search's SNR for the cube's PSF (treeSnrLoss; issue 16).
inline constexpr double kAutoTreeMaxSnrLoss = 0.03;

/// The tree search's SNR loss against the exact search (the worst of 12 objects) on matched-filtered point
/// sources of PSF FWHM `fwhmPx` (Moffat beta 4, the paper's problem's tree: tracks within 2 px of the exact
/// ones). Measured by tests/core/test_tree_snr_loss_slow.cpp at FWHM 1.5, 2, 2.5 and 3.5 px (3.0, 2.2, 1.6,
/// 1.0%; README "Performance"); linear in between, constant above, the first slope extrapolated below (so
/// `auto` keeps the exact search for PSFs narrower than ~1.5 px). NaN for a non-positive FWHM.
double treeSnrLoss(double fwhmPx);

/// Throughputs and fixed costs of one backend. Rates are for the whole backend (all threads or devices).
struct MethodCostModel {
  double exactAdditionsPerS = 0.0;  ///< exact search, additions per second
  double exactFixedS = 0.0;         ///< exact search start-up, s
  /// Narrow images run the exact kernel slower (row tiles, edges): its rate is scaled by
  /// min(1, (512 + w0) / 512 x width / (width + w0)) with w0 = exactWidthPx (0: no scaling).
  double exactWidthPx = 0.0;
  double treeOpsWeight = 1.0;  ///< one tree addition (treeAdditions) in exact-equivalent additions
  double treeFixedS = 0.0;     ///< tree search start-up (plan, tile buffers), s
  /// The CPU tree splits a grid too large for one tree into velocity blocks (tree_search.hpp); the CUDA tree
  /// does not, so its estimate prices one tree.
  bool treeVelocityBlocks = true;
  /// The tree's additions priced at tiles of this many rows (0: the CPU's per-thread tiles). The CUDA tree's
  /// device tiles are hundreds of rows whatever the host's threads (16 host threads gave the paper's problem
  /// 2-row CPU tiles: 2.5x the additions the device makes).
  int treePricedTileRows = 0;
  double autoTreeMinSavingS = kAutoTreeMinSavingS;  ///< "auto"'s least saving for the tree, s
};

/// The CPU model for `threads` workers; `exactAdditionsPerS` defaults to
/// kCpuAdditionsPerSecondPerThread x threads (velocity_grid.hpp), or a measured rate (the GUI's live stack).
MethodCostModel cpuCostModel(unsigned threads, std::optional<double> exactAdditionsPerS = std::nullopt);

/// The CUDA model (README, H100): exact 9.5e12 additions/s plus 0.05 s; tree ~0.12 s (upload, set-up) plus
/// the plan's additions at 128-row tiles (treePricedTileRows) at 1.4e11/s (the paper problem in 0.2 s end
/// to end); "auto" takes the tree from a 0.1 s saving (kCudaAutoTreeMinSavingS).
MethodCostModel cudaCostModel();

/// cudaCostModel() for a backend whose name() starts with "cuda", else cpuCostModel(st::workerCount()).
MethodCostModel costModelFor(const SearchBackend& backend);

/// What each method would cost on one problem.
struct MethodEstimate {
  double exactAdditions = 0.0;        ///< N_pix x N_f x N_v
  double treeAdditions = 0.0;         ///< treeAdditions() of the plan (0 when no plan could be built)
  double exactSeconds = 0.0;          ///< estimated wall time
  double treeSeconds = 0.0;           ///< estimated wall time (infinite when no plan could be built)
  std::size_t exactWorkingBytes = 0;  ///< on top of the cube (estimateSearch)
  std::size_t treeWorkingBytes = 0;   ///< partial stacks of every thread's tile, map and N_in ranges
  std::size_t cubeBytes = 0;          ///< the cube, already held
  int width = 0;                      ///< image width, px (for priceMethods)
  int treeTileRows = 0;               ///< rows per tile (treeTileRows)
  std::size_t treeTileBytes = 0;      ///< one thread's partial stacks (treeTileBytes of those rows)
  unsigned treeBusyThreads = 0;       ///< threads holding a tile at once (min(threads, tiles of rows))
  int treeBlocks = 1;                 ///< velocity blocks, one tree each (treeVelocityBlocks)
  int treeMaxShiftErrorPx = 0;        ///< max |tree shift - round(v dt)| over the grid (tree_plan.hpp)
  double psfFwhmPx = 0.0;             ///< the cube's PSF FWHM, px (0: unknown)
  double treeSnrLoss = 0.0;           ///< treeSnrLoss(psfFwhmPx), 0 when the FWHM is unknown
  double autoTreeMinSavingS = kAutoTreeMinSavingS;  ///< the model's (priceMethods), for chooseMethod
};

/// Estimates both methods for frames of width x height at offsets `dtS` (t_n - t_ref, s) over `grid`, with
/// `threads` workers. The tree is priced only when a plan can be built (at least 2 distinct times, a
/// non-empty grid); otherwise treeSeconds is infinite. Never throws for such input.
/// `bufferBytes`: the tree's partial stacks of all threads together (SearchParams::bufferBytes; 0 = default).
/// `offsets`: the frames' registration offsets (FrameCube::frameOffsets()), those the search will use: the
/// tree is priced on the plan the search then takes from sharedTreePlan instead of building another.
MethodEstimate estimateMethods(int width, int height, const std::vector<double>& dtS,
                               const VelocityGrid& grid, const MethodCostModel& model, unsigned threads,
                               std::size_t bufferBytes = 0, const std::vector<PixelOffset>& offsets = {});

/// Records the cube's PSF FWHM in `estimate` (psfFwhmPx, treeSnrLoss) for chooseMethod's SNR rule; a
/// non-positive FWHM leaves it unknown (the rule off).
void setPsf(MethodEstimate& estimate, double psfFwhmPx);

/// (Re)prices `estimate`'s additions with `model`: exactSeconds and treeSeconds (infinite without a tree
/// plan). For a new measured throughput without rebuilding the tree plan.
void priceMethods(MethodEstimate& estimate, const MethodCostModel& model);

/// The resolved method and why.
struct MethodChoice {
  SearchMethod method = SearchMethod::Exact;  ///< Exact or Tree
  std::string reason;  ///< one line for people: "requested", or "auto: ..." with the estimates behind it
};

/// Searches estimated to take longer than this (s) are announced with longSearchWarning.
inline constexpr double kLongSearchS = 600.0;

/// "" when the chosen method's estimate is at most `thresholdS`; else one line for people: the estimated
/// minutes (or hours), the velocity grid, and what shortens it (the velocities grow as the square of the
/// largest rate searched; a GPU backend). A 15-frame Lowell cube spanning 72 min with the default rates is a
/// 3909 x 3909 grid, 5.2 h on 2 CPU cores.
std::string longSearchWarning(const MethodEstimate& estimate, const MethodChoice& choice,
                              const VelocityGrid& grid, double thresholdS = kLongSearchS);

/// Resolves `requested` (Auto, Exact or Tree) for a backend that does (or does not) support the tree, from
/// `estimate` (see the decision rule above). Exact and Tree are returned as requested (reason "requested"); a
/// requested tree on a backend without it throws st::InputError naming the backend; SearchMethod::Unknown
/// throws st::InputError.
MethodChoice chooseMethod(SearchMethod requested, const MethodEstimate& estimate, bool treeSupported,
                          const std::string& backendName);

/// chooseMethod() for `backend` on `cube` and `grid`, pricing with costModelFor(backend). `estimate`, when
/// given, receives the estimate used.
MethodChoice resolveMethod(const SearchBackend& backend, const FilteredCube& cube, const VelocityGrid& grid,
                           SearchMethod requested, MethodEstimate* estimate = nullptr);

/// Runs backend.search() with choice.method and records the method and choice.reason in the result
/// (SearchResult::method, methodReason). A tree search's first kPolishedTreeCandidates (tree_polish.hpp)
/// candidates are then re-scored by the exact search around their cells (polishTreeCandidates; what it did is
/// a line of backendNote). Throws what the backend throws.
SearchResult searchWithChoice(SearchBackend& backend, const FilteredCube& cube, const VelocityGrid& grid,
                              const SearchParams& params, const MethodChoice& choice, ProgressSink& progress,
                              CancelToken& cancel);

/// Resolves params.method (resolveMethod) and runs it (searchWithChoice). Throws what resolveMethod and the
/// backend throw (st::InputError, st::Cancelled, st::GpuError).
SearchResult searchWithMethod(SearchBackend& backend, const FilteredCube& cube, const VelocityGrid& grid,
                              const SearchParams& params, ProgressSink& progress, CancelToken& cancel);

}  // namespace st::search
