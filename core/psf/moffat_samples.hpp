#pragma once
// The pixel-mean Moffat model of fitMoffat (moffat_fit.cpp) and its gradient, four samples at a time.
//
// The model of a pixel is a weighted sum over samples (smear offsets x Gauss points), each an exp and a log:
// ~90% of the PSF's fits (paper-neo: 9 stars, 1225 pixels x 144 samples x 5 evaluations each; 78 ms of the
// 2-core machine's pre-processing, 31 ms on the GPU host's critical path, 2026-12-04). Here the samples run
// in four AVX2 lanes with an exp and a log of our own (laneExp, laneLog: fdlibm's reductions and
// polynomials in plain IEEE operations, no FMA): 5.4 ns a sample against 15 with the C library's. Their
// scalar form gives the same bits (the tests' reference) but runs at ~20 ns, so fitMoffat keeps the model of
// before (moffatModelAtLibm) where the CPU has no AVX2. Each lane sums its samples, and the lanes are summed
// as (0 + 1) + (2 + 3).
#include <atomic>
#include <cstddef>
#include <vector>

#include "st/psf/moffat.hpp"
#include "st/psf/stack_smear.hpp"

namespace st::psf::detail {

/// exp(x) within 1 ulp of the correctly rounded value for |x| < 700 (std::exp outside, and for NaN).
double laneExp(double x);
/// log(x) within 1 ulp of the correctly rounded value for normal finite x > 0 (std::log otherwise).
double laneLog(double x);
/// Four of each, lane by lane: the same bits as laneExp and laneLog (AVX2 where the CPU has it).
void laneExp4(const double* x, double* out);
void laneLog4(const double* x, double* out);

/// The samples of a pixel's model relative to its centre: offset (ox, oy) and weight, in the order smear
/// offset, Gauss y, Gauss x; padded with weight-0 samples to a multiple of four.
struct MoffatSamples {
  std::vector<double> ox, oy, weight;
};
MoffatSamples moffatSamples(const Moffat::GaussRule& g, const SmearKernel& smear);

/// The parameters' order (moffat_fit.cpp's Param).
enum MoffatParam { kX0 = 0, kY0, kR, kBeta, kAmp, kBg };

/// The model at pixel (px, py) for parameters p[6], and its gradient into grad[6] when grad is not null.
double moffatModelAt(const double* p, double px, double py, const MoffatSamples& s, double* grad);
/// moffatModelAt with its lanes as AVX2 (where the CPU has it) or as scalars: the same bits (the tests').
double moffatModelAtLanes(const double* p, double px, double py, const MoffatSamples& s, double* grad,
                          bool avx2);

/// The model as before 2026-12-04: sample by sample in one sum, with std::exp and std::log (the tests'
/// reference; ST_PSF_LIBM_MODEL=1 fits with it, for before/after figures from one binary).
double moffatModelAtLibm(const double* p, double px, double py, const Moffat::GaussRule& g,
                         const SmearKernel& smear, double* grad);
/// ST_PSF_LIBM_MODEL=1 (read once), or a LibmModelScope alive.
bool moffatModelLibm();
/// fitMoffat with the model of before while it lives, on every thread (the tests' A/B in one process).
class LibmModelScope {
 public:
  LibmModelScope();
  ~LibmModelScope();
  LibmModelScope(const LibmModelScope&) = delete;
  LibmModelScope& operator=(const LibmModelScope&) = delete;
};

/// Whether moffatModelAt runs its lanes as AVX2 (for the tests' notes).
bool moffatLanesAvx2();

}  // namespace st::psf::detail
