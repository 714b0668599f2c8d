// `synthtrack-cli bench preprocess`: full pre-processing (calibration with the simulator's bias and flat,
// cosmic rays, background, static sources, PSF, matched filter) of the paper-neo preset (500 x 512^2) made
// by the simulator, timed once after the simulation. Budget (issue 3): <= 20 s on the 2-core dev machine.
// Also scores the result against the simulator's truth: sigma_n, background bias, cosmic-ray hits removed,
// pixels of the moving object removed.
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include "cli_args.hpp"
#include "backend_factory.hpp"
#include "bench_util.hpp"
#include "commands.hpp"
#include "st/common/fnv1a.hpp"
#include "st/common/parallel.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/sim/simulator.hpp"
#include "terminal_progress.hpp"

namespace st::app {
namespace {

struct Score {
  double sigmaTruth = 0.0, skyTruth = 0.0, bias = 0.0;
  std::size_t hits = 0, hitsRemoved = 0, objectPixelsRemoved = 0, objectPixels = 0;
  std::size_t truthPixels = 0;  ///< pixels of the truth's hits
  /// Flagged pixels on no truth hit (nor next to one), by the distance to the nearest star in that frame:
  /// < 5 px, 5-15 px, farther; and those near (< 15 px) a saturated star.
  std::size_t falseNear = 0, falseMid = 0, falseFar = 0, falseNearSaturated = 0;
};

// Scores against the truth: a hit is removed when its brightest pixel was flagged; an object pixel is one
// within 1 px of the object's centre in a frame where no hit touched it.
Score score(const sim::SimResult& sim, const pipeline::Prepared& p) {
  Score s;
  const auto& t = sim.truth;
  for (double v : t.noiseSigmaAdu)
    s.sigmaTruth += v / t.noiseSigmaAdu.size();
  for (double v : t.skyAdu)
    s.skyTruth += v / t.skyAdu.size();
  for (float v : p.background.pixels)
    s.bias += (v - s.skyTruth) / p.background.size();
  const std::set<std::uint64_t> flagged(p.cosmicRayPixels.begin(), p.cosmicRayPixels.end());
  const int w = p.frames.width(), h = p.frames.height();
  const std::size_t np = p.frames.framePixels();
  std::set<std::uint64_t> hitPixels;
  for (const auto& cr : t.cosmicRays) {
    for (const auto& [x, y] : cr.pixels)
      hitPixels.insert(cr.frame * np + static_cast<std::size_t>(y) * w + x);
    const int x = static_cast<int>(std::lround(cr.xPx)), y = static_cast<int>(std::lround(cr.yPx));
    if (x < 0 || y < 0 || x >= w || y >= h) continue;
    ++s.hits;
    bool removed = false;
    for (const auto& [px, py] : cr.pixels)
      removed |= flagged.count(cr.frame * np + static_cast<std::size_t>(py) * w + px) != 0;
    s.hitsRemoved += removed;
  }
  s.truthPixels = hitPixels.size();
  const auto dt = p.frames.timeOffsetsS();
  for (std::uint64_t q : p.cosmicRayPixels) {
    const std::size_t n = q / np;
    const int x = static_cast<int>(q % np) % w, y = static_cast<int>(q % np) / w;
    bool onHit = false;
    for (int dy = -1; dy <= 1 && !onHit; ++dy)
      for (int dx = -1; dx <= 1 && !onHit; ++dx)
        onHit = x + dx >= 0 && y + dy >= 0 && x + dx < w && y + dy < h &&
                hitPixels.count(n * np + static_cast<std::size_t>(y + dy) * w + (x + dx)) != 0;
    if (onHit) continue;
    double nearest = 1e30;
    bool saturated = false;
    for (const auto& st : t.stars) {
      const double d =
          std::hypot(st.xRefPx + t.skyVxPxPerS * dt[n] - x, st.yRefPx + t.skyVyPxPerS * dt[n] - y);
      if (d < nearest) nearest = d;
      if (d < 15.0 && st.saturated) saturated = true;
    }
    (nearest < 5.0 ? s.falseNear : nearest < 15.0 ? s.falseMid : s.falseFar) += 1;
    s.falseNearSaturated += saturated;
  }
  for (const auto& o : t.objects) {
    for (std::size_t n = 0; n < p.frames.frameCount(); ++n) {
      const double cx = o.xRefPx + o.vxPxPerS * dt[n], cy = o.yRefPx + o.vyPxPerS * dt[n];
      for (int y = static_cast<int>(std::floor(cy)) - 1; y <= static_cast<int>(std::ceil(cy)) + 1; ++y)
        for (int x = static_cast<int>(std::floor(cx)) - 1; x <= static_cast<int>(std::ceil(cx)) + 1; ++x) {
          if (x < 0 || y < 0 || x >= w || y >= h) continue;
          const std::uint64_t q = n * np + static_cast<std::size_t>(y) * w + x;
          if (hitPixels.count(q)) continue;
          ++s.objectPixels;
          s.objectPixelsRemoved += flagged.count(q) != 0;
        }
    }
  }
  return s;
}

// FNV-1a of each of `n` blocks of `bytes` bytes (on every core), then those hashes folded in order, each as
// one 64-bit step: equal data, bit for bit, give equal values whatever the thread count.
std::uint64_t blockHash(const unsigned char* data, std::size_t n, std::size_t bytes) {
  constexpr std::uint64_t kPrime = 1099511628211ull;
  std::vector<std::uint64_t> blockHashes(n);
  parallelFor(n, 1, [&](std::size_t f0, std::size_t f1) {
    for (std::size_t f = f0; f < f1; ++f)
      blockHashes[f] = fnv1a(data + f * bytes, bytes);
  });
  std::uint64_t h = kFnv1aBasis;
  for (std::uint64_t b : blockHashes)
    h = (h ^ b) * kPrime;
  return h;
}

// A cube's pixels, frame by frame (blockHash).
std::uint64_t cubeHash(const FrameCube& cube) {
  return blockHash(reinterpret_cast<const unsigned char*>(cube.pixels().data()), cube.frameCount(),
                   cube.framePixels() * sizeof(float));
}

// Its mask likewise; 0 when it has none.
std::uint64_t maskHash(const FrameCube& cube) {
  if (cube.mask().empty()) return 0;
  return blockHash(cube.mask().data(), cube.frameCount(), cube.framePixels());
}

}  // namespace

int benchPreprocess(const Args& args) {
  const CliArgs a(args, {"preset", "seed", "frames", "size", "backend"},
                  {"json", "help", "given-sky-rate", "fingerprint", "chain-remeasure", "no-stacks-ahead"});
  if (a.flag("help")) {
    std::printf(
        "usage: synthtrack-cli bench preprocess [--preset paper-neo] [--seed 1] [--frames N] [--size PX] "
        "[--backend cpu|cuda] [--json] [--fingerprint] [--chain-remeasure] [--no-stacks-ahead]\n"
        "  --fingerprint   also print the results to every digit and hashes of the zero-biased and filtered\n"
        "                  cubes (after the timing): equal lines, the same pre-processing bit for bit\n"
        "  --chain-remeasure  the sky rate's chain as before 2026-12-02: every link in its first iteration\n"
        "                  too, and every block stack and link again in each iteration\n"
        "  --no-stacks-ahead  with a device, each stack at the sky rate made when asked, as before "
        "2026-12-03\n"
        "                  (not the protection's and the static sources' thirds and halves ahead)\n");
    return 0;
  }
  const std::string presetName = a.value("preset").value_or("paper-neo");
  sim::SimParams params = sim::preset(presetName);
  sim::resize(params, static_cast<int>(a.integer("size").value_or(0)),
              static_cast<int>(a.integer("size").value_or(0)),
              static_cast<int>(a.integer("frames").value_or(0)));
  const auto seed = static_cast<std::uint64_t>(a.integer("seed").value_or(1));
  TerminalProgress progress;
  CancelToken& cancel = processCancelToken();
  const auto s0 = std::chrono::steady_clock::now();
  sim::SimResult sim = sim::simulate(params, seed, progress, cancel);
  const double simS = std::chrono::duration<double>(std::chrono::steady_clock::now() - s0).count();
  pipeline::PreprocessParams pp;
  pp.masters = sim::exactMasters(sim);
  pp.skyRateParams.chainKeepUnchanged = !a.flag("chain-remeasure");
  pp.skyRateParams.chainCoarseFirst = !a.flag("chain-remeasure");
  pp.stacksAhead = !a.flag("no-stacks-ahead");
  if (a.flag("given-sky-rate")) pp.skyRate = Velocity{sim.truth.skyVxPxPerS, sim.truth.skyVyPxPerS};
  // --backend cuda: the per-pixel background and the matched filter on the GPU (issue 16).
  const BackendSelection backend = makeBackend(parseBackendChoice(a.value("backend").value_or("cpu")));
  std::string accelMessage;
  const auto accel = makePreprocessAccelerator(*backend.backend, accelMessage);
  pp.accelerator = accel.get();
  const std::size_t frames = sim.cube.frameCount();
  const int w = sim.cube.width(), h = sim.cube.height();
  const double cpu0 = processCpuSeconds();
  const pipeline::Prepared out = pipeline::preprocess(std::move(sim.cube), pp, progress, cancel);
  const double cpu = processCpuSeconds() - cpu0;
  progress.finish();
  const Score sc = score(sim, out);
  char host[256] = "unknown";
  gethostname(host, sizeof host - 1);
  if (a.flag("json")) {
    std::printf(
        "{\"bench\": \"preprocess\", \"preset\": \"%s\", \"frames\": %zu, \"width\": %d, \"height\": %d, "
        "\"threads\": %u, \"wall_s\": %.3f, \"cpu_s\": %.3f, \"budget_s\": 20, \"sigma_n\": %.5g, "
        "\"sigma_n_truth\": %.5g, \"background_bias_sigma\": %.4g, \"hits\": %zu, \"hits_removed\": %zu, "
        "\"object_pixels_removed\": %zu, \"stars\": %zu, \"psf_fwhm_px\": %.4g, \"psf_fwhm_truth_px\": %.4g, "
        "\"cpu\": \"%s\", \"host\": \"%s\", \"date_utc\": \"%s\"}\n",
        presetName.c_str(), frames, w, h, workerCount(), out.elapsedS, cpu, out.sigmaN, sc.sigmaTruth,
        sc.bias / sc.sigmaTruth, sc.hits, sc.hitsRemoved, sc.objectPixelsRemoved, out.stars.size(),
        out.psf.fwhm(), sim.truth.psfFwhmPx, cpuModel().c_str(), host, utcNow().c_str());
    return 0;
  }
  std::printf("machine: %s (%s), %u threads, %s\n", cpuModel().c_str(), host, workerCount(),
              utcNow().c_str());
  std::printf("simulated %s (%zu x %d x %d) in %.1f s\n", presetName.c_str(), frames, w, h, simS);
  std::printf("preprocess: %.2f s wall, %.2f s CPU (budget 20 s wall); %s\n", out.elapsedS, cpu,
              accelMessage.c_str());
  for (const auto& [stage, t] : out.stageSeconds) {
    const auto cpuOf = std::find_if(out.stageCpuSeconds.begin(), out.stageCpuSeconds.end(),
                                    [&stage](const auto& s) { return s.first == stage; });
    if (cpuOf == out.stageCpuSeconds.end())
      std::printf("  %-34s %7.3f s\n", stage.c_str(), t);
    else
      std::printf("  %-34s %7.3f s  (CPU %.3f s: %.1f cores)\n", stage.c_str(), t, cpuOf->second,
                  t > 0.0 ? cpuOf->second / t : 0.0);
  }
  std::printf("sigma_n %.5g vs truth %.5g (%+.2f%%); background bias %+.4f sigma\n", out.sigmaN,
              sc.sigmaTruth, 100.0 * (out.sigmaN / sc.sigmaTruth - 1.0), sc.bias / sc.sigmaTruth);
  std::printf("sky rate (%.4g, %.4g) px/s vs truth (%.4g, %.4g)\n", out.skyRate.vx, out.skyRate.vy,
              sim.truth.skyVxPxPerS, sim.truth.skyVyPxPerS);
  std::printf(
      "cosmic rays: %zu of %zu hits removed (%.1f%%), %zu pixels flagged; object pixels removed: %zu of "
      "%zu\n",
      sc.hitsRemoved, sc.hits, sc.hits ? 100.0 * sc.hitsRemoved / sc.hits : 100.0, out.cosmicRays,
      sc.objectPixelsRemoved, sc.objectPixels);
  std::printf(
      "cosmic-ray pixels flagged %zu, truth's hit pixels %zu (%.2fx); flagged on no hit: %zu within 5 px of "
      "a "
      "star, %zu at 5-15 px, %zu farther; %zu of them within 15 px of a saturated star\n",
      out.cosmicRayPixels.size(), sc.truthPixels,
      sc.truthPixels ? double(out.cosmicRayPixels.size()) / double(sc.truthPixels) : 0.0, sc.falseNear,
      sc.falseMid, sc.falseFar, sc.falseNearSaturated);
  std::printf("stars %zu (truth %zu); PSF FWHM %.3f px (%s) vs truth %.3f; sigma_F %.4g\n", out.stars.size(),
              sim.truth.stars.size(), out.psf.fwhm(), out.psfFitted ? "fitted" : "fallback",
              sim.truth.psfFwhmPx, out.filtered.sigmaF);
  for (const auto& n : out.notes)
    std::printf("note: %s\n", n.c_str());
  if (a.flag("fingerprint")) {
    std::printf(
        "fingerprint: sigma_n %.17g, sky rate (%.17g, %.17g), cosmic-ray pixels %zu, stars %zu, PSF R %.17g "
        "beta %.17g, sigma_F %.17g, zero-biased cube %016llx (mask %016llx), filtered cube %016llx\n",
        out.sigmaN, out.skyRate.vx, out.skyRate.vy, out.cosmicRayPixels.size(), out.stars.size(),
        out.psf.radius, out.psf.beta, out.filtered.sigmaF,
        static_cast<unsigned long long>(cubeHash(out.frames)),
        static_cast<unsigned long long>(maskHash(out.frames)),
        static_cast<unsigned long long>(cubeHash(out.filtered.frames)));
  }
  return 0;
}

}  // namespace st::app
