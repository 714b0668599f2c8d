#include "st/candidate/candidate_measurement.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>

#include "st/common/error.hpp"
#include "st/search/sidelobes.hpp"
#include "st/search/sky_motion.hpp"

namespace st::candidate {
namespace {

constexpr std::pair<Label, const char*> kLabels[] = {{Label::Unvetted, "unvetted"},
                                                     {Label::Real, "real"},
                                                     {Label::Artifact, "artifact"},
                                                     {Label::Unsure, "unsure"}};
constexpr std::pair<ArtifactReason, const char*> kReasons[] = {
    {ArtifactReason::None, ""},
    {ArtifactReason::ChargeLeakage, "charge_leakage"},
    {ArtifactReason::Diffraction, "diffraction"},
    {ArtifactReason::CosmicRay, "cosmic_ray"},
    {ArtifactReason::Ghost, "ghost"},
    {ArtifactReason::Other, "other"}};

}  // namespace

const char* toString(Label label) noexcept {
  for (const auto& [l, s] : kLabels)
    if (l == label) return s;
  return "unvetted";
}
const char* toString(ArtifactReason reason) noexcept {
  for (const auto& [r, s] : kReasons)
    if (r == reason) return s;
  return "";
}
Label labelFromString(const std::string& text) {
  for (const auto& [l, s] : kLabels)
    if (text == s) return l;
  throw InputError("unknown vetting label '" + text + "' (unvetted, real, artifact, unsure)");
}
ArtifactReason reasonFromString(const std::string& text) {
  for (const auto& [r, s] : kReasons)
    if (text == s) return r;
  throw InputError("unknown artifact reason '" + text +
                   "' (charge_leakage, diffraction, cosmic_ray, ghost, other)");
}

const char* labelColour(Label label) noexcept {
  switch (label) {
    case Label::Real:
      return "green";
    case Label::Artifact:
      return "red";
    case Label::Unsure:
      return "yellow";
    case Label::Unvetted:
      break;
  }
  return "cyan";
}

bool operator==(const SearchMeasurement& a, const SearchMeasurement& b) noexcept {
  const search::Candidate &p = a.cell, &q = b.cell;
  return p.x == q.x && p.y == q.y && p.v == q.v && p.ivx == q.ivx && p.ivy == q.ivy && p.sum == q.sum &&
         p.nIn == q.nIn && p.snr == q.snr && p.fap == q.fap && p.clusterCells == q.clusterCells &&
         a.flags == b.flags && a.rateDegPerDay == b.rateDegPerDay && a.paDeg == b.paDeg;
}

vet::Track CandidateMeasurement::track() const noexcept {
  if (fitted()) return {fit->x, fit->y, fit->v};
  return {static_cast<double>(search.cell.x), static_cast<double>(search.cell.y), search.cell.v};
}

double CandidateMeasurement::snr() const noexcept {
  return fitted() ? fit->snr : search.cell.snr;
}

const SkyPosition* CandidateMeasurement::sky() const noexcept {
  return fitted() && fit->sky ? &*fit->sky : nullptr;
}

FitSummary summarize(const fit::FitResult& f) {
  FitSummary s;
  s.status = f.status;
  s.message = f.message;
  s.iterations = f.iterations;
  s.x = f.params.xc;
  s.y = f.params.yc;
  s.v = f.params.v;
  s.sigma = {f.sigmaNoiseModel[fit::kXc], f.sigmaNoiseModel[fit::kYc], f.sigmaNoiseModel[fit::kVx],
             f.sigmaNoiseModel[fit::kVy], f.sigmaPosPaper,              f.sigmaVelPaper};
  s.photonsPerFrame = f.photonsPerFrame;
  s.snr = f.snr;
  return s;
}

std::vector<char> crossesBrighter(const search::FilteredCube& cube, const search::VelocityGrid& grid,
                                  const std::vector<search::Candidate>& all) {
  constexpr double kBrighter = 10.0;  // SNR ratio
  std::vector<char> out(all.size(), 0);
  // The frames' span, read once, and only when a pair needs it (a cube without frames has no times).
  std::optional<std::pair<double, double>> span;
  const auto spanOfFrames = [&] {
    if (!span) {
      const auto dt = cube.frames.timeOffsetsS();
      const auto [t0, t1] = std::minmax_element(dt.begin(), dt.end());
      span = dt.empty() ? std::pair{0.0, 0.0} : std::pair{*t0, *t1};
    }
    return *span;
  };
  const double reach = 2.0 * (cube.psfFwhmPx > 0.0 ? cube.psfFwhmPx : 3.0);
  for (std::size_t i = 0; i < all.size(); ++i)
    for (const search::Candidate& b : all) {
      const search::Candidate& c = all[i];
      if (!(b.snr >= kBrighter * c.snr)) continue;
      if (std::hypot(b.v.vx - c.v.vx, b.v.vy - c.v.vy) <= grid.stepPxS) continue;  // the same motion
      const auto [t0, t1] = spanOfFrames();
      if (search::closestApproach(c, b, t0, t1) <= reach) {
        out[i] = 1;
        break;
      }
    }
  return out;
}

SearchMeasurement measureSearch(const search::FilteredCube& cube, const search::VelocityGrid& grid,
                                const search::Candidate& c, bool crossingBrighter) {
  SearchMeasurement m;
  m.cell = c;
  const Velocity onSky{c.v.vx - cube.skyRate.vx, c.v.vy - cube.skyRate.vy};
  // Within one grid step of the stars' motion: a static source that pre-processing did not remove.
  if (std::abs(onSky.vx) <= grid.stepPxS && std::abs(onSky.vy) <= grid.stepPxS) m.flags.push_back("at_sky_rate");
  // Fewer frames than the cube has: the track leaves the frame (edge of the field).
  if (static_cast<std::size_t>(c.nIn) < cube.frames.frameCount()) m.flags.push_back("partial");
  if (crossingBrighter) m.flags.push_back("crosses_brighter");
  const search::SkyMotion motion = search::skyMotion(cube.frames, c.x, c.y, onSky);
  m.rateDegPerDay = motion.rateDegPerDay;
  m.paDeg = motion.paDeg;
  return m;
}

}  // namespace st::candidate
