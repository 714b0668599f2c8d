#pragma once
// The pre-processing settings a person can change (issue 18 item 3): the core's one description of them,
// with stable keys, display labels, units, ranges and defaults. The GUI builds its Processing panel from it;
// session files store the settings by the stable keys (format 3); preprocessParams() turns them into the
// typed pipeline::PreprocessParams. Labels are for people only and may change; keys never do.
//
// Session format 2 (until 2026-11-27) keyed the stages by their display labels (the parameters already had
// the keys below): each stage lists those labels in `formerKeys`, so such files still load.
#include <map>
#include <string>
#include <vector>

#include "st/pipeline/preprocess.hpp"

namespace st::session {

/// One numeric parameter of a stage.
struct PreprocessParamSpec {
  std::string key;            ///< stable, e.g. "cr.threshold" (session files)
  std::string label;          ///< shown, e.g. "Hit threshold"
  std::string unit;           ///< shown after the value, e.g. "σ", "px", "" for none
  double defaultValue = 0.0;  ///< pipeline::PreprocessParams' default (the paper's value where it has one)
  double minimum = 0.0;
  double maximum = 0.0;
  int decimals = 2;  ///< digits shown
  std::string help;  ///< what it does and where the default comes from
};

/// A list of files or folders a stage reads (the calibration's bias, flat and dark frames).
struct PreprocessFilesSpec {
  std::string key;    ///< stable: "bias", "flat", "dark"
  std::string label;  ///< shown
  std::string help;
};

/// One stage as a person sees it: on/off (when optional), its parameters and file lists.
struct PreprocessStageSpec {
  std::string key;    ///< stable, e.g. "cosmic_rays" (session files)
  std::string label;  ///< shown, e.g. "Cosmic rays"
  /// Keys older session files used for this stage (format 2: the label as it was on 2026-11-27).
  std::vector<std::string> formerKeys;
  bool enabledByDefault = true;
  bool optional = true;  ///< false: always on
  std::vector<PreprocessParamSpec> params;
  std::vector<PreprocessFilesSpec> files;
  std::string help;  ///< what the stage does, in a sentence (the label is kept short for a narrow panel)
};

/// Stable stage keys.
inline constexpr const char* kCalibrationStageKey = "calibration";
inline constexpr const char* kRegistrationStageKey = "registration";
inline constexpr const char* kCosmicRaysStageKey = "cosmic_rays";
inline constexpr const char* kBackgroundStageKey = "background";
inline constexpr const char* kSkyRateStageKey = "sky_rate";
inline constexpr const char* kStaticSourcesStageKey = "static_sources";
inline constexpr const char* kPsfStageKey = "psf";

/// The stages in the order they run and are shown, with pipeline::PreprocessParams' defaults.
[[nodiscard]] std::vector<PreprocessStageSpec> preprocessStageSpecs();

/// What a person set, by stable key. A stage or parameter not listed keeps its default.
struct PreprocessSettings {
  std::map<std::string, bool> enabled;   ///< stage key -> on (optional stages only)
  std::map<std::string, double> values;  ///< parameter key -> value
};

/// pipeline::PreprocessParams with `settings` applied: calibration off ignores the headers' overscan and
/// image sections; registration and cosmic rays on/off; the sky-rate stage off uses ("sky.vx", "sky.vy") px/s
/// instead of measuring it; every parameter onto its typed field. The calibration masters are not made here
/// (the caller loads the frames: app/common). Throws st::InputError naming a key that is no stage or
/// parameter of preprocessStageSpecs(), or a value outside its range.
[[nodiscard]] pipeline::PreprocessParams preprocessParams(const PreprocessSettings& settings);

}  // namespace st::session
