#pragma once
// What the candidate inspector shows, computed off the GUI thread from the search's own data (the matched-
// filtered cube, so every number is on the search statistic's scale, ARCHITECTURE.md "SNR of the search
// statistic"):
//  - stamps around the candidate stacked at its velocity and at the sky rate (st::vet::stackStamp, the
//    search's rounding), in SNR units S / (sigma_F sqrt(N_in));
//  - the segment strip: K equal-time segments (st::vet::splitEqualTime, paper §4.4 / fig_4epoch), each
//    stacked at the candidate's velocity with its SNR and the SNR the whole stack predicts for it;
//  - the frame-by-frame cutouts along the track (for the movie);
//  - the artifact checks of st::vet (charge leakage, bright star, diffraction, edge, masked, transient) and
//    the known-object match, each with its evidence.
// Pure function of its input; no Qt. Polls the CancelToken between frames.
#include <memory>
#include <optional>
#include <vector>

#include "st/common/image.hpp"
#include "st/common/progress.hpp"
#include "st/detect/static_sources.hpp"
#include "st/search/types.hpp"
#include "st/vet/artifacts.hpp"
#include "st/vet/known_objects.hpp"
#include "st/vet/segments.hpp"

namespace st::candidate {

struct InspectionInput {
  std::shared_ptr<const search::FilteredCube> filtered;  ///< the search's cube (required)
  /// Frames for the cutout movie (the unfiltered, zero-biased frames); null: the filtered frames.
  std::shared_ptr<const FrameCube> movieFrames;
  search::Candidate candidate;
  std::vector<detect::Star> stars;    ///< the static-source catalog (Prepared::stars); may be empty
  int stampHalf = 16;                 ///< stamps are (2 stampHalf + 1)^2 pixels
  int segments = 4;                   ///< K (paper §5.1: 4)
  std::size_t maxMovieFrames = 1500;  ///< more frames are sampled evenly
  vet::ArtifactParams artifactParams;
  vet::SegmentOptions segmentOptions;  ///< missing-signal and consistency thresholds
  /// Known objects and the candidate's sky position at t_ref (RA, Dec in degrees), when a WCS placed it.
  std::shared_ptr<const std::vector<vet::KnownObject>> knownObjects;
  std::optional<std::pair<double, double>> skyPosition;
  double knownObjectRadiusArcsec = 10.0;
};

struct Inspection {
  Image trackStamp;       ///< at the candidate's velocity, SNR units
  Image skyStamp;         ///< at the sky rate, SNR units (same centre and scale)
  double trackSnr = 0.0;  ///< centre pixel of trackStamp
  double skySnr = 0.0;    ///< centre pixel of skyStamp
  /// The segment strip. Each measurement's forcedSnr is S_k / (sigma_F sqrt(N_in,k)) at the candidate's
  /// cell, expectedSnr = trackSnr sqrt(N_in,k / N_in) (what a steady source gives), `missing` by
  /// SegmentOptions' rule, `stack` the segment's stamp in SNR units. Flux consistency: sum over segments of
  /// (SNR_k - expected_k)^2 is chi^2 with K - 1 degrees of freedom for a steady source (fluxChi2/fluxDof/
  /// fluxProbability). No fits are made here (fitStatus stays Diverged): the co-moving fit is separate.
  vet::SegmentReport segments;
  /// Cutouts centred on the track in each frame (search rounding), with their frame index and time (s).
  std::vector<Image> movie;
  std::vector<std::size_t> movieFrameIndex;
  std::vector<double> movieTimeS;
  /// The st::vet artifact checks (checkArtifacts' order), the static-source check (vet::staticSourceFlag),
  /// and the known-object match last.
  std::vector<vet::ArtifactFlag> flags;
};

/// A stamp of st::vet::stackStamp in SNR units: the IPSA sum of `frames` around the candidate's cell
/// (c.x, c.y) at velocity v (px/s; the search's rounding), divided by sigma_F sqrt(N_in), N_in = the frames
/// whose sample of the centre cell is inside the frame and unmasked. (2 half + 1)^2 pixels.
struct SnrStamp {
  Image image;
  double centreSnr = 0.0;  ///< image at the centre: the search statistic of the cell
  std::size_t nIn = 0;
};
[[nodiscard]] SnrStamp snrStampAt(const search::FilteredCube& cube, const std::vector<std::size_t>& frames,
                                  const search::Candidate& c, Velocity v, int half);

/// Computes everything above. Throws st::InputError when the input has no filtered cube or sigma_F <= 0,
/// st::Cancelled when cancelled.
[[nodiscard]] Inspection inspectCandidate(const InspectionInput& input, CancelToken& cancel);

}  // namespace st::candidate
