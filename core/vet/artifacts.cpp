#include "st/vet/artifacts.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <numbers>

#include "st/common/error.hpp"

namespace st::vet {
namespace {

std::string format(const char* fmt, auto... args) {
  char buf[512];
  std::snprintf(buf, sizeof buf, fmt, args...);
  return buf;
}

double percent(std::size_t n, std::size_t total) {
  return total == 0 ? 0.0 : 100.0 * static_cast<double>(n) / static_cast<double>(total);
}

bool isBright(const detect::Star& s, const ArtifactParams& p) {
  return s.saturated || s.snr >= p.brightStarMinSnr;
}

void requireTimes(const ArtifactContext& ctx) {
  if (ctx.timesS.empty()) throw InputError("artifact checks: the context has no frame times");
  if (ctx.frames != nullptr && ctx.frames->frameCount() != ctx.timesS.size()) {
    throw InputError("artifact checks: " + std::to_string(ctx.frames->frameCount()) + " frames but " +
                     std::to_string(ctx.timesS.size()) + " frame times");
  }
}

/// Star position at frame time t (stars move with the sky rate).
double starX(const ArtifactContext& ctx, const detect::Star& s, double t) {
  return s.x + ctx.skyRate.vx * t;
}
double starY(const ArtifactContext& ctx, const detect::Star& s, double t) {
  return s.y + ctx.skyRate.vy * t;
}

}  // namespace

const char* toString(ArtifactKind kind) noexcept {
  switch (kind) {
    case ArtifactKind::ChargeLeakage:
      return "charge_leakage";
    case ArtifactKind::BrightStar:
      return "bright_star";
    case ArtifactKind::Diffraction:
      return "diffraction";
    case ArtifactKind::Edge:
      return "edge";
    case ArtifactKind::Masked:
      return "masked";
    case ArtifactKind::Transient:
      return "transient";
    case ArtifactKind::KnownObject:
      return "known_object";
    case ArtifactKind::StaticSource:
      return "static_source";
  }
  return "unknown";
}

ArtifactContext makeArtifactContext(const FrameCube& frames, std::vector<detect::Star> stars,
                                    Velocity skyRate, double psfFwhmPx) {
  ArtifactContext ctx;
  ctx.width = frames.width();
  ctx.height = frames.height();
  ctx.timesS = frames.timeOffsetsS();
  ctx.stars = std::move(stars);
  ctx.skyRate = skyRate;
  ctx.psfFwhmPx = psfFwhmPx;
  ctx.frames = &frames;
  return ctx;
}

ArtifactFlag checkChargeLeakage(const ArtifactContext& ctx, const Track& track, const ArtifactParams& p) {
  requireTimes(ctx);
  ArtifactFlag flag{ArtifactKind::ChargeLeakage, false, 0.0, "no saturated star in the catalog"};
  const std::size_t n = ctx.timesS.size();
  std::size_t bestCount = 0;
  bool any = false;
  for (const auto& s : ctx.stars) {
    if (!s.saturated) continue;
    std::vector<double> columns{s.x};
    for (int c : s.bleedColumns)
      columns.push_back(c);
    std::size_t onColumn = 0, onRow = 0, onAny = 0;
    for (double t : ctx.timesS) {
      const double tx = track.xAt(t), ty = track.yAt(t);
      bool col = false;
      for (double c : columns)
        col = col || std::abs(tx - (c + ctx.skyRate.vx * t)) <= p.leakageHalfWidthPx;
      const bool row = std::abs(ty - starY(ctx, s, t)) <= p.leakageHalfWidthPx;
      onColumn += col;
      onRow += row;
      onAny += (col || row);
    }
    if (!any || onAny > bestCount) {
      any = true;
      bestCount = onAny;
      const char* where = onColumn >= onRow ? "column (or a bleed column)" : "row";
      flag.value = static_cast<double>(onAny) / static_cast<double>(n);
      flag.evidence = format(
          "on the %s of the saturated star at (%.1f, %.1f) with %zu bleed column(s) in %.0f%% of the frames "
          "(%zu/%zu; threshold %.0f%%, within %.1f px)",
          where, s.x, s.y, s.bleedColumns.size(), percent(onAny, n), onAny, n, 100.0 * p.leakageMinFraction,
          p.leakageHalfWidthPx);
    }
  }
  flag.triggered = any && bestCount > 0 && flag.value >= p.leakageMinFraction;
  return flag;
}

ArtifactFlag checkBrightStar(const ArtifactContext& ctx, const Track& track, const ArtifactParams& p) {
  requireTimes(ctx);
  ArtifactFlag flag{ArtifactKind::BrightStar, false, 0.0, "no bright star in the catalog"};
  double best = 1e300;
  for (const auto& s : ctx.stars) {
    if (!isBright(s, p)) continue;
    const double radius = p.nearStarRadiusFwhm * ctx.psfFwhmPx * (s.saturated ? 2.0 : 1.0);
    double dMin = 1e300;
    for (double t : ctx.timesS) {
      dMin = std::min(dMin, std::hypot(track.xAt(t) - starX(ctx, s, t), track.yAt(t) - starY(ctx, s, t)));
    }
    // Rank stars by how deep inside their radius the track comes.
    if (dMin / radius < best) {
      best = dMin / radius;
      flag.value = dMin;
      flag.triggered = dMin <= radius;
      flag.evidence =
          format("closest approach %.1f px to the %s star at (%.1f, %.1f) (SNR %.0f); radius %.1f px", dMin,
                 s.saturated ? "saturated" : "bright", s.x, s.y, s.snr, radius);
    }
  }
  return flag;
}

ArtifactFlag checkDiffraction(const ArtifactContext& ctx, const Track& track, const ArtifactParams& p) {
  requireTimes(ctx);
  ArtifactFlag flag{ArtifactKind::Diffraction, false, 0.0, "no bright star in the catalog"};
  const std::size_t n = ctx.timesS.size();
  std::size_t bestCount = 0;
  bool any = false;
  for (const auto& s : ctx.stars) {
    if (!isBright(s, p)) continue;
    for (double angle : p.spikeAnglesDeg) {
      const double a = angle * std::numbers::pi / 180.0;
      const double ux = std::cos(a), uy = std::sin(a);
      std::size_t on = 0;
      for (double t : ctx.timesS) {
        const double dx = track.xAt(t) - starX(ctx, s, t), dy = track.yAt(t) - starY(ctx, s, t);
        const double along = std::abs(ux * dx + uy * dy), across = std::abs(-uy * dx + ux * dy);
        on += (along <= p.spikeLengthPx && across <= p.spikeHalfWidthPx);
      }
      if (!any || on > bestCount) {
        any = true;
        bestCount = on;
        flag.value = static_cast<double>(on) / static_cast<double>(n);
        flag.evidence = format(
            "on the %.0f deg spike of the star at (%.1f, %.1f) (SNR %.0f) in %.0f%% of the frames (%zu/%zu; "
            "threshold %.0f%%, within %.1f px of the spike, %.0f px long)",
            angle, s.x, s.y, s.snr, percent(on, n), on, n, 100.0 * p.spikeMinFraction, p.spikeHalfWidthPx,
            p.spikeLengthPx);
      }
    }
  }
  flag.triggered = any && bestCount > 0 && flag.value >= p.spikeMinFraction;
  return flag;
}

ArtifactFlag checkEdge(const ArtifactContext& ctx, const Track& track, const ArtifactParams& p) {
  requireTimes(ctx);
  ArtifactFlag flag{ArtifactKind::Edge, false, 0.0, ""};
  const double margin = p.edgeMarginFwhm * ctx.psfFwhmPx;
  double dMin = 1e300;
  std::size_t outside = 0;
  for (double t : ctx.timesS) {
    const double x = track.xAt(t), y = track.yAt(t);
    const double d = std::min({x + 0.5, y + 0.5, ctx.width - 0.5 - x, ctx.height - 0.5 - y});
    dMin = std::min(dMin, d);
    outside += d < 0.0;
  }
  flag.value = dMin;
  flag.triggered = dMin < margin;
  flag.evidence = outside > 0
                      ? format(
                            "the track is outside the frame in %zu of %zu frames (%.1f px beyond the "
                            "edge at most); margin %.1f px",
                            outside, ctx.timesS.size(), -dMin, margin)
                      : format("closest approach to the frame edge %.1f px; margin %.1f px", dMin, margin);
  return flag;
}

ArtifactFlag checkMasked(const ArtifactContext& ctx, const Track& track, const ArtifactParams& p) {
  requireTimes(ctx);
  ArtifactFlag flag{ArtifactKind::Masked, false, 0.0, "no pixel mask"};
  if (ctx.frames == nullptr || ctx.frames->mask().empty()) return flag;
  const FrameCube& cube = *ctx.frames;
  const double r = std::max(0.5, p.maskRadiusFwhm * ctx.psfFwhmPx);
  const int ir = static_cast<int>(std::ceil(r));
  std::size_t samples = 0, masked = 0;
  for (std::size_t f = 0; f < cube.frameCount(); ++f) {
    const double t = ctx.timesS[f];
    const int cx = static_cast<int>(std::lround(track.xAt(t) + cube.info()[f].offsetXPx)),
              cy = static_cast<int>(std::lround(track.yAt(t) + cube.info()[f].offsetYPx));
    for (int dy = -ir; dy <= ir; ++dy) {
      for (int dx = -ir; dx <= ir; ++dx) {
        const int x = cx + dx, y = cy + dy;
        if (dx * dx + dy * dy > r * r || x < 0 || y < 0 || x >= cube.width() || y >= cube.height()) continue;
        ++samples;
        masked += cube.isMasked(f, x, y);
      }
    }
  }
  flag.value = samples == 0 ? 0.0 : static_cast<double>(masked) / static_cast<double>(samples);
  flag.triggered = samples > 0 && flag.value >= p.maskedMinFraction;
  flag.evidence = format(
      "%.1f%% of the pixels within %.1f px of the track are masked (%zu/%zu over %zu frames; "
      "threshold %.0f%%)",
      100.0 * flag.value, r, masked, samples, cube.frameCount(), 100.0 * p.maskedMinFraction);
  return flag;
}

ArtifactFlag checkTransient(const ArtifactContext& ctx, const Track& track, const ArtifactParams& p,
                            const SegmentReport* segments) {
  requireTimes(ctx);
  ArtifactFlag flag{ArtifactKind::Transient, false, 0.0, "no frames to sample"};
  if (ctx.frames != nullptr) {
    const FrameCube& cube = *ctx.frames;
    std::vector<double> c;
    for (std::size_t f = 0; f < cube.frameCount(); ++f) {
      // The search's own rounding: the IPSA sample of this frame (ARCHITECTURE.md, "IPSA").
      const FrameInfo& fi = cube.info()[f];
      const int x =
          static_cast<int>(std::lround(track.x + std::round(fi.offsetXPx + track.v.vx * ctx.timesS[f])));
      const int y =
          static_cast<int>(std::lround(track.y + std::round(fi.offsetYPx + track.v.vy * ctx.timesS[f])));
      if (x < 0 || y < 0 || x >= cube.width() || y >= cube.height() || cube.isMasked(f, x, y)) continue;
      c.push_back(cube.frame(f)[static_cast<std::size_t>(y) * cube.width() + x]);
    }
    double sum = 0.0;
    for (double v : c)
      sum += v;
    const std::size_t k =
        std::min<std::size_t>(c.size(), static_cast<std::size_t>(std::max(1, p.transientTopFrames)));
    std::partial_sort(c.begin(), c.begin() + static_cast<std::ptrdiff_t>(k), c.end(), std::greater<>());
    double top = 0.0;
    for (std::size_t i = 0; i < k; ++i)
      top += c[i];
    if (c.empty()) {
      flag.evidence = "the track has no unmasked sample inside the frames";
    } else if (!(sum > 0.0)) {
      flag.value = 1.0;
      flag.triggered = true;
      flag.evidence = format("the track's sum over %zu frames is not positive (%.3g)", c.size(), sum);
    } else {
      flag.value = top / sum;
      flag.triggered = flag.value >= p.transientMaxShare;
      flag.evidence = format(
          "the %zu largest single-frame samples carry %.0f%% of the track's sum over %zu frames "
          "(threshold %.0f%%)",
          k, 100.0 * flag.value, c.size(), 100.0 * p.transientMaxShare);
    }
  }
  if (segments != nullptr && (segments->missingSignal || segments->fluxInconsistent)) {
    flag.triggered = true;
    for (const auto& r : segments->reasons)
      flag.evidence += "; segments: " + r;
  }
  return flag;
}

std::vector<ArtifactFlag> checkArtifacts(const ArtifactContext& ctx, const Track& track,
                                         const ArtifactParams& params, const SegmentReport* segments) {
  return {checkChargeLeakage(ctx, track, params), checkBrightStar(ctx, track, params),
          checkDiffraction(ctx, track, params),   checkEdge(ctx, track, params),
          checkMasked(ctx, track, params),        checkTransient(ctx, track, params, segments)};
}

ArtifactFlag staticSourceFlag(double trackSnr, double skySnr, double maxRatio) {
  ArtifactFlag f{ArtifactKind::StaticSource, false, 0.0, ""};
  char buf[200];
  if (!(trackSnr > 0.0)) {
    f.evidence = "no SNR at the candidate's velocity";
    return f;
  }
  f.value = skySnr / trackSnr;
  f.triggered = f.value >= maxRatio;
  std::snprintf(buf, sizeof buf, "SNR %.1f stacked at the sky rate against %.1f at its own velocity (%.0f%%; %s %.0f%%)",
                skySnr, trackSnr, 100.0 * f.value, f.triggered ? "a static source reaches" : "threshold",
                100.0 * maxRatio);
  f.evidence = buf;
  return f;
}

}  // namespace st::vet
