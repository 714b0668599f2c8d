#pragma once
// Two steps of preprocess() (core/pipeline/preprocess.cpp), kept here to keep that file to the stages' order:
// the PSF measured on the sky-rate stack, and the frames' saturation level in calibrated counts.
#include <optional>
#include <string>
#include <vector>

#include "st/calib/calibration.hpp"
#include "st/common/frame_cube.hpp"
#include "st/detect/sky_stack.hpp"
#include "st/pipeline/preprocess.hpp"

namespace st::pipeline::detail {

// The PSF from the sky-rate stack `s` of the frames before the per-pixel background (which, where the stars
// do not drift, takes the wings of every star just outside its mask into the background and leaves a
// narrow, steep-winged profile: FWHM 2.0 px, beta 7.95 on Lowell frames whose stars measure 2.35-2.56 px),
// isolated unsaturated catalog stars away from the edges, the median of up to 5 accepted; the fallback FWHM
// with a note when none is usable, and a note when the accepted stars disagree. `stackNoise`:
// psf::robustImageNoise(s.mean) where the caller has measured it (beside other work), else measured here.
// The notes go to `notes` where given (a thread beside may be adding to out.notes), else to out.notes.
void measurePsfInto(Prepared& out, const detect::SkyStack& s, const PreprocessParams& params,
                    std::optional<double> stackNoise = std::nullopt,
                    std::vector<std::string>* notes = nullptr);

// The ADC full scale of the raw frames (SATURATE, else the integer BITPIX's full scale 2^(BITPIX-1) - 1 +
// BZERO: 65535 for unsigned 16-bit frames without SATURATE), less the bias (the overscan level and the master
// bias), in calibrated counts, with a 5% margin for the flat and the bias pattern; none when the header says
// neither. Without it, stars clipped in a few frames show no flat top in the stack and are taken for the PSF
// (Lowell: FWHM +11%), and the tips of bleed columns are taken for cosmic rays.
std::optional<double> saturationCounts(const FrameCube& cube, const PreprocessParams& params,
                                       const calib::CalibrationReport& calibration);

}  // namespace st::pipeline::detail
