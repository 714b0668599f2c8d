// synthtrack-cli bench fit: times one co-moving PSF fit (the issue's target: 500 frames, 25x25 stamp), and
// with --montecarlo runs the paper's fig_snr experiment (astrometric error RMS against photons per frame for
// three background noise levels, R = 3.3, beta = 4), writing a CSV table and an SVG plot.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli_args.hpp"
#include "commands.hpp"
#include "st/common/parallel.hpp"
#include "st/fit/comoving_fit.hpp"
#include "st/fit/montecarlo.hpp"
#include "st/fit/uncertainty.hpp"
#include "terminal_progress.hpp"

namespace st::app {
namespace {

constexpr const char* kUsage =
    R"(usage: synthtrack-cli bench fit [--frames N] [--stamp H] [--repeat R] [--json]
       synthtrack-cli bench fit --montecarlo [--trials N] [--frames N] [--out DIR]

Default: one co-moving fit of a rendered moving source (R = 3.3, beta = 4, N_ph = 300, sigma_n = 3) on
N frames (default 500) of 64x64 with a (2H+1)^2 stamp (default H = 12: 25x25), repeated R times (default 5).
--montecarlo: the paper's fig_snr experiment; writes DIR/fit_montecarlo.csv and DIR/fit_montecarlo.svg.
)";

int benchTiming(const CliArgs& a) {
  const int frames = static_cast<int>(a.integer("frames").value_or(500));
  const int half = static_cast<int>(a.integer("stamp").value_or(12));
  const int repeat = static_cast<int>(a.integer("repeat").value_or(5));
  const psf::Moffat psf{3.3, 4.0};
  FrameCube cube = fit::makeEmptyCube(64, frames, 0.06);
  const double span = cube.timeSpanS();
  const Velocity v{20.0 / span, -10.0 / span};  // 20 px across the cube
  fit::renderMovingSource(cube, psf, {32.3, 31.7, v, 300.0});
  fit::addNoise(cube, 3.0, true, 1);
  fit::FitOptions o;
  o.psf = psf;
  o.stampHalfSize = half;
  const fit::FitParams start{{v.vx + 0.5 / span, v.vy - 0.5 / span}, 32.0, 32.0, std::nan(""), 0.0};
  std::vector<double> times, cpu;
  fit::FitResult r;
  for (int i = 0; i < repeat; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::clock_t c0 = std::clock();
    r = fit::fitComoving(cube, start, o);
    cpu.push_back(static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC);
    times.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(cpu.begin(), cpu.end());
  const double cpuMedian = cpu[cpu.size() / 2];
  std::sort(times.begin(), times.end());
  const double median = times[times.size() / 2];
  const double evals = static_cast<double>(r.costHistory.size() + r.iterations) * r.pixels;
  if (a.flag("json")) {
    nlohmann::json j = {
        {"bench", "fit"},           {"frames", frames},           {"stamp", 2 * half + 1},
        {"threads", workerCount()}, {"median_s", median},         {"min_s", times.front()},
        {"cpu_s", cpuMedian},       {"iterations", r.iterations}, {"status", fit::toString(r.status)}};
    std::printf("%s\n", j.dump().c_str());
  } else {
    std::printf(
        "fit  %d frames  %dx%d stamp  %u threads  wall median %.4f s  min %.4f s  cpu %.4f s  "
        "%d iterations (%s)  ~%.1f Mpix-evals/s\n",
        frames, 2 * half + 1, 2 * half + 1, workerCount(), median, times.front(), cpuMedian, r.iterations,
        fit::toString(r.status), evals / median / 1e6);
  }
  return r.ok() ? 0 : 1;
}

// A log-log SVG like the paper's fig_snr: measured scatter (markers) and eq:sig (lines) per noise level.
void writeSvg(const std::string& path, const std::vector<fit::MonteCarloPoint>& pts,
              const std::vector<double>& noises) {
  const double w = 640, h = 480, l = 70, r = 20, t = 30, b = 55;
  double x0 = 1e300, x1 = 0, y0 = 1e300, y1 = 0;
  for (const auto& p : pts) {
    x0 = std::min(x0, p.config.photonsPerFrame);
    x1 = std::max(x1, p.config.photonsPerFrame);
    for (double y : {p.sdPos, p.predictedSigmaPos}) {
      if (y > 0) y0 = std::min(y0, y), y1 = std::max(y1, y);
    }
  }
  const double lx0 = std::floor(std::log10(x0)), lx1 = std::ceil(std::log10(x1));
  const double ly0 = std::floor(std::log10(y0)), ly1 = std::ceil(std::log10(y1));
  const auto X = [&](double v) { return l + (std::log10(v) - lx0) / (lx1 - lx0) * (w - l - r); };
  const auto Y = [&](double v) { return h - b - (std::log10(v) - ly0) / (ly1 - ly0) * (h - t - b); };
  std::ofstream f(path);
  f << "<svg xmlns='http://www.w3.org/2000/svg' width='" << w << "' height='" << h
    << "' font-family='sans-serif'"
    << " font-size='12'>\n<rect width='100%' height='100%' fill='white'/>\n";
  f << "<rect x='" << l << "' y='" << t << "' width='" << w - l - r << "' height='" << h - t - b
    << "' fill='none' stroke='black'/>\n";
  for (double e = lx0; e <= lx1; ++e) {
    f << "<text x='" << X(std::pow(10, e)) << "' y='" << h - b + 18 << "' text-anchor='middle'>1e" << e
      << "</text>\n";
  }
  for (double e = ly0; e <= ly1; ++e) {
    f << "<text x='" << l - 6 << "' y='" << Y(std::pow(10, e)) + 4 << "' text-anchor='end'>1e" << e
      << "</text>\n";
  }
  f << "<text x='" << (w + l - r) / 2 << "' y='" << h - 12
    << "' text-anchor='middle'>photons per frame N_ph</text>\n";
  f << "<text x='16' y='" << (h - b + t) / 2 << "' transform='rotate(-90 16 " << (h - b + t) / 2
    << ")' text-anchor='middle'>position error RMS (px)</text>\n";
  const char* colours[] = {"#1f77b4", "#d62728", "#2ca02c"};
  const char* shapes[] = {"square", "triangle", "circle"};
  for (std::size_t k = 0; k < noises.size(); ++k) {
    const char* c = colours[k % 3];
    std::string line;
    for (const auto& p : pts) {
      if (p.config.sigmaN != noises[k]) continue;
      line +=
          std::to_string(X(p.config.photonsPerFrame)) + "," + std::to_string(Y(p.predictedSigmaPos)) + " ";
      if (!(p.sdPos > 0)) continue;
      const double px = X(p.config.photonsPerFrame), py = Y(p.sdPos);
      if (k % 3 == 0)
        f << "<rect x='" << px - 4 << "' y='" << py - 4 << "' width='8' height='8' fill='" << c << "'/>\n";
      if (k % 3 == 1)
        f << "<polygon points='" << px << "," << py - 5 << " " << px - 5 << "," << py + 4 << " " << px + 5
          << "," << py + 4 << "' fill='" << c << "'/>\n";
      if (k % 3 == 2) f << "<circle cx='" << px << "' cy='" << py << "' r='4.5' fill='" << c << "'/>\n";
    }
    f << "<polyline points='" << line << "' fill='none' stroke='" << c << "'/>\n";
    f << "<text x='" << w - r - 150 << "' y='" << t + 18 + 16 * k << "' fill='" << c << "'>" << shapes[k % 3]
      << ": sigma_n = " << noises[k] << "</text>\n";
  }
  f << "<text x='" << w - r - 150 << "' y='" << t + 18 + 16 * noises.size()
    << "'>lines: eq:sig</text>\n</svg>\n";
}

int benchMonteCarlo(const CliArgs& a) {
  const int trials = static_cast<int>(a.integer("trials").value_or(100));
  const int frames = static_cast<int>(a.integer("frames").value_or(50));
  const std::filesystem::path dir = a.value("out").value_or(".");
  std::filesystem::create_directories(dir);
  const std::vector<double> noises{1.0, 3.0, 10.0};
  TerminalProgress progress;
  CancelToken& cancel = processCancelToken();
  std::vector<fit::MonteCarloPoint> pts;
  std::vector<fit::MonteCarloConfig> configs;
  for (double sn : noises) {
    // From SNR ~ 12 (detection_snr with 50 frames is ~1.37 N_ph / sigma_n) up to 30000 photons.
    for (double nph = 9.0 * sn; nph <= 30000.0; nph *= 2.5) {
      fit::MonteCarloConfig c;
      c.frames = frames;
      c.trials = trials;
      c.sigmaN = sn;
      c.photonsPerFrame = nph;
      c.seed = 7 + configs.size();
      configs.push_back(c);
    }
  }
  std::ofstream csv(dir / "fit_montecarlo.csv");
  csv << "sigma_n,photons_per_frame,frames,trials,converged,snr_mean,sd_pos_px,eq_sig_px,ratio_pos,"
         "mean_dx_px,mean_dy_px,hessian_sigma_px,sd_vel_px_s,vel_snr_px_s,ratio_vel\n";
  for (std::size_t i = 0; i < configs.size(); ++i) {
    progress.report(static_cast<double>(i) / configs.size(), "fit Monte Carlo");
    const fit::MonteCarloPoint p = fit::runMonteCarlo(configs[i], cancel);
    pts.push_back(p);
    csv << p.config.sigmaN << ',' << p.config.photonsPerFrame << ',' << p.config.frames << ','
        << p.config.trials << ',' << p.converged << ',' << p.meanSnr << ',' << p.sdPos << ','
        << p.predictedSigmaPos << ',' << p.sdPos / p.predictedSigmaPos << ',' << p.meanDx << ',' << p.meanDy
        << ',' << p.meanHessianSigmaPos << ',' << p.sdVel << ',' << p.predictedSigmaVel << ','
        << p.sdVel / p.predictedSigmaVel << std::endl;  // flushed: long runs leave a partial table
  }
  progress.finish();
  writeSvg((dir / "fit_montecarlo.svg").string(), pts, noises);
  std::printf("%-8s %-10s %-8s %-10s %-10s %-7s %-10s %-10s %-7s\n", "sigma_n", "N_ph", "SNR", "sd_pos",
              "eq:sig", "ratio", "sd_vel", "vel_snr", "ratio");
  for (const auto& p : pts) {
    std::printf("%-8g %-10.4g %-8.1f %-10.4g %-10.4g %-7.3f %-10.4g %-10.4g %-7.3f\n", p.config.sigmaN,
                p.config.photonsPerFrame, p.meanSnr, p.sdPos, p.predictedSigmaPos,
                p.sdPos / p.predictedSigmaPos, p.sdVel, p.predictedSigmaVel, p.sdVel / p.predictedSigmaVel);
  }
  std::printf("wrote %s and %s\n", (dir / "fit_montecarlo.csv").c_str(),
              (dir / "fit_montecarlo.svg").c_str());
  return 0;
}

}  // namespace

int benchFit(const Args& args) {
  if (!args.empty() && args[0] == "--help") {
    std::printf("%s", kUsage);
    return 0;
  }
  const CliArgs a(args, {"frames", "stamp", "repeat", "trials", "out"}, {"json", "montecarlo"});
  return a.flag("montecarlo") ? benchMonteCarlo(a) : benchTiming(a);
}

}  // namespace st::app
