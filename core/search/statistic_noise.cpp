#include "st/search/statistic_noise.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "st/common/parallel.hpp"
#include "st/search/ipsa.hpp"
#include "st/stats/sigma_clip.hpp"

namespace st::search {
namespace {

constexpr double kSamples = 1e7;  ///< frame samples in all (cells x frames)
constexpr int kMinCells = 2000, kMaxCells = 20000;
constexpr int kMinKept = 1000;  ///< fewer cells with N_in >= minFrames: not measured
constexpr double kClip = 3.0;
constexpr double kClipCorrection = 0.98658;  ///< sd of a unit normal truncated at +-3
constexpr std::size_t kFramesPerChunk = 64;  ///< fixed chunks: the same sums whatever the threads

struct Cell {
  int x = 0, y = 0;
  Velocity v;
};

}  // namespace

int statisticNoiseCells(std::size_t frames) noexcept {
  if (frames == 0) return 0;
  const double n = kSamples / static_cast<double>(frames);
  return static_cast<int>(std::clamp(n, static_cast<double>(kMinCells), static_cast<double>(kMaxCells)));
}

StatisticNoise measureStatisticNoise(const FilteredCube& cube, const VelocityGrid& grid, int minFrames,
                                     CancelToken& cancel, std::uint64_t seed) {
  StatisticNoise out;
  const FrameCube& f = cube.frames;
  const std::size_t nf = f.frameCount();
  const int w = f.width(), h = f.height();
  if (!(cube.sigmaF > 0.0) || nf == 0 || w <= 0 || h <= 0 || grid.nvx <= 0 || grid.nvy <= 0) return out;
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> ux(0, w - 1), uy(0, h - 1), uvx(0, grid.nvx - 1), uvy(0, grid.nvy - 1);
  std::vector<Cell> cells(static_cast<std::size_t>(statisticNoiseCells(nf)));
  for (Cell& c : cells) {
    c.x = ux(rng);
    c.y = uy(rng);
    const int ivx = uvx(rng);
    c.v = grid.at(ivx, uvy(rng));
  }
  // Frame by frame (each frame's samples of every cell, a frame at a time in cache), in fixed chunks of
  // frames whose partial sums are added in order.
  const std::vector<double> dt = f.timeOffsetsS();
  const std::size_t chunks = (nf + kFramesPerChunk - 1) / kFramesPerChunk;
  std::vector<double> sums(chunks * cells.size(), 0.0);
  std::vector<int> counts(chunks * cells.size(), 0);
  parallelFor(chunks, 1, [&](std::size_t c0, std::size_t c1) {
    for (std::size_t c = c0; c < c1; ++c) {
      cancel.throwIfCancelled();
      double* s = sums.data() + c * cells.size();
      int* k = counts.data() + c * cells.size();
      for (std::size_t n = c * kFramesPerChunk; n < std::min(nf, (c + 1) * kFramesPerChunk); ++n) {
        const FrameInfo& info = f.info()[n];
        const float* img = f.frame(n);
        for (std::size_t i = 0; i < cells.size(); ++i) {
          const int xs = cells[i].x + ipsaShift(cells[i].v.vx, dt[n], info.offsetXPx);
          const int ys = cells[i].y + ipsaShift(cells[i].v.vy, dt[n], info.offsetYPx);
          if (xs < 0 || ys < 0 || xs >= w || ys >= h) continue;
          s[i] += img[static_cast<std::size_t>(ys) * w + xs];
          ++k[i];
        }
      }
    }
  });
  std::vector<float> snr;
  snr.reserve(cells.size());
  for (std::size_t i = 0; i < cells.size(); ++i) {
    double s = 0.0;
    int nIn = 0;
    for (std::size_t c = 0; c < chunks; ++c) {
      s += sums[c * cells.size() + i];
      nIn += counts[c * cells.size() + i];
    }
    if (nIn >= std::max(1, minFrames))
      snr.push_back(static_cast<float>(s / (cube.sigmaF * std::sqrt(static_cast<double>(nIn)))));
  }
  if (static_cast<int>(snr.size()) < kMinKept) return out;
  // The project's symmetric iterative clip (a source on a random track is an outlier either way round).
  const stats::ClipStats clip = stats::sigmaClipSymmetric(snr.data(), snr.size(), kClip);
  if (static_cast<int>(clip.count) < kMinKept || !(clip.sigma > 0.0)) return out;
  out.scale = clip.sigma / kClipCorrection;
  out.mean = clip.mean;
  out.cells = static_cast<int>(snr.size());
  out.standardError = out.scale / std::sqrt(2.0 * static_cast<double>(clip.count));
  return out;
}

std::string statisticNoiseNote(const StatisticNoise& noise) {
  if (!noise.measured()) return "search statistic's noise: not measured (too few cells inside the frames)";
  char text[320];
  std::snprintf(text, sizeof text,
                "search statistic's noise on this cube: %.3f +- %.3f of the unit sigma_F sqrt(N_in), mean "
                "%+.3f (%d random cells, 3-sigma clipped; the paper's Prob_false assumes 1 and 0)",
                noise.scale, noise.standardError, noise.mean, noise.cells);
  return text;
}

}  // namespace st::search
