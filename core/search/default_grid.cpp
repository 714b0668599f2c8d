#include "st/search/default_grid.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "st/common/error.hpp"
#include "st/common/units.hpp"

namespace st::search {
namespace {

void require(bool ok, const char* what, double value) {
  if (ok) return;
  char msg[160];
  std::snprintf(msg, sizeof msg, "default velocity grid: %s must be positive, got %g", what, value);
  throw InputError(msg);
}

/// Half-steps needed to cover `limitPxS` (as makeVelocityGrid rounds: ceil, so the grid covers it).
int stepsCovering(double limitPxS, double step) {
  const double k = std::ceil(limitPxS / step - 1e-9);
  return k > 1e6 ? 1'000'000 : static_cast<int>(std::max(0.0, k));
}

double exactSecondsFor(const DefaultGridInput& in, int halfSteps) {
  const double n = 2.0 * halfSteps + 1.0;
  MethodEstimate e;
  e.width = in.width;
  e.exactAdditions = static_cast<double>(in.width) * in.height * static_cast<double>(in.frames) * n * n;
  priceMethods(e, in.model);
  return e.exactSeconds;
}

}  // namespace

DefaultGrid defaultVelocityGrid(const DefaultGridInput& in) {
  require(in.width > 0, "width", in.width);
  require(in.height > 0, "height", in.height);
  require(in.frames > 0, "frame count", static_cast<double>(in.frames));
  require(in.timeSpanS > 0.0 && std::isfinite(in.timeSpanS), "time span (s)", in.timeSpanS);
  require(in.stepPx > 0.0, "step (px over the span)", in.stepPx);
  require(in.budgetS > 0.0, "time budget (s)", in.budgetS);
  require(in.model.exactAdditionsPerS > 0.0, "backend throughput (additions/s)", in.model.exactAdditionsPerS);
  require(in.minFrameFraction > 0.0, "minimum frame fraction", in.minFrameFraction);
  DefaultGrid g;
  const double step = in.stepPx / in.timeSpanS;
  g.paperLimitPxS = in.plateScaleArcsecPerPx && *in.plateScaleArcsecPerPx > 0.0
                        ? degPerDayToPxPerSec(in.paperHalfRangeDegPerDay, *in.plateScaleArcsecPerPx)
                        : in.paperHalfRangeDegPerDay * step;  // 12 steps, as synthtrack-cli search
  g.frameLimitPxS = std::max(in.width, in.height) / (std::min(1.0, in.minFrameFraction) * in.timeSpanS);
  // Largest k with exactSeconds((2k+1)^2 velocities) <= budget: closed form, then checked against the pricing
  // (its width efficiency and rounding) by stepping down.
  const double perVelocity = exactSecondsFor(in, 0) - in.model.exactFixedS;
  const double room = (in.budgetS - in.model.exactFixedS) / std::max(perVelocity, 1e-300);
  int kBudget = room >= 9.0 ? static_cast<int>(std::floor((std::sqrt(room) - 1.0) / 2.0)) : 1;
  kBudget = std::clamp(kBudget, 1, 1'000'000);
  while (kBudget > 1 && exactSecondsFor(in, kBudget) > in.budgetS) --kBudget;
  g.budgetLimitPxS = kBudget * step;

  const int kPaper = std::max(1, stepsCovering(g.paperLimitPxS, step));
  const int kFrame = std::max(1, stepsCovering(g.frameLimitPxS, step));
  g.halfSteps = kPaper;
  g.limit = DefaultGridLimit::Paper;
  if (kFrame < g.halfSteps) {
    g.halfSteps = kFrame;
    g.limit = DefaultGridLimit::Frame;
  }
  if (kBudget < g.halfSteps) {
    g.halfSteps = kBudget;
    g.limit = DefaultGridLimit::Budget;
  }
  g.halfRangePxS = g.halfSteps * step;
  g.stepPx = in.stepPx;
  g.grid.centre = in.centre;
  g.grid.stepPxS = step;
  g.grid.nvx = g.grid.nvy = 2 * g.halfSteps + 1;
  g.exactSeconds = exactSecondsFor(in, g.halfSteps);
  return g;
}

std::string describeDefaultGrid(const DefaultGrid& g, std::optional<double> plateScale) {
  const bool angular = plateScale && *plateScale > 0.0;
  auto speed = [&](double pxS) {
    char s[48];
    if (angular)
      std::snprintf(s, sizeof s, "±%.3g deg/day", pxPerSecToDegPerDay(pxS, *plateScale));
    else
      std::snprintf(s, sizeof s, "±%.3g px/s", pxS);
    return std::string(s);
  };
  const char* why = g.limit == DefaultGridLimit::Budget  ? "limited by the ~1 min time budget"
                    : g.limit == DefaultGridLimit::Frame ? "limited by what can stay in the frame"
                                                         : "the paper's range";
  char line[400];
  std::snprintf(line, sizeof line,
                "%s in %.3g px steps over the span (%d × %d velocities, about %.0f s exact on this backend): %s "
                "(the frame allows %s, the paper %s%s)",
                speed(g.halfRangePxS).c_str(), g.stepPx, g.grid.nvx, g.grid.nvy, g.exactSeconds, why,
                speed(g.frameLimitPxS).c_str(), speed(g.paperLimitPxS).c_str(),
                angular ? "" : ", 12 steps without a plate scale");
  return line;
}

}  // namespace st::search
