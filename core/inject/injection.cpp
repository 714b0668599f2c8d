#include "st/inject/injection.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>

#include "st/common/error.hpp"
#include "st/common/units.hpp"
#include "st/io/sections.hpp"
#include "st/sim/samplers.hpp"

namespace st::inject {
namespace {

InjectParams resolved(const InjectParams& p, const psf::Moffat& psf) {
  auto bad = [](const std::string& what) { throw InputError("inject: " + what); };
  if (p.count < 1) bad("the number of movers must be >= 1, got " + std::to_string(p.count));
  if (!(p.snrMin > 0.0) || !(p.snrMax >= p.snrMin))
    bad("the SNR range must satisfy 0 < A <= B, got " + std::to_string(p.snrMin) + "," + std::to_string(p.snrMax));
  if (!(p.rateMinPxS >= 0.0) || !(p.rateMaxPxS >= p.rateMinPxS))
    bad("the rate range must satisfy 0 <= A <= B, got " + std::to_string(p.rateMinPxS) + "," +
        std::to_string(p.rateMaxPxS) + " px/s");
  if (p.minStarDistancePx < 0.0 || p.edgeMarginPx < 0.0 || p.minSeparationPx < 0.0)
    bad("distances must be >= 0");
  InjectParams r = p;
  const double w = psf.fwhm();
  if (r.minStarDistancePx == 0.0) r.minStarDistancePx = std::max(5.0, 3.0 * w);
  if (r.edgeMarginPx == 0.0) r.edgeMarginPx = std::max(10.0, 3.0 * w);
  if (r.minSeparationPx == 0.0) r.minSeparationPx = std::max(10.0, 5.0 * w);
  return r;
}

struct Track {
  double x, y, vx, vy;
  [[nodiscard]] double xAt(double t) const { return x + vx * t; }
  [[nodiscard]] double yAt(double t) const { return y + vy * t; }
};

/// Every frame's start, middle and end time (s from t_ref), and the whole span.
std::vector<double> trackTimes(const InjectionPlan& plan) {
  std::vector<double> t;
  for (std::size_t n = 0; n < plan.tOffsetS.size(); ++n)
    for (const double f : {-0.5, 0.0, 0.5})
      t.push_back(plan.tOffsetS[n] + f * plan.exposureS[n]);
  return t;
}

/// The closest approach of the track (sampled every <= 0.5 px over the whole span) to the mask, or -1 when
/// it leaves the margins.
double trackClearance(const Track& tr, const InjectionPlan& plan, const Field& field, double tFirst,
                      double tLast) {
  const double m = plan.params.edgeMarginPx;
  const double length = std::hypot(tr.vx, tr.vy) * (tLast - tFirst);
  const int steps = std::max(1, static_cast<int>(std::ceil(length / 0.5)));
  double clearance = 1e30;
  for (int k = 0; k <= steps; ++k) {
    const double t = tFirst + (tLast - tFirst) * k / steps;
    const double x = tr.xAt(t), y = tr.yAt(t);
    if (x < m || y < m || x > plan.width - 1 - m || y > plan.height - 1 - m) return -1.0;
    const int ix = static_cast<int>(std::lround(x)), iy = static_cast<int>(std::lround(y));
    clearance = std::min(clearance, static_cast<double>(field.maskDistancePx[static_cast<std::size_t>(iy) * plan.width + ix]));
  }
  return clearance;
}

bool separated(const Track& tr, const std::vector<InjectedObject>& placed, const std::vector<double>& times,
               double minSeparation) {
  for (const auto& o : placed)
    for (const double t : times)
      if (std::hypot(tr.xAt(t) - (o.xPx + o.vxPxS * t), tr.yAt(t) - (o.yPx + o.vyPxS * t)) < minSeparation)
        return false;
  return true;
}

std::vector<Stamp> stampsOf(const Track& tr, const InjectionPlan& plan) {
  std::vector<Stamp> s;
  for (std::size_t n = 0; n < plan.tOffsetS.size(); ++n) {
    const double ta = plan.tOffsetS[n] - 0.5 * plan.exposureS[n], tb = plan.tOffsetS[n] + 0.5 * plan.exposureS[n];
    s.push_back(trailedStamp(plan.psf, tr.xAt(ta), tr.yAt(ta), tr.xAt(tb), tr.yAt(tb), plan.stampRadiusPx));
  }
  return s;
}

io::PixelRegion noiseRegion(const std::vector<Stamp>& stamps) {
  int x0 = stamps.front().x0, y0 = stamps.front().y0, x1 = x0 + stamps.front().width,
      y1 = y0 + stamps.front().height;
  for (const auto& s : stamps) {
    x0 = std::min(x0, s.x0);
    y0 = std::min(y0, s.y0);
    x1 = std::max(x1, s.x0 + s.width);
    y1 = std::max(y1, s.y0 + s.height);
  }
  constexpr int kGrow = 10;
  return {x0 - kGrow, y0 - kGrow, x1 - x0 + 2 * kGrow, y1 - y0 + 2 * kGrow};
}

}  // namespace

double magnitudeOf(double flux, double exposureS, double zeroPointMag) {
  return zeroPointMag - 2.5 * std::log10(flux / exposureS);
}

InjectionPlan planInjection(const FrameCube& cube, const Field& field, const InjectParams& params,
                            CancelToken& cancel) {
  if (cube.width() != field.width || cube.height() != field.height)
    throw InputError("inject: the field was measured on " + std::to_string(field.width) + " x " +
                     std::to_string(field.height) + " px frames, the cube is " + std::to_string(cube.width()) +
                     " x " + std::to_string(cube.height()));
  InjectionPlan plan;
  plan.params = resolved(params, field.psf);
  plan.tRefMjd = cube.tRefMjd();
  plan.tOffsetS = cube.timeOffsetsS();
  for (const auto& i : cube.info())
    plan.exposureS.push_back(i.exposureS);
  plan.width = cube.width();
  plan.height = cube.height();
  plan.psf = field.psf;
  plan.psfMeasured = field.psfMeasured;
  plan.stampRadiusPx = stampRadiusPx(plan.psf, plan.params.lostFluxFraction);
  const std::vector<double> times = trackTimes(plan);
  const double tFirst = *std::min_element(times.begin(), times.end());
  const double tLast = *std::max_element(times.begin(), times.end());
  double meanExposure = 0.0;
  for (const double e : plan.exposureS)
    meanExposure += e / static_cast<double>(plan.exposureS.size());
  const InjectParams& p = plan.params;
  sim::Rng rng(sim::streamSeed(p.seed, 0));
  for (int id = 1; id <= p.count; ++id) {
    cancel.throwIfCancelled();
    const double speed = p.rateMinPxS + (p.rateMaxPxS - p.rateMinPxS) * sim::uniform01(rng);
    const double angle = 2.0 * M_PI * sim::uniform01(rng);
    const double snr = p.snrMin + (p.snrMax - p.snrMin) * sim::uniform01(rng);
    bool placed = false;
    for (int attempt = 0; attempt < p.triesPerObject && !placed; ++attempt) {
      Track tr{(plan.width - 1) * sim::uniform01(rng), (plan.height - 1) * sim::uniform01(rng),
               speed * std::cos(angle), speed * std::sin(angle)};
      const double clearance = trackClearance(tr, plan, field, tFirst, tLast);
      if (clearance < p.minStarDistancePx || !separated(tr, plan.objects, times, p.minSeparationPx)) continue;
      InjectedObject o;
      o.stamps = stampsOf(tr, plan);
      try {
        o.frameNoise = localFrameNoise(cube, field.mask, noiseRegion(o.stamps));
      } catch (const InputError&) {
        continue;  // too few usable pixels around: somewhere else
      }
      o.id = id;
      o.xPx = tr.x;
      o.yPx = tr.y;
      o.vxPxS = tr.vx;
      o.vyPxS = tr.vy;
      o.expectedSnr = snr;
      o.flux = fluxForSnr(snr, trackInformation(o.stamps, o.frameNoise));
      o.minMaskDistancePx = clearance;
      if (p.zeroPointMag) o.magnitude = magnitudeOf(o.flux, meanExposure, *p.zeroPointMag);
      plan.objects.push_back(std::move(o));
      placed = true;
    }
    if (!placed)
      throw InputError("inject: placed " + std::to_string(plan.objects.size()) + " of " + std::to_string(p.count) +
                       " movers; no room for more " + std::to_string(p.minStarDistancePx) +
                       " px from stars, " + std::to_string(p.edgeMarginPx) + " px from the edges and " +
                       std::to_string(p.minSeparationPx) +
                       " px from each other (lower --n, --min-star-distance or the rates)");
  }
  return plan;
}

RawGeometry rawGeometry(const FrameCube& raw, const calib::MasterCalibration& masters,
                        const calib::CalibParams& params) {
  RawGeometry g;
  g.width = raw.width();
  g.height = raw.height();
  std::optional<io::PixelRegion> trim;
  if (!masters.bias.empty()) {
    trim = masters.trimSec;
  } else {
    trim = params.trimSec ? params.trimSec : io::sectionFromHeader(raw.header, "TRIMSEC");
  }
  if (trim && params.trim) {
    calib::checkSectionInside(*trim, raw.width(), raw.height(), "TRIMSEC");
    g.offsetX = trim->x0;
    g.offsetY = trim->y0;
  }
  g.flat = masters.flat;
  g.integerCounts = raw.header.getDouble("BITPIX").value_or(-32.0) > 0.0;
  const double em = raw.header.getDouble("EMGAIN").value_or(1.0);
  g.emGain = em > 1.0 && std::isfinite(em) ? em : 1.0;
  return g;
}

Image rawSignal(const InjectionPlan& plan, std::size_t frame, const RawGeometry& g) {
  Image signal(g.width, g.height, 0.0f);
  std::vector<double> expected(signal.size(), 0.0);
  for (const auto& o : plan.objects) {
    const Stamp& s = o.stamps.at(frame);
    for (int y = 0; y < s.height; ++y)
      for (int x = 0; x < s.width; ++x) {
        const int cx = s.x0 + x, cy = s.y0 + y;
        if (cx < 0 || cy < 0 || cx >= plan.width || cy >= plan.height) continue;  // trimmed away
        const int rx = cx + g.offsetX, ry = cy + g.offsetY;
        if (rx < 0 || ry < 0 || rx >= g.width || ry >= g.height) continue;
        const std::size_t i = static_cast<std::size_t>(ry) * g.width + rx;
        const double flat = g.flat.empty() ? 1.0 : g.flat.pixels[i];
        expected[i] += o.flux * s.at(x, y) * flat;
      }
  }
  sim::Rng rng(sim::streamSeed(plan.params.seed, 1 + frame));
  for (std::size_t i = 0; i < expected.size(); ++i) {
    if (!(expected[i] > 0.0)) continue;
    double v = expected[i];
    if (g.gainEPerAdu > 0.0 && g.emGain > 1.0) {
      const std::int64_t photoelectrons = sim::poisson(rng, expected[i] * g.gainEPerAdu / g.emGain);
      v = sim::emRegister(rng, photoelectrons, g.emGain) / g.gainEPerAdu;
    } else if (g.gainEPerAdu > 0.0) {
      v = static_cast<double>(sim::poisson(rng, expected[i] * g.gainEPerAdu)) / g.gainEPerAdu;
    }
    if (g.integerCounts) {
      const double whole = std::floor(v);
      v = whole + (sim::uniform01(rng) < v - whole ? 1.0 : 0.0);
    }
    signal.pixels[i] = static_cast<float>(v);
  }
  return signal;
}

void addToCube(FrameCube& raw, const InjectionPlan& plan, const RawGeometry& g) {
  if (raw.width() != g.width || raw.height() != g.height || raw.frameCount() != plan.tOffsetS.size())
    throw InputError("inject: the cube does not match the plan's raw geometry");
  for (std::size_t n = 0; n < raw.frameCount(); ++n) {
    const Image s = rawSignal(plan, n, g);
    float* f = raw.frame(n);
    for (std::size_t i = 0; i < s.size(); ++i)
      f[i] += s.pixels[i];
  }
}

std::string injectedFileName(const std::string& input) {
  std::string name = std::filesystem::path(input).filename().string();
  for (const char* suffix : {".fz", ".gz"}) {
    const std::string s = suffix;
    if (name.size() > s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0) {
      name.erase(name.size() - s.size());
      break;
    }
  }
  auto endsWith = [&](const std::string& s) {
    return name.size() >= s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0;
  };
  if (!endsWith(".fits") && !endsWith(".fit") && !endsWith(".fts")) name += ".fits";
  return name;
}

}  // namespace st::inject
