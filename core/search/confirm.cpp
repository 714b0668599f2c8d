#include "st/search/confirm.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "ipsa_kernel.hpp"
#include "st/common/error.hpp"
#include "st/common/units.hpp"
#include "st/search/ipsa.hpp"
#include "st/search/search_run.hpp"
#include "st/stats/false_alarm.hpp"

namespace st::search {

namespace {

void validate(const FilteredCube& cube2, const ConfirmRequest& r) {
  if (!(r.gridStepPxS > 0.0) || !std::isfinite(r.gridStepPxS)) {
    throw InputError("confirmation needs the velocity grid step of the first search, got " +
                     std::to_string(r.gridStepPxS) + " px/s");
  }
  if (!(r.sigmaPosPx >= 0.0) || (r.sigmaVelPxS && !(*r.sigmaVelPxS >= 0.0)) || !(r.nSigma > 0.0)) {
    throw InputError("confirmation: the uncertainties must be >= 0 and the window (in sigmas) > 0");
  }
  if (!std::isfinite(r.x) || !std::isfinite(r.y) || !std::isfinite(r.v.vx) || !std::isfinite(r.v.vy)) {
    throw InputError("confirmation candidate position or velocity is not finite");
  }
  if (cube2.frames.frameCount() < 2) throw InputError("the second cube needs at least 2 frames");
}

}  // namespace

ConfirmResult confirmCandidate(const FilteredCube& cube2, const ConfirmRequest& r, ProgressSink& progress,
                               CancelToken& cancel) {
  validate(cube2, r);
  ConfirmResult out;
  out.tRef2Mjd = cube2.frames.tRefMjd();
  out.dtS = (out.tRef2Mjd - r.tRef1Mjd) * kSecondsPerDay;
  out.predX = r.x + r.v.vx * out.dtS - r.offsetX;
  out.predY = r.y + r.v.vy * out.dtS - r.offsetY;
  const double sigmaV = r.sigmaVelPxS.value_or(r.gridStepPxS);
  out.sigmaPosPx = r.sigmaPosPx + sigmaV * std::abs(out.dtS);
  // Window: +-nSigma sigma around the prediction, at least +-1 PSF FWHM (and 1 px) in position and +-1 grid
  // step in velocity.
  const double halfPos = std::max({r.nSigma * out.sigmaPosPx, cube2.psfFwhmPx, 1.0});
  const int w = cube2.frames.width();
  const int h = cube2.frames.height();
  const int xa = std::max(0, static_cast<int>(std::floor(out.predX - halfPos)));
  const int xb = std::min(w - 1, static_cast<int>(std::ceil(out.predX + halfPos)));
  const int ya = std::max(0, static_cast<int>(std::floor(out.predY - halfPos)));
  const int yb = std::min(h - 1, static_cast<int>(std::ceil(out.predY + halfPos)));
  if (xa > xb || ya > yb) {
    std::ostringstream os;
    os << "predicted position (" << out.predX << ", " << out.predY << ") +- " << halfPos
       << " px lies outside the second cube (" << w << " x " << h << " px)";
    throw InputError(os.str());
  }
  out.x0 = xa;
  out.y0 = ya;
  out.width = xb - xa + 1;
  out.height = yb - ya + 1;
  const int halfSteps = std::max(1, static_cast<int>(std::ceil(r.nSigma * sigmaV / r.gridStepPxS - 1e-9)));
  out.grid = VelocityGrid{r.v, r.gridStepPxS, 2 * halfSteps + 1, 2 * halfSteps + 1};
  out.trials = TrialCounts{out.width, out.height, out.grid.nvx, out.grid.nvy};
  out.snrThreshold =
      stats::snrThresholdForFap(std::min(r.targetFap, 0.5 * out.trials.total()), out.trials.total());
  validateSearchInput(cube2, out.grid, SearchParams{});

  detail::KernelParams kp;
  kp.sigmaF = cube2.sigmaF;
  kp.snrThreshold = out.snrThreshold;
  kp.minFrames = minFramesFor(SearchParams{}, cube2.frames.frameCount());
  kp.maxHits = 1;
  const detail::Roi roi{out.x0, out.y0, out.width, out.height};
  const detail::KernelOutput k = detail::runIpsaKernel(cube2.frames, out.grid, roi, kp, progress, cancel);
  const auto& m = k.map;
  std::size_t bestIv = 0;
  for (std::size_t i = 1; i < m.maxSnr.size(); ++i) {
    if (m.argX[i] >= 0 && (m.argX[bestIv] < 0 || m.maxSnr[i] > m.maxSnr[bestIv])) bestIv = i;
  }
  if (m.argX[bestIv] < 0) throw InputError("no cell of the confirmation window had enough frames in view");
  Candidate& b = out.best;
  b.ivx = static_cast<int>(bestIv % out.grid.nvx);
  b.ivy = static_cast<int>(bestIv / out.grid.nvx);
  b.v = out.grid.at(b.ivx, b.ivy);
  b.x = m.argX[bestIv];
  b.y = m.argY[bestIv];
  const IpsaCell cell = ipsaReference(cube2.frames, cube2.frames.timeOffsetsS(), b.x, b.y, b.v);
  b.sum = cell.sum;
  b.nIn = cell.nIn;
  b.snr = m.maxSnr[bestIv];
  out.snr = b.snr;
  out.fap = stats::confirmationFap(out.snr, out.trials.nx, out.trials.ny, out.trials.nvx, out.trials.nvy);
  b.fap = out.fap;
  out.confirmed = out.snr > out.snrThreshold;
  return out;
}

}  // namespace st::search
