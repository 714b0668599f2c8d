#include "st/pipeline/preprocess_out_of_core.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <sstream>

#include "st/common/error.hpp"
#include "st/io/fits_writer.hpp"
#include "st/pipeline/prepared_cube.hpp"
#include "st/psf/moffat.hpp"
#include "st/stack/matched_filter.hpp"

namespace st::pipeline {
namespace {

int roundUp(int v, int step) {
  return (v + step - 1) / step * step;
}

/// Strips owning `own` rows each (the last the rest), read with `overlap` rows on both sides.
std::vector<PreprocessStrip> cutStrips(int width, int height, int own, int overlap) {
  std::vector<PreprocessStrip> strips;
  for (int y = 0; y < height; y += own) {
    PreprocessStrip s;
    s.ownY0 = y;
    s.ownRows = std::min(own, height - y);
    const int r0 = std::max(0, y - overlap);
    const int r1 = std::min(height, y + s.ownRows + overlap);
    s.read = {0, r0, width, r1 - r0};
    strips.push_back(s);
  }
  return strips;
}

MemoryEstimate stripPeak(const CubeShape& shape, int readRows, unsigned threads) {
  return estimatePreprocessPeak({shape.width, readRows, shape.frames}, false, threads);
}

/// The header of the whole (trimmed) image from a strip's whose first row is `rowsBefore` rows below the
/// image's: the WCS reference pixel moved back.
FitsHeader wholeImageHeader(FitsHeader h, int rowsBefore) {
  if (const auto crpix2 = h.getDouble("CRPIX2")) h.setNumber("CRPIX2", *crpix2 + rowsBefore);
  return h;
}

void appendOnce(std::vector<std::string>& to, const std::vector<std::string>& from) {
  for (const auto& w : from)
    if (std::find(to.begin(), to.end(), w) == to.end()) to.push_back(w);
}

}  // namespace

int PreprocessHalo::overlap() const {
  return std::max({meshes, staticSources, filter, cosmicRays});
}

std::string PreprocessHalo::describe() const {
  std::ostringstream o;
  o << overlap() << " px (meshes " << meshes << ", static sources " << staticSources << ", filter " << filter
    << ", cosmic rays " << cosmicRays << ")";
  return o.str();
}

PreprocessHalo preprocessHalo(const PreprocessParams& params) {
  PreprocessHalo h;
  // SEP's background (mesh cells, a 3-cell median filter, a bicubic spline through the cell centres) and the
  // residual means (bilinear between cell centres): with half a cell above and below, the owned rows lie
  // between the strip's cell centres (interpolated, never extrapolated as a frame's outer half-cells are).
  // Two cells (the reach of the median filter; before 2026-11-27) read 5x the rows under 129 MB (16 strips
  // of 64 rows for 100 x 256 x 1024) and came no closer to the in-memory candidates than half a cell (bench
  // memory --raw): SEP's spline runs along whole columns, so no finite overlap gives the frame's mesh anyway.
  const int mesh = std::max(params.frameBackground.enabled ? params.frameBackground.meshPx : 0,
                            params.removeResidualMean ? params.residualMeshPx : 0);
  h.meshes = (mesh + 1) / 2;
  // A star whose centre is outside the strip but whose footprint reaches the owned rows is found in the
  // sky-rate stack when its core and the local background's cell around it are read.
  h.staticSources = std::max(params.stars.meshPx,
                             static_cast<int>(std::ceil(params.stars.dilateFwhm * params.psfFwhmPx)) + 1);
  // The matched filter's kernel (truncated at kDefaultTruncation of the peak) at twice the assumed FWHM:
  // the PSF is fitted on the reference strip and may be wider than assumed.
  h.filter = static_cast<int>(
      std::ceil(psf::Moffat::fromFwhm(2.0 * params.psfFwhmPx).radiusAtFraction(stack::kDefaultTruncation)));
  if (!params.matchedFilter) h.filter = 0;
  // A cosmic-ray seed is judged on its 5 x 5 neighbourhood and grows over 8-neighbours.
  h.cosmicRays = params.removeCosmicRays ? 3 : 0;
  return h;
}

int preprocessOverlapPx(const PreprocessParams& params) {
  return preprocessHalo(params).overlap();
}

OutOfCorePreprocessPlan planOutOfCorePreprocess(const CubeShape& shape, std::size_t budgetBytes,
                                                unsigned threads, int overlapPx, int stepPx) {
  OutOfCorePreprocessPlan plan;
  plan.overlapPx = overlapPx;
  stepPx = std::max(stepPx, 1);
  const double budget = static_cast<double>(budgetBytes);
  const int smallestRead = std::min(shape.height, kMinStripRows + 2 * overlapPx);
  plan.smallestStrip = stripPeak(shape, smallestRead, threads);
  if (shape.height <= 0 || plan.smallestStrip.total() > budget) return plan;
  // The tallest owned height whose strips fit (the estimate grows with the tallest strip's rows read: an
  // interior one reads both overlaps, the two of a 2-strip plan one each).
  const auto tallestRead = [&](int own) {
    int tallest = 0;
    for (const auto& s : cutStrips(shape.width, shape.height, own, overlapPx))
      tallest = std::max(tallest, s.read.height);
    return tallest;
  };
  const auto fits = [&](int own) { return stripPeak(shape, tallestRead(own), threads).total() <= budget; };
  const int smallest = std::min(kMinStripRows, shape.height);
  int best = smallest;
  for (int own = roundUp(shape.height, stepPx); own > smallest; own -= stepPx) {
    if (fits(std::min(own, shape.height))) {
      best = std::min(own, shape.height);
      break;
    }
  }
  // As few strips as that allows, their owned heights evened out on the step.
  const int count = (shape.height + best - 1) / best;
  int own = std::min(roundUp((shape.height + count - 1) / count, stepPx), shape.height);
  if (own > best && !fits(own)) own = best;
  plan.strips = cutStrips(shape.width, shape.height, own, overlapPx);
  plan.reference = plan.strips.size() / 2;
  int tallest = 0;
  for (const auto& s : plan.strips)
    tallest = std::max(tallest, s.read.height);
  plan.perStrip = stripPeak(shape, tallest, threads);
  return plan;
}

OutOfCorePrepared preprocessOutOfCore(const RawRegionLoader& load, const CubeShape& shape,
                                      const std::optional<calib::Section>& trim, const PreprocessParams& params,
                                      const OutOfCorePreprocessPlan& plan, const std::string& outPath,
                                      ProgressSink& progress, CancelToken& cancel) {
  if (plan.strips.empty()) throw InputError("out-of-core pre-processing: no strip fits the memory budget");
  if (!params.matchedFilter) throw InputError("out-of-core pre-processing writes the matched-filtered cube");
  const auto start = std::chrono::steady_clock::now();
  OutOfCorePrepared out;
  out.path = outPath;
  std::unique_ptr<io::CubeRegionWriter> writer;
  FrameCube framesInfo;  // the frames' times, origins and offsets for the FRAMES table
  // The strips in the order they are processed: the reference first.
  // The image written: the raw frames' rows [ty0, ty0 + outH) and columns [trim->x0, trim->x0 + outW) (0 on
  // without a trim).
  const int ty0 = trim ? trim->y0 : 0;
  const int outW = trim ? trim->width : shape.width, outH = trim ? trim->height : shape.height;
  const auto keptRows = [&](const PreprocessStrip& st) {
    return std::pair{std::max(st.ownY0, ty0), std::min(st.ownY0 + st.ownRows, ty0 + outH)};
  };
  std::size_t reference = plan.reference;  // the central strip with rows in the image
  if (keptRows(plan.strips[reference]).first >= keptRows(plan.strips[reference]).second) {
    for (std::size_t i = 0; i < plan.strips.size(); ++i)
      if (keptRows(plan.strips[i]).first < keptRows(plan.strips[i]).second) reference = i;
  }
  std::vector<std::size_t> order{reference};
  for (std::size_t i = 0; i < plan.strips.size(); ++i)
    if (i != reference) order.push_back(i);
  double rowsDone = 0.0;
  try {
    for (const std::size_t i : order) {
      cancel.throwIfCancelled();
      const PreprocessStrip& strip = plan.strips[i];
      const bool isReference = i == reference;
      const auto [keep0, keep1] = keptRows(strip);
      if (keep0 >= keep1) {  // rows outside the trim region (overscan rows): nothing to write
        rowsDone += strip.ownRows;
        continue;
      }
      SubProgress sub(progress, rowsDone / shape.height, (rowsDone + strip.ownRows) / shape.height);
      sub.report(0.0, "pre-processing rows " + std::to_string(strip.ownY0 + 1) + "-" +
                          std::to_string(strip.ownY0 + strip.ownRows) + " of " + std::to_string(shape.height) +
                          " (out of core)");
      RawRegion region = load(strip.read);
      appendOnce(out.warnings, region.raw.warnings);
      PreprocessParams p = params;
      p.masters = std::move(region.masters);
      p.keepZeroBiased = false;  // filtered in place: one cube per strip
      // A strip moved by whole pixels onto frame 0's grid would lose the rows its shift pushes out of the
      // strip (no halo is that wide): its frames keep their own grids and whole offsets.
      p.registration.alignWholePixels = false;
      if (!isReference) {
        const Prepared& ref = out.reference;
        p.skyRate = ref.skyRate;
        p.givenRegistration = ref.registration;
        // One PSF for the file (its header's PSFFWHM, the search grid's step). Fitting each strip's own
        // instead (Lowell: 1.38 px in the central strip, 1.56 px over the whole frame in memory) left
        // 5945's SNR the same to 6 digits and widened the strips' sigma_F from 18.8-19.2 to 18.8-21.4.
        p.givenPsf = ref.psf;
      }
      Prepared prep = preprocess(std::move(region.raw), p, sub, cancel);
      appendOnce(out.warnings, prep.calibration.warnings);
      FrameCube& f = prep.filtered.frames;
      // The strip's first row after its trim, in raw-frame rows.
      const int first = std::max(strip.read.y0, ty0);
      const int expectRows = std::min(strip.read.y0 + strip.read.height, ty0 + outH) - first;
      if (f.width() != outW || f.height() != expectRows)
        throw InputError("out-of-core pre-processing: rows " + std::to_string(strip.read.y0 + 1) + "-" +
                         std::to_string(strip.read.y0 + strip.read.height) + " came out of calibration as " +
                         std::to_string(f.width()) + " x " + std::to_string(f.height()) + " px, not " +
                         std::to_string(outW) + " x " + std::to_string(expectRows) +
                         " px (the frame's trim region); give a larger --memory-limit, or --ignore-sections");
      out.stripSigmaF.push_back(prep.filtered.sigmaF);
      out.cosmicRays += prep.cosmicRays;
      out.staticPixelsZeroed += prep.staticPixelsZeroed;
      if (isReference) {
        out.sigmaF = prep.filtered.sigmaF;
        out.sigmaN = prep.sigmaN;
        framesInfo = FrameCube(1, 1, f.frameCount());
        framesInfo.info() = f.info();
        Prepared summary;  // the reference's facts without its pixels
        summary.sigmaN = prep.sigmaN;
        summary.global = prep.global;
        summary.stars = prep.stars;
        summary.movers = prep.movers;
        summary.skyRate = prep.skyRate;
        summary.skyRateMeasured = prep.skyRateMeasured;
        summary.registration = prep.registration;
        summary.calibration = prep.calibration;
        summary.psf = prep.psf;
        summary.psfFitted = prep.psfFitted;
        summary.psfStarAt = prep.psfStarAt;
        summary.notes = prep.notes;
        summary.stageSeconds = prep.stageSeconds;
        summary.filtered.sigmaF = prep.filtered.sigmaF;
        summary.filtered.skyRate = prep.skyRate;
        summary.filtered.psfFwhmPx = prep.psf.fwhm();
        out.reference = std::move(summary);
        writer = std::make_unique<io::CubeRegionWriter>(
            outPath, outW, outH, shape.frames, wholeImageHeader(f.header, first - ty0), nullptr,
            preparedCubeCards(out.reference, PreparedState::Filtered));
      } else if (prep.filtered.sigmaF > 0.0 && out.sigmaF > 0.0) {
        // One SIGMAF for the file: this strip's filtered frames scaled to the reference's noise.
        const float scale = static_cast<float>(out.sigmaF / prep.filtered.sigmaF);
        for (auto& v : f.pixels())
          v *= scale;
      }
      writer->write(f, 0, keep0 - first, outW, keep1 - keep0, 0, keep0 - ty0);
      rowsDone += strip.ownRows;
    }
    writer->finish(framesInfo);
    // What the strips freed stays in the threads' arenas (the next strip reuses it); the search that follows
    // counts none of it (measured: 114 -> 82 MB resident when the search of 100 x 256 x 1024 starts).
    releaseFreeHeapMemory();
  } catch (...) {
    writer.reset();
    std::error_code ec;
    std::filesystem::remove(outPath, ec);
    throw;
  }
  const auto [lo, hi] = std::minmax_element(out.stripSigmaF.begin(), out.stripSigmaF.end());
  const PreprocessStrip& ref = plan.strips[reference];
  std::ostringstream note;
  note << "out of core: pre-processed in " << plan.strips.size() << " strips of up to "
       << plan.strips.front().ownRows << " rows (+" << plan.overlapPx
       << " rows of overlap each side); registration, sky rate and PSF measured on rows " << ref.ownY0 + 1 << "-"
       << ref.ownY0 + ref.ownRows << "; the strips' sigma_F " << *lo << " to " << *hi
       << ", each scaled to the reference's " << out.sigmaF << "; filtered cube written to " << outPath
       << "; peak resident memory so far " << formatBytes(static_cast<double>(peakResidentBytes()));
  out.notes = out.reference.notes;
  out.notes.push_back(note.str());
  out.elapsedS = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace st::pipeline
