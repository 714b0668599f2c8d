#pragma once
// Fills st::ui::CoreServices with the real core: st::io::loadFrames, st::sim::simulate(preset "paper-neo"),
// st::pipeline::preprocess, st::psf::fitMoffat + radialProfile, st::Wcs, and the backend factory
// (app/common/backend_factory.hpp, the one place a backend is chosen).
#include "core_services.hpp"

namespace st::app {

/// Seed of the demo observation (the same as `synthtrack-cli simulate --preset paper-neo`'s default).
inline constexpr std::uint64_t kDemoSeed = 1;

ui::CoreServices makeCoreServices();

}  // namespace st::app
