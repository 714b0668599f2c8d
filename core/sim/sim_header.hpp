#pragma once
// Internal to core/sim: the FITS header cards of a simulated cube (real-looking: instrument, times,
// detector, TAN WCS of the first frame) and time formatting.
#include <cstdint>
#include <string>

#include "scene.hpp"
#include "st/common/fits_header.hpp"

namespace st::sim::detail {

/// MJD (UTC) -> "YYYY-MM-DDThh:mm:ss.ssssss" (ISO 8601, as FITS DATE-OBS).
std::string mjdToIsoUtc(double mjd);

FitsHeader simHeader(const SimParams& params, std::uint64_t seed, const Scene& scene);

}  // namespace st::sim::detail
