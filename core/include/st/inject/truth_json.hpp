#pragma once
// The truth file of an injection (DIR/truth.json) and its reading back by `recovery`. Units in the keys
// (ARCHITECTURE.md): positions x_px, y_px are 0-based pixels of the calibrated (trimmed) frame at t_ref,
// velocities vx_px_s, vy_px_s in the frames, flux in calibrated counts per frame.
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "st/inject/injection.hpp"

namespace st::inject {

/// What the truth file records beside the plan (the CLI knows these).
struct TruthMeta {
  std::vector<std::string> biasFiles;
  std::vector<std::string> flatFiles;
  std::string gainSource;                      ///< e.g. "GAIN keyword" or "--gain"
  std::optional<double> plateScaleArcsecPerPx; ///< for rates in deg/day
  std::string rateUnit = "px-s";               ///< the unit the rates were asked in ("px-s" or "deg-day")
  double rateMinAsked = 0.0;                   ///< the rates as asked, in rateUnit
  double rateMaxAsked = 0.0;
};

/// The truth JSON of an injection run: format/version, software, seed, t_ref_mjd, frames, frame size, raw
/// offset, input/output/bias/flat files, gain, plate scale, zero point (null when unknown), the PSF used
/// (moffat fwhm_px, beta, radius_px, source measured|given, per-frame FWHMs, stamp radius), the placement
/// distances, the request, and "objects": id, x_px, y_px, vx_px_s, vy_px_s, rate_px_s, rate_deg_day (null
/// without a plate scale), flux, expected_snr, magnitude (null without a zero point), frame_noise (sigma_n,
/// calibrated counts), min_star_distance_px.
nlohmann::json truthToJson(const InjectionRun& run, const TruthMeta& meta);

/// One object of a truth file, as `recovery` needs it.
struct TruthObject {
  int id = 0;
  double xPx = 0.0;
  double yPx = 0.0;
  double vxPxS = 0.0;
  double vyPxS = 0.0;
  double flux = 0.0;
  double expectedSnr = 0.0;
  std::optional<double> magnitude;
};

struct Truth {
  std::optional<double> tRefMjd;  ///< absent in hand-made files: positions are then taken as at the search's t_ref
  std::vector<TruthObject> objects;
};

/// Reads a truth JSON (truthToJson's, or a hand-made one with at least "objects" holding id, x_px, y_px,
/// vx_px_s, vy_px_s, expected_snr). Throws st::InputError naming the key at fault.
Truth truthFromJson(const nlohmann::json& json);

}  // namespace st::inject
