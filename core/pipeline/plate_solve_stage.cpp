#include "st/pipeline/plate_solve_stage.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>

#include "st/common/error.hpp"
#include "st/io/wcs.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/stats/sigma_clip.hpp"

namespace st::pipeline {

std::vector<io::XyStar> firstFrameStars(const std::vector<detect::Star>& stars, const FrameCube& cube,
                                        Velocity skyRate) {
  if (cube.empty()) throw InputError("plate solving: the cube has no frames");
  const double dt0 = cube.timeOffsetsS().front();
  const FrameInfo& first = cube.info().front();
  const double dx = skyRate.vx * dt0 + first.offsetXPx, dy = skyRate.vy * dt0 + first.offsetYPx;
  std::vector<io::XyStar> out;
  for (const auto& s : stars) {
    const double x = s.x + dx, y = s.y + dy;
    if (x < -0.5 || y < -0.5 || x > cube.width() - 0.5 || y > cube.height() - 0.5) continue;
    out.push_back(io::XyStar{x, y, s.flux});
  }
  return out;
}

namespace {

/// The centre of a bright star's core: the unweighted mean position of the pixels at or above half its peak
/// (above the median of the box's edge), connected or not, within a (2 kHalf + 1)^2 box. For saturated
/// stars this is the middle of the clipped plateau, which the charge trailed faintly along the serial
/// register (CTI) does not pull as it pulls a flux-weighted centroid.
void coreCentroid(const Image& image, io::XyStar& s) {
  constexpr int kHalf = 12;
  const int cx = static_cast<int>(std::lround(s.x)), cy = static_cast<int>(std::lround(s.y));
  if (cx < kHalf || cy < kHalf || cx >= image.width - kHalf || cy >= image.height - kHalf) return;
  std::vector<float> edge;
  float peak = -std::numeric_limits<float>::infinity();
  for (int dy = -kHalf; dy <= kHalf; ++dy)
    for (int dx = -kHalf; dx <= kHalf; ++dx) {
      const float v = image.at(cx + dx, cy + dy);
      if (std::abs(dx) == kHalf || std::abs(dy) == kHalf) edge.push_back(v);
      if (std::abs(dx) <= 3 && std::abs(dy) <= 3) peak = std::max(peak, v);
    }
  std::nth_element(edge.begin(), edge.begin() + edge.size() / 2, edge.end());
  const double bkg = edge[edge.size() / 2];
  const double half = bkg + 0.5 * (peak - bkg);
  double n = 0.0, sx = 0.0, sy = 0.0;
  for (int dy = -kHalf + 1; dy < kHalf; ++dy)
    for (int dx = -kHalf + 1; dx < kHalf; ++dx)
      if (image.at(cx + dx, cy + dy) >= half) {
        n += 1.0;
        sx += cx + dx;
        sy += cy + dy;
      }
  if (n >= 1.0 && std::hypot(sx / n - s.x, sy / n - s.y) < 3.0) {
    s.x = sx / n;
    s.y = sy / n;
  }
}

}  // namespace

std::vector<io::XyStar> frameStars(const FrameCube& cube, ProgressSink& progress, CancelToken& cancel) {
  if (cube.empty()) throw InputError("plate solving: the cube has no frames");
  FrameCube one(cube.width(), cube.height(), 1);
  std::copy_n(cube.frame(0), cube.framePixels(), one.frame(0));
  if (!cube.mask().empty()) one.mask().assign(cube.mask().begin(), cube.mask().begin() + cube.framePixels());
  one.info().front() = cube.info().front();
  one.info().front().offsetXPx = one.info().front().offsetYPx = 0.0;
  // Sigma-clipped level of unmasked pixels: the scalar background findStaticSources removes before its mesh.
  std::vector<float> values;
  values.reserve(one.framePixels());
  for (std::size_t i = 0; i < one.framePixels(); ++i)
    if (one.mask().empty() || one.mask()[i] == 0) values.push_back(one.frame(0)[i]);
  const stats::ClipStats level = stats::sigmaClipSymmetric(values.data(), values.size(), 3.0);
  detect::StaticSourceParams sp;
  sp.keepMovers = false;  // one frame: nothing to compare thirds of
  sp.subtractStars = false;
  sp.maskWings = false;
  const detect::StaticSources found =
      detect::findStaticSources(one, Velocity{0.0, 0.0}, level.mean, sp, progress, cancel);
  std::vector<io::XyStar> out;
  out.reserve(found.stars.size());
  for (const auto& s : found.stars)
    out.push_back(io::XyStar{s.x, s.y, s.flux});
  std::stable_sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.flux > b.flux; });
  const Image image = one.frameImage(0);
  for (std::size_t i = 0; i < std::min<std::size_t>(out.size(), 50); ++i)
    if (found.stars.size() > 0) coreCentroid(image, out[i]);
  return out;
}

astro::PlateSolution plateSolveCube(FrameCube& cube, const std::vector<io::XyStar>& stars,
                                    astro::PlateSolveParams params, ProgressSink& progress,
                                    CancelToken& cancel) {
  if (!params.scaleArcsecPerPx && cube.plateScaleArcsecPerPx)
    params.scaleArcsecPerPx = cube.plateScaleArcsecPerPx;
  astro::applyHints(params, astro::plateSolveHints(cube.header));
  astro::PlateSolution solution =
      astro::plateSolve(stars, cube.width(), cube.height(), params, progress, cancel);
  cube.wcs = solution.wcs;
  cube.plateScaleArcsecPerPx = solution.scaleArcsecPerPx;
  return solution;
}

astro::PlateSolution plateSolveRawCube(FrameCube& cube, const astro::PlateSolveParams& params,
                                       ProgressSink& progress, CancelToken& cancel) {
  const std::vector<io::XyStar> stars = frameStars(cube, progress, cancel);
  astro::PlateSolution solution = plateSolveCube(cube, stars, params, progress, cancel);
  attachHeaderWcs(cube, solution.wcs, cube.plateScaleArcsecPerPx);
  return solution;
}

void attachHeaderWcs(FrameCube& cube, std::shared_ptr<const Wcs> wcs,
                     std::optional<double> plateScaleArcsecPerPx) {
  if (!wcs) return;
  std::vector<FitsCard> kept;
  for (auto& c : cube.header.cards)
    if (!Wcs::isWcsKeyword(c.key)) kept.push_back(std::move(c));
  cube.header.cards = std::move(kept);
  for (const auto& c : wcs->toHeader().cards)
    cube.header.cards.push_back(c);
  cube.wcs = std::move(wcs);
  cube.plateScaleArcsecPerPx = plateScaleArcsecPerPx;
}

astro::PlateSolution plateSolvePrepared(Prepared& prepared, const astro::PlateSolveParams& params,
                                        ProgressSink& progress, CancelToken& cancel) {
  const std::vector<io::XyStar> stars = firstFrameStars(prepared.stars, prepared.frames, prepared.skyRate);
  astro::PlateSolution solution = plateSolveCube(prepared.frames, stars, params, progress, cancel);
  // The matched-filtered cube has the same pixels: it carries the same WCS (as preprocess copies a header's).
  if (!prepared.filtered.frames.empty()) {
    prepared.filtered.frames.wcs = prepared.frames.wcs;
    prepared.filtered.frames.plateScaleArcsecPerPx = prepared.frames.plateScaleArcsecPerPx;
  }
  prepared.notes.push_back("WCS " + describeSolution(solution));
  return solution;
}

std::string describeSolution(const astro::PlateSolution& s) {
  const std::string index =
      s.index.empty() ? std::string("index not named") : std::filesystem::path(s.index).filename().string();
  char text[200];
  std::snprintf(text, sizeof text, "centre RA %.6f Dec %+.6f deg, %.4f arcsec/px, %zu stars given, %.1f s",
                s.centreRaDeg, s.centreDecDeg, s.scaleArcsecPerPx, s.starsGiven, s.elapsedS);
  return "plate-solved by astrometry.net: " + std::string(text) + " (" + index +
         (s.method.empty() ? std::string{} : ", " + s.method) + ")";
}

}  // namespace st::pipeline
