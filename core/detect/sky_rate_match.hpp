#pragma once
// Internal to the sky-rate measurement (sky_rate.cpp, sky_rate_chain.cpp): the offset of the star field
// between two images of it. Sources are found and paired on thresholded, compressed images (0 where faint,
// log1p(value / threshold) elsewhere); the chain then measures them on the linear images.
#include <cstddef>
#include <vector>

#include <opencv2/core.hpp>

namespace st::detect::detail {

/// Sources voting in the consensus offsets peak at >= 4 times the detection threshold (log1p(4) in the
/// compressed images): bright enough to centroid to a small fraction of a pixel.
double minPeakCompressed();

/// Centroid (weighted by the image values) and peak of one connected source of a thresholded image.
struct Source {
  double x = 0.0, y = 0.0, peak = 0.0;
};

/// The sources of a thresholded, compressed image: 8-connected components of at least 4 pixels whose peak
/// reaches `minPeak`; each source counts once, however large.
std::vector<Source> sourcesOf(const cv::Mat& image, double minPeak);

/// A source of image `a` and the source of image `b` paired with it.
struct SourcePair {
  Source a, b;
};

/// Pairs each source of `a` (peak >= minPeak) with the source of `b` nearest to where `coarse` (offset of
/// b relative to a, px) puts it, within 3 px; unpaired sources are dropped.
std::vector<SourcePair> pairSources(const cv::Mat& a, const cv::Mat& b, cv::Point2d coarse, double minPeak);

/// A linear image (background removed) with its per-pixel noise and where it is valid, for the windowed
/// centroids of `windowedOffset`.
struct LinearImage {
  cv::Mat value;  ///< CV_32F, counts (read into doubles)
  cv::Mat noise;  ///< CV_32F, 1-sigma of each pixel, counts
  cv::Mat valid;  ///< CV_8U, 255 where value is defined
};

/// The offset of the star field from `a` to `b` from paired sources: for each pair, Gaussian-windowed
/// centroids (SExtractor's XWIN iteration, the window's sigma from the source's second moments in `a`,
/// the same window in both images) on the linear images, whose difference is one estimate with its
/// variance from the pixel noise; estimates further than 3 sigma + 0.1 px from their median are dropped
/// (a moving object, a blend), the rest averaged with inverse-variance weights (each at least 0.03 px, so
/// that no single star decides). False with fewer than 2 estimates. `var` gets the variance of the average
/// along x and y, px^2.
bool windowedOffset(const LinearImage& a, const LinearImage& b, const std::vector<SourcePair>& pairs,
                    cv::Point2d* d, cv::Point2d* var);

/// The stars' consensus offset of `b` relative to `a` (CV_64F images as above): each bright source of `a` is
/// paired with the source of `b` nearest to where `coarse` puts it (within 3 px), and the median of the
/// pairs' centroid offsets is the offset. One vote per source, so that a bright moving object (a streak,
/// whose pixels all peak alike) counts as one outlier among the stars, not as many votes, and no source
/// weighs more for being brighter. False with fewer than 3 pairs.
bool consensusOffset(const cv::Mat& a, const cv::Mat& b, cv::Point2d coarse, double minPeak, cv::Point2d* d);

/// phaseShift's FFT input: the window (or none) times the CV_64F image, rounded to float, its rows `stride`
/// floats apart in `out` (also what a device's phase correlations are given, so that both transform the same
/// floats).
void windowedFloats(const cv::Mat& image, const cv::Mat& window, float* out, std::size_t stride);

/// cv::phaseCorrelate(a, b, window) (offset of b relative to a, px, and the response), computed as OpenCV
/// does (zero padding to its optimal DFT size, the normalised cross-power spectrum, its quadrant swap, the
/// 5 x 5 centroid) but with single-precision FFTW transforms: 1.5x-3x faster than OpenCV's double DFTs on the
/// sky rate's 54 links of 512^2 images (issue 16), within ~1e-3 px and ~1e-4 in response of OpenCV
/// (tests/core/test_sky_rate_phase_shift.cpp). The inputs are not changed.
cv::Point2d phaseShift(const cv::Mat& a, const cv::Mat& b, const cv::Mat& window, double* response);

/// phaseShift's normalised cross-power spectrum, in place of `fa` (n complexes of FFTW's layout): A conj(B)
/// / |A conj(B)| in double, each rounded to float, 0 where it vanishes. `vectorised`: AVX2 where the CPU has
/// it (the same floats as the scalar loop; false for the tests' reference).
void normaliseCrossPower(float (*fa)[2], const float (*fb)[2], std::size_t n, bool vectorised = true);

/// phaseShift's peak: the index, in the quadrant-swapped surface (x - nx / 2 and y - ny / 2 modulo the
/// size), of c's largest value (row-major nx x ny); of equal values, the first in that swapped row order.
std::size_t firstLargestShifted(const float* c, int nx, int ny);

}  // namespace st::detect::detail
