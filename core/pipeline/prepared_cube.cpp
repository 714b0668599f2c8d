#include "st/pipeline/prepared_cube.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "st/common/error.hpp"
#include "st/io/fits_writer.hpp"
#include "st/stack/matched_filter.hpp"

namespace st::pipeline {
namespace {

std::string numberText(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

// What to run instead, for the messages that refuse a file.
std::string whatToRun() {
  return "run `synthtrack-cli preprocess RAW... -o PREPARED.fits` on the raw frames and search PREPARED.fits "
         "with --preprocessed, or search the raw frames without --preprocessed";
}

// A number keyword; a value that is not a number names the file and the keyword.
std::optional<double> number(const FitsHeader& h, const char* key, const std::string& source) {
  try {
    return h.getDouble(key);
  } catch (const InputError& e) {
    throw InputError(source + ": " + e.what());
  }
}

std::optional<bool> logical(const FitsHeader& h, const char* key, const std::string& source) {
  const auto v = h.getString(key);
  if (!v) return std::nullopt;
  if (*v == "T") return true;
  if (*v == "F") return false;
  throw InputError(source + ": header keyword " + key + " = '" + *v +
                   "' must be T (matched-filtered) or F (zero-biased)");
}

std::optional<psf::Moffat> headerPsf(const FitsHeader& h, const std::string& source) {
  const auto fwhm = number(h, "PSFFWHM", source);
  if (!fwhm) return std::nullopt;
  const double beta = number(h, "PSFBETA", source).value_or(kDefaultPsfBeta);
  if (!(*fwhm > 0.0) || !(beta > 1.0)) {
    throw InputError(source + ": PSFFWHM = " + numberText(*fwhm) + ", PSFBETA = " + numberText(beta) +
                     " is no PSF (needs FWHM > 0 and beta > 1)");
  }
  return psf::Moffat::fromFwhm(*fwhm, beta);
}

// STFILT when present; else what files written before it say (see the header comment).
std::optional<std::pair<PreparedState, std::string>> stateOf(const FitsHeader& h, const std::string& source) {
  if (const auto filtered = logical(h, kFilteredKeyword, source)) {
    return std::pair{*filtered ? PreparedState::Filtered : PreparedState::ZeroBiased,
                     std::string(kFilteredKeyword) + (*filtered ? " = T" : " = F")};
  }
  if (h.has(kPreparedKeyword)) {
    throw InputError(source + ": has " + kPreparedKeyword + " but no " + kFilteredKeyword +
                     " keyword, so it cannot be told whether its frames are matched-filtered; " +
                     whatToRun());
  }
  if (h.has("SIGMAF")) return std::pair{PreparedState::Filtered, std::string("SIGMAF (no STFILT)")};
  if (h.getString("STEP").value_or("") == "preprocess" && h.has("PSFFWHM")) {
    return std::pair{PreparedState::ZeroBiased,
                     std::string("STEP = 'preprocess' without SIGMAF (no STFILT)")};
  }
  return std::nullopt;
}

}  // namespace

FitsHeader preparedCubeCards(const Prepared& prepared, std::optional<PreparedState> state) {
  FitsHeader h = io::provenanceCards("preprocess");
  if (state) {
    h.setNumber(kPreparedKeyword, kPreparedVersion, "written by synthtrack preprocess (keyword version)");
    h.set(kFilteredKeyword, *state == PreparedState::Filtered ? "T" : "F",
          *state == PreparedState::Filtered ? "frames matched-filtered with the PSF below"
                                            : "zero-biased frames, NOT matched-filtered");
  }
  h.setNumber("SIGMAN", prepared.sigmaN, "noise of one pixel of one frame, counts");
  h.setNumber("SKYVX", prepared.skyRate.vx, "sky rate x, px/s");
  h.setNumber("SKYVY", prepared.skyRate.vy, "sky rate y, px/s");
  h.setNumber("PSFFWHM", prepared.psf.fwhm(), "Moffat FWHM, px");
  h.setNumber("PSFBETA", prepared.psf.beta, "Moffat beta");
  if (state == PreparedState::Filtered) {
    h.setNumber("SIGMAF", prepared.filtered.sigmaF, "noise of one filtered frame, counts");
  }
  if (state == PreparedState::ZeroBiased && !prepared.backgroundWindows.empty()) {
    const stats::PixelBackgroundWindows& w = prepared.backgroundWindows;
    h.setNumber("BGWINS", w.windowS, "per-pixel background: frames within +- s left out");
    h.setNumber("BGNFRM", static_cast<double>(w.frames.size()), "per-pixel background: evenly spaced frames");
    h.setNumber("BGMINOUT", static_cast<double>(w.minOutside), "per-pixel background: fewest left in");
    h.setNumber("BGCLIP", w.clipXi, "per-pixel background: clip xi, sigma");
  }
  return h;
}

namespace {

// BGWINS, BGNFRM, BGMINOUT and BGCLIP: all four or none.
std::optional<PreparedBackgroundWindows> headerWindows(const FitsHeader& h, const std::string& source) {
  constexpr const char* kKeys[] = {"BGWINS", "BGNFRM", "BGMINOUT", "BGCLIP"};
  std::optional<double> v[4];
  int present = 0;
  for (int i = 0; i < 4; ++i) {
    v[i] = number(h, kKeys[i], source);
    present += v[i].has_value();
  }
  if (present == 0) return std::nullopt;
  for (int i = 0; i < 4; ++i)
    if (!v[i]) {
      throw InputError(source + ": has BGWINS, BGNFRM, BGMINOUT or BGCLIP but no " + kKeys[i] +
                       " (the per-pixel background's windows need all four)");
    }
  const auto count = [&](int i) {
    if (!(*v[i] >= 0.0) || *v[i] != std::floor(*v[i]) || *v[i] > 1e9) {
      throw InputError(source + ": " + kKeys[i] + " = " + numberText(*v[i]) + " is not a frame count");
    }
    return static_cast<std::size_t>(*v[i]);
  };
  if (!(*v[0] >= 0.0) || !std::isfinite(*v[0])) {
    throw InputError(source + ": BGWINS = " + numberText(*v[0]) + " is not a window (s, >= 0)");
  }
  if (!(*v[3] > 0.0) || !std::isfinite(*v[3])) {
    throw InputError(source + ": BGCLIP = " + numberText(*v[3]) + " is not a clip (sigma, > 0)");
  }
  return PreparedBackgroundWindows{*v[0], count(1), count(2), *v[3]};
}

}  // namespace

stats::PixelBackgroundWindows preparedBackgroundWindows(const PreparedHeader& header, const FrameCube& frames,
                                                        std::vector<std::string>& notes) {
  const std::string keep =
      ": the co-moving fit keeps the paper's model of the background (a slow mover's own "
      "flux in it is not modelled)";
  if (!header.backgroundWindows) {
    notes.push_back(cubeSource(frames) +
                    " records no per-pixel background windows (BGWINS; written before "
                    "2026-12-05, or not a zero-biased cube)" +
                    keep);
    return {};
  }
  const PreparedBackgroundWindows& w = *header.backgroundWindows;
  if (w.setSize == 0 || w.setSize > frames.frameCount()) {
    notes.push_back(cubeSource(frames) + ": BGNFRM = " + std::to_string(w.setSize) + " does not fit its " +
                    std::to_string(frames.frameCount()) + " frames" + keep);
    return {};
  }
  const std::vector<double> t = frames.timeOffsetsS();
  if (w.windowS > 0.0 && !std::is_sorted(t.begin(), t.end())) {
    notes.push_back(cubeSource(frames) + ": BGWINS = " + numberText(w.windowS) +
                    " s but the frames are not in time order" + keep);
    return {};
  }
  return stats::PixelBackgroundWindows::evenlyOver(frames.frameCount(), w.setSize, w.windowS, w.minOutside,
                                                   w.clipXi);
}

std::string preparedSidecarPath(const std::string& cubePath) {
  std::filesystem::path p(cubePath);
  p.replace_extension(".json");
  return p.string();
}

std::optional<PreparedHeader> recognisePreparedHeader(const FitsHeader& header, const std::string& source) {
  const auto state = stateOf(header, source);
  if (!state) return std::nullopt;
  PreparedHeader p;
  p.state = state->first;
  p.evidence = state->second;
  p.psf = headerPsf(header, source);
  p.sigmaF = number(header, "SIGMAF", source);
  p.sigmaN = number(header, "SIGMAN", source);
  p.skyRate = {number(header, "SKYVX", source).value_or(0.0), number(header, "SKYVY", source).value_or(0.0)};
  p.backgroundWindows = headerWindows(header, source);
  return p;
}

PreparedHeader readPreparedHeader(const FitsHeader& header, const std::string& source) {
  if (auto p = recognisePreparedHeader(header, source)) return *p;
  throw InputError(
      source + ": not a pre-processed cube: the header has no " + kFilteredKeyword +
      " keyword (nor SIGMAF or PSFFWHM from preprocess), so it cannot be told whether its frames "
      "are matched-filtered; " +
      whatToRun());
}

void checkNotPrepared(const FrameCube& raw, const std::string& whatToDo) {
  const std::string source = cubeSource(raw);
  if (const auto p = recognisePreparedHeader(raw.header, source)) {
    throw InputError(source + ": is already pre-processed (" + p->evidence + ", " +
                     (p->state == PreparedState::Filtered ? "matched-filtered" : "zero-biased") + "); " +
                     whatToDo);
  }
}

std::string cubeSource(const FrameCube& cube) {
  if (cube.empty() || cube.info().front().file.empty()) return "the input";
  return cube.info().front().file;
}

PreparedSearchInput searchInputFromPrepared(FrameCube loaded, const PreparedOverrides& overrides,
                                            ProgressSink& progress, CancelToken& cancel) {
  const std::string source = cubeSource(loaded);
  PreparedSearchInput in;
  in.header = readPreparedHeader(loaded.header, source);
  in.warnings = std::move(loaded.warnings);
  loaded.warnings.clear();
  const PreparedHeader& h = in.header;
  if (overrides.psfFwhmPx && !(*overrides.psfFwhmPx > 0.0)) {
    throw InputError("PSF FWHM must be > 0, got " + numberText(*overrides.psfFwhmPx));
  }
  if (h.state == PreparedState::ZeroBiased) {
    if (!h.psf && !overrides.psfFwhmPx) {
      throw InputError(source + ": zero-biased cube (" + h.evidence +
                       ") without PSFFWHM: the matched filter needs the PSF; give its FWHM (--fwhm) or " +
                       whatToRun());
    }
    const double beta = h.psf ? h.psf->beta : kDefaultPsfBeta;
    const psf::Moffat psf = overrides.psfFwhmPx ? psf::Moffat::fromFwhm(*overrides.psfFwhmPx, beta) : *h.psf;
    in.cube = stack::makeFilteredCube(std::move(loaded), psf, h.skyRate, progress, cancel);
    in.filteredHere = true;
    in.notes.push_back(source + ": zero-biased cube (" + h.evidence + "), matched-filtered with the " +
                       (overrides.psfFwhmPx ? "given" : "header's") + " PSF (Moffat FWHM " +
                       numberText(psf.fwhm()) + " px, beta " + numberText(psf.beta) + "); sigma_F " +
                       numberText(in.cube.sigmaF) + " measured");
  } else {
    in.cube.frames = std::move(loaded);
    in.cube.revision = search::nextCubeRevision();
    in.cube.skyRate = h.skyRate;
    in.cube.psfFwhmPx = overrides.psfFwhmPx.value_or(h.psf ? h.psf->fwhm() : 3.0);
    if (!overrides.psfFwhmPx && !h.psf) {
      in.notes.push_back(source + ": filtered cube without PSFFWHM: the grid assumes a PSF FWHM of 3 px");
    }
    if (h.sigmaF) in.cube.sigmaF = *h.sigmaF;
  }
  if (overrides.sigmaF) in.cube.sigmaF = *overrides.sigmaF;
  if (h.state == PreparedState::Filtered && !overrides.sigmaF && !h.sigmaF) {
    const int border = static_cast<int>(std::ceil(2.0 * in.cube.psfFwhmPx));
    in.cube.sigmaF = stack::measureFilteredNoise(in.cube.frames, border);
    if (!(in.cube.sigmaF > 0.0)) {
      throw InputError(source +
                       ": filtered cube without SIGMAF, and sigma_F could not be measured from the "
                       "data (fewer than 1000 usable pixels); give it (--sigma-f)");
    }
    in.notes.push_back(source + ": filtered cube without SIGMAF: sigma_F " + numberText(in.cube.sigmaF) +
                       " measured (1.4826 MAD)");
  }
  if (!(in.cube.sigmaF > 0.0)) {
    throw InputError(source + ": sigma_F must be > 0, got " + numberText(in.cube.sigmaF));
  }
  return in;
}

}  // namespace st::pipeline
