#include "fit_service.hpp"

#include <chrono>
#include <cmath>

#include "candidate_fit.hpp"
#include "st/common/error.hpp"
#include "st/fit/pixel_psf.hpp"

namespace st::app {

Image residualAlongTrack(const FrameCube& frames, const fit::FitParams& p, const psf::Moffat& psf, int half) {
  const int side = 2 * half + 1;
  Image out(side, side, 0.0f);
  const fit::PixelPsfTable table(psf, 1.5 * half + 2.0);
  const std::vector<double> times = frames.timeOffsetsS();
  for (std::size_t n = 0; n < frames.frameCount(); ++n) {
    const double px = p.xc + p.v.vx * times[n];
    const double py = p.yc + p.v.vy * times[n];
    const int ox = static_cast<int>(std::lround(px)) - half;
    const int oy = static_cast<int>(std::lround(py)) - half;
    const float* img = frames.frame(n);
    for (int sy = 0; sy < side; ++sy) {
      const int y = oy + sy;
      if (y < 0 || y >= frames.height()) continue;
      for (int sx = 0; sx < side; ++sx) {
        const int x = ox + sx;
        if (x < 0 || x >= frames.width() || frames.isMasked(n, x, y)) continue;
        const double d = img[static_cast<std::size_t>(y) * frames.width() + x];
        if (!std::isfinite(d)) continue;
        out.at(sx, sy) += static_cast<float>(d - (p.alpha * table.value(x - px, y - py) + p.i0));
      }
    }
  }
  return out;
}

ui::FitOutcome fitCandidate(const ui::PreparedView& prepared, const search::Candidate& candidate,
                            CancelToken& cancel, const ui::FitStepCallback& onStep) {
  if (!prepared.unfiltered || prepared.unfiltered->frames.empty() || !prepared.products)
    throw InputError("co-moving fit: pre-processing kept no unfiltered frames or PSF (run it again)");
  const FrameCube& frames = prepared.unfiltered->frames;
  const pipeline::Prepared& products = *prepared.products;
  const double gain = frames.header.getDouble("GAIN").value_or(1.0);
  const int half = fit::defaultStampHalfSize(products.psf);
  using Clock = std::chrono::steady_clock;
  auto last = Clock::now() - std::chrono::hours(1);
  const fit::IterationCallback onIteration = [&](const fit::FitIteration& it) {
    if (!onStep) return;
    ui::FitStep step{it, nullptr};
    const auto now = Clock::now();
    if (now - last >= std::chrono::milliseconds(kResidualIntervalMs) && std::isfinite(it.params.alpha)) {
      step.residual =
          std::make_shared<const Image>(residualAlongTrack(frames, it.params, products.psf, half));
      last = now;
    }
    onStep(step);
  };
  ui::FitOutcome out;
  out.json = fitCandidateJson(frames, products, candidate, gain, cancel, onIteration, &out.result);
  return out;
}

}  // namespace st::app
