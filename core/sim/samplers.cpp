#include "st/sim/samplers.hpp"

#include <cmath>

namespace st::sim {

namespace {

std::uint64_t splitMix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ULL);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

// Sequential search of the CDF with one uniform (exact up to rounding of the CDF, < 1e-15 for mean < 10).
std::int64_t poissonInversion(Rng& rng, double mean) {
  const double u = uniform01(rng);
  double p = std::exp(-mean);
  double cdf = p;
  std::int64_t k = 0;
  while (u > cdf && k < 1000) {
    ++k;
    p *= mean / static_cast<double>(k);
    cdf += p;
  }
  return k;
}

// Hormann (1993), "The transformed rejection method for generating Poisson random variables", PTRS.
std::int64_t poissonPtrs(Rng& rng, double mean) {
  const double slam = std::sqrt(mean);
  const double loglam = std::log(mean);
  const double b = 0.931 + 2.53 * slam;
  const double a = -0.059 + 0.02483 * b;
  const double invalpha = 1.1239 + 1.1328 / (b - 3.4);
  const double vr = 0.9277 - 3.6224 / (b - 2.0);
  for (;;) {
    const double u = uniform01(rng) - 0.5;
    const double v = uniform01(rng);
    const double us = 0.5 - std::fabs(u);
    const double k = std::floor((2.0 * a / us + b) * u + mean + 0.43);
    if (us >= 0.07 && v <= vr) return static_cast<std::int64_t>(k);
    if (k < 0.0 || (us < 0.013 && v > us)) continue;
    if (std::log(v) + std::log(invalpha) - std::log(a / (us * us) + b) <=
        -mean + k * loglam - std::lgamma(k + 1.0)) {
      return static_cast<std::int64_t>(k);
    }
  }
}

}  // namespace

std::uint64_t streamSeed(std::uint64_t seed, std::uint64_t stream) {
  std::uint64_t state = seed;
  const std::uint64_t a = splitMix64(state);
  state = a ^ (stream * 0xD1B54A32D192ED03ULL);
  splitMix64(state);
  return splitMix64(state);
}

double normal01(Rng& rng) {
  for (;;) {
    const double u = 2.0 * uniform01(rng) - 1.0;
    const double v = 2.0 * uniform01(rng) - 1.0;
    const double s = u * u + v * v;
    if (s > 0.0 && s < 1.0) return u * std::sqrt(-2.0 * std::log(s) / s);
  }
}

double NormalPairs::next(Rng& rng) {
  if (m_hasSpare) {
    m_hasSpare = false;
    return m_spare;
  }
  for (;;) {
    const double u = 2.0 * uniform01(rng) - 1.0;
    const double v = 2.0 * uniform01(rng) - 1.0;
    const double s = u * u + v * v;
    if (s > 0.0 && s < 1.0) {
      const double f = std::sqrt(-2.0 * std::log(s) / s);
      m_spare = v * f;
      m_hasSpare = true;
      return u * f;
    }
  }
}

double emRegister(Rng& rng, std::int64_t electrons, double gain) {
  if (electrons <= 0) return 0.0;
  if (electrons > 12) return gammaSample(rng, static_cast<double>(electrons), gain);
  double product = uniformOpen0(rng);
  for (std::int64_t k = 1; k < electrons; ++k)
    product *= uniformOpen0(rng);
  return -gain * std::log(product);
}

std::int64_t poisson(Rng& rng, double mean) {
  if (!(mean > 0.0)) return 0;
  return mean < 10.0 ? poissonInversion(rng, mean) : poissonPtrs(rng, mean);
}

double gammaSample(Rng& rng, double shape, double scale) {
  if (shape < 1.0) {
    // Gamma(k) = Gamma(k + 1) * U^(1/k).
    return gammaSample(rng, shape + 1.0, scale) * std::pow(uniformOpen0(rng), 1.0 / shape);
  }
  const double d = shape - 1.0 / 3.0;
  const double c = 1.0 / std::sqrt(9.0 * d);
  for (;;) {
    double x = 0.0;
    double v = 0.0;
    do {
      x = normal01(rng);
      v = 1.0 + c * x;
    } while (v <= 0.0);
    v = v * v * v;
    const double u = uniformOpen0(rng);
    if (u < 1.0 - 0.0331 * x * x * x * x) return d * v * scale;
    if (std::log(u) < 0.5 * x * x + d * (1.0 - v + std::log(v))) return d * v * scale;
  }
}

}  // namespace st::sim
