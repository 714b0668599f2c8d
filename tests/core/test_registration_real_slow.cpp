// Registration on real frames (issue 15, "done when"): the Lowell 42-inch sequence of (5945) Roachapproach
// (../shared/data/real/lowell42-5945; skipped when absent), calibrated with its biases and flats, then given
// simulated pointing errors: every frame but the first moved by an integer dither of up to 20 px per axis,
// and the second half by a further re-pointing of (61, -43) px (each frame's 1024 x 1024 window taken from the
// trimmed frame at a position moved by the dither, so every pixel holds real sky, as at a telescope; until
// 2026-11-27 the crop itself was shifted, with masked bands along its edges that real dithers do not have).
// Pre-processed and searched like the undithered sequence (test_pipeline_real_slow.cpp's grid,
// +-0.2 deg/day in 1 px steps over the span), the asteroid must be found at the same place (within 1 px), the
// same velocity relative to the stars (within 3 px over the span) and an SNR not below 97% of the
// undithered one (the 3%), both taken at the best phase of the
// search's pixel lattice (refine_candidate.hpp: the dithered
// run's offsets count from its first frame, the undithered run's model from t_ref, and the rounding of the
// shifts then falls differently on the asteroid's sub-pixel track); the registration must report per-frame
// offsets that match the dithers within 0.3 px. Runs on a 1024 x 1024 crop around the asteroid: ~100 CPU-s
// (3-4 min wall on the shared 2-core machine).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "dither_frames.hpp"
#include "refine_candidate.hpp"
#include "st/calib/calibration.hpp"
#include "st/detect/registration.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/search/cpu_backend.hpp"
#include "test_support.hpp"

namespace st::pipeline {
namespace {

// The asteroid in the full trimmed frame, and the 1024 x 1024 crop both runs use (a quarter of the pixels:
// the two pre-processings and searches stay within the slow suite's budget).
constexpr int kCropX = 161, kCropY = 211, kCrop = 1024;
constexpr double kX = 673.0 - kCropX, kY = 723.5 - kCropY;

/// The 1024 x 1024 window at (kCropX, kCropY) of every frame; with `dithers`, frame n's window moved by
/// -d[n], so that its star field moves by +d[n] and every pixel still holds real sky (a telescope's dither,
/// not an image shifted with an uncovered band).
FrameCube crop(const FrameCube& in, const std::vector<std::pair<int, int>>& dithers = {}) {
  FrameCube out(kCrop, kCrop, in.frameCount());
  out.info() = in.info();
  out.header = in.header;
  out.plateScaleArcsecPerPx = in.plateScaleArcsecPerPx;
  const bool masked = !in.mask().empty();
  if (masked) out.mask().assign(out.framePixels() * in.frameCount(), 0);
  for (std::size_t n = 0; n < in.frameCount(); ++n) {
    const int dx = dithers.empty() ? 0 : dithers[n].first, dy = dithers.empty() ? 0 : dithers[n].second;
    for (int y = 0; y < kCrop; ++y) {
      const std::size_t src =
          n * in.framePixels() + static_cast<std::size_t>(y + kCropY - dy) * in.width() + (kCropX - dx);
      const std::size_t dst = n * out.framePixels() + static_cast<std::size_t>(y) * kCrop;
      std::copy_n(in.pixels().begin() + static_cast<std::ptrdiff_t>(src), kCrop,
                  out.pixels().begin() + static_cast<std::ptrdiff_t>(dst));
      if (masked)
        std::copy_n(in.mask().begin() + static_cast<std::ptrdiff_t>(src), kCrop,
                    out.mask().begin() + static_cast<std::ptrdiff_t>(dst));
    }
  }
  return out;
}

struct Found {
  search::Candidate candidate;  ///< at the refined velocity (refine_candidate.hpp)
  search::Candidate phased;     ///< at the refined velocity and the best lattice phase
  double gridSnr = 0.0;          ///< on the search's own grid
  bool found = false;
  detect::Registration registration;
  Velocity skyRate;
};

Found prepareAndSearch(FrameCube calibrated, double plateFallback) {
  NullProgress p;
  CancelToken c;
  PreprocessParams params;  // the frames are calibrated already: no overscan, no trim, no masters
  params.registerFrames = true;
  params.calib.subtractOverscan = false;
  params.calib.trim = false;
  params.calib.useHeaderSections = false;
  Prepared out = preprocess(std::move(calibrated), params, p, c);
  for (const auto& n : out.notes)
    std::printf("  note: %s\n", n.c_str());
  const double span = out.filtered.frames.timeSpanS();
  const double step = 1.0 / span;
  const double plate = out.filtered.frames.plateScaleArcsecPerPx.value_or(plateFallback);
  const int half = static_cast<int>(std::ceil(degPerDayToPxPerSec(0.2, plate) / step));
  const search::VelocityGrid grid{out.skyRate, step, 2 * half + 1, 2 * half + 1};
  const search::SearchResult r = search::makeCpuBackend()->search(out.filtered, grid, {}, p, c);
  Found f;
  f.registration = out.registration;
  f.skyRate = out.skyRate;
  const auto it = std::find_if(r.candidates.begin(), r.candidates.end(), [](const search::Candidate& cd) {
    return std::hypot(cd.x - kX, cd.y - kY) <= 2.0;
  });
  if (it != r.candidates.end()) {
    f.gridSnr = it->snr;
    f.candidate = test::refineCandidate(out.filtered, *it, step);
    f.phased = test::refineCandidatePhase(out.filtered, f.candidate, step);
    f.found = true;
  }
  return f;
}

TEST(RegistrationReal, Lowell5945DitheredAndRepointedIsFoundAsUndithered) {
  test::Lowell5945 lowell = test::loadLowell5945();
  if (!lowell.found) GTEST_SKIP() << "no real data";
  FrameCube cube = std::move(lowell.science);
  ASSERT_EQ(cube.frameCount(), 15u);
  const FrameCube& bias = lowell.bias;
  const FrameCube& flat = lowell.flat;
  NullProgress p;
  CancelToken c;
  calib::CalibParams cp;
  const calib::MasterCalibration masters = calib::buildMasters(bias, FrameCube{}, flat, cube, cp, p, c);
  calib::applyCalibration(cube, masters, cp, p, c);
  const auto dithers = test::randomDithers(cube.frameCount(), 20, {61, -43}, 42);
  for (const auto& [dx, dy] : dithers) {  // every moved window inside the trimmed frame
    ASSERT_TRUE(kCropX - dx >= 0 && kCropX - dx + kCrop <= cube.width()) << dx;
    ASSERT_TRUE(kCropY - dy >= 0 && kCropY - dy + kCrop <= cube.height()) << dy;
  }
  FrameCube dithered = crop(cube, dithers);
  cube = crop(cube);

  std::printf("undithered:\n");
  const Found still = prepareAndSearch(std::move(cube), 0.981);
  std::printf("dithered:\n");
  const Found moved = prepareAndSearch(std::move(dithered), 0.981);
  ASSERT_TRUE(still.found) << "5945 not found in the undithered frames";
  ASSERT_TRUE(moved.found) << "5945 not found in the dithered frames";
  std::printf("undithered (%d, %d) v (%.5f, %.5f) SNR %.2f; dithered (%d, %d) v (%.5f, %.5f) SNR %.2f\n",
              still.candidate.x, still.candidate.y, still.candidate.v.vx, still.candidate.v.vy,
              still.candidate.snr, moved.candidate.x, moved.candidate.y, moved.candidate.v.vx,
              moved.candidate.v.vy, moved.candidate.snr);
  EXPECT_EQ(still.registration.model, detect::Registration::Model::Linear) << still.registration.note;
  ASSERT_EQ(moved.registration.model, detect::Registration::Model::PerFrame) << moved.registration.note;
  // The measured star-field positions (relative to the first frame) are the dithers plus the undithered
  // sequence's own (sub-pixel) drift.
  ASSERT_EQ(moved.registration.offsets.size(), dithers.size());
  const auto& pos = moved.registration.position;
  const auto& drift = still.registration.position;
  ASSERT_EQ(pos.size(), dithers.size());
  ASSERT_EQ(drift.size(), dithers.size());
  double worst = 0.0, sum2 = 0.0;
  for (std::size_t n = 0; n < dithers.size(); ++n) {
    const double ex = pos[n].x - dithers[n].first - drift[n].x, ey = pos[n].y - dithers[n].second - drift[n].y;
    worst = std::max(worst, std::hypot(ex, ey));
    sum2 += ex * ex + ey * ey;
    std::printf("frame %2zu: dither (%3d, %3d) measured - dither - drift (%+.3f, %+.3f) px\n", n, dithers[n].first,
                dithers[n].second, ex, ey);
  }
  std::printf("registration error: rms %.3f px, max %.3f px\n", std::sqrt(sum2 / dithers.size()), worst);
  for (std::size_t n = 0; n < dithers.size(); ++n) {
    EXPECT_NEAR(pos[n].x - dithers[n].first, drift[n].x, 0.3) << "frame " << n;
    EXPECT_NEAR(pos[n].y - dithers[n].second, drift[n].y, 0.3) << "frame " << n;
  }
  EXPECT_LE(std::abs(moved.candidate.x - still.candidate.x), 1);
  EXPECT_LE(std::abs(moved.candidate.y - still.candidate.y), 1);
  // Velocities relative to the stars (the fitted rates of the two runs differ a little).
  const double span = 15 * 300.0;
  const Velocity a{still.candidate.v.vx - still.skyRate.vx, still.candidate.v.vy - still.skyRate.vy};
  const Velocity b{moved.candidate.v.vx - moved.skyRate.vx, moved.candidate.v.vy - moved.skyRate.vy};
  EXPECT_LE(std::hypot(a.vx - b.vx, a.vy - b.vy) * span, 3.0) << "relative velocities differ";
  // The 3%, at each run's best lattice phase. Measured 2026-11-27 (dev VM): refined 1187.2 vs 1056.6
  // (0.890) with the lattices as they fall, 1.02 with the dithered offsets moved by the undithered model's
  // 0.31 px. Until the cosmic-ray stage kept the cores of resolved sources (calib/cosmic_rays.hpp,
  // sourceMedianLow) it zeroed 2-10 of 5945's core pixels per frame, differently in the two runs: 790 vs 712.
  std::printf("SNR ratio dithered / undithered %.3f at refined velocities, %.3f on the grids; at the best lattice "
              "phases %.2f / %.2f = %.3f (issue target 0.97-1.03)\n",
              moved.candidate.snr / still.candidate.snr, moved.gridSnr / still.gridSnr, moved.phased.snr,
              still.phased.snr, moved.phased.snr / still.phased.snr);
  // The 3%: 0.973 (2026-11-27, dev VM) since the dithered frames are moved by whole pixels onto
  // the first frame's grid for the per-pixel stages and back after the matched filter
  // (RegistrationParams::alignWholePixels, on by default; 0.934 without). What is left: the PSF fit picks
  // 1.29 px on the dithered stack against 1.57 px undithered among the same 9 disagreeing stars.
  EXPECT_GE(moved.phased.snr, 0.97 * still.phased.snr);
}

}  // namespace
}  // namespace st::pipeline
