#include "st/common/fftw_plans.hpp"

#include <map>
#include <mutex>
#include <tuple>

#include "st/common/error.hpp"

namespace st::fftw {

RealBuf allocReal(std::size_t n, const std::string& what) {
  RealBuf b(static_cast<float*>(fftwf_malloc(sizeof(float) * n)));
  if (!b) throw InputError(what + ": out of memory for an FFT buffer of " + std::to_string(n) + " floats");
  return b;
}

CplxBuf allocCplx(std::size_t n, const std::string& what) {
  CplxBuf b(static_cast<fftwf_complex*>(fftwf_malloc(sizeof(fftwf_complex) * n)));
  if (!b) throw InputError(what + ": out of memory for an FFT buffer of " + std::to_string(n) + " values");
  return b;
}

namespace {

/// One pair per (nx, ny, measure), destroyed at exit. No fftwf_cleanup*: that would invalidate plans other
/// code might still hold.
class PlanCache {
 public:
  ~PlanCache() {
    for (auto& [key, p] : m_plans) {
      fftwf_destroy_plan(p.forward);
      fftwf_destroy_plan(p.inverse);
    }
  }

  PlanPair get(int nx, int ny, bool measure) {
    std::lock_guard lock(m_mutex);
    auto it = m_plans.find({nx, ny, measure});
    if (it != m_plans.end()) return it->second;
    const std::size_t nReal = std::size_t(nx) * ny, nCplx = std::size_t(nx / 2 + 1) * ny;
    RealBuf r = allocReal(nReal, "FFT planning");
    CplxBuf c = allocCplx(nCplx, "FFT planning");
    const unsigned flags = measure ? FFTW_MEASURE : FFTW_ESTIMATE;
    fftwf_plan_with_nthreads(1);
    PlanPair p;
    p.forward = fftwf_plan_dft_r2c_2d(ny, nx, r.get(), c.get(), flags);
    p.inverse = fftwf_plan_dft_c2r_2d(ny, nx, c.get(), r.get(), flags);
    if (!p.forward || !p.inverse) {
      if (p.forward) fftwf_destroy_plan(p.forward);
      if (p.inverse) fftwf_destroy_plan(p.inverse);
      throw InputError("FFTW could not plan a " + std::to_string(nx) + " x " + std::to_string(ny) + " FFT");
    }
    m_plans.emplace(std::make_tuple(nx, ny, measure), p);
    return p;
  }

 private:
  std::mutex m_mutex;
  std::map<std::tuple<int, int, bool>, PlanPair> m_plans;
};

}  // namespace

PlanPair plans2d(int nx, int ny, bool measure) {
  static std::once_flag once;
  std::call_once(once, [] {
    fftwf_init_threads();
    fftwf_make_planner_thread_safe();
  });
  static PlanCache cache;  // constructed after the init above, so destroyed before anything it needs
  return cache.get(nx, ny, measure);
}

}  // namespace st::fftw
