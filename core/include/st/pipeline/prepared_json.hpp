#pragma once
// The JSON sidecar of a pre-processed cube (prepared.json next to prepared.fits): noise, background level,
// PSF, sky rate, registration (model, residuals, each frame's measured star-field position and applied
// offset), cosmic-ray and single-frame counts, and the star catalog (positions at t_ref, with RA/Dec when
// the cube has a WCS). Units are in the keys (ARCHITECTURE.md).
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "st/pipeline/prepared_cube.hpp"
#include "st/pipeline/preprocess.hpp"

namespace st::pipeline {

/// The sidecar as JSON (schema "synthtrack.prepared", version 1).
nlohmann::json preparedToJson(const Prepared& prepared);

/// Writes preparedToJson atomically (temporary file + rename). Throws st::InputError naming the path when it
/// cannot be written.
void writePreparedSidecar(const std::string& path, const Prepared& prepared);

/// The moving sources of a sidecar ("moving_sources": the movers the static-source search left out of the
/// per-pixel background, Prepared::movers, each with moving = true); nullopt when `path` does not exist.
/// Throws st::InputError naming the path and the key when it cannot be read or is not such a sidecar.
std::optional<std::vector<detect::MovingSource>> readPreparedMovers(const std::string& path);

/// What the co-moving fit of a zero-biased prepared cube takes of its per-pixel background, as
/// candidate::fitOptions takes it from the Prepared of frames pre-processed in memory.
struct PreparedBackgroundModel {
  stats::PixelBackgroundWindows windows;  ///< preparedBackgroundWindows (prepared_cube.hpp)
  std::string sidecar;                    ///< where the movers were looked for (empty without windows)
  /// The sidecar's movers, left out of the background; nullopt without windows, without a sidecar, or
  /// when it could not be read.
  std::optional<std::vector<detect::MovingSource>> movers;
  std::string sidecarError;  ///< readPreparedMovers' message when the sidecar exists but cannot be read
};

/// The windows of `frames` from `header` (notes in `notes` when none can be used) and, when there are some,
/// the movers of the sidecar beside the cube's file (preparedSidecarPath of cubeSource). Never throws for
/// the sidecar: its error is in sidecarError, for the front end to refuse or warn.
PreparedBackgroundModel readPreparedBackgroundModel(const PreparedHeader& header, const FrameCube& frames,
                                                    std::vector<std::string>& notes);

}  // namespace st::pipeline
