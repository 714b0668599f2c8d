#pragma once
// The candidate's whole life after the search as one typed record (issue 18 §1; STYLE.md "a typed record for
// every result that outlives a function"): what the search measured, the accepted co-moving fit with its
// uncertainties, segment check and sky position, the artifact flags, and the person's label and notes. The
// session (st::session::Session) holds these records; JSON is written and read only by the session file
// (session.cpp) and the report writers (candidate_json.hpp).
#include <optional>
#include <string>
#include <vector>

#include "st/common/units.hpp"
#include "st/fit/comoving_fit.hpp"
#include "st/search/types.hpp"
#include "st/vet/artifacts.hpp"

namespace st::candidate {

/// A person's verdict on a candidate.
enum class Label { Unvetted, Real, Artifact, Unsure };
/// Why a candidate labelled Artifact is one.
enum class ArtifactReason { None, ChargeLeakage, Diffraction, CosmicRay, Ghost, Other };

/// Stable keys: "unvetted", "real", "artifact", "unsure"; "", "charge_leakage", "diffraction", "cosmic_ray",
/// "ghost", "other".
[[nodiscard]] const char* toString(Label label) noexcept;
[[nodiscard]] const char* toString(ArtifactReason reason) noexcept;
/// Throws st::InputError naming the text when it is not one of the keys above.
[[nodiscard]] Label labelFromString(const std::string& text);
[[nodiscard]] ArtifactReason reasonFromString(const std::string& text);

/// The colour of a label on the image, the velocity map and in DS9 regions (DS9 colour names): real green,
/// artifact red, unsure yellow, unvetted cyan.
[[nodiscard]] const char* labelColour(Label label) noexcept;

/// The search's candidate (one velocity-grid cell) with what the report derives from the cube
/// (report::candidateToJson): flags "at_sky_rate" (within one grid step of the stars' motion) and "partial"
/// (the track leaves the frame), and the on-sky rate and position angle when the plate scale is known.
struct SearchMeasurement {
  search::Candidate cell;
  std::vector<std::string> flags;
  std::optional<double> rateDegPerDay;  ///< relative to the stars
  std::optional<double> paDeg;          ///< east of north
  friend bool operator==(const SearchMeasurement& a, const SearchMeasurement& b) noexcept;
};

/// 1-sigma uncertainties of a co-moving fit: the noise model's (FitResult::sigmaNoiseModel) and the paper's
/// closed-form sigma_pos, sigma_vel (eq. sig).
struct FitUncertainty {
  double xPx = 0.0, yPx = 0.0;
  double vxPxS = 0.0, vyPxS = 0.0;
  double posPaperPx = 0.0;
  double velPaperPxS = 0.0;
  friend bool operator==(const FitUncertainty&, const FitUncertainty&) = default;
};

/// One segment's own position (vet::SegmentMeasurement's fit, the velocity held at the whole fit's): an
/// observation at the mean time of the segment's frames, one of the several positions per object that a
/// submission to the MPC needs (report::realDetections).
struct SegmentPosition {
  int segment = 0;                        ///< 1-based segment number
  double mjdUtc = 0.0;                    ///< the mean of the segment's frames' mid-times
  double tOffsetS = 0.0;                  ///< the same, seconds from the cube's t_ref
  double x = 0.0, y = 0.0;                ///< 0-based pixels at that time
  double sigmaXPx = 0.0, sigmaYPx = 0.0;  ///< noise-model errors
  double snr = 0.0;                       ///< the segment fit's detection SNR
  /// ICRS at that time (astro::skyMeasurement through the frames' WCS); absent without a WCS.
  std::optional<double> raDeg, decDeg;
  std::optional<double> sigmaRaArcsec, sigmaDecArcsec;  ///< RA cos Dec and Dec
  friend bool operator==(const SegmentPosition&, const SegmentPosition&) = default;
};

/// The K-segment consistency check of a fit (vet::checkSegments, paper §4.4): whether it flags the
/// candidate, why, each segment's forced SNR; and the fit's tracklet: the positions of its
/// positionSegments equal-time segments (candidate::trackletSegments; the check's own when 4) that are worth
/// submitting (candidate::fitCandidate says which).
struct SegmentSummary {
  bool flagged = false;
  std::vector<std::string> reasons;
  std::vector<double> snr;
  std::vector<SegmentPosition> positions;
  int positionSegments = 0;  ///< the segments the positions are of (0: none were cut)
  friend bool operator==(const SegmentSummary&, const SegmentSummary&) = default;
};

/// The fitted object on the sky at t_ref (astro::skyMeasurement through the frames' WCS).
struct SkyPosition {
  double raDeg = 0.0, decDeg = 0.0;
  double rateDegPerDay = 0.0;  ///< relative to the stars
  double rateArcsecPerMin = 0.0;
  double paDeg = 0.0;  ///< direction of motion, east of north
  friend bool operator==(const SkyPosition&, const SkyPosition&) = default;
};

/// The summary of one co-moving PSF fit that outlives the fit (fitCandidate, candidate_fit.hpp). Positions
/// are at the cube's t_ref, 0-based pixels; velocities in the frames, px/s.
struct FitSummary {
  fit::FitStatus status = fit::FitStatus::Diverged;
  std::string message;  ///< why, when not converged
  int iterations = 0;
  double x = 0.0, y = 0.0;
  Velocity v;
  FitUncertainty sigma;
  double photonsPerFrame = 0.0;
  double snr = 0.0;
  std::optional<SegmentSummary> segments;  ///< absent when sigma_n was unknown
  std::optional<SkyPosition> sky;          ///< absent without a WCS or when the fit failed
  // Values for the submission that other tools may add to a fit (report::realDetections reads them).
  std::optional<double> tRefMjd;  ///< epoch of the position (default: the search's t_ref)
  std::optional<double> sigmaRaArcsec, sigmaDecArcsec;
  std::optional<double> mag;
  std::optional<std::string> band;
  [[nodiscard]] bool converged() const noexcept { return status == fit::FitStatus::Converged; }
  friend bool operator==(const FitSummary&, const FitSummary&) = default;
};

/// Everything known about one candidate after the search.
struct CandidateMeasurement {
  SearchMeasurement search;
  std::optional<FitSummary> fit;             ///< the accepted co-moving fit
  std::vector<vet::ArtifactFlag> artifacts;  ///< artifact checks (and the known-object check), with evidence
  Label label = Label::Unvetted;
  ArtifactReason reason = ArtifactReason::None;  ///< only for Label::Artifact
  std::string note;

  /// True when an accepted fit converged: its position and velocity supersede the search cell's.
  [[nodiscard]] bool fitted() const noexcept { return fit && fit->converged(); }
  /// The best track: the converged fit's, else the search cell's (position at t_ref, px; velocity px/s).
  [[nodiscard]] vet::Track track() const noexcept;
  /// The converged fit's SNR, else the search's.
  [[nodiscard]] double snr() const noexcept;
  /// The converged fit's sky position, when it has one.
  [[nodiscard]] const SkyPosition* sky() const noexcept;
  friend bool operator==(const CandidateMeasurement&, const CandidateMeasurement&) = default;
};

/// The summary of a fit result (no segments or sky position: fitCandidate adds them).
[[nodiscard]] FitSummary summarize(const fit::FitResult& result);

/// Per candidate of a search's list `all`: whether its track meets, within 2 PSF FWHM over the frames'
/// span, the track of a candidate at least 10 times brighter (SNR) at a velocity more than a grid step
/// away. A very bright mover gives such cells from the frames where the two tracks overlap (the known-pair
/// demo's SNR-4000 object: 16 cells of SNR 186-216 around it, whose excess the sidelobe model, the filter's
/// response to a beta-4 Moffat, does not predict); flagged for the person, not dropped: a faint mover may
/// cross a bright one's track.
[[nodiscard]] std::vector<char> crossesBrighter(const search::FilteredCube& cube,
                                                const search::VelocityGrid& grid,
                                                const std::vector<search::Candidate>& all);

/// The search's measurement of candidate `c` of a search on `cube` with `grid`: the flags and the on-sky
/// rate and position angle relative to the stars (search::skyMotion; absent without a plate scale);
/// "crosses_brighter" among the flags when `crossingBrighter` (crossesBrighter() of the search's list).
[[nodiscard]] SearchMeasurement measureSearch(const search::FilteredCube& cube,
                                              const search::VelocityGrid& grid, const search::Candidate& c,
                                              bool crossingBrighter = false);

}  // namespace st::candidate
