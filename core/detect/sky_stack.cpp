#include "st/detect/sky_stack.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <exception>
#include <limits>
#include <mutex>
#include <system_error>
#include <thread>
#include <vector>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#endif

#include "st/common/env_flag.hpp"
#include "st/common/parallel.hpp"
#include "st/common/parallel_cap.hpp"
#include "st/stats/sigma_clip.hpp"

namespace st::detect {
namespace {

// One frame row added into the stack's canvas row (sum, cnt and mx already offset to the frame's column 0),
// leaving out masked samples. The AVX2 path does the same arithmetic as the scalar one: an excluded sample
// adds +0.0 to the sum (x + 0.0 == x) and to the count, and leaves the maximum; max_ps(v, m) is std::max(m,
// v) for NaN and signed zeros too.
void addStackRowMaskedScalar(double* sum, float* cnt, float* mx, const float* row, const std::uint8_t* mrow,
                             int x0, int w, double subtract) {
  for (int x = x0; x < w; ++x) {
    if (mrow[x]) continue;
    sum[x] += row[x] - subtract;
    cnt[x] += 1.0f;
    mx[x] = std::max(mx[x], row[x]);
  }
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define ST_SKY_STACK_AVX2 1
__attribute__((target("avx2"))) void addStackRowMaskedAvx2(double* sum, float* cnt, float* mx,
                                                           const float* row, const std::uint8_t* mrow, int w,
                                                           double subtract) {
  const __m256d sub = _mm256_set1_pd(subtract);
  const __m256 one = _mm256_set1_ps(1.0f);
  const __m256i zero = _mm256_setzero_si256();
  int x = 0;
  for (; x + 8 <= w; x += 8) {
    const __m128i m8 = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(mrow + x));
    const __m256 in = _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_cvtepu8_epi32(m8), zero));
    const __m256d inLo = _mm256_castsi256_pd(_mm256_cmpeq_epi64(_mm256_cvtepu8_epi64(m8), zero));
    const __m256d inHi =
        _mm256_castsi256_pd(_mm256_cmpeq_epi64(_mm256_cvtepu8_epi64(_mm_srli_si128(m8, 4)), zero));
    const __m256 v = _mm256_loadu_ps(row + x);
    _mm256_storeu_ps(cnt + x, _mm256_add_ps(_mm256_loadu_ps(cnt + x), _mm256_and_ps(in, one)));
    const __m256 m = _mm256_loadu_ps(mx + x);
    _mm256_storeu_ps(mx + x, _mm256_blendv_ps(m, _mm256_max_ps(v, m), in));
    const __m256d dLo = _mm256_sub_pd(_mm256_cvtps_pd(_mm256_castps256_ps128(v)), sub);
    const __m256d dHi = _mm256_sub_pd(_mm256_cvtps_pd(_mm256_extractf128_ps(v, 1)), sub);
    _mm256_storeu_pd(sum + x, _mm256_add_pd(_mm256_loadu_pd(sum + x), _mm256_and_pd(dLo, inLo)));
    _mm256_storeu_pd(sum + x + 4, _mm256_add_pd(_mm256_loadu_pd(sum + x + 4), _mm256_and_pd(dHi, inHi)));
  }
  addStackRowMaskedScalar(sum, cnt, mx, row, mrow, x, w, subtract);
}
#endif

void addStackRowMasked(double* sum, float* cnt, float* mx, const float* row, const std::uint8_t* mrow, int w,
                       double subtract) {
#ifdef ST_SKY_STACK_AVX2
  static const bool avx2 = __builtin_cpu_supports("avx2") != 0;
  if (avx2) return addStackRowMaskedAvx2(sum, cnt, mx, row, mrow, w, subtract);
#endif
  addStackRowMaskedScalar(sum, cnt, mx, row, mrow, 0, w, subtract);
}

__attribute__((target_clones("avx2", "default"))) void addStackRow(double* __restrict sum,
                                                                   float* __restrict cnt,
                                                                   float* __restrict mx,
                                                                   const float* __restrict row, int w,
                                                                   double subtract) {
  for (int x = 0; x < w; ++x) {
    const float v = row[x];
    sum[x] += static_cast<double>(v) - subtract;
    cnt[x] += 1.0f;
    mx[x] = std::max(mx[x], v);
  }
}

}  // namespace

SkyStack stackAtSkyRate(const FrameCube& cube, Velocity rate, double subtract, ProgressSink& progress,
                        CancelToken& cancel, std::size_t first, std::size_t last) {
  if (last == 0 || last > cube.frameCount()) last = cube.frameCount();
  const MovingMask geom(cube, rate);
  SkyStack s;
  s.x0 = geom.x0();
  s.y0 = geom.y0();
  const int cw = geom.canvasWidth(), ch = geom.canvasHeight(), w = cube.width(), h = cube.height();
  s.mean = Image(cw, ch);
  s.count = Image(cw, ch);
  s.max = Image(cw, ch, -std::numeric_limits<float>::infinity());
  const auto& mask = cube.mask();
  const std::size_t np = cube.framePixels();
  // Bands of canvas rows, frames in the outer loop: each frame's rows of the band are contiguous in memory
  // (streamed), the band's sums stay in cache; every canvas pixel still sums its frames in order.
  constexpr std::size_t kBand = 8;
  parallelFor(static_cast<std::size_t>(ch), kBand, [&](std::size_t j0, std::size_t j1) {
    cancel.throwIfCancelled();
    std::vector<double> sums(static_cast<std::size_t>(cw) * (j1 - j0), 0.0);
    for (std::size_t n = first; n < last; ++n) {
      const int off = geom.shiftX(n) + s.x0;  // frame column x -> canvas column x - off
      for (std::size_t j = j0; j < j1; ++j) {
        const int y = s.y0 + static_cast<int>(j) + geom.shiftY(n);
        if (y < 0 || y >= h) continue;
        double* sum = sums.data() + (j - j0) * cw;
        float* cnt = s.count.data() + j * cw;
        float* mx = s.max.data() + j * cw;
        const float* row = cube.frame(n) + static_cast<std::size_t>(y) * w;
        // Canvas column i = x - off; the first canvas column of this frame row is -off.
        if (mask.empty())
          addStackRow(sum - off, cnt - off, mx - off, row, w, subtract);
        else
          addStackRowMasked(sum - off, cnt - off, mx - off, row,
                            mask.data() + n * np + static_cast<std::size_t>(y) * w, w, subtract);
      }
    }
    for (std::size_t j = j0; j < j1; ++j) {
      const double* sum = sums.data() + (j - j0) * cw;
      float* cnt = s.count.data() + j * cw;
      float* mx = s.max.data() + j * cw;
      float* mean = s.mean.data() + j * cw;
      for (int i = 0; i < cw; ++i) {
        mean[i] = cnt[i] > 0 ? static_cast<float>(sum[i] / cnt[i]) : 0.0f;
        if (cnt[i] == 0) mx[i] = 0.0f;
      }
    }
    progress.report(static_cast<double>(j1) / ch, "stack at sky rate");
  });
  return s;
}

// The stacks a prefetch makes on its thread, handed to stack() one by one.
struct SkyStackCache::Prefetch {
  std::mutex mutex;
  std::condition_variable changed;
  std::vector<Key> keys;
  std::vector<std::optional<SkyStack>> stacks;  // none: the provider declined (the CPU makes it)
  std::vector<std::exception_ptr> errors;       // rethrown by the stack() that asks for it
  std::vector<char> finished, taken;
  double seconds = 0.0;
  std::jthread thread;  // last: joined before the members it writes are destroyed

  // The stack of `key` when it is one of them not taken yet (`*found`), waiting for it: none when the
  // provider did not make it; its exception rethrown.
  std::optional<SkyStack> take(const Key& key, bool* found) {
    std::unique_lock lock(mutex);
    *found = false;
    for (std::size_t k = 0; k < keys.size(); ++k) {
      if (taken[k] || keys[k] != key) continue;
      changed.wait(lock, [&] { return finished[k] != 0; });
      taken[k] = 1;
      *found = true;
      if (errors[k]) std::rethrow_exception(errors[k]);
      return std::move(stacks[k]);
    }
    return std::nullopt;
  }
};

void SkyStackCache::prefetch(const FrameCube& cube, Velocity rate, double subtract,
                             const std::vector<Range>& ranges) {
  if (!m_provider || !m_prefetchAllowed) return;
  // The ranges' stacks not made, not made ahead and (with `inFlight`) not being made by the prefetch in
  // flight, once each.
  const auto toMake = [&](bool inFlight) {
    std::vector<Key> keys;
    const std::size_t nf = cube.frameCount();
    for (auto [first, last] : ranges) {
      if (last == 0 || last > nf) last = nf;
      const Key key{cube.pixels().data(), rate.vx, rate.vy, subtract, first, last};
      const auto listed = [&key](const std::vector<Key>& in) {
        return std::find(in.begin(), in.end(), key) != in.end();
      };
      if (first < last && !m_stacks.contains(key) && !m_ahead.contains(key) && !listed(keys) &&
          !(inFlight && m_prefetch && listed(m_prefetch->keys)))
        keys.push_back(key);
    }
    return keys;
  };
  // Nothing new: the one in flight is not waited for.
  if (toMake(true).empty()) return;
  if (m_prefetch) {
    settle();  // one in flight: its stacks first (its provider makes one at a time)
    // The stacks the last one made that were not asked for are kept (counted when handed out).
    for (std::size_t k = 0; k < m_prefetch->keys.size(); ++k)
      if (!m_prefetch->taken[k] && m_prefetch->stacks[k] && !m_prefetch->errors[k])
        m_ahead.emplace(m_prefetch->keys[k], std::move(*m_prefetch->stacks[k]));
    m_prefetchSecondsBefore += m_prefetch->seconds;
    m_prefetch.reset();
  }
  const std::vector<Key> keys = toMake(false);
  if (keys.empty()) return;
  auto pf = std::make_shared<Prefetch>();
  pf->keys = keys;
  pf->stacks.resize(keys.size());
  pf->errors.resize(keys.size());
  pf->finished.assign(keys.size(), 0);
  pf->taken.assign(keys.size(), 0);
  // The thread reads the cube, a copy of the provider and the state it is joined with (never *this, which
  // may be moved meanwhile).
  try {
    pf->thread = std::jthread(
        [state = pf.get(), provider = m_provider, c = &cube, rate, subtract](std::stop_token stop) {
          // Beside the caller's loops on every core: this thread's own (the provider's host copies) on two.
          const ParallelThreadCap cap(2);
          const auto t0 = std::chrono::steady_clock::now();
          for (std::size_t k = 0; k < state->keys.size(); ++k) {
            std::optional<SkyStack> made;
            std::exception_ptr error;
            // The cache going away (a cancel or an error unwinding its owner): the rest is not made.
            if (!stop.stop_requested()) {
              try {
                made = provider(*c, rate, subtract, std::get<4>(state->keys[k]), std::get<5>(state->keys[k]));
              } catch (...) {
                error = std::current_exception();
              }
            }
            const std::lock_guard lock(state->mutex);
            state->stacks[k] = std::move(made);
            state->errors[k] = error;
            state->finished[k] = 1;
            if (k + 1 == state->keys.size())
              state->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
            state->changed.notify_all();
          }
        });
  } catch (const std::system_error&) {
    return;  // no thread: stack() makes each as before
  }
  m_prefetch = std::move(pf);
}

std::optional<SkyStack> SkyStackCache::takePrefetched(const FrameCube& cube, Velocity rate, double subtract,
                                                      std::size_t first, std::size_t last, bool* found) {
  *found = false;
  if (!m_prefetch) return std::nullopt;
  if (last == 0 || last > cube.frameCount()) last = cube.frameCount();
  bool taken = false;
  std::optional<SkyStack> s =
      m_prefetch->take(Key{cube.pixels().data(), rate.vx, rate.vy, subtract, first, last}, &taken);
  *found = s.has_value();  // one declined ahead is the caller's to ask again
  if (s) ++m_prefetched;
  return s;
}

void SkyStackCache::settle() {
  if (m_prefetch && m_prefetch->thread.joinable()) m_prefetch->thread.join();
}

double SkyStackCache::prefetchSeconds() const {
  double s = m_prefetchSecondsBefore;
  if (m_prefetch) {
    const std::lock_guard lock(m_prefetch->mutex);
    s += m_prefetch->seconds;
  }
  return s;
}

const SkyStack& SkyStackCache::stack(const FrameCube& cube, Velocity rate, double subtract,
                                     ProgressSink& progress, CancelToken& cancel, std::size_t first,
                                     std::size_t last) {
  if (last == 0 || last > cube.frameCount()) last = cube.frameCount();
  const Key key{cube.pixels().data(), rate.vx, rate.vy, subtract, first, last};
  auto it = m_stacks.find(key);
  if (it != m_stacks.end()) {
    progress.report(1.0, "stack at sky rate");
    return it->second;
  }
  const auto t0 = std::chrono::steady_clock::now();
  std::optional<SkyStack> made;
  if (auto ahead = m_ahead.find(key); ahead != m_ahead.end()) {
    made = std::move(ahead->second);
    m_ahead.erase(ahead);
  } else if (m_prefetch) {
    bool found = false;
    made = m_prefetch->take(key, &found);
  }
  if (made) ++m_prefetched;
  // One the provider declined ahead is asked again (the device may hold the cube by now).
  if (m_provider && !made) made = m_provider(cube, rate, subtract, first, last);
  if (made) {
    ++m_provided;
    progress.report(1.0, "stack at sky rate");
  } else {
    made = stackAtSkyRate(cube, rate, subtract, progress, cancel, first, last);
  }
  ++m_made;
  it = m_stacks.emplace(key, std::move(*made)).first;
  m_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return it->second;
}

Image meshBackground(const Image& image, const Image& weight, int mesh) {
  const int w = image.width, h = image.height;
  mesh = std::max(4, mesh);
  const int nx = std::max(1, (w + mesh - 1) / mesh), ny = std::max(1, (h + mesh - 1) / mesh);
  std::vector<double> cell(static_cast<std::size_t>(nx) * ny, std::numeric_limits<double>::quiet_NaN());
  // The cells are independent: clipped in parallel (serial before issue 16: ~15 ms a call on the paper's
  // canvas, ten calls per pre-processing).
  parallelFor(cell.size(), 4, [&](std::size_t c0, std::size_t c1) {
    std::vector<float> v;
    for (std::size_t c = c0; c < c1; ++c) {
      const int cy = static_cast<int>(c / nx), cx = static_cast<int>(c % nx);
      v.clear();
      for (int y = cy * mesh; y < std::min(h, (cy + 1) * mesh); ++y)
        for (int x = cx * mesh; x < std::min(w, (cx + 1) * mesh); ++x)
          if (weight.at(x, y) > 0) v.push_back(image.at(x, y));
      if (v.size() >= 8) cell[c] = stats::sigmaClip(v.data(), v.size(), 3.0).mean;
    }
  });
  // Empty cells take the mean of the filled ones.
  double fill = 0.0;
  int nFill = 0;
  for (double c : cell)
    if (!std::isnan(c)) fill += c, ++nFill;
  fill = nFill ? fill / nFill : 0.0;
  for (double& c : cell)
    if (std::isnan(c)) c = fill;
  Image out(w, h);
  parallelFor(static_cast<std::size_t>(h), 16, [&](std::size_t yb, std::size_t ye) {
    for (int y = static_cast<int>(yb); y < static_cast<int>(ye); ++y) {
      const double fy = std::clamp((y + 0.5) / mesh - 0.5, 0.0, ny - 1.0);
      const int iy = std::min(static_cast<int>(fy), ny - 1), iy1 = std::min(iy + 1, ny - 1);
      const double ty = fy - iy;
      for (int x = 0; x < w; ++x) {
        const double fx = std::clamp((x + 0.5) / mesh - 0.5, 0.0, nx - 1.0);
        const int ix = std::min(static_cast<int>(fx), nx - 1), ix1 = std::min(ix + 1, nx - 1);
        const double tx = fx - ix;
        auto c = [&](int a, int b) { return cell[static_cast<std::size_t>(b) * nx + a]; };
        out.at(x, y) = static_cast<float>((1 - ty) * ((1 - tx) * c(ix, iy) + tx * c(ix1, iy)) +
                                          ty * ((1 - tx) * c(ix, iy1) + tx * c(ix1, iy1)));
      }
    }
  });
  return out;
}

Image residualWhereCounted(const Image& mean, const Image& count, const Image& local) {
  Image out(mean.width, mean.height);
  parallelFor(out.size(), std::size_t{1} << 16, [&](std::size_t i0, std::size_t i1) {
    for (std::size_t i = i0; i < i1; ++i)
      out.pixels[i] = count.pixels[i] > 0 ? mean.pixels[i] - local.pixels[i] : 0.0f;
  });
  return out;
}

std::shared_ptr<const void> SkyStackCache::derived(Derived kind, const FrameCube& cube, Velocity rate,
                                                   double subtract, int meshPx) const {
  const auto it = m_derived.find({kind, cube.pixels().data(), rate.vx, rate.vy, subtract, meshPx});
  return it == m_derived.end() ? nullptr : it->second;
}

void SkyStackCache::keepDerived(Derived kind, const FrameCube& cube, Velocity rate, double subtract,
                                int meshPx, std::shared_ptr<const void> value) {
  // Benchmark knob: ST_NO_KEPT_DERIVED=1 keeps none (each search derives its own, as before issue 16's).
  static const bool none = envFlag("ST_NO_KEPT_DERIVED");
  if (none) return;
  m_derived[{kind, cube.pixels().data(), rate.vx, rate.vy, subtract, meshPx}] = std::move(value);
}

}  // namespace st::detect
