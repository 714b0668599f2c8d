#pragma once
// Photometry from the co-moving fit (paper §5.1): photons from alpha * sum P, magnitudes from a zero point
// that is given or derived from a calibration star of known magnitude, and the uncertainty from the
// scatter of the segment photometry. Pure arithmetic, tested against the paper's numbers (6300 photons in
// 30 s against a 9.1 mag star giving 8.1e7 photons/s is 23.1 mag).
#include <vector>

#include "st/common/fits_header.hpp"
#include "st/psf/moffat.hpp"

namespace st::astro {

/// Photo-electrons per data unit of a frame from its header: GAIN (e-/ADU at the output amplifier; else
/// EGAIN; 1 when neither or not positive) divided by EMGAIN when it is above 1 (an EMCCD's multiplication: each detected
/// photon leaves the register as EMGAIN electrons on average). The `gain` of photonsFromAmplitude and the
/// co-moving fit; GAIN alone counted an EMCCD's photons EMGAIN times over (the paper-neo demo: 2489 for
/// the truth's 12.2 photons per frame).
[[nodiscard]] double photoelectronsPerCount(const FitsHeader& header);
/// The source's photon-noise variance over Poisson's for a frame from its header: 2 with EMGAIN above 1 (an
/// EMCCD's multiplication register at high gain; the simulator's EMCCD presets draw it so), else 1.
[[nodiscard]] double excessNoiseFactor(const FitsHeader& header);

/// Photons per frame of a source of PSF amplitude alpha (data units, P with peak 1): gain * alpha * sum P,
/// with sum P over pixels = the Moffat integral pi R^2 / (beta - 1). gain in photons (e-) per data unit.
[[nodiscard]] double photonsFromAmplitude(double alpha, const psf::Moffat& psf, double gain) noexcept;

/// Zero point: the magnitude of a source giving 1 photon/s, from a star of magnitude `starMag` that gives
/// `starPhotonsPerS`: zp = m_star + 2.5 log10(F_star).
[[nodiscard]] double zeroPointFromStar(double starMag, double starPhotonsPerS) noexcept;

/// Magnitude of a source giving `photonsPerS`: m = zp - 2.5 log10(F). NaN for F <= 0 (no magnitude).
[[nodiscard]] double magnitude(double photonsPerS, double zeroPoint) noexcept;

/// Photometric scatter over segments (paper §5.1: the standard deviation of the segment photometry).
struct SegmentScatter {
  int segments = 0;
  double mean = 0.0;             ///< mean photons/s (or any flux unit) over segments
  double sd = 0.0;               ///< sample standard deviation of the segment fluxes
  double sigmaMean = 0.0;        ///< sd / sqrt(K): the uncertainty of the whole observation's flux
  double sigmaMagSegment = 0.0;  ///< 2.5 / ln 10 * sd / mean: one segment's magnitude scatter
  double sigmaMag = 0.0;         ///< 2.5 / ln 10 * sigmaMean / mean: the uncertainty of the magnitude
};
/// Needs >= 2 fluxes and a positive mean (else all zeros but `segments`).
[[nodiscard]] SegmentScatter segmentScatter(const std::vector<double>& fluxes) noexcept;

}  // namespace st::astro
