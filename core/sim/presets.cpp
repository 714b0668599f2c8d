#include <cmath>

#include "st/common/error.hpp"
#include "st/common/units.hpp"
#include "st/sim/simulator.hpp"

namespace st::sim {

namespace {

constexpr double kPaperNeoSnr = 15.0;
constexpr double kSmallSnr = 20.0;
// Seeing of the paper-neo night: R = 4.1 px, beta = 4 gives FWHM 3.57 px = 1.09" (typical for Palomar), with
// which the 23 px streak of the object in a star-tracking stack has SNR ~4, as the paper states (§1). The
// paper's R ~ 3.3 was fitted on the 2009 BL2 night (known-pair), which keeps it.
constexpr double kPaperNeoMoffatR = 4.1;
constexpr std::uint64_t kTuningSeed = 0;  // the flat barely changes sigma (< 1e-3 relative) between seeds

// Sets the sky level so that the first object's expected SNR is `target` (sigma ~ 1 / SNR; sigma^2 =
// F^2 sky + (read / EM gain)^2 in photon units, refined twice for the flat's small effect).
void tuneSkyForSnr(SimParams& p, double target) {
  const double excess2 = p.emGain > 1.0 ? 2.0 : 1.0;
  const double readPhotons = p.readNoiseE / std::max(1.0, p.emGain);
  for (int iteration = 0; iteration < 3; ++iteration) {
    const Truth t = predictTruth(p, kTuningSeed);
    const double sigma = t.noiseSigmaPhotons * t.objects.front().expectedSnr / target;
    p.skyPhotonsPerPxPerFrame = std::max(0.0, (sigma * sigma - readPhotons * readPhotons) / excess2);
  }
}

void tuneMagnitudeForSnr(SimParams& p, double target) {
  for (int iteration = 0; iteration < 2; ++iteration) {
    const Truth t = predictTruth(p, kTuningSeed);
    p.objects.front().magnitude += 2.5 * std::log10(t.objects.front().expectedSnr / target);
  }
}

/// Frame size and cadence.
struct Cadence {
  int width = 0;
  int height = 0;
  int frames = 0;
  double frameRateHz = 0.0;
  double exposureS = 0.0;
};

/// The star field: random stars, the extra bright (saturated, spiked) ones, and spikes.
struct StarField {
  int count = 0;
  double magMin = 0.0;
  double magMax = 0.0;
  int brightStars = 0;
  double brightMagMin = 0.0;
  double brightMagMax = 0.0;
  double spikeMagLimit = 0.0;
  double minSeparationPx = 0.0;  ///< from any moving object's path
};

/// A preset's name and cadence on top of the SimParams defaults.
SimParams base(const char* name, const Cadence& c) {
  SimParams p;
  p.presetName = name;
  p.width = c.width;
  p.height = c.height;
  p.frames = c.frames;
  p.frameRateHz = c.frameRateHz;
  p.exposureS = c.exposureS;
  return p;
}

/// The paper's instrument (Palomar 200-inch, CHIMERA EMCCD, 0.305"/px): read noise 50 e-, 20 e-/ADU, bias
/// 1000 ADU with a 3 ADU column pattern, a 1% flat, the paper's zero point. EM gain and full well differ
/// between the two nights.
void chimeraDetector(SimParams& p, double emGain, double fullWellE) {
  p.plateScaleArcsecPerPx = 0.305;
  p.readNoiseE = 50.0;
  p.gainEPerAdu = 20.0;
  p.emGain = emGain;
  p.biasLevelAdu = 1000.0;
  p.biasColumnPatternAdu = 3.0;
  p.flatAmplitude = 0.01;
  p.fullWellE = fullWellE;
  p.zeroPointPhotonsPerS = paperZeroPointPhotonsPerS();
}

void setStarField(SimParams& p, const StarField& s) {
  p.starCount = s.count;
  p.starMagMin = s.magMin;
  p.starMagMax = s.magMax;
  p.brightStars = s.brightStars;
  p.brightStarMagMin = s.brightMagMin;
  p.brightStarMagMax = s.brightMagMax;
  p.spikeMagLimit = s.spikeMagLimit;
  p.starMinSeparationPx = s.minSeparationPx;
}

SimParams paperNeo() {
  // Frame-transfer EMCCD at 16.7 Hz: no dead time.
  SimParams p = base("paper-neo", {512, 512, 500, 16.7, 1.0 / 16.7});
  p.startMjd = 56546.29166666667;  // 2013-09-11 07:00 UTC, the paper's detection night
  p.raDeg = 352.0;
  p.decDeg = -2.0;
  p.psf = psf::Moffat{kPaperNeoMoffatR, 4.0};
  // Effective full well: the EM register and the ADC saturate near 6500 photo-electrons.
  chimeraDetector(p, 200.0, 6000.0);
  p.skyDriftXPxPerS = 5.0 / p.plateScaleArcsecPerPx;  // 5"/s scan
  setStarField(p, {40, 14.0, 23.5, 2, 10.0, 11.5, 13.0, 0.0});
  p.cosmicRaysPerFrame = 0.05;
  p.hotPixels = 20;
  p.hotPixelMinAdu = 30.0;
  p.hotPixelMaxAdu = 1000.0;
  p.objects = {MovingObject::fromRate("neo", 256.0, 240.0, 5.97, 150.0, 23.1, p.plateScaleArcsecPerPx)};
  p.skyPhotonsPerPxPerFrame = 6.0;
  tuneSkyForSnr(p, kPaperNeoSnr);
  return p;
}

SimParams knownPair() {
  SimParams p = base("known-pair", {256, 256, 960, 2.0, 0.5});
  p.startMjd = 56385.25;  // 2013-04-03 06:00 UTC (the paper's 2009 BL2 night)
  p.raDeg = 190.0;
  p.decDeg = 10.0;
  p.psf = psf::Moffat{3.3, 4.0};
  chimeraDetector(p, 50.0, 25000.0);
  p.skyPhotonsPerPxPerFrame = 50.0;  // ~21.3 mag/arcsec^2, as in paper-neo
  // One bright star: the paper's 16th-magnitude reference star.
  setStarField(p, {15, 17.0, 23.0, 1, 16.0, 16.0, 15.0, 10.0});
  p.cosmicRaysPerFrame = 0.05;
  p.hotPixels = 10;
  p.objects = {
      MovingObject::fromRate("2009BL2-like", 120.0, 120.0, 0.6, 20.0, 18.5, p.plateScaleArcsecPerPx)};
  return p;
}

SimParams small() {
  // A conventional CCD (the SimParams detector defaults: 5 e- read noise, no EM gain) at 10 Hz.
  SimParams p = base("small", {128, 128, 64, 10.0, 0.09});
  p.psf = psf::Moffat{2.5, 3.5};
  p.readNoiseE = 5.0;
  p.gainEPerAdu = 2.0;
  p.emGain = 1.0;
  p.skyPhotonsPerPxPerFrame = 50.0;
  p.biasLevelAdu = 500.0;
  p.flatAmplitude = 0.02;
  p.fullWellE = 60000.0;
  p.zeroPointPhotonsPerS = paperZeroPointPhotonsPerS();
  setStarField(p, {5, 15.0, 19.0, 1, 10.0, 10.5, 14.0, 15.0});
  p.cosmicRaysPerFrame = 0.5;
  p.hotPixels = 5;
  p.objects = {MovingObject::fromRate("obj1", 60.0, 70.0, pxPerSecToDegPerDay(4.0, p.plateScaleArcsecPerPx),
                                      30.0, 21.0, p.plateScaleArcsecPerPx)};
  tuneMagnitudeForSnr(p, kSmallSnr);
  return p;
}

}  // namespace

std::vector<std::string> presetNames() {
  return {"paper-neo", "known-pair", "small"};
}

SimParams preset(std::string_view name) {
  if (name == "paper-neo") return paperNeo();
  if (name == "known-pair") return knownPair();
  if (name == "small") return small();
  std::string valid;
  for (const auto& n : presetNames())
    valid += (valid.empty() ? "" : ", ") + n;
  throw InputError("unknown simulator preset '" + std::string(name) + "' (valid: " + valid + ")");
}

double presetDemoHalfRangeDegPerDay(std::string_view name) {
  (void)preset(name);  // validates the name
  if (name == "known-pair") return 1.5;
  if (name == "small") return 40.0;
  return kDemoHalfRangeDegPerDay;
}

void resize(SimParams& p, int width, int height, int frames) {
  if (width > 0 || height > 0) {
    const int w = width > 0 ? width : p.width;
    const int h = height > 0 ? height : p.height;
    for (auto& o : p.objects) {
      o.xRefPx += 0.5 * (w - p.width);
      o.yRefPx += 0.5 * (h - p.height);
    }
    p.starCount = static_cast<int>(
        std::lround(p.starCount * (static_cast<double>(w) * h) / (static_cast<double>(p.width) * p.height)));
    p.width = w;
    p.height = h;
  }
  if (frames > 0) p.frames = frames;
}

}  // namespace st::sim
