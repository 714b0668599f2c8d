// `synthtrack-cli bench stack`: one IPSA and one CSA stack of a FRAMES x SIZE^2 cube of random data made in
// memory (default 500 x 512^2, frames at 16.7 Hz as in the paper), several repetitions, median time.
// Budgets (issue 3): IPSA <= 40 ms (live scrubbing in the GUI), CSA <= 1.5 s.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

#include "cli_args.hpp"
#include "bench_util.hpp"
#include "commands.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/parallel.hpp"
#include "st/stack/csa.hpp"
#include "st/stack/ipsa.hpp"

namespace st::app {
namespace {

/// Wall-clock seconds of each run; *cpuS (optional) gets the CPU seconds of each run over all threads, which
/// tells a busy machine (wall >> cpu / threads) from a slow program.
template <class F>
std::vector<double> timeRuns(int reps, F&& f, std::vector<double>* cpuS = nullptr) {
  std::vector<double> t;
  for (int i = 0; i < reps; ++i) {
    const double c = processCpuSeconds();
    const auto a = std::chrono::steady_clock::now();
    f();
    t.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - a).count());
    if (cpuS) cpuS->push_back(processCpuSeconds() - c);
  }
  return t;
}

double loadAverage() {
  std::ifstream in("/proc/loadavg");
  double l = -1.0;
  in >> l;
  return l;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

}  // namespace

int benchStack(const Args& args) {
  const CliArgs a(args, {"frames", "size", "reps", "vx-px-s", "vy-px-s", "rate-hz"}, {"json", "help"});
  if (a.flag("help")) {
    std::printf(
        "usage: synthtrack-cli bench stack [--frames 500] [--size 512] [--reps 9] [--vx-px-s 3.1]\n"
        "                                  [--vy-px-s -1.7] [--rate-hz 16.7] [--json]\n");
    return 0;
  }
  const long long frames = a.integer("frames").value_or(500), size = a.integer("size").value_or(512);
  const int reps = int(a.integer("reps").value_or(9));
  if (frames < 1 || frames > 65535 || size < 16 || size > 8192 || reps < 1)
    throw UsageError("bench stack: need 1 <= --frames <= 65535, 16 <= --size <= 8192, --reps >= 1");
  const Velocity v{a.number("vx-px-s", 3.1), a.number("vy-px-s", -1.7)};
  const double rate = a.number("rate-hz", 16.7);

  FrameCube cube{static_cast<int>(size), static_cast<int>(size), static_cast<std::size_t>(frames)};
  std::mt19937 rng(42);
  std::normal_distribution<float> g(0.0f, 1.0f);
  for (auto& p : cube.pixels())
    p = g(rng);
  for (long long n = 0; n < frames; ++n)
    cube.info()[std::size_t(n)].mjdMid = 60000.0 + double(n) / rate / 86400.0;
  const std::vector<double> dt = cube.timeOffsetsS();

  volatile float sink = 0.0f;
  // The floor for any exact stack: reading every frame once (a plain parallel sum over the cube).
  const auto floorRuns = timeRuns(reps, [&] {
    std::vector<double> part(cube.frameCount(), 0.0);
    parallelFor(cube.frameCount(), 4, [&](std::size_t b, std::size_t e) {
      for (std::size_t n = b; n < e; ++n) {
        float acc[64] = {};  // independent lanes: a vectorised, bandwidth-bound read
        const float* f = cube.frame(n);
        const std::size_t np = cube.framePixels(), body = np - np % 64;
        for (std::size_t i = 0; i < body; i += 64)
          for (int k = 0; k < 64; ++k)
            acc[k] += f[i + std::size_t(k)];
        for (std::size_t i = body; i < np; ++i)
          acc[0] += f[i];
        for (int k = 1; k < 64; ++k)
          acc[0] += acc[k];
        part[n] = acc[0];
      }
    });
    sink = sink + float(part[0]);
  });
  (void)stack::stackIpsa(cube, dt, v);  // warm-up: page in the cube
  std::vector<double> ipsaCpu, csaCpu;
  const auto ipsa = timeRuns(
      reps, [&] { sink = sink + stack::stackIpsa(cube, dt, v).sum.pixels[0]; }, &ipsaCpu);
  NullProgress progress;
  CancelToken cancel;
  const auto first =
      timeRuns(1, [&] { sink = sink + stack::stackCsa(cube, dt, v, progress, cancel).sum.pixels[0]; });
  const auto csa = timeRuns(
      std::max(1, reps / 3),
      [&] { sink = sink + stack::stackCsa(cube, dt, v, progress, cancel).sum.pixels[0]; }, &csaCpu);

  char host[256] = "unknown";
  gethostname(host, sizeof host - 1);
  const double mIpsa = median(ipsa), mCsa = median(csa), mFloor = median(floorRuns);
  const double cIpsa = median(ipsaCpu), cCsa = median(csaCpu), load = loadAverage();
  const double gb = double(frames) * double(size) * double(size) * 4.0 / 1e9;
  if (a.flag("json")) {
    std::printf(
        "{\"bench\": \"stack\", \"frames\": %lld, \"size\": %lld, \"vx_px_s\": %g, \"vy_px_s\": %g, "
        "\"threads\": %u, \"ipsa_median_s\": %.6f, \"ipsa_cpu_median_s\": %.6f, \"ipsa_reps\": %zu, "
        "\"csa_median_s\": %.6f, \"csa_cpu_median_s\": %.6f, \"csa_reps\": %zu, \"csa_first_call_s\": %.6f, "
        "\"read_once_median_s\": %.6f, \"load_average\": %.2f, \"cpu\": \"%s\", \"host\": \"%s\", "
        "\"date_utc\": \"%s\"}\n",
        frames, size, v.vx, v.vy, workerCount(), mIpsa, cIpsa, ipsa.size(), mCsa, cCsa, csa.size(), first[0],
        mFloor, load, cpuModel().c_str(), host, utcNow().c_str());
    return 0;
  }
  std::printf("machine: %s (%s), %u threads, load average %.2f, %s\n", cpuModel().c_str(), host,
              workerCount(), load, utcNow().c_str());
  std::printf(
      "ipsa  %lld x %lld^2  v=(%g, %g) px/s  median %8.2f ms wall, %8.2f ms CPU (all threads), %zu runs"
      "  (%.1f GB/s of frames)\n",
      frames, size, v.vx, v.vy, mIpsa * 1e3, cIpsa * 1e3, ipsa.size(), gb / mIpsa);
  std::printf("read  %lld x %lld^2  every frame once (the floor of any exact stack)  median %8.2f ms wall\n",
              frames, size, mFloor * 1e3);
  std::printf(
      "csa   %lld x %lld^2  v=(%g, %g) px/s  median %8.2f ms wall, %8.2f ms CPU (all threads), %zu runs"
      "  (first call %.2f s, with FFTW planning)\n",
      frames, size, v.vx, v.vy, mCsa * 1e3, cCsa * 1e3, csa.size(), first[0]);
  return 0;
}

}  // namespace st::app
