#include "fit_service.hpp"

#include <chrono>
#include <cmath>

#include "st/candidate/candidate_fit.hpp"
#include "st/common/error.hpp"

namespace st::app {

ui::FitOutcome fitCandidate(const ui::PreparedView& prepared, const search::Candidate& candidate,
                            CancelToken& cancel, const ui::FitStepCallback& onStep) {
  if (!prepared.unfiltered || prepared.unfiltered->frames.empty() || !prepared.products)
    throw InputError("co-moving fit: pre-processing kept no unfiltered frames or PSF (run it again)");
  const FrameCube& frames = prepared.unfiltered->frames;
  const pipeline::Prepared& products = *prepared.products;
  const fit::FitOptions stackOptions = candidate::fitOptions(frames, products, candidate);
  using Clock = std::chrono::steady_clock;
  auto last = Clock::now() - std::chrono::hours(1);
  const fit::IterationCallback onIteration = [&](const fit::FitIteration& it) {
    if (!onStep) return;
    ui::FitStep step{it, nullptr};
    const auto now = Clock::now();
    if (now - last >= std::chrono::milliseconds(kResidualIntervalMs) && std::isfinite(it.params.alpha)) {
      step.residual = std::make_shared<const Image>(fit::stacksAt(frames, it.params, stackOptions).residual);
      last = now;
    }
    onStep(step);
  };
  ui::FitOutcome out;
  out.summary = candidate::fitCandidate(frames, products, candidate, cancel, onIteration, &out.result);
  return out;
}

}  // namespace st::app
