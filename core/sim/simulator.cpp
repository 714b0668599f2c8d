#include "st/sim/simulator.hpp"

#include <atomic>
#include <cmath>
#include <string>

#include "frame_renderer.hpp"
#include "scene.hpp"
#include "sim_header.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/common/units.hpp"
#include "st/io/fits_reader.hpp"
#include "st/sim/samplers.hpp"

namespace st::sim {

namespace {

void require(bool ok, const std::string& what, double value) {
  if (!ok) throw InputError("simulator: invalid " + what + " (got " + std::to_string(value) + ")");
}

// Exact matched-filter SNRs of one object (truth.hpp explains both).
void objectSnr(const SimParams& p, const detail::Scene& s, const detail::FrameRenderer& r, std::size_t k,
               double sigmaPhotons, TruthObject& o) {
  const PsfStamp& stamp = r.objectStamp(k);
  const int rad = stamp.radius();
  double sumP2 = 0.0;
  int inside = 0;
  double maxDx = 0.0, maxDy = 0.0;
  for (int n = 0; n < p.frames; ++n) {
    const double t = s.tOffsetS[n];
    const double x = o.xRefPx + o.vxPxPerS * t;
    const double y = o.yRefPx + o.vyPxPerS * t;
    if (x < -0.5 || y < -0.5 || x >= p.width - 0.5 || y >= p.height - 0.5) continue;
    ++inside;
    stamp.forEach(x, y, rad, [&](int ix, int iy, double w) {
      if (ix >= 0 && iy >= 0 && ix < p.width && iy < p.height) sumP2 += w * w;
    });
    maxDx = std::max(maxDx, std::fabs(o.skyVxPxPerS * t));
    maxDy = std::max(maxDy, std::fabs(o.skyVyPxPerS * t));
  }
  o.framesInside = inside;
  o.expectedSnr = sigmaPhotons > 0.0 ? o.photonsPerFrame * std::sqrt(sumP2) / sigmaPhotons : 0.0;
  if (inside == 0 || !(sigmaPhotons > 0.0)) return;
  // Sky-rate stack: the object streaks by its own motion; filter with the (sky-trailed) star profile.
  const int hx = static_cast<int>(std::ceil(maxDx)) + rad + 2;
  const int hy = static_cast<int>(std::ceil(maxDy)) + rad + 2;
  const int pw = 2 * hx + 1, ph = 2 * hy + 1;
  std::vector<double> patch(static_cast<std::size_t>(pw) * ph, 0.0);
  const double bx = hx + (o.xRefPx - std::floor(o.xRefPx));
  const double by = hy + (o.yRefPx - std::floor(o.yRefPx));
  for (int n = 0; n < p.frames; ++n) {
    const double t = s.tOffsetS[n];
    const double x = o.xRefPx + o.vxPxPerS * t;
    const double y = o.yRefPx + o.vyPxPerS * t;
    if (x < -0.5 || y < -0.5 || x >= p.width - 0.5 || y >= p.height - 0.5) continue;
    stamp.add(patch.data(), pw, ph, bx + o.skyVxPxPerS * t, by + o.skyVyPxPerS * t, 1.0, rad);
  }
  double dot = 0.0, sumH2 = 0.0;
  r.starStamp().forEach(bx, by, std::min(rad, r.starStamp().radius()), [&](int ix, int iy, double w) {
    sumH2 += w * w;
    if (ix >= 0 && iy >= 0 && ix < pw && iy < ph) dot += w * patch[static_cast<std::size_t>(iy) * pw + ix];
  });
  o.skyStackSnr = o.photonsPerFrame * dot / (sigmaPhotons * std::sqrt(inside * sumH2));
}

Truth makeTruth(const SimParams& p, std::uint64_t seed, const detail::Scene& s,
                const detail::FrameRenderer& r) {
  Truth t;
  t.preset = p.presetName;
  t.seed = seed;
  t.width = p.width;
  t.height = p.height;
  t.frames = p.frames;
  t.noiseless = p.noiseless;
  t.tRefMjd = s.tRefMjd;
  t.frameRateHz = p.frameRateHz;
  t.exposureS = p.exposureS;
  t.plateScaleArcsecPerPx = p.plateScaleArcsecPerPx;
  t.psfRadiusPx = p.psf.radius;
  t.psfBeta = p.psf.beta;
  t.psfFwhmPx = p.psf.fwhm();
  t.skyVxPxPerS = p.skyDriftXPxPerS;
  t.skyVyPxPerS = p.skyDriftYPxPerS;
  t.gainEPerAdu = p.gainEPerAdu;
  t.emGain = p.emGain;
  t.aduPerPhoton = std::max(1.0, p.emGain) / p.gainEPerAdu;
  t.zeroPointPhotonsPerS = p.zeroPointPhotonsPerS;
  const double sigmaAdu = detail::calibratedSigmaAdu(p, s.flat);
  t.skyAdu.assign(p.frames, p.skyPhotonsPerPxPerFrame * t.aduPerPhoton);
  t.noiseSigmaAdu.assign(p.frames, sigmaAdu);
  t.noiseSigmaPhotons = sigmaAdu / t.aduPerPhoton;
  t.objects = s.objects;
  for (std::size_t k = 0; k < t.objects.size(); ++k)
    objectSnr(p, s, r, k, t.noiseSigmaPhotons, t.objects[k]);
  t.stars = s.stars;
  for (auto& star : t.stars) {
    const double core = star.photonsPerFrame * (star.spikes ? 1.0 - p.spikeFraction : 1.0);
    star.saturated = core * r.starStamp().peakFraction() > p.fullWellE ||
                     core * r.starStamp().peakFraction() * t.aduPerPhoton + p.biasLevelAdu > p.saturationAdu;
  }
  for (const auto& c : s.cosmic)
    t.cosmicRays.push_back(c.truth);
  t.hotPixels = s.hot;
  return t;
}

}  // namespace

double paperZeroPointPhotonsPerS() {
  return kPaperCalPhotonsPerS * std::pow(10.0, 0.4 * kPaperCalMag);
}

MovingObject MovingObject::fromRate(std::string name, double xRefPx, double yRefPx, double rateDegPerDay,
                                    double directionDeg, double magnitude, double plateScaleArcsecPerPx) {
  MovingObject o;
  o.name = std::move(name);
  o.xRefPx = xRefPx;
  o.yRefPx = yRefPx;
  const double v = degPerDayToPxPerSec(rateDegPerDay, plateScaleArcsecPerPx);
  o.skyVxPxPerS = v * std::cos(directionDeg * M_PI / 180.0);
  o.skyVyPxPerS = v * std::sin(directionDeg * M_PI / 180.0);
  o.magnitude = magnitude;
  return o;
}

void SimParams::validate() const {
  require(width > 0 && width <= 16384, "width", width);
  require(height > 0 && height <= 16384, "height", height);
  require(frames > 0 && frames <= 1000000, "frames", frames);
  require(frameRateHz > 0.0, "frame rate, Hz", frameRateHz);
  require(exposureS > 0.0 && exposureS <= 1.0 / frameRateHz * (1.0 + 1e-9),
          "exposure, s (0 < exposure <= 1 / frame rate)", exposureS);
  require(plateScaleArcsecPerPx > 0.0, "plate scale, arcsec/px", plateScaleArcsecPerPx);
  require(psf.radius > 0.0, "PSF Moffat radius R, px", psf.radius);
  require(psf.beta > 1.0, "PSF Moffat beta (must be > 1)", psf.beta);
  require(skyPhotonsPerPxPerFrame >= 0.0, "sky, photons per pixel per frame", skyPhotonsPerPxPerFrame);
  require(readNoiseE >= 0.0, "read noise, e-", readNoiseE);
  require(gainEPerAdu > 0.0, "gain, e-/ADU", gainEPerAdu);
  require(emGain >= 1.0, "EM gain (1 = none)", emGain);
  require(flatAmplitude >= 0.0 && flatAmplitude < 0.5, "flat-field amplitude (must be in [0, 0.5))",
          flatAmplitude);
  require(fullWellE > 0.0, "full well, e-", fullWellE);
  require(saturationAdu > biasLevelAdu, "saturation level, ADU (must exceed the bias level)", saturationAdu);
  require(zeroPointPhotonsPerS > 0.0, "photometric zero point, photons/s", zeroPointPhotonsPerS);
  require(starCount >= 0, "number of stars", starCount);
  require(starMagMax >= starMagMin, "faintest star magnitude (must be >= the brightest)", starMagMax);
  require(brightStars >= 0, "number of bright stars", brightStars);
  require(spikeFraction >= 0.0 && spikeFraction < 1.0, "diffraction-spike fraction (must be in [0, 1))",
          spikeFraction);
  require(cosmicRaysPerFrame >= 0.0, "cosmic rays per frame", cosmicRaysPerFrame);
  require(cosmicRayMinAdu > 0.0 && cosmicRayMaxAdu >= cosmicRayMinAdu, "cosmic-ray amplitude range, ADU",
          cosmicRayMinAdu);
  require(hotPixels >= 0, "number of hot pixels", hotPixels);
  require(hotPixelMinAdu > 0.0 && hotPixelMaxAdu >= hotPixelMinAdu, "hot-pixel amplitude range, ADU",
          hotPixelMinAdu);
}

calib::MasterCalibration exactMasters(const SimResult& result) {
  calib::MasterCalibration m;
  m.width = result.cube.width();
  m.height = result.cube.height();
  m.bias = result.biasFrame;
  m.flat = result.flatFrame;
  return m;
}

SimResult simulate(const SimParams& params, std::uint64_t seed, ProgressSink& progress, CancelToken& cancel) {
  params.validate();
  const detail::Scene scene = detail::planScene(params, seed);
  const detail::FrameRenderer renderer(params, scene);
  SimResult result;
  result.cube = FrameCube(params.width, params.height, static_cast<std::size_t>(params.frames));
  for (int n = 0; n < params.frames; ++n) {
    FrameInfo& info = result.cube.info()[n];
    info.mjdMid = scene.mjdMid[n];
    info.exposureS = params.exposureS;
    info.plane = n;
  }
  std::atomic<int> done{0};
  progress.report(0.0, "simulating frames");
  parallelFor(static_cast<std::size_t>(params.frames), 1, [&](std::size_t b, std::size_t e) {
    std::vector<double> photons;
    for (std::size_t n = b; n < e; ++n) {
      cancel.throwIfCancelled();
      Rng rng(streamSeed(seed, detail::kStreamFrame + n));
      renderer.expectedPhotons(static_cast<int>(n), photons);
      renderer.detector(static_cast<int>(n), photons, rng, result.cube.frame(n));
      progress.report(static_cast<double>(++done) / params.frames, "simulating frames");
    }
  });
  result.truth = makeTruth(params, seed, scene, renderer);
  result.cube.header = detail::simHeader(params, seed, scene);
  result.cube.plateScaleArcsecPerPx = params.plateScaleArcsecPerPx;
  // The header's WCS as the reader attaches it to the cube written from it: a cube used in memory (the GUI's
  // demo, the CLI demo's stacks) had none, so no sky positions, until written and read.
  result.cube.wcs = io::cubeWcs(result.cube.header, &result.cube.warnings);
  result.biasFrame = scene.bias;
  result.flatFrame = scene.flat;
  return result;
}

Truth predictTruth(const SimParams& params, std::uint64_t seed) {
  params.validate();
  const detail::Scene scene = detail::planScene(params, seed);
  const detail::FrameRenderer renderer(params, scene);
  return makeTruth(params, seed, scene, renderer);
}

CalibrationFrames simulateCalibrationFrames(const SimParams& params, std::uint64_t seed, int nBias, int nFlat,
                                            double flatLevelE) {
  params.validate();
  require(nBias >= 0 && nFlat >= 0, "number of calibration frames", std::min(nBias, nFlat));
  SimParams p = params;
  p.objects.clear();
  p.starCount = 0;
  p.brightStars = 0;
  const detail::Scene s = detail::planScene(p, seed);
  CalibrationFrames out;
  const double readAdu = p.readNoiseE / p.gainEPerAdu;
  for (int k = 0; k < nBias + nFlat; ++k) {
    Rng rng(streamSeed(seed, detail::kStreamCalib + static_cast<std::uint64_t>(k)));
    Image img(p.width, p.height);
    const bool flat = k >= nBias;
    for (std::size_t i = 0; i < img.size(); ++i) {
      double adu = s.bias.pixels[i];
      if (flat) {
        const double lambda = flatLevelE * s.flat.pixels[i];
        adu += (p.noiseless ? lambda : static_cast<double>(poisson(rng, lambda))) / p.gainEPerAdu;
      }
      if (!p.noiseless) adu += readAdu * normal01(rng);
      img.pixels[i] = static_cast<float>(std::clamp(adu, 0.0, p.saturationAdu));
    }
    (flat ? out.flat : out.bias).push_back(std::move(img));
  }
  return out;
}

}  // namespace st::sim
