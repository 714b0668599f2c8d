#pragma once
// FITS stacks for the record: a 2-D stack at one velocity, with a WCS that maps the stack's pixels (which
// are positions at t_ref) to the sky, and provenance (software, step, velocity, epoch, inputs).
#include <cstdint>
#include <string>
#include <vector>

#include "st/common/fits_header.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/units.hpp"

namespace st {
class Wcs;
}

namespace st::report {

struct StackProvenance {
  std::string what;      ///< e.g. "candidate 3, IPSA at its fitted velocity"
  Velocity velocity;     ///< px/s, the stack's velocity in the frames
  Velocity skyRate;      ///< px/s
  double tRefMjd = 0.0;  ///< epoch of the stack's pixel positions
  std::size_t frames = 0;
  std::string mode = "IPSA";        ///< "IPSA" or "CSA"
  std::vector<std::string> inputs;  ///< files the frames came from (HISTORY cards)
  std::string bunit;                ///< BUNIT of the pixels (empty: none written)
  std::string bunitComment;         ///< e.g. "per frame, background subtracted"
};

/// A stack as it is useful in DS9 (issue 18 §6: raw sums carried a background varying 260k-522k counts
/// across the demo frame, the asteroid's +2.6k invisible): the mean over the frames that contributed to each
/// pixel (S / N_in, so the edges and masked areas are not darker), minus a smooth background: the median of
/// each `box` x `box` cell (0 = max(16, min(width, height) / 8) px; cells less than a quarter covered take the
/// median of all covered pixels), interpolated bilinearly between the cells' centres and extrapolated
/// linearly to the edges. Pixels no frame covered are NaN. `coverage` is row-major like `sum`.
[[nodiscard]] Image backgroundSubtractedMean(const Image& sum, const std::vector<std::uint16_t>& coverage,
                                             int box = 0);

/// The WCS cards of `wcs` (the frame at mappingEpochOffsetS seconds from t_ref, usually the first frame, with
/// the registration offset `mappingFrameOffset`, FrameInfo::offsetXPx/offsetYPx) moved to t_ref: CRPIXi -=
/// skyRate_i * mappingEpochOffsetS + offset_i, so a star's pixel in a stack at t_ref maps to its sky position
/// (the convention of skyMappingAtTRef). SIP terms are relative to CRPIX and move with it.
[[nodiscard]] FitsHeader wcsCardsAtTRef(const Wcs& wcs, Velocity skyRate, double mappingEpochOffsetS,
                                        PixelOffset mappingFrameOffset = {});

/// Writes `stack` as a float32 FITS image (io::writeImage) with provenance cards (SOFTWARE, STEP, DATE,
/// STVX/STVY px/s, SKYVX/SKYVY px/s, TREFMJD, NFRAMES, STMODE, one HISTORY card per input) and, when `wcs`
/// is given, wcsCardsAtTRef and WCSEPOCH = tRefMjd (the epoch the WCS maps pixels at; `report --wcs` reads
/// it). Throws st::FitsError.
/// With `coverage` (may be null), a second HDU "COVERAGE" (uint16, BUNIT "frames") holds the number of frames
/// that contributed to each pixel. BUNIT from provenance.bunit when set.
void writeStackFits(const std::string& path, const Image& stack, const StackProvenance& provenance,
                    const Wcs* wcs, double mappingEpochOffsetS,
                    const std::vector<std::uint16_t>* coverage = nullptr,
                    PixelOffset mappingFrameOffset = {});

}  // namespace st::report
