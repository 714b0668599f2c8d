#pragma once
// FFTW (single precision) plans and aligned buffers shared by every stage that uses FFTW (CSA stacking,
// registration). One process-wide cache: plans are made once per size under a lock (FFTW's planner is not
// thread-safe) and executed with the new-array functions (fftwf_execute_dft_*) on fftwf_malloc'ed buffers,
// which is thread-safe. The cache destroys its plans at exit, so leak checkers see none.
//
// Internal to st_core: the header names FFTW's types, and only core's .cpp files include it.

#include <fftw3.h>

#include <cstddef>
#include <memory>
#include <string>

namespace st::fftw {

struct FftwFree {
  void operator()(void* p) const noexcept { fftwf_free(p); }
};
using RealBuf = std::unique_ptr<float[], FftwFree>;
using CplxBuf = std::unique_ptr<fftwf_complex[], FftwFree>;

/// fftwf_malloc'ed buffers of n values; throw InputError naming `what` when memory runs out.
RealBuf allocReal(std::size_t n, const std::string& what);
CplxBuf allocCplx(std::size_t n, const std::string& what);

/// A forward real-to-complex and an inverse complex-to-real plan of one 2-D size (nx columns, ny rows).
struct PlanPair {
  fftwf_plan forward = nullptr;
  fftwf_plan inverse = nullptr;
};

/// The process's plans for nx x ny (FFTW_MEASURE when `measure`, else FFTW_ESTIMATE), made on first use.
/// Throws InputError when FFTW cannot plan the size.
PlanPair plans2d(int nx, int ny, bool measure);

}  // namespace st::fftw
