#include "st/pipeline/demo_search.hpp"

#include "st/search/demo_grid.hpp"

namespace st::pipeline {

search::GridSpec demoGridSpec(std::optional<double> plateScaleArcsecPerPx) {
  search::GridSpec spec;
  spec.halfRange = search::kDemoHalfRangeDegPerDay;
  spec.unit = search::VelocityUnit::DegPerDay;
  spec.plateScaleArcsecPerPx = plateScaleArcsecPerPx;
  spec.stepRule = search::StepRule::PixelsOverSpan;
  spec.stepPx = search::kDemoGridStepPx;
  return spec;
}

search::SearchParams demoSearchParams() {
  search::SearchParams params;
  params.method = search::SearchMethod::Auto;
  return params;
}

}  // namespace st::pipeline
