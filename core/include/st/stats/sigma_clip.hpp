#pragma once
// The iterative sigma-clip of the paper (§3.1, "Estimating the background"): start with every sample in the
// background set B, compute the sample mean and the sample standard deviation (N(B) - 1 in the
// denominator), replace B by {i | y_i <= mean + xi * sigma} (one-sided: only signals above the background
// are outliers), and iterate until B no longer changes.
#include <cstddef>

namespace st::stats {

struct ClipStats {
  double mean = 0.0;       ///< sample mean of the converged background set B
  double sigma = 0.0;      ///< sample standard deviation of B, N(B) - 1 in the denominator; 0 when N(B) < 2
  std::size_t count = 0;   ///< N(B)
  int iterations = 0;      ///< passes over the data until B stopped changing
  bool converged = false;  ///< false when maxIterations was reached first
};

/// The paper's one-sided iterative clip (§3.1) of `n` samples. `xi` is the threshold in sigmas (the paper
/// uses 5 for the global background from ~50 frames, 4 for the per-pixel background over ~2000 frames).
/// B is always of the form {y <= t}, so "B unchanged" is tested exactly by N(B) unchanged. Values must be
/// finite (callers leave masked samples out). n == 0 gives count 0, mean 0, sigma 0.
ClipStats sigmaClip(const float* values, std::size_t n, double xi, int maxIterations = 100);

/// A symmetric variant, B = {i | |y_i - mean| <= xi * sigma}, for quantities whose outliers go both ways
/// (frame differences, where a cosmic ray in either frame gives a positive or a negative outlier). Same
/// estimators and convergence rule (B unchanged) as sigmaClip. Its sums are made per chunk of 65536 values
/// on every core and added in chunk order: the same result on any number of threads (for more values than
/// one chunk it differs from one pass of 8-lane sums over them, as before 2026-12-02, in the last bits).
ClipStats sigmaClipSymmetric(const float* values, std::size_t n, double xi, int maxIterations = 100);

}  // namespace st::stats
