#pragma once
// The JSON sidecar of a pre-processed cube (prepared.json next to prepared.fits): noise, background level,
// PSF, sky rate, registration (model, residuals, each frame's measured star-field position and applied
// offset), cosmic-ray and single-frame counts, and the star catalog (positions at t_ref, with RA/Dec when
// the cube has a WCS). Units are in the keys (ARCHITECTURE.md).
#include <string>

#include <nlohmann/json.hpp>

#include "st/pipeline/preprocess.hpp"

namespace st::pipeline {

/// The sidecar as JSON (schema "synthtrack.prepared", version 1).
nlohmann::json preparedToJson(const Prepared& prepared);

/// Writes preparedToJson atomically (temporary file + rename). Throws st::InputError naming the path when it
/// cannot be written.
void writePreparedSidecar(const std::string& path, const Prepared& prepared);

}  // namespace st::pipeline
