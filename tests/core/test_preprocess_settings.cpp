// The core's one description of the pre-processing settings (session/preprocess_settings.hpp, issue 18 item
// 3): stable keys, defaults that are the pipeline's own, ranges that hold them, and settings applied onto the
// typed pipeline::PreprocessParams with unknown keys and out-of-range values refused by name.
#include <gtest/gtest.h>

#include <set>
#include <string>

#include "st/common/error.hpp"
#include "st/session/preprocess_settings.hpp"

namespace st::session {
namespace {

TEST(PreprocessSettings, KeysAreStableUniqueAndDefaultsAreThePipelines) {
  const std::vector<PreprocessStageSpec> specs = preprocessStageSpecs();
  std::vector<std::string> stageKeys;
  std::set<std::string> paramKeys;
  for (const auto& s : specs) {
    stageKeys.push_back(s.key);
    EXPECT_FALSE(s.label.empty()) << s.key;
    EXPECT_FALSE(s.formerKeys.empty()) << s.key << ": format-2 sessions stored the label";
    for (const auto& p : s.params) {
      EXPECT_TRUE(paramKeys.insert(p.key).second) << "duplicate parameter key " << p.key;
      EXPECT_LE(p.minimum, p.defaultValue) << p.key;
      EXPECT_GE(p.maximum, p.defaultValue) << p.key;
      EXPECT_FALSE(p.label.empty()) << p.key;
    }
  }
  // These keys are in session files: changing one loses people's settings.
  EXPECT_EQ(stageKeys, (std::vector<std::string>{"calibration", "registration", "cosmic_rays", "background",
                                                 "sky_rate", "static_sources", "psf"}));
  EXPECT_EQ(paramKeys, (std::set<std::string>{"reg.linearRms", "cr.threshold", "cr.grow", "bg.globalFrames",
                                              "bg.globalXi", "bg.xi", "bg.maxFrames", "sky.vx", "sky.vy",
                                              "stars.snr", "stars.grow", "stars.dilate", "single.snr",
                                              "psf.fwhm", "psf.beta"}));
  // No settings: exactly the pipeline's defaults.
  const pipeline::PreprocessParams d;
  const pipeline::PreprocessParams p = preprocessParams({});
  EXPECT_EQ(p.registerFrames, d.registerFrames);
  EXPECT_EQ(p.removeCosmicRays, d.removeCosmicRays);
  EXPECT_EQ(p.cosmicRays.thresholdSigma, d.cosmicRays.thresholdSigma);
  EXPECT_EQ(p.cosmicRays.growSigma, d.cosmicRays.growSigma);
  EXPECT_EQ(p.background.global.frames, d.background.global.frames);
  EXPECT_EQ(p.background.global.xi, d.background.global.xi);
  EXPECT_EQ(p.background.xi, d.background.xi);
  EXPECT_EQ(p.background.maxFrames, d.background.maxFrames);
  EXPECT_EQ(p.registration.linearRmsPx, d.registration.linearRmsPx);
  EXPECT_EQ(p.stars.snrThreshold, d.stars.snrThreshold);
  EXPECT_EQ(p.stars.growSnr, d.stars.growSnr);
  EXPECT_EQ(p.stars.dilateFwhm, d.stars.dilateFwhm);
  EXPECT_EQ(p.singleFrameSnr, d.singleFrameSnr);
  EXPECT_EQ(p.psfFwhmPx, d.psfFwhmPx);
  EXPECT_EQ(p.psfBeta, d.psfBeta);
  EXPECT_FALSE(p.skyRate.has_value());
  EXPECT_EQ(p.calib.subtractOverscan, d.calib.subtractOverscan);
  EXPECT_EQ(p.calib.useHeaderSections, d.calib.useHeaderSections);
}

TEST(PreprocessSettings, SettingsReachTheTypedParametersAndBadOnesAreNamed) {
  PreprocessSettings s;
  s.enabled = {{"calibration", false}, {"registration", false}, {"cosmic_rays", false}, {"sky_rate", false}};
  s.values = {{"cr.threshold", 9.5}, {"bg.globalFrames", 80}, {"sky.vx", 0.25}, {"sky.vy", -1.5},
              {"psf.beta", 3.0}, {"stars.snr", 6.0}};
  const pipeline::PreprocessParams p = preprocessParams(s);
  EXPECT_FALSE(p.calib.subtractOverscan);
  EXPECT_FALSE(p.calib.useHeaderSections);
  EXPECT_FALSE(p.registerFrames);
  EXPECT_FALSE(p.removeCosmicRays);
  EXPECT_EQ(p.cosmicRays.thresholdSigma, 9.5);
  EXPECT_EQ(p.background.global.frames, 80u);
  ASSERT_TRUE(p.skyRate.has_value());
  EXPECT_EQ(p.skyRate->vx, 0.25);
  EXPECT_EQ(p.skyRate->vy, -1.5);
  EXPECT_EQ(p.psfBeta, 3.0);
  EXPECT_EQ(p.stars.snrThreshold, 6.0);
  // A stage that cannot be switched off stays on.
  EXPECT_NO_THROW((void)preprocessParams({{{"background", false}}, {}}));

  const auto message = [](const PreprocessSettings& bad) {
    try {
      (void)preprocessParams(bad);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message({{}, {{"cr.thresh", 8.0}}}).find("'cr.thresh'"), std::string::npos);
  EXPECT_NE(message({{{"Cosmic rays", false}}, {}}).find("'Cosmic rays'"), std::string::npos);
  EXPECT_NE(message({{}, {{"psf.beta", 0.5}}}).find("'psf.beta'"), std::string::npos);
}

}  // namespace
}  // namespace st::session
