#pragma once
// Random samplers of the simulator, written here on top of std::mt19937_64 so that a seed gives the same
// numbers with any standard library (std::*_distribution are implementation-defined).
#include <cstdint>
#include <random>

namespace st::sim {

using Rng = std::mt19937_64;

/// A well-mixed 64-bit seed for stream `stream` of a simulation with `seed` (SplitMix64 of both), so
/// per-frame streams are independent of each other and of the thread count.
std::uint64_t streamSeed(std::uint64_t seed, std::uint64_t stream);

/// Uniform in [0, 1) with 53 random bits.
inline double uniform01(Rng& rng) {
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;
}
/// Uniform in (0, 1]: safe for log().
inline double uniformOpen0(Rng& rng) {
  return (static_cast<double>(rng() >> 11) + 1.0) * 0x1.0p-53;
}

/// Standard normal (Marsaglia polar method; the second value of each pair is discarded).
double normal01(Rng& rng);

/// Standard normals from the polar method, keeping the second value of each pair (twice as fast as
/// normal01 in per-pixel loops).
class NormalPairs {
 public:
  double next(Rng& rng);

 private:
  double m_spare = 0.0;
  bool m_hasSpare = false;
};
/// Poisson with mean `mean` >= 0: inversion for mean < 10, Hormann's PTRS transformed rejection above
/// (W. Hormann 1993, the method numpy uses). Exact in distribution.
std::int64_t poisson(Rng& rng, double mean);
/// Output of an EM register of gain `gain` for `electrons` input electrons: Gamma(electrons, gain)
/// (Basden et al. 2003, high-gain limit), 0 for no electrons. Sum of exponentials for up to 12
/// electrons (one log), Marsaglia-Tsang above.
double emRegister(Rng& rng, std::int64_t electrons, double gain);
/// Gamma with integer-or-real shape k > 0 and scale theta (Marsaglia & Tsang 2000; k < 1 by boosting).
double gammaSample(Rng& rng, double shape, double scale);

}  // namespace st::sim
