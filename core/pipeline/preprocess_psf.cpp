#include "preprocess_psf.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "st/common/error.hpp"
#include "st/common/timed_parts.hpp"
#include "st/psf/psf_star.hpp"
#include "st/psf/stack_smear.hpp"

namespace st::pipeline::detail {

void measurePsfInto(Prepared& out, const detect::SkyStack& s, const PreprocessParams& params,
                    std::optional<double> stackNoise, std::vector<std::string>* notes) {
  std::vector<std::string>& said = notes ? *notes : out.notes;
  std::vector<psf::StarCandidate> candidates;
  for (const auto& st : out.stars)
    candidates.push_back({st.x - s.x0, st.y - s.y0, st.flux, st.saturated});
  TimedParts parts;
  PartTimer timer(parts);
  psf::PsfStarOptions opt;
  opt.fit.noiseSigma = 0.0;
  opt.imageNoise = stackNoise;
  opt.fit.smear = psf::stackSmear(out.frames, out.skyRate);  // the stack's trails and shift rounding
  timer.lap("smear");
  try {
    const psf::PsfMeasurement m = params.psfStar ? psf::measurePsfAt(s.mean, params.psfStar->first - s.x0,
                                                                     params.psfStar->second - s.y0, opt)
                                                 : psf::measurePsf(s.mean, candidates, opt);
    timer.lap("fits");
    std::ostringstream fitted;
    if (params.psfStar)
      fitted << "PSF: the given star fitted";
    else
      fitted << "PSF: " << m.candidatesConsidered << " star(s) fitted, " << m.acceptedFwhm.size()
             << " accepted";
    if (!m.rejected.empty()) fitted << " (first rejected: " << m.rejected.front() << ")";
    fitted << "; " << parts.text();
    said.push_back(fitted.str());
    out.psf = m.fit.model;
    out.psfFitted = true;
    out.psfStarAt = std::make_pair(m.fit.x0 + s.x0, m.fit.y0 + s.y0);
    const auto& f = m.acceptedFwhm;
    if (f.size() >= 2 && f.back() > 1.2 * f.front()) {
      std::ostringstream note;
      note << "PSF: the " << f.size() << " stars accepted disagree (FWHM " << f.front() << " to " << f.back()
           << " px); the median star's " << out.psf.fwhm() << " px is used (variable seeing or focus?)";
      said.push_back(note.str());
    }
  } catch (const InputError& e) {
    out.psf = psf::Moffat::fromFwhm(params.psfFwhmPx, params.psfBeta);
    out.psfFitted = false;
    std::ostringstream note;
    note << "PSF: " << e.what() << "; using the given FWHM " << params.psfFwhmPx << " px, beta "
         << params.psfBeta;
    said.push_back(note.str());
  }
}

std::optional<double> saturationCounts(const FrameCube& cube, const PreprocessParams& params,
                                       const calib::CalibrationReport& calibration) {
  std::optional<double> fullScale = cube.header.getDouble("SATURATE");
  if (!fullScale) {
    const auto bitpix = cube.header.getDouble("BITPIX");
    if (bitpix && *bitpix > 0 && *bitpix <= 32)
      fullScale =
          std::ldexp(1.0, static_cast<int>(*bitpix) - 1) - 1.0 + cube.header.getDouble("BZERO").value_or(0.0);
  }
  if (!fullScale) return std::nullopt;
  auto median = [](std::vector<float> v) {
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return static_cast<double>(v[v.size() / 2]);
  };
  double biasLevel = 0.0;
  if (params.masters && !params.masters->bias.empty()) biasLevel += median(params.masters->bias.pixels);
  if (!calibration.overscanLevel.empty()) biasLevel += median(calibration.overscanLevel);
  return 0.95 * (*fullScale - biasLevel);
}

}  // namespace st::pipeline::detail
