#pragma once
// The stack of a cube at the sky rate (paper §4.3: "synthetically track at the sidereal rate"), on the
// MovingMask canvas so that stars drifting through the field are stacked too. IPSA convention
// (ARCHITECTURE.md): frame n is shifted by round(v (t_n - t_ref)); samples outside a frame contribute nothing
// and are not counted; masked samples neither.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <tuple>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/progress.hpp"
#include "st/detect/moving_mask.hpp"

namespace st::detect {

struct SkyStack {
  int x0 = 0;  ///< reference position of canvas pixel (0, 0)
  int y0 = 0;
  Image mean;   ///< mean over contributing frames of (F_n - subtract), counts per frame
  Image count;  ///< number of contributing frames
  Image max;    ///< largest raw value met (for saturation), counts
};

/// Stacks frames [first, last) of `cube` at `rate` (px/s) on the canvas of MovingMask(cube..., rate), with
/// `subtract` (e.g. the global background) removed from every sample. last = 0 means all frames.
SkyStack stackAtSkyRate(const FrameCube& cube, Velocity rate, double subtract, ProgressSink& progress,
                        CancelToken& cancel, std::size_t first = 0, std::size_t last = 0);

/// What the static sources' matched-filtered SNR of a stack is made from (issue 16: a device may make it):
/// rc = the residual stack times its count (float), `count`, and the Moffat kernel's (2r+1)^2 taps `k` (row
/// by row). Pixel (x, y) of the result is float(num / (sigma sqrt(den))) where den > 0, else 0, with
/// num = sum k(i, j) rc(x + i, y + j) and den = sum (k(i, j) k(i, j)) count(x + i, y + j) over the taps
/// inside the image, in double, rows j then columns i ascending, each product rounded before its sum.
struct FilteredSnrInputs {
  const float* rc = nullptr;
  const float* count = nullptr;
  int width = 0, height = 0;
  const double* k = nullptr;
  int r = 0;
  double sigma = 0.0;
};

/// Stacks of one cube at one rate, made once and handed out again: pre-processing asks for the same stacks
/// several times (the PSF's catalogue: the whole cube's stack and its thirds'; the PSF: the whole cube's; the
/// static-source search at the fitted FWHM: those and its halves'), one full pass over the cube each. The
/// cube must not change while the cache is in use; requests differing in rate, subtracted level or frame
/// range are separate stacks.
class SkyStackCache {
 public:
  /// Makes a stack elsewhere (a device, issue 16): the same contract as stackAtSkyRate(cube, rate, subtract,
  /// first, last) with `last` resolved (never 0); none: not made there, the CPU makes it.
  using Provider = std::function<std::optional<SkyStack>(
      const FrameCube& cube, Velocity rate, double subtract, std::size_t first, std::size_t last)>;

  /// stackAtSkyRate(cube, rate, subtract, progress, cancel, first, last), made on the first request (by the
  /// provider when there is one and it makes it).
  const SkyStack& stack(const FrameCube& cube, Velocity rate, double subtract, ProgressSink& progress,
                        CancelToken& cancel, std::size_t first = 0, std::size_t last = 0);

  void setProvider(Provider provider) { m_provider = std::move(provider); }

  /// Makes the filtered SNR of FilteredSnrInputs elsewhere (a device, issue 16), the same values; none: not
  /// made there, the CPU makes it.
  using SnrProvider = std::function<std::optional<std::vector<float>>(const FilteredSnrInputs& in)>;
  void setSnrProvider(SnrProvider provider) { m_snrProvider = std::move(provider); }
  /// The SNR provider, or null.
  [[nodiscard]] const SnrProvider* snrProvider() const { return m_snrProvider ? &m_snrProvider : nullptr; }
  /// A frame range [first, last) of a cube (last = 0: to its last frame).
  using Range = std::pair<std::size_t, std::size_t>;
  /// Starts making the stacks of these ranges (those not made yet) by the provider, one after another on a
  /// thread of its own (issue 16: a device makes them beside the host work that comes before they are asked
  /// for); stack() takes each as it is asked for, waiting for it if need be, and the CPU makes one the
  /// provider did not. Nothing without a provider; one in flight is waited for first. The provider is then
  /// called from that thread beside this thread's own calls of it and of the SNR provider: the caller makes
  /// those calls exclusive (pipeline/preprocess.cpp). The cube must stay unchanged until settle() or the
  /// cache's end.
  void prefetch(const FrameCube& cube, Velocity rate, double subtract, const std::vector<Range>& ranges);
  /// False: prefetch() does nothing (each stack made when asked; the same stacks).
  void allowPrefetch(bool allow) { m_prefetchAllowed = allow; }
  /// Waits for a prefetch in flight; its stacks stay for stack().
  void settle();
  /// The prefetch's stack of this range moved out to the caller (waiting for it; not kept here): `*found`
  /// says whether it had one (not when its provider declined it: the caller asks again); its exception
  /// rethrown.
  std::optional<SkyStack> takePrefetched(const FrameCube& cube, Velocity rate, double subtract,
                                         std::size_t first, std::size_t last, bool* found);

  /// Stacks made so far, those of them the provider made, and the wall time spent making them (s): on this
  /// thread (a prefetched stack counts the wait for it only).
  [[nodiscard]] int made() const { return m_made; }
  [[nodiscard]] int provided() const { return m_provided; }
  [[nodiscard]] double seconds() const { return m_seconds; }
  /// The stacks handed out that the provider made ahead on the prefetches' thread, and that thread's wall
  /// time (s).
  [[nodiscard]] int prefetched() const { return m_prefetched; }
  [[nodiscard]] double prefetchSeconds() const;

  /// What a static-source search derives from these stacks without the FWHM (issue 16: ~8 ms each on
  /// paper-neo's 1500 frames): the stacks of the thirds less their mesh backgrounds (the movers' test) and
  /// the whole stack's first analysis (mesh background, residual, noise, per-pixel SNR). Kept for a later
  /// search of the same cube at the same rate, level and mesh (the PSF's catalogue, then the search at the
  /// fitted FWHM); the caller knows each kind's type (static_sources.cpp). Null: none kept.
  enum class Derived { Thirds, FirstAnalysis };
  [[nodiscard]] std::shared_ptr<const void> derived(Derived kind, const FrameCube& cube, Velocity rate,
                                                    double subtract, int meshPx) const;
  void keepDerived(Derived kind, const FrameCube& cube, Velocity rate, double subtract, int meshPx,
                   std::shared_ptr<const void> value);

 private:
  using Key = std::tuple<const void*, double, double, double, std::size_t, std::size_t>;
  struct Prefetch;  // sky_stack.cpp; shared_ptr: its thread is joined when the last owner lets it go
  std::map<Key, SkyStack> m_stacks;
  Provider m_provider;
  SnrProvider m_snrProvider;
  std::shared_ptr<Prefetch> m_prefetch;
  std::map<Key, SkyStack> m_ahead;  // made ahead, not asked for yet (a settled prefetch's)
  std::map<std::tuple<Derived, const void*, double, double, double, int>, std::shared_ptr<const void>>
      m_derived;
  int m_made = 0, m_provided = 0, m_prefetched = 0;
  bool m_prefetchAllowed = true;
  double m_seconds = 0.0, m_prefetchSecondsBefore = 0.0;
};

/// A smooth local background of an image: one-sided clip (xi = 3) of each `mesh` x `mesh` cell over pixels
/// with weight > 0, bilinearly interpolated between cell centres (the SExtractor scheme).
Image meshBackground(const Image& image, const Image& weight, int mesh);

/// `mean` less `local` where `count` > 0, else 0 (a stack less its mesh background), on every core.
Image residualWhereCounted(const Image& mean, const Image& count, const Image& local);

}  // namespace st::detect
