#pragma once
// Artifact checks of a candidate (issue 8, ARCHITECTURE.md "vetting"): each check follows the candidate's
// track over the frames (x + vx (t_n - t_ref), y + vy (t_n - t_ref)), not only its position at t_ref, and
// returns its evidence — a number and a sentence — whether it fires or not, so a person can judge.
//   charge leakage   on the column or row of a saturated star, or on one of its bleed columns
//   bright star      within a radius of a bright star (which moves with the sky rate)
//   diffraction      on a diffraction spike of a bright star (angles a parameter; detector axes by default)
//   edge             close to (or beyond) the frame edge
//   masked           on masked pixels (FrameCube::mask) along the track
//   transient        signal carried by a few frames (top-k share of the track's sum, or the segment flags)
//   known object     a catalogued object at the candidate's sky position (known_objects.hpp)
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/units.hpp"
#include "st/detect/static_sources.hpp"
#include "st/vet/segments.hpp"

namespace st::vet {

enum class ArtifactKind {
  ChargeLeakage,
  BrightStar,
  Diffraction,
  Edge,
  Masked,
  Transient,
  KnownObject,
  StaticSource  ///< as bright at the sky rate as at its own velocity (staticSourceFlag)
};
/// Stable lower-case key ("charge_leakage", "bright_star", ...), used in JSON.
[[nodiscard]] const char* toString(ArtifactKind kind) noexcept;

/// One check and its evidence.
struct ArtifactFlag {
  ArtifactKind kind = ArtifactKind::Edge;
  bool triggered = false;
  double value = 0.0;    ///< the measured number the decision is made on (its unit is in `evidence`)
  std::string evidence;  ///< one sentence, e.g. "on bleed column 212 of the saturated star at (212.0, 80.4)
                         ///< in 96% of the frames (480/500)"
  friend bool operator==(const ArtifactFlag&, const ArtifactFlag&) = default;
};

/// A straight track: 0-based pixel position at t_ref and velocity in the frames (px/s).
struct Track {
  double x = 0.0;
  double y = 0.0;
  Velocity v;
  [[nodiscard]] double xAt(double tS) const noexcept { return x + v.vx * tS; }
  [[nodiscard]] double yAt(double tS) const noexcept { return y + v.vy * tS; }
};

struct ArtifactParams {
  /// Charge leakage: the track is "on" a saturated star's column/row/bleed column within this distance (px).
  double leakageHalfWidthPx = 1.5;
  /// ... in at least this fraction of the frames.
  double leakageMinFraction = 0.25;
  /// A bright star: catalog SNR at or above this, or saturated.
  double brightStarMinSnr = 50.0;
  /// Near a bright star: closer than this many PSF FWHM at some frame (doubled for a saturated star).
  double nearStarRadiusFwhm = 4.0;
  /// Diffraction spikes: angles in degrees from the +x axis towards +y (0 and 90: along the detector axes,
  /// as the simulator draws them; each spike is a line through the star, both directions).
  std::vector<double> spikeAnglesDeg = {0.0, 90.0};
  double spikeHalfWidthPx = 2.0;   ///< distance from the spike's line
  double spikeLengthPx = 60.0;     ///< extent from the star's centre along the spike
  double spikeMinFraction = 0.25;  ///< fraction of frames on a spike
  /// Edge: closer than this many PSF FWHM to the frame's border at some frame (or outside it).
  double edgeMarginFwhm = 2.0;
  /// Masked: a disc of this many FWHM around the track is sampled in every frame; fires when the masked
  /// fraction of those samples is at or above maskedMinFraction.
  double maskRadiusFwhm = 1.0;
  double maskedMinFraction = 0.1;
  /// Transient: share of the track's sum carried by its `transientTopFrames` largest single-frame samples.
  /// For a steady source of SNR s over N frames the share is about k (s/sqrt(N) + 3) / (s sqrt(N)), a few
  /// per cent for the paper's numbers; a cosmic ray or a flash carries most of the sum.
  int transientTopFrames = 3;
  double transientMaxShare = 0.5;
};

/// What the checks know about the observation.
struct ArtifactContext {
  int width = 0;
  int height = 0;
  std::vector<double> timesS;       ///< t_n - t_ref, seconds (FrameCube::timeOffsetsS)
  std::vector<detect::Star> stars;  ///< positions at t_ref (Prepared::stars)
  Velocity skyRate;                 ///< px/s, the stars' motion in the frames
  double psfFwhmPx = 3.0;
  /// Frames sampled for the mask and transient checks (may be null: those checks then do not fire and say
  /// so). Pass Prepared::filtered.frames to sample the search statistic's own summands, or Prepared::frames.
  const FrameCube* frames = nullptr;
};

/// Builds the context from a cube (size, times) and the pre-processing's catalog.
[[nodiscard]] ArtifactContext makeArtifactContext(const FrameCube& frames, std::vector<detect::Star> stars,
                                                  Velocity skyRate, double psfFwhmPx);

/// Each check throws st::InputError when ctx has no frame times, or frames whose count differs from them.
[[nodiscard]] ArtifactFlag checkChargeLeakage(const ArtifactContext& ctx, const Track& track,
                                              const ArtifactParams& params);
[[nodiscard]] ArtifactFlag checkBrightStar(const ArtifactContext& ctx, const Track& track,
                                           const ArtifactParams& params);
[[nodiscard]] ArtifactFlag checkDiffraction(const ArtifactContext& ctx, const Track& track,
                                            const ArtifactParams& params);
[[nodiscard]] ArtifactFlag checkEdge(const ArtifactContext& ctx, const Track& track,
                                     const ArtifactParams& params);
[[nodiscard]] ArtifactFlag checkMasked(const ArtifactContext& ctx, const Track& track,
                                       const ArtifactParams& params);
/// `segments` (may be null): the segment report of the candidate's fit; its missing-signal and
/// flux-inconsistency flags also fire this check, with their reasons in the evidence.
[[nodiscard]] ArtifactFlag checkTransient(const ArtifactContext& ctx, const Track& track,
                                          const ArtifactParams& params, const SegmentReport* segments);

/// The static-source check (issue 18 §6: a Lowell streak scored SNR 14.6 stacked at the sky rate against 15.3
/// at its own velocity, with every other check "ok"): triggered when the stack at the sky rate reaches
/// `maxRatio` (default 0.8) of the candidate's own SNR, i.e. the source does not need its velocity to be
/// seen. value = skySnr / trackSnr.
[[nodiscard]] ArtifactFlag staticSourceFlag(double trackSnr, double skySnr, double maxRatio = 0.8);

/// Every check above, in the order of ArtifactKind (the known-object check is separate: knownObjectFlag).
[[nodiscard]] std::vector<ArtifactFlag> checkArtifacts(const ArtifactContext& ctx, const Track& track,
                                                       const ArtifactParams& params,
                                                       const SegmentReport* segments = nullptr);

/// Every threshold of `params`, with units in the keys (for the session's parameters).
[[nodiscard]] nlohmann::json toJson(const ArtifactParams& params);

/// {"kind": "charge_leakage", "triggered": true, "value": 0.96, "evidence": "..."}.
[[nodiscard]] nlohmann::json toJson(const ArtifactFlag& flag);

/// A context from the pre-processing's sidecar (pipeline/prepared_json.hpp: width_px, height_px, stars with
/// x_px, y_px, snr, saturated, bleed_columns, sky_rate_px_s {vx, vy}, psf {fwhm_px}) and the frames'
/// mid-times (MJD; t_ref is their mean). No frames: the mask and transient checks say so and do not fire.
/// Throws st::InputError naming the key at fault (`where` names the file).
[[nodiscard]] ArtifactContext artifactContextFromPrepared(const nlohmann::json& prepared,
                                                          const std::vector<double>& mjdMid,
                                                          const std::string& where);

}  // namespace st::vet
