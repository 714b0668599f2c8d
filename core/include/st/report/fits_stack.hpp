#pragma once
// FITS stacks for the record: a 2-D stack at one velocity, with a WCS that maps the stack's pixels (which
// are positions at t_ref) to the sky, and provenance (software, step, velocity, epoch, inputs).
#include <string>
#include <vector>

#include "st/common/fits_header.hpp"
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
};

/// The WCS cards of `wcs` (the frame at mappingEpochOffsetS seconds from t_ref, usually the first frame)
/// moved to t_ref: CRPIXi -= skyRate_i * mappingEpochOffsetS, so a star's pixel in a stack at t_ref maps to
/// its sky position (the convention of skyMappingAtTRef). SIP terms are relative to CRPIX and move with it.
[[nodiscard]] FitsHeader wcsCardsAtTRef(const Wcs& wcs, Velocity skyRate, double mappingEpochOffsetS);

/// Writes `stack` as a float32 FITS image (io::writeImage) with provenance cards (SOFTWARE, STEP, DATE,
/// STVX/STVY px/s, SKYVX/SKYVY px/s, TREFMJD, NFRAMES, STMODE, one HISTORY card per input) and, when `wcs`
/// is given, wcsCardsAtTRef and WCSEPOCH = tRefMjd (the epoch the WCS maps pixels at; `report --wcs` reads
/// it). Throws st::FitsError.
void writeStackFits(const std::string& path, const Image& stack, const StackProvenance& provenance,
                    const Wcs* wcs, double mappingEpochOffsetS);

}  // namespace st::report
