#pragma once
// Measuring the PSF of an observation: choose a bright, isolated, unsaturated star (from a catalog of
// candidates, e.g. the static-source catalog, or from local maxima found here) in a well-exposed image
// (a sky-rate stack or a zero-biased frame) and fit the Moffat profile to it (st/psf/moffat_fit.hpp).
// When no star is usable, st::InputError says so and asks for a FWHM (Moffat::fromFwhm is the fallback).
#include <optional>
#include <string>
#include <vector>

#include "st/common/image.hpp"
#include "st/psf/moffat_fit.hpp"

namespace st::psf {

/// A star that might serve for the PSF. Plain data so that any catalog (st::detect's static sources) can be
/// passed in.
struct StarCandidate {
  double x = 0.0;          ///< column, 0-based px
  double y = 0.0;          ///< row, 0-based px
  double flux = 0.0;       ///< any brightness measure in image units (larger = brighter); used for ranking
  bool saturated = false;  ///< saturated or bleeding: never used
};

/// How a PSF star is chosen and accepted.
struct PsfStarOptions {
  std::optional<double>
      saturationLevel;              ///< pixel values >= this are saturated (image units); none = unknown
  double minPeakSnr = 20.0;         ///< fitted amplitude / image noise must reach this
  double isolationRadiusPx = 15.0;  ///< no other candidate brighter than isolationFluxRatio x this star's
                                    ///< flux (or saturated) within this radius, px
  double isolationFluxRatio = 0.05;
  int edgeMarginPx = 32;   ///< candidates closer to the edge are skipped (at most 1/8 of the image)
  double minFwhmPx = 0.8;  ///< fits outside [min, max] FWHM are rejected as not a star
  double maxFwhmPx = 40.0;
  int maxTries = 30;     ///< candidates fitted, brightest first, before giving up
  int maxAccepted = 9;   ///< stars accepted before stopping (see measurePsf for the choice among them)
  MoffatFitOptions fit;  ///< options of the Moffat fit
  /// robustImageNoise(image) where the caller has it already (issue 16: measured beside other work); else
  /// measurePsf measures it. minPeakSnr is in its units.
  std::optional<double> imageNoise;
};

/// The PSF measured on one star.
struct PsfMeasurement {
  MoffatFit fit;
  StarCandidate star;                 ///< the star used
  int candidatesConsidered = 0;       ///< candidates after the saturation/edge/isolation cuts
  std::vector<std::string> rejected;  ///< why earlier candidates were rejected (for the user to see)
  std::vector<double> acceptedFwhm;   ///< FWHM (px) of every accepted star, increasing (measurePsf)
};

/// Robust noise of an image: 1.4826 x MAD about the median over the non-zero finite pixels (every pixel
/// up to 2^20 of them, then an even subsample). Returns 0 when fewer than 16 usable pixels.
double robustImageNoise(const Image& image);

/// Local maxima of `image` above median + thresholdSigma x robust noise (3x3 neighbourhood, strictly
/// greater than the pixels before it, >= those after it, so plateaus give one maximum), with flux = the
/// background-subtracted sum over a 5x5 box, and `saturated` set when the peak reaches saturationLevel or
/// the peak is a plateau of >= 3 equal pixels (a clipped star). Sorted by decreasing flux.
std::vector<StarCandidate> findStarCandidates(const Image& image, double thresholdSigma = 10.0,
                                              std::optional<double> saturationLevel = std::nullopt);

/// Fits the brightest candidates that are unsaturated, away from the edges and isolated, and accepts fits
/// that converged with a plausible FWHM and peak SNR, beta inside the fit's bounds and no flat-topped core
/// (more than max(8, pi (0.1 FWHM + 1)^2) pixels within 3% of the peak: a saturated star the catalog did
/// not flag; an unsaturated Moffat has at most a few), up to maxAccepted of them. The PSF is the brightest
/// accepted star's, unless three or more were accepted: then the brightest whose FWHM is within
/// max(3 sigma, 2%) of their median, so that one star blended with a faint neighbour does not set it. With
/// `candidates` empty, finds them with findStarCandidates. Throws st::InputError ("no star usable for the
/// PSF ... give a FWHM") when none is accepted; the message lists why the best candidates were rejected.
PsfMeasurement measurePsf(const Image& image, const std::vector<StarCandidate>& candidates,
                          const PsfStarOptions& options = {});

/// Fits the star the user named near (x, y). Throws st::InputError naming the position when the fit does
/// not converge or gives an implausible FWHM.
PsfMeasurement measurePsfAt(const Image& image, double x, double y, const PsfStarOptions& options = {});

}  // namespace st::psf
