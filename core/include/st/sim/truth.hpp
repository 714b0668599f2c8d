#pragma once
// The truth of a simulated observation: what the simulator put into the frames, for scoring every later
// stage. Written next to the cube as OUT.truth.json; JSON keys carry their units (ARCHITECTURE.md).
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace st::sim {

struct TruthObject {
  std::string name;
  double xRefPx = 0.0;  ///< x at t_ref, 0-based (frame coordinates)
  double yRefPx = 0.0;
  double vxPxPerS = 0.0;  ///< velocity in the frames (sky drift + own motion), px/s: what a search finds
  double vyPxPerS = 0.0;
  double skyVxPxPerS = 0.0;  ///< own motion relative to the stars, px/s
  double skyVyPxPerS = 0.0;
  double rateDegPerDay = 0.0;       ///< |own motion| relative to the stars, deg/day
  double frameRateDegPerDay = 0.0;  ///< |velocity in the frames|, deg/day
  double magnitude = 0.0;
  double photonsPerFrame = 0.0;  ///< detected photons per frame (before flat, EM gain)
  /// Expected matched-filter SNR, paper \label{detection_snr}: photons * sqrt(sum_n sum_px P_n^2) / sigma_n,
  /// with P_n the object's rendered (pixel-integrated, trailed) profile in frame n normalised to unit sum,
  /// summed over the frames where it is inside; sigma_n = noise per pixel in photon units. Equal to
  /// photons sqrt(N_f) sqrt(sum P^2) / sigma_n for identical frames.
  double expectedSnr = 0.0;
  /// The same SNR in a stack that tracks the sky (the stars): the object is streaked; exact on the grid
  /// for a point-source (PSF) matched filter at the streak centre.
  double skyStackSnr = 0.0;
  int framesInside = 0;  ///< frames in which the object's centre is inside the frame
};

struct TruthStar {
  double xRefPx = 0.0;  ///< at t_ref, 0-based; moves with the sky drift
  double yRefPx = 0.0;
  double magnitude = 0.0;
  double photonsPerFrame = 0.0;
  bool saturated = false;  ///< some pixel reached the full well in the noise-free image
  bool spikes = false;     ///< diffraction spikes were drawn
};

struct TruthCosmicRay {
  int frame = 0;
  double xPx = 0.0;  ///< centre of the hit, 0-based
  double yPx = 0.0;
  double peakAdu = 0.0;                     ///< amplitude added to the brightest pixel, ADU
  std::vector<std::pair<int, int>> pixels;  ///< every pixel (x, y) that received charge
};

struct TruthHotPixel {
  int x = 0;
  int y = 0;
  double excessAdu = 0.0;  ///< added to every frame, ADU
};

struct Truth {
  std::string preset;
  std::uint64_t seed = 0;
  int width = 0;
  int height = 0;
  int frames = 0;
  bool noiseless = false;  ///< frames hold expected values; the sigmas below are the model's
  double tRefMjd = 0.0;
  double frameRateHz = 0.0;
  double exposureS = 0.0;
  double plateScaleArcsecPerPx = 0.0;
  double psfRadiusPx = 0.0;  ///< Moffat R
  double psfBeta = 0.0;
  double psfFwhmPx = 0.0;
  double skyVxPxPerS = 0.0;  ///< drift of the star field in the frames
  double skyVyPxPerS = 0.0;
  double gainEPerAdu = 0.0;
  double emGain = 1.0;
  double aduPerPhoton = 0.0;  ///< emGain / gainEPerAdu: calibrated ADU per detected photon
  double zeroPointPhotonsPerS = 0.0;
  /// Per frame, calibrated ((raw - bias) / flat) ADU: sky level and per-pixel noise sigma (rms over pixels
  /// of the flat's effect).
  std::vector<double> skyAdu;
  std::vector<double> noiseSigmaAdu;
  double noiseSigmaPhotons = 0.0;  ///< sigma_n of detection_snr, photon units (frame 0)
  std::vector<TruthObject> objects;
  std::vector<TruthStar> stars;
  std::vector<TruthCosmicRay> cosmicRays;
  std::vector<TruthHotPixel> hotPixels;
};

nlohmann::json toJson(const Truth& truth);
/// Throws st::InputError naming the missing or malformed key.
Truth truthFromJson(const nlohmann::json& json);
/// Writes pretty JSON; throws st::InputError naming the path when it cannot be written.
void writeTruth(const std::string& path, const Truth& truth);
/// Reads a truth file; throws st::InputError naming the path (missing, not JSON, wrong keys).
Truth readTruth(const std::string& path);

}  // namespace st::sim
