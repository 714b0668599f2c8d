// `synthtrack-cli search` end to end: a matched-filtered cube with a moving source written as FITS, searched
// by the CLI; the JSON must carry the source at the right place, velocity and SNR, and the trial counts.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../core/search_test_cubes.hpp"
#include "cli_runner.hpp"
#include "st/io/fits_writer.hpp"
#include "test_support.hpp"

namespace st {
namespace {

using test::cliPath;
using test::quoted;
using test::readText;
using test::runCli;

// Simulates the small preset's raw frames (64 frames of 128 px) into `raw`; the CLI's exit status.
int simulateSmall(const std::filesystem::path& cli, const std::filesystem::path& raw, int seed) {
  return runCli(cli, "simulate --preset small --seed " + std::to_string(seed) + " -o " + quoted(raw) +
                         " > /dev/null 2>&1");
}

TEST(SearchCli, FindsInjectedSourceAndWritesJsonAndCsv) {
  const auto cli = cliPath();
  if (cli.empty()) GTEST_SKIP() << "synthtrack-cli not built";
  const psf::Moffat psf{psf::Moffat::radiusForFwhm(3.0, 4.0), 4.0};
  const int r = 6;
  FrameCube cube = test::noiseCube(64, 48, test::unevenTimes(30, 0.5, 8), 1.0, 8);
  const double span = cube.timeSpanS();
  const double p2 = test::sumP2(psf, r);
  const Velocity truth{8.0 / span, -4.0 / span};  // a grid velocity: 8 and -4 steps of 1 px / span
  test::injectMoffat(cube, psf, 20.0 / (std::sqrt(30.0) * std::sqrt(p2)), 30.0, 20.0, truth);
  test::matchedFilter(cube, psf, r);
  test::TempDir dir;
  const auto fits = dir / "filtered.fits";
  FitsHeader extra;  // no STFILT: SIGMAF alone says filtered (files written before STFILT existed)
  extra.setNumber("SIGMAF", std::sqrt(p2), "noise of one filtered frame");
  extra.setNumber("PSFFWHM", psf.fwhm(), "px");
  io::writeCube(fits.string(), cube, extra);
  const auto json = dir / "out.json";
  const auto csv = dir / "out.csv";
  std::string args;
  args.append("search ").append(quoted(fits)).append(" --preprocessed --vmax-px-s ");
  args.append(std::to_string(10.0 / span)).append(" --backend cpu --json --out ").append(quoted(csv));
  args.append(" > ").append(quoted(json)).append(" 2>/dev/null");
  ASSERT_EQ(runCli(cli, args), 0) << args;
  nlohmann::json j;
  std::ifstream(json) >> j;
  EXPECT_EQ(j["trials"]["nx"], 64);
  EXPECT_EQ(j["trials"]["ny"], 48);
  EXPECT_EQ(j["trials"]["nvx"], 21);
  EXPECT_EQ(j["trials"]["nvy"], 21);
  EXPECT_NEAR(j["t_ref_mjd"].get<double>(), cube.tRefMjd(), 1e-9);
  EXPECT_DOUBLE_EQ(j["snr_threshold"].get<double>(), 7.0);
  ASSERT_EQ(j["candidates"].size(), 1u) << j.dump(2);
  const auto& c = j["candidates"][0];
  EXPECT_NEAR(c["x"].get<int>(), 30, 1);
  EXPECT_NEAR(c["y"].get<int>(), 20, 1);
  EXPECT_NEAR(c["vx_px_s"].get<double>(), truth.vx, 1.01 / span);
  EXPECT_NEAR(c["vy_px_s"].get<double>(), truth.vy, 1.01 / span);
  EXPECT_GT(c["snr"].get<double>(), 0.8 * 20.0);
  EXPECT_LT(c["snr"].get<double>(), 1.1 * 20.0);
  EXPECT_EQ(c["n_frames"], 30);
  EXPECT_FALSE(c.contains("rate_deg_day"));  // no plate scale in this file
  std::ifstream in(csv);
  std::string header, row;
  std::getline(in, header);
  std::getline(in, row);
  EXPECT_EQ(header.rfind("x,y,vx_px_s,vy_px_s,snr,n_frames,fap", 0), 0u);
  EXPECT_FALSE(row.empty());
}

// --timings on raw frames: the steps in order on stderr, each pre-processing stage with its seconds, the
// frames' reading first (issue 16: where FITS-to-candidates time goes), and nothing of it without the flag.
TEST(SearchCli, TimingsListEveryStepInOrder) {
  const auto cli = cliPath();
  if (cli.empty()) GTEST_SKIP() << "synthtrack-cli not built";
  test::TempDir dir;
  const auto raw = dir / "raw.fits";
  ASSERT_EQ(simulateSmall(cli, raw, 3), 0);
  const auto err = dir / "err.txt";
  ASSERT_EQ(runCli(cli, "search " + quoted(raw) + " --vmax-deg-day 20 --backend cpu --timings > /dev/null 2> " +
                            quoted(err)),
            0);
  const std::vector<std::string> steps = test::timingLines(err);
  // The backend is made while the frames are read, and ready when the pre-processing asks for it.
  const std::vector<std::string> order = {"memory plan", "backend ready", "read the frames", "matched filter",
                                          "loaded and pre-processed", "search planned", "searched",
                                          "outputs written"};
  EXPECT_EQ(test::stepsInOrder(steps, order), order.size()) << "steps seen: " << steps.size();
  ASSERT_EQ(runCli(cli, "search " + quoted(raw) + " --vmax-deg-day 20 --backend cpu > /dev/null 2> " + quoted(err)),
            0);
  EXPECT_EQ(readText(err).find("timings:"), std::string::npos);
}

// --grid-auto: the GUI's data-derived grid from the command line. On the small preset (64 frames of 128 px)
// the paper's +-12 deg/day bounds it (the frame allows more, and it takes well under a minute): the grid and
// its note say so, the search runs on it; with a --vmax-* half-width it is a usage error.
TEST(SearchCli, GridAutoTakesTheDataDerivedDefault) {
  const auto cli = cliPath();
  if (cli.empty()) GTEST_SKIP() << "synthtrack-cli not built";
  test::TempDir dir;
  const auto raw = dir / "raw.fits";
  ASSERT_EQ(simulateSmall(cli, raw, 4), 0);
  const auto json = dir / "out.json", err = dir / "err.txt";
  ASSERT_EQ(runCli(cli, "search " + quoted(raw) + " --grid-auto --backend cpu --json > " + quoted(json) + " 2> " +
                            quoted(err)),
            0);
  const std::string all = readText(err);
  EXPECT_NE(all.find("grid (--grid-auto): "), std::string::npos) << all;
  EXPECT_NE(all.find("the paper's range"), std::string::npos) << all;
  nlohmann::json j;
  std::ifstream(json) >> j;
  const int nvx = j["trials"]["nvx"].get<int>();
  EXPECT_EQ(nvx, j["trials"]["nvy"].get<int>());
  EXPECT_GE(nvx, 3);
  EXPECT_EQ(nvx % 2, 1);
  EXPECT_EQ(runCli(cli, "search " + quoted(raw) + " --grid-auto --vmax-deg-day 5 > /dev/null 2>&1"), 2);
}

TEST(SearchCli, BadInputIsAClearError) {
  const auto cli = cliPath();
  if (cli.empty()) GTEST_SKIP() << "synthtrack-cli not built";
  // --fit with an already filtered cube: usage error (2); --snr and --fap together: usage error.
  EXPECT_EQ(runCli(cli, "search x.fits --preprocessed --fit 2>/dev/null"), 2);
  EXPECT_EQ(runCli(cli, "search x.fits --preprocessed --snr 5 --fap 0.1 2>/dev/null"), 2);
  // Missing file: input error (1).
  EXPECT_EQ(runCli(cli, "search /nonexistent.fits --preprocessed 2>/dev/null"), 1);
  // Raw input goes through pre-processing first: a missing raw file is an input error too.
  EXPECT_EQ(runCli(cli, "search /nonexistent.fits 2>/dev/null"), 1);
}

}  // namespace
}  // namespace st
