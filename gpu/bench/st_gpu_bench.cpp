// st_gpu_bench: the benchmark of issue 5 on the device machine. The paper's problem (Zhai et al. 2014,
// section 4: 1500 frames of 512 x 512, 100 x 100 trial velocities; a Tesla K20c took just under 90 s):
//   - end-to-end CudaBackend::search (plan, upload, kernels, reduction, candidates), twice;
//   - additions/s of the tiled kernel, and of the naive one-thread-per-(pixel, velocity) kernel on the
//     same cube (a band of velocity rows, so the naive run stays short), both timed with device events;
//   - stackAt for 500 x 512^2 (device time of the kernels, and the whole call).
//   - the tree search (method "tree") on the same cube: end-to-end, upload, kernels, operation count;
//   - exact: the stair kernel's variants, and Float16 frames against Float32 (SNR error on the map of every
//     velocity and on the candidates, the cube with its source and a cube of noise alone).
// Usage: st_gpu_bench [frames] [size] [nv] [naiveRows] [stackFrames] [all|tree|exact|half]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>
#include <thread>
#include <vector>

#include "st/common/error.hpp"
#include "st/gpu/cuda_backend.hpp"
#include "cuda_bench_options.hpp"
#include "st/psf/moffat.hpp"
#include "stack_engine.hpp"

namespace {

using st::search::FilteredCube;
using st::search::VelocityGrid;

/// Noise of sigma ~1 (sum of 4 uniforms, scaled), generated on every core; a source at (200, 300).
FilteredCube makeCube(int n, int size, st::Velocity src, float peak = 0.4f) {
  FilteredCube c;
  c.frames = st::FrameCube(size, size, static_cast<std::size_t>(n));
  c.sigmaF = 1.0;
  c.psfFwhmPx = 2.5;
  c.revision = st::search::nextCubeRevision();  // kept on the device between searches
  for (int k = 0; k < n; ++k)
    c.frames.info()[k].mjdMid = 60000.0 + (k / 16.7) / st::kSecondsPerDay;
  st::PixelVector& px = c.frames.pixels();
  const unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  std::vector<std::thread> pool;
  for (unsigned t = 0; t < threads; ++t) {
    pool.emplace_back([&, t] {
      std::uint64_t s = 0x9E3779B97F4A7C15ull * (t + 1);
      const std::size_t b = px.size() * t / threads;
      const std::size_t e = px.size() * (t + 1) / threads;
      for (std::size_t i = b; i < e; ++i) {
        float u = 0.0f;
        for (int j = 0; j < 4; ++j) {
          s ^= s << 13;
          s ^= s >> 7;
          s ^= s << 17;
          u += static_cast<float>(s >> 40) * (1.0f / 16777216.0f);
        }
        px[i] = (u - 2.0f) * 1.7320508f;  // variance of the sum of 4 U(0,1) is 1/3
      }
    });
  }
  for (auto& t : pool)
    t.join();
  // The source: a matched-filtered point source (the PSF convolved with itself: a Moffat of FWHM
  // sqrt(2) x psfFwhmPx, peak 0.4 sigma) at its true sub-pixel position in each frame (issue 16: the tree's
  // SNR cost is measured on a PSF, not on a single pixel, which loses whole frames to +-1 px track errors).
  const st::psf::Moffat filtered = st::psf::Moffat::fromFwhm(std::sqrt(2.0) * c.psfFwhmPx);
  const std::vector<double> dt = c.frames.timeOffsetsS();
  for (int k = 0; k < n; ++k) {
    const double xc = 200 + src.vx * dt[k], yc = 300 + src.vy * dt[k];
    const int x0 = static_cast<int>(std::lround(xc)), y0 = static_cast<int>(std::lround(yc));
    for (int y = y0 - 5; y <= y0 + 5; ++y)
      for (int x = x0 - 5; x <= x0 + 5; ++x)
        if (x >= 0 && y >= 0 && x < size && y < size)
          c.frames.frame(k)[static_cast<std::size_t>(y) * size + x] +=
              peak * static_cast<float>(filtered.pixelMean(x - xc, y - yc, 4));
  }
  return c;
}

struct Quiet final : st::ProgressSink {
  void report(double, std::string_view) override {}
};

/// Float16 against Float32 on the same cube: relative SNR error over the map of every velocity (its best
/// cell) and over the candidates found by both (same cell and velocity).
void compareHalf(const char* what, const st::search::SearchResult& f, const st::search::SearchResult& h) {
  double mapMax = 0.0, mapSum = 0.0;
  int moved = 0, n = 0;
  for (std::size_t i = 0; i < f.map.maxSnr.size(); ++i) {
    if (f.map.argX[i] < 0 || h.map.argX[i] < 0) continue;
    const double e = std::abs(double(h.map.maxSnr[i]) - f.map.maxSnr[i]) /
                     std::max(1e-6, std::abs(double(f.map.maxSnr[i])));
    mapMax = std::max(mapMax, e);
    mapSum += e;
    ++n;
    if (f.map.argX[i] != h.map.argX[i] || f.map.argY[i] != h.map.argY[i]) ++moved;
  }
  double candMax = 0.0;
  int matched = 0;
  for (const auto& c : f.candidates) {
    for (const auto& d : h.candidates) {
      if (c.x == d.x && c.y == d.y && c.ivx == d.ivx && c.ivy == d.ivy) {
        candMax = std::max(candMax, std::abs(double(d.snr) - c.snr) / std::abs(double(c.snr)));
        ++matched;
        break;
      }
    }
  }
  std::printf(
      "  Float16 vs Float32, %s: map of %d velocities: max relative SNR error %.2e, mean %.2e, best cell "
      "moved in %d; candidates %zu vs %zu, %d the same cell, max relative error %.2e; best SNR %.4f vs "
      "%.4f\n",
      what, n, mapMax, n > 0 ? mapSum / n : 0.0, moved, f.candidates.size(), h.candidates.size(), matched,
      candMax, f.candidates.empty() ? 0.0 : f.candidates.front().snr,
      h.candidates.empty() ? 0.0 : h.candidates.front().snr);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

int run(int argc, char** argv) {
  const int frames = argc > 1 ? std::atoi(argv[1]) : 1500;
  const int size = argc > 2 ? std::atoi(argv[2]) : 512;
  const int nv = argc > 3 ? std::atoi(argv[3]) : 100;
  const int naiveRows = argc > 4 ? std::atoi(argv[4]) : 12;
  const int stackFrames = argc > 5 ? std::atoi(argv[5]) : 500;
  const bool treeOnly = argc > 6 && std::string(argv[6]) == "tree";    // exact end-to-end + tree only
  const bool exactOnly = argc > 6 && std::string(argv[6]) == "exact";  // exact search variants only
  const bool halfOnly = argc > 6 && std::string(argv[6]) == "half";    // Float32 vs Float16 only
  // The default tree search alone, no exact search first (profiling its kernels).
  const bool treeAlone = argc > 6 && std::string(argv[6]) == "treeonly";
  const std::time_t now = std::time(nullptr);
  char date[64];
  std::strftime(date, sizeof(date), "%Y-%m-%d %H:%M UTC", std::gmtime(&now));
  std::printf("st_gpu_bench %s\n%s", date, st::gpu::deviceSummary().c_str());

  std::string whyNot;
  auto backend = st::gpu::makeCudaSearchBackend(whyNot, {});
  if (!backend) {
    std::printf("no CUDA backend: %s\n", whyNot.c_str());
    return 2;
  }
  const double span = (frames - 1) / 16.7;
  // Neighbouring velocities differ by 1 px at the ends of the span (the paper's grid design).
  VelocityGrid grid{{0.5, -0.3}, 2.0 / span, nv, nv};
  auto t0 = std::chrono::steady_clock::now();
  FilteredCube cube = makeCube(frames, size, grid.at(nv / 3, nv / 2));
  std::printf(
      "cube %d x %d x %d (%.2f GiB) made in %.1f s; grid %d x %d, step %.4f px/s, |v| up to %.2f px/s\n",
      frames, size, size, cube.frames.pixels().size() * 4.0 / (1 << 30),
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), nv, nv, grid.stepPxS,
      grid.at(0, 0).norm());
  const double additions = double(frames) * size * size * double(grid.count());
  st::search::SearchParams params;
  Quiet quiet;
  st::CancelToken cancel;
  for (int rep = 0; rep < (treeAlone ? 0 : 2); ++rep) {
    const auto r = backend->search(cube, grid, params, quiet, cancel);
    std::printf(
        "search %d: end-to-end %.3f s, kernels %.3f s = %.3g additions/s; %zu candidates, best SNR %.1f "
        "at (%d, %d) v[%d,%d]\n  %s",
        rep, r.elapsedS, backend->lastKernelSeconds(), additions / backend->lastKernelSeconds(),
        r.candidates.size(), r.candidates.empty() ? 0.0 : r.candidates.front().snr,
        r.candidates.empty() ? -1 : r.candidates.front().x,
        r.candidates.empty() ? -1 : r.candidates.front().y,
        r.candidates.empty() ? -1 : r.candidates.front().ivx,
        r.candidates.empty() ? -1 : r.candidates.front().ivy, backend->lastNote().c_str());
  }
  if (exactOnly || halfOnly) {  // the stair kernel's variants on the whole problem, twice each
    struct Variant {
      const char* name;
      st::gpu::CudaOptions o;
      st::gpu::CudaBenchOptions b;
    };
    std::vector<Variant> variants;
    auto add = [&](const char* name, st::gpu::ExactKernel k, st::gpu::FramePrecision pr, int maxStage,
                   bool pipe) {
      Variant v{name, {}, {}};
      v.o.exactKernel = k;
      v.o.precision = pr;
      v.b.stairMaxFramesPerStage = maxStage;
      v.b.stairPipelined = pipe;
      variants.push_back(v);
    };
    using st::gpu::ExactKernel;
    using st::gpu::FramePrecision;
    add("auto (Float32)", ExactKernel::Auto, FramePrecision::Float32, 0, false);
    add("Float16, 16 frames per stage", ExactKernel::Auto, FramePrecision::Float16, 0, false);
    add("Float16, 8 frames per stage", ExactKernel::Auto, FramePrecision::Float16, 8, false);
    add("Float16, 24 frames per stage", ExactKernel::Auto, FramePrecision::Float16, 24, false);
    add("Float16, 28 frames per stage", ExactKernel::Auto, FramePrecision::Float16, 28, false);
    if (exactOnly) {
      add("stair, at most 8 frames per stage", ExactKernel::Auto, FramePrecision::Float32, 8, false);
      add("stair, software-pipelined", ExactKernel::Auto, FramePrecision::Float32, 0, true);
      add("stair, 4-row tiles", ExactKernel::StairFourRows, FramePrecision::Float32, 0, false);
    }
    FilteredCube noise = makeCube(frames, size, grid.at(nv / 3, nv / 2), 0.0f);
    std::vector<st::search::SearchResult> ref(2);
    for (std::size_t vi = 0; vi < variants.size(); ++vi) {
      const Variant& v = variants[vi];
      auto bv = st::gpu::makeCudaBenchBackend(whyNot, v.o, v.b);
      for (int rep = 0; rep < 2; ++rep) {
        const auto r = bv->search(cube, grid, params, quiet, cancel);
        std::printf(
            "search %d, %s: end-to-end %.3f s, kernels %.4f s = %.3g additions/s; %zu candidates, best SNR "
            "%.4f\n  %s",
            rep, v.name, r.elapsedS, bv->lastKernelSeconds(), additions / bv->lastKernelSeconds(),
            r.candidates.size(), r.candidates.empty() ? 0.0 : r.candidates.front().snr,
            bv->lastNote().c_str());
        if (rep == 1 && vi == 0) ref[0] = r;
        if (rep == 1 && v.o.precision == FramePrecision::Float16)
          compareHalf("PSF source in noise", ref[0], r);
      }
      if (vi == 0 || v.o.precision == FramePrecision::Float16) {
        const auto r = bv->search(noise, grid, params, quiet, cancel);
        if (vi == 0)
          ref[1] = r;
        else
          compareHalf("noise alone", ref[1], r);
      }
    }
    return 0;
  }
  // The tree search (method "tree") on the same cube, side by side with the exact search above.
  // shape -1: the default with direct nodes frame by frame from the tables (the level kernel before
  // 2026-11-27).
  for (const auto& [cut, shape] : {std::pair{0, 0}, std::pair{0, -1}, std::pair{3, 0}, std::pair{0, 6}}) {
    if (treeAlone && (cut != 0 || shape != 0)) continue;
    st::gpu::CudaOptions to;
    to.treeCut = cut;
    st::gpu::CudaBenchOptions tb;
    tb.treeRootShape = std::max(shape, 0);
    tb.treeDirectPlain = shape < 0;
    tb.profileTree = true;
    auto tree = st::gpu::makeCudaBenchBackend(whyNot, to, tb);
    st::search::SearchParams tp = params;
    tp.method = st::search::SearchMethod::Tree;
    for (int rep = 0; rep < 2; ++rep) {
      const auto r = tree->search(cube, grid, tp, quiet, cancel);
      std::printf(
          "tree search %d (cut %d, root shape %d): end-to-end %.3f s, upload %.1f ms, kernels %.1f ms; "
          "%.3g "
          "additions "
          "(%.0fx "
          "fewer than exact) = %.3g additions/s; %zu candidates, best SNR %.2f at (%d, %d) v[%d,%d]\n  "
          "%s",
          rep, cut == 0 ? st::gpu::kTreeDefaultCut : cut, shape, r.elapsedS, 1e3 * tree->lastUploadSeconds(),
          1e3 * tree->lastKernelSeconds(), tree->lastTreeAdditions(), additions / tree->lastTreeAdditions(),
          tree->lastTreeAdditions() / tree->lastKernelSeconds(), r.candidates.size(),
          r.candidates.empty() ? 0.0 : r.candidates.front().snr,
          r.candidates.empty() ? -1 : r.candidates.front().x,
          r.candidates.empty() ? -1 : r.candidates.front().y,
          r.candidates.empty() ? -1 : r.candidates.front().ivx,
          r.candidates.empty() ? -1 : r.candidates.front().ivy, tree->lastNote().c_str());
    }
  }
  if (treeOnly || treeAlone) return 0;
  {
    st::gpu::CudaOptions o16;
    o16.exactKernel = st::gpu::ExactKernel::StairFourRows;
    auto b16 = st::gpu::makeCudaSearchBackend(whyNot, o16);
    for (int rep = 0; rep < 2; ++rep) {
      const auto r = b16->search(cube, grid, params, quiet, cancel);
      std::printf(
          "search %d, stair kernel with 4-row tiles: end-to-end %.3f s, kernels %.3f s = %.3g "
          "additions/s; "
          "%zu candidates\n  %s",
          rep, r.elapsedS, b16->lastKernelSeconds(), additions / b16->lastKernelSeconds(),
          r.candidates.size(), b16->lastNote().c_str());
    }
  }
  // Tiled vs naive on the same band of velocity rows.
  VelocityGrid band = grid;
  band.nvy = std::min(naiveRows, nv);
  const double bandAdds = double(frames) * size * size * double(band.count());
  st::gpu::CudaOptions naiveOptions;
  naiveOptions.exactKernel = st::gpu::ExactKernel::Naive;
  auto naive = st::gpu::makeCudaSearchBackend(whyNot, naiveOptions);
  double naiveS = 1e30;
  for (int rep = 0; rep < 2; ++rep) {
    naive->search(cube, band, params, quiet, cancel);
    naiveS = std::min(naiveS, naive->lastKernelSeconds());
  }
  std::printf("band of %d x %d velocities: naive kernel %.4f s = %.3g additions/s\n", band.nvx, band.nvy,
              naiveS, bandAdds / naiveS);
  using st::gpu::ExactKernel;
  for (const ExactKernel variant : {ExactKernel::Auto, ExactKernel::StairCpAsync, ExactKernel::StairFourRows,
                                    ExactKernel::AutoNoStair, ExactKernel::Row, ExactKernel::Tiled}) {
    const char* name = variant == ExactKernel::Auto            ? "auto (stair kernel)"
                       : variant == ExactKernel::StairCpAsync  ? "stair kernel, cp.async windows"
                       : variant == ExactKernel::StairFourRows ? "stair kernel, 4-row tiles"
                       : variant == ExactKernel::AutoNoStair   ? "auto without the stair kernel"
                       : variant == ExactKernel::Row           ? "row kernel"
                                                               : "tiled, reuse by branches";
    st::gpu::CudaOptions o;
    o.exactKernel = variant;
    auto b = st::gpu::makeCudaSearchBackend(whyNot, o);
    double best = 1e30;
    for (int rep = 0; rep < 2; ++rep) {
      b->search(cube, band, params, quiet, cancel);
      best = std::min(best, b->lastKernelSeconds());
    }
    std::printf("band, %-34s %.4f s = %.3g additions/s, %.1fx naive\n  %s", name, best, bandAdds / best,
                naiveS / best, b->lastNote().c_str());
  }

  // stackAt, 500 x size^2: the first call uploads the cube, the next ones only stack.
  FilteredCube small;
  const int sf = std::min(stackFrames, frames);
  small.frames = st::FrameCube(size, size, static_cast<std::size_t>(sf));
  std::copy_n(cube.frames.pixels().begin(), small.frames.pixels().size(), small.frames.pixels().begin());
  std::copy_n(cube.frames.info().begin(), sf, small.frames.info().begin());
  small.sigmaF = 1.0;
  st::gpu::StackEngine engine(0);
  engine.stack(small, {0.1, 0.2});
  std::vector<double> kernel, call;
  for (int i = 0; i < 21; ++i) {
    const auto c0 = std::chrono::steady_clock::now();
    engine.stack(small, grid.at(i, 2 * i % nv));
    call.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - c0).count());
    kernel.push_back(engine.lastKernelSeconds());
  }
  std::printf("stackAt IPSA %d x %d^2: kernels %.3f ms (median of 21), whole call %.3f ms (cube resident)\n",
              sf, size, 1e3 * median(kernel), 1e3 * median(call));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "st_gpu_bench: %s\n", e.what());
    return 1;
  }
}
