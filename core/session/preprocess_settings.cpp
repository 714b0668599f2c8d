#include "st/session/preprocess_settings.hpp"

#include <cmath>
#include <functional>

#include "st/common/error.hpp"

namespace st::session {
namespace {

using Params = pipeline::PreprocessParams;

/// Where each parameter goes in pipeline::PreprocessParams.
const std::map<std::string, std::function<void(Params&, double)>>& setters() {
  static const std::map<std::string, std::function<void(Params&, double)>> kSetters = {
      {"reg.linearRms", [](Params& p, double v) { p.registration.linearRmsPx = v; }},
      {"cr.threshold", [](Params& p, double v) { p.cosmicRays.thresholdSigma = v; }},
      {"cr.grow", [](Params& p, double v) { p.cosmicRays.growSigma = v; }},
      {"bg.globalFrames",
       [](Params& p, double v) { p.background.global.frames = static_cast<std::size_t>(std::lround(v)); }},
      {"bg.globalXi", [](Params& p, double v) { p.background.global.xi = v; }},
      {"bg.xi", [](Params& p, double v) { p.background.xi = v; }},
      {"bg.maxFrames",
       [](Params& p, double v) { p.background.maxFrames = static_cast<std::size_t>(std::lround(v)); }},
      {"sky.vx", [](Params&, double) {}},  // used only with the stage off (preprocessParams)
      {"sky.vy", [](Params&, double) {}},
      {"stars.snr", [](Params& p, double v) { p.stars.snrThreshold = v; }},
      {"stars.grow", [](Params& p, double v) { p.stars.growSnr = v; }},
      {"stars.dilate", [](Params& p, double v) { p.stars.dilateFwhm = v; }},
      {"single.snr", [](Params& p, double v) { p.singleFrameSnr = v; }},
      {"psf.fwhm", [](Params& p, double v) { p.psfFwhmPx = v; }},
      {"psf.beta", [](Params& p, double v) { p.psfBeta = v; }},
  };
  return kSetters;
}

}  // namespace

std::vector<PreprocessStageSpec> preprocessStageSpecs() {
  const Params d;
  using P = PreprocessParamSpec;
  using F = PreprocessFilesSpec;
  return {
      // Off: the headers' image sections (BIASSEC, TRIMSEC, DATASEC) are ignored, for headers that describe
      // another readout; on, a section that does not fit the frames is clipped with a warning. Bias, flat and
      // dark frames as `synthtrack-cli preprocess --bias/--flat/--dark` takes them (files or folders).
      {kCalibrationStageKey,
       "Calibration",
       {"Calibration (overscan, trim, bad pixels)"},
       true,
       true,
       {},
       {F{"bias", "Bias frames", "bias (zero) frames, combined per pixel by the median"},
        F{"flat", "Flat frames",
          "flat-field frames (twilight or dome), bias-subtracted, median-combined and normalised to 1"},
        F{"dark", "Dark frames", "dark frames, bias-subtracted and scaled by exposure"}},
       "overscan subtracted and trimmed by the headers' sections, bias, dark and flat applied, bad pixels "
       "masked"},
      {kRegistrationStageKey,
       "Registration",
       {"Registration (per-frame offsets from the stars)"},
       d.registerFrames,
       true,
       {P{"reg.linearRms", "Linear sky rate up to rms", "px", d.registration.linearRmsPx, 0.0, 1000.0, 2,
          "each frame's star field is followed from frame to frame; while it stays within this rms of one "
          "linear sky rate that is the model, beyond it (dithers, guiding, re-pointing) per-frame offsets "
          "are used by every stage and the search"}},
       {},
       "per-frame offsets from the stars (dithers, guiding drift), or one linear sky rate when the field "
       "moves linearly"},
      {kCosmicRaysStageKey,
       "Cosmic rays",
       {"Cosmic rays"},
       d.removeCosmicRays,
       true,
       {P{"cr.threshold", "Hit threshold", "σ", d.cosmicRays.thresholdSigma, 3, 50, 1,
          "F_n - max(two nearest frames) above this many single-frame sigma"},
        P{"cr.grow", "Grow threshold", "σ", d.cosmicRays.growSigma, 1, 50, 1,
          "neighbours above this join a hit"}},
       {}},
      {kBackgroundStageKey,
       "Background",
       {"Background"},
       true,
       false,
       {P{"bg.globalFrames", "Global frames", "", static_cast<double>(d.background.global.frames), 1, 1e6, 0,
          "frames of the first, pixel-independent estimate (paper §4.2: 50)"},
        P{"bg.globalXi", "Global clip ξ", "σ", d.background.global.xi, 1, 20, 1, "paper §3.1: 5"},
        P{"bg.xi", "Per-pixel clip ξ", "σ", d.background.xi, 1, 20, 1, "paper §3.1: 4"},
        P{"bg.maxFrames", "Frames per pixel", "", static_cast<double>(d.background.maxFrames), 10, 1e6, 0,
          "paper: ~2000"}},
       {}},
      {kSkyRateStageKey,
       "Sky rate (measured from the stars)",
       {"Sky rate (measured from the stars)"},
       true,
       true,
       {P{"sky.vx", "vx if not measured", "px/s", 0.0, -1e4, 1e4, 4, "used when the stage is off"},
        P{"sky.vy", "vy if not measured", "px/s", 0.0, -1e4, 1e4, 4, "used when the stage is off"}},
       {}},
      {kStaticSourcesStageKey,
       "Static sources",
       {"Static sources"},
       true,
       false,
       {P{"stars.snr", "Detection SNR", "", d.stars.snrThreshold, 2, 100, 1,
          "in the sky-rate stack (paper §4.3: 7)"},
        P{"stars.grow", "Footprint down to SNR", "", d.stars.growSnr, 0.5, 50, 1, ""},
        P{"stars.dilate", "Dilation", "FWHM", d.stars.dilateFwhm, 0, 10, 1, ""},
        P{"single.snr", "Single-frame SNR", "", d.singleFrameSnr, 2, 100, 1, "paper §4.3: 7"}},
       {}},
      {kPsfStageKey,
       "PSF and matched filter",
       {"PSF and matched filter"},
       true,
       false,
       {P{"psf.fwhm", "Fallback FWHM", "px", d.psfFwhmPx, 0.5, 50, 2,
          "used when no star can be fitted (paper: ~3 px)"},
        P{"psf.beta", "Fallback β", "", d.psfBeta, 1.1, 20, 2, "paper §3.3: 4"}},
       {}},
  };
}

pipeline::PreprocessParams preprocessParams(const PreprocessSettings& settings) {
  const std::vector<PreprocessStageSpec> specs = preprocessStageSpecs();
  const auto stageOn = [&](const char* key) {
    const auto it = settings.enabled.find(key);
    for (const auto& s : specs)
      if (s.key == key) return s.optional && it != settings.enabled.end() ? it->second : s.enabledByDefault;
    return true;
  };
  for (const auto& [key, on] : settings.enabled) {
    bool known = false;
    for (const auto& s : specs)
      known = known || s.key == key;
    if (!known) throw InputError("pre-processing: unknown stage '" + key + "'");
  }
  Params p;
  std::map<std::string, double> values;
  for (const auto& s : specs)
    for (const auto& param : s.params)
      values[param.key] = param.defaultValue;
  for (const auto& [key, value] : settings.values) {
    const PreprocessParamSpec* spec = nullptr;
    for (const auto& s : specs)
      for (const auto& param : s.params)
        if (param.key == key) spec = &param;
    if (!spec) throw InputError("pre-processing: unknown parameter '" + key + "'");
    if (!(value >= spec->minimum && value <= spec->maximum)) {
      throw InputError("pre-processing: parameter '" + key + "' is " + std::to_string(value) + ", outside " +
                       std::to_string(spec->minimum) + " to " + std::to_string(spec->maximum));
    }
    values[key] = value;
  }
  for (const auto& [key, value] : values)
    setters().at(key)(p, value);
  if (!stageOn(kCalibrationStageKey)) {
    p.calib.subtractOverscan = false;
    p.calib.useHeaderSections = false;
  }
  p.registerFrames = stageOn(kRegistrationStageKey);
  p.removeCosmicRays = stageOn(kCosmicRaysStageKey);
  if (!stageOn(kSkyRateStageKey)) p.skyRate = Velocity{values.at("sky.vx"), values.at("sky.vy")};
  return p;
}

}  // namespace st::session
