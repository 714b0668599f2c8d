// synthtrack-cli bench load: writes FRAMES x (W x H) float32 frames to a temporary folder (as 2-D files with
// DATE-OBS/EXPTIME, and as one cube with a FRAMES table), then times loadFrames on each from the page cache
// (the files were just written; they are read once more before timing). Rate = pixel bytes / wall time.
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "cli_args.hpp"
#include "commands.hpp"
#include "load_args.hpp"
#include "st/common/parallel.hpp"
#include "st/common/units.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/fits_writer.hpp"

namespace st::app {
namespace {

namespace fs = std::filesystem;

void warmPageCache(const fs::path& dir) {
  std::vector<char> buf(1 << 20);
  for (const auto& e : fs::directory_iterator(dir)) {
    std::ifstream in(e.path(), std::ios::binary);
    while (in.read(buf.data(), static_cast<std::streamsize>(buf.size())) || in.gcount() > 0) {
    }
  }
}

FitsHeader frameHeader(std::size_t n, double cadenceS) {
  FitsHeader h;
  const double mjdStart = 60000.0 + static_cast<double>(n) * cadenceS / kSecondsPerDay;
  h.setString("DATE-OBS", isoFromMjd(mjdStart), "exposure start (UTC)");
  h.setNumber("EXPTIME", cadenceS, "exposure (s)");
  return h;
}

struct Timing {
  double wallS = 0.0;
  double cpuS = 0.0;  ///< process CPU time (all threads, user + system): shows contention on a shared machine
};

Timing timeLoad(const std::vector<std::string>& inputs, std::size_t frames) {
  NullProgress progress;
  CancelToken cancel;
  const std::clock_t c0 = std::clock();
  const auto t0 = std::chrono::steady_clock::now();
  const FrameCube cube = io::loadFrames(inputs, io::LoadOptions{}, progress, cancel);
  Timing t;
  t.wallS = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  t.cpuS = static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
  if (cube.frameCount() != frames) throw std::runtime_error("bench load: loaded the wrong number of frames");
  return t;
}

}  // namespace

int benchLoad(const Args& args) {
  if (!args.empty() && args[0] == "--help") {
    std::printf(
        "usage: synthtrack-cli bench load [--frames 1500] [--size 512x512] [--layout files|cube|both] "
        "[--json]\n");
    return 0;
  }
  const CliArgs cli(args, {"frames", "size", "layout", "dir"}, {"json"});
  const auto frames = static_cast<std::size_t>(cli.integer("frames").value_or(1500));
  int w = 512;
  int h = 512;
  if (auto s = cli.value("size"); s && std::sscanf(s->c_str(), "%dx%d", &w, &h) != 2) {
    throw UsageError("--size needs WxH, got '" + *s + "'");
  }
  if (frames < 2 || w < 1 || h < 1) throw UsageError("--frames must be >= 2 and --size positive");
  const std::string layout = cli.value("layout").value_or("both");
  if (layout != "files" && layout != "cube" && layout != "both")
    throw UsageError("--layout is files, cube or both");
  const fs::path base = cli.value("dir") ? fs::path(*cli.value("dir")) : fs::temp_directory_path();
  const fs::path dir = base / ("synthtrack-bench-load-" + std::to_string(std::random_device{}()));
  fs::create_directories(dir / "files");
  struct Cleanup {
    fs::path p;
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(p, ec);
    }
  } cleanup{dir};

  const double cadenceS = 1.0 / 16.7;
  Image img(w, h);
  std::mt19937 rng(1);
  std::normal_distribution<float> noise(100.0f, 10.0f);
  for (auto& p : img.pixels)
    p = noise(rng);
  std::vector<std::string> files;
  if (layout != "cube") {
    for (std::size_t n = 0; n < frames; ++n) {
      char name[32];
      std::snprintf(name, sizeof name, "f%05zu.fits", n);
      files.push_back((dir / "files" / name).string());
      io::writeImage(files.back(), img, frameHeader(n, cadenceS));
    }
  }
  const std::string cubePath = (dir / "cube.fits").string();
  if (layout != "files") {
    FrameCube cube(w, h, frames);
    for (std::size_t n = 0; n < frames; ++n) {
      std::copy(img.pixels.begin(), img.pixels.end(), cube.frame(n));
      cube.info()[n].mjdMid = 60000.0 + (static_cast<double>(n) + 0.5) * cadenceS / kSecondsPerDay;
      cube.info()[n].exposureS = cadenceS;
    }
    io::writeCube(cubePath, cube);
  }
  warmPageCache(dir / "files");
  warmPageCache(dir);
  const double mb = static_cast<double>(frames) * w * h * sizeof(float) / 1e6;
  nlohmann::json out = nlohmann::json::array();
  auto report = [&](const char* what, Timing t) {
    std::printf("load %-6s %zu x %dx%d float32 (%.0f MB), %u threads: %.3f s, %.0f MB/s (CPU %.3f s)\n", what,
                frames, w, h, mb, workerCount(), t.wallS, mb / t.wallS, t.cpuS);
    out.push_back({{"what", std::string("load ") + what},
                   {"frames", frames},
                   {"width", w},
                   {"height", h},
                   {"megabytes", mb},
                   {"threads", workerCount()},
                   {"seconds", t.wallS},
                   {"mb_per_s", mb / t.wallS},
                   {"cpu_seconds", t.cpuS}});
  };

  if (layout != "cube") report("files", timeLoad(files, frames));
  if (layout != "files") report("cube", timeLoad({cubePath}, frames));
  if (cli.flag("json")) std::printf("%s\n", out.dump(2).c_str());
  return 0;
}

}  // namespace st::app
