#include "st/pipeline/demo_search.hpp"

#include "st/sim/simulator.hpp"

namespace st::pipeline {

search::GridSpec demoGridSpec(std::optional<double> plateScaleArcsecPerPx) {
  search::GridSpec spec;
  spec.halfRange = sim::kDemoHalfRangeDegPerDay;
  spec.unit = search::VelocityUnit::DegPerDay;
  spec.plateScaleArcsecPerPx = plateScaleArcsecPerPx;
  spec.stepRule = search::StepRule::PixelsOverSpan;
  spec.stepPx = sim::kDemoGridStepPx;
  return spec;
}

search::SearchParams demoSearchParams() {
  search::SearchParams params;
  params.method = "auto";
  return params;
}

}  // namespace st::pipeline
