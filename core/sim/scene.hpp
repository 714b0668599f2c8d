#pragma once
// Internal to core/sim: the plan of one simulated observation (times, calibration patterns, sources,
// artefacts), drawn from the seed before any frame is rendered, so that frames can be rendered in any order.
#include <cstdint>
#include <vector>

#include "st/common/image.hpp"
#include "st/sim/simulator.hpp"
#include "st/sim/truth.hpp"

namespace st::sim::detail {

/// RNG stream numbers (streamSeed): fixed so a seed always means the same scene.
enum Stream : std::uint64_t {
  kStreamStars = 1,
  kStreamFlat = 2,
  kStreamBias = 3,
  kStreamCosmic = 4,
  kStreamHot = 5,
  kStreamCalib = 1000000,  // + k for calibration frame k
  kStreamFrame = 2000000,  // + n for frame n
};

struct CosmicRayPlan {
  TruthCosmicRay truth;
  std::vector<double> amplitudesAdu;  // per truth.pixels entry
};

struct Scene {
  std::vector<double> mjdMid;    // per frame
  std::vector<double> tOffsetS;  // t_n - t_ref, s
  double tRefMjd = 0.0;
  Image flat;  // mean 1
  Image bias;  // ADU
  std::vector<TruthStar> stars;
  std::vector<int> starRadius;  // stamp radius drawn per star
  std::vector<TruthObject> objects;
  std::vector<std::vector<std::size_t>> cosmicByFrame;  // indices into cosmic
  std::vector<CosmicRayPlan> cosmic;
  std::vector<TruthHotPixel> hot;
};

/// Photons per frame of a source of magnitude `mag`.
double photonsPerFrame(const SimParams& p, double mag);

Scene planScene(const SimParams& params, std::uint64_t seed);

/// Noise of a calibrated frame ((raw - bias) / flat) at the sky level of `p`: rms over pixels of the
/// per-pixel sigma, ADU. Uses the flat (empty flat = 1 everywhere).
double calibratedSigmaAdu(const SimParams& p, const Image& flat);

}  // namespace st::sim::detail
