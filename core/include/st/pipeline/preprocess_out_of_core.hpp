#pragma once
// Pre-processing raw frames out of core (issue 20): when the whole cube does not fit the memory budget, the
// detector is cut into strips of full rows, each read with its overlap (CFITSIO's subset reader, through a
// RawRegionLoader), pre-processed by pipeline::preprocess as if it were the whole frame, matched-filtered in
// place, and the rows it owns written to one filtered cube on disk (io::CubeRegionWriter). That file is then
// searched out of core like any filtered pre-processed cube (search/tiled_search.hpp).
//
// What is measured once, on the reference strip (the central one, processed first), and given to the others:
// the registration (per-frame offsets), the sky rate and the PSF, so that every strip shifts, masks and
// filters alike. What each strip measures for itself: the frames' SEP backgrounds, hot pixels, cosmic rays,
// the static sources of its rows, the per-pixel background, the residual means and the noise model (all
// local). The overlap is what the stages that look at neighbouring rows need (PreprocessHalo: half a cell of
// the SEP and residual-mean meshes, so that the owned rows lie between cell centres, interpolated and never
// extrapolated; a cell of the sky-rate stack's local background for the static sources; the matched filter's
// radius; a cosmic ray's neighbourhood), 32 px with the defaults; the mesh stages are not exact with any
// finite overlap (SEP's spline runs along whole columns), so a strip's mesh starts at its first read row.
// Each strip's filtered frames are scaled to the reference strip's sigma_F, so that one SIGMAF holds for
// the file.
//
// Frames that calibration trims (TRIMSEC/DATASEC, overscan columns): strips are cut from the raw frames and
// each is trimmed to the part of the frame's trim region it holds (calib::trimRegion gives the frame's), so
// the file is the trimmed image, as in memory; the overscan level is the median of the strip's own rows.
// Not done out of core: the co-moving fit (needs the zero-biased cube in memory).
#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "st/calib/calibration.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/memory_budget.hpp"
#include "st/common/progress.hpp"
#include "st/pipeline/memory_plan.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/search/tiled_search.hpp"

namespace st::pipeline {

/// One strip: `read` (full width, the owned rows plus the overlap, clipped to the image) and the rows
/// [ownY0, ownY0 + ownRows) whose filtered pixels it writes.
struct PreprocessStrip {
  search::TileRect read;
  int ownY0 = 0;
  int ownRows = 0;
};

struct OutOfCorePreprocessPlan {
  std::vector<PreprocessStrip> strips;  ///< top to bottom; empty when not even the smallest strip fits
  std::size_t reference = 0;            ///< the strip measured first (registration, sky rate, PSF)
  int overlapPx = 0;
  MemoryEstimate perStrip;       ///< the peak while the tallest strip is pre-processed
  MemoryEstimate smallestStrip;  ///< the need of the smallest strip (for the message when none fits)
};

/// The rows above and below its own that a strip is read with, per stage (issue 20). Stages that work on
/// single pixels or along time need none: calibration (the masters cropped to the strip; the overscan level
/// from the strip's own rows), hot pixels, the per-pixel background, zeroing, the noise model; nor does the
/// registration out of core (offsets given to every strip; frames keep their own grids, no whole-pixel
/// shift). The sky-rate drift of a drifting field (star templates along it) is not counted.
struct PreprocessHalo {
  int meshes = 0;         ///< half a cell of the larger of the SEP frame-background and residual-mean meshes
  int staticSources = 0;  ///< a cell of the sky-rate stack's local background (StaticSourceParams::meshPx)
  int filter = 0;         ///< the matched filter's kernel radius at twice the assumed PSF FWHM
  int cosmicRays = 0;     ///< a seed's 5 x 5 neighbourhood and its growth
  [[nodiscard]] int overlap() const;
  /// "32 px (meshes 32, static sources 32, filter 13, cosmic rays 3)"
  [[nodiscard]] std::string describe() const;
};

/// The halo of `params` (stages turned off need none).
PreprocessHalo preprocessHalo(const PreprocessParams& params);

/// Overlap of the strips for `params`: preprocessHalo(params).overlap().
int preprocessOverlapPx(const PreprocessParams& params);

/// The fewest rows a strip owns (the smallest plan; below it the budget is refused).
inline constexpr int kMinStripRows = 64;

/// Strips of `shape` under `budgetBytes` (the estimate of estimatePreprocessPeak for the tallest strip read
/// with `threads` workers): as few as fit, their owned heights as equal as multiples of `stepPx` allow (the
/// last takes the rest), each read with `overlapPx` rows above and below; the smallest strip owns
/// kMinStripRows rows. Taller strips read fewer overlap rows in all: 1024 rows in 4 strips with 32 px of
/// overlap read 1216 rows (1.19x), in 16 strips with 128 px 5120 (5x).
OutOfCorePreprocessPlan planOutOfCorePreprocess(const CubeShape& shape, std::size_t budgetBytes,
                                                unsigned threads, int overlapPx, int stepPx = 8);

/// The raw frames of `rect` (image coordinates) and the calibration masters for exactly that region (none
/// when the observation has no calibration frames).
struct RawRegion {
  FrameCube raw;
  std::optional<calib::MasterCalibration> masters;
};
using RawRegionLoader = std::function<RawRegion(const search::TileRect&)>;

struct OutOfCorePrepared {
  std::string path;      ///< the filtered cube written (STPREP/STFILT = T, SIGMAF, SIGMAN, PSF, sky rate)
  Prepared reference;    ///< the reference strip's result, without its cubes (notes, PSF, rates, stars)
  double sigmaF = 0.0;   ///< pooled over the strips, counts (every strip scaled to it)
  double sigmaN = 0.0;   ///< pooled, counts
  std::vector<double> stripSigmaF;  ///< each strip's own sigma_F before scaling, top to bottom
  std::size_t cosmicRays = 0;       ///< over all strips
  std::size_t staticPixelsZeroed = 0;
  std::vector<std::string> notes;     ///< the plan and the per-strip facts, for the user
  std::vector<std::string> warnings;  ///< the loader's and calibration's (once each)
  double elapsedS = 0.0;
};

/// Pre-processes the observation of `shape` (raw frames) strip by strip (`plan`, non-empty) into the
/// filtered cube `outPath` (overwritten; removed again when this throws), the image `trim` (raw-frame
/// coordinates, calib::trimRegion; none = the whole frame). `params.masters` is ignored: each region's come
/// from `load`; params.matchedFilter must be on; the zero-biased frames are not kept. Throws st::InputError
/// (a strip trimmed otherwise than `trim` says, loader errors, a strip without usable pixels),
/// st::FitsError, st::Cancelled.
OutOfCorePrepared preprocessOutOfCore(const RawRegionLoader& load, const CubeShape& shape,
                                      const std::optional<calib::Section>& trim, const PreprocessParams& params,
                                      const OutOfCorePreprocessPlan& plan, const std::string& outPath,
                                      ProgressSink& progress, CancelToken& cancel);

}  // namespace st::pipeline
