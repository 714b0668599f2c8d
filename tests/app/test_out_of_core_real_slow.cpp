// Issue 20 on real frames: the shared Lowell 42-inch sequence of 5945 (15 x 300 s, 5 biases, 3 flats;
// ../shared/data/real/lowell42-5945, skipped when absent) searched by the CLI in memory and under a
// --memory-limit that its in-memory pre-processing (~800 MB) does not fit: the raw frames are then
// calibrated and pre-processed out of core in strips of rows (overscan columns trimmed, one set of masters
// cropped to every strip) and the written filtered cube searched. 5945 is the best candidate of both runs,
// at the same pixel, with the out-of-core SNR within 5% of the in-memory one (the PSF comes from the central
// strip: 1.38 px against 1.56 px fitted over the whole frame, 2026-11-27), under the budget.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "cli_runner.hpp"
#include "test_support.hpp"

namespace st {
namespace {

using test::cliPath;
using test::quoted;
using test::readText;

TEST(OutOfCoreReal, Lowell5945PreProcessedInStripsIsFoundAsInMemory) {
  if (cliPath().empty()) GTEST_SKIP() << "synthtrack-cli not built";
  const std::filesystem::path data = test::realDataDir();
  if (data.empty() || !std::filesystem::exists(data / "lowell42-5945")) GTEST_SKIP() << "no real data";
  const std::filesystem::path l = data / "lowell42-5945";
  test::TempDir dir;
  const std::string common = "search " + quoted(l / "science") + " --bias " + quoted(l / "bias") + " --flat " +
                             quoted(l / "flat") + " --vmax-deg-day 0.2 --backend cpu --json --scratch " +
                             quoted(dir.path());
  auto run = [&](const std::string& limit, const std::string& tag) {
    const int rc = test::runCli(cliPath(), common + " --memory-limit " + limit + " > " + quoted(dir / (tag + ".json")) +
                                               " 2> " + quoted(dir / (tag + ".err")));
    EXPECT_EQ(rc, 0) << readText(dir / (tag + ".err"));
    nlohmann::json j;
    if (rc == 0) std::ifstream(dir / (tag + ".json")) >> j;
    return j;
  };
  const nlohmann::json mem = run("4G", "mem");
  const nlohmann::json ooc = run("450M", "ooc");
  ASSERT_FALSE(mem.is_null());
  ASSERT_FALSE(ooc.is_null());
  const std::string err = readText(dir / "ooc.err");
  EXPECT_NE(err.find("pre-processing out of core: "), std::string::npos) << err;
  ASSERT_GE(mem["candidates"].size(), 1u);
  ASSERT_GE(ooc["candidates"].size(), 1u);
  const auto& a = mem["candidates"][0];
  const auto& b = ooc["candidates"][0];
  std::printf("5945: in memory (%d, %d) SNR %.1f, sigma_F %.2f, PSF %.2f px; out of core (%d, %d) SNR %.1f, "
              "sigma_F %.2f, PSF %.2f px; VmHWM %.0f MB (budget 450 MB)\n",
              a["x"].get<int>(), a["y"].get<int>(), a["snr"].get<double>(), mem["sigma_f"].get<double>(),
              mem["psf_fwhm_px"].get<double>(), b["x"].get<int>(), b["y"].get<int>(), b["snr"].get<double>(),
              ooc["sigma_f"].get<double>(), ooc["psf_fwhm_px"].get<double>(),
              ooc["memory"]["peak_resident_bytes"].get<double>() / 1048576.0);
  EXPECT_NEAR(a["x"].get<int>(), 673, 2);
  EXPECT_NEAR(a["y"].get<int>(), 724, 2);
  EXPECT_NEAR(b["x"].get<int>(), a["x"].get<int>(), 1);
  EXPECT_NEAR(b["y"].get<int>(), a["y"].get<int>(), 1);
  EXPECT_NEAR(b["snr"].get<double>(), a["snr"].get<double>(), 0.05 * a["snr"].get<double>());
  EXPECT_LT(ooc["memory"]["peak_resident_bytes"].get<double>(), 450.0 * 1048576.0);
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()) ||
              !std::filesystem::exists(dir / "science.synthtrack-filtered.fits"));
}

}  // namespace
}  // namespace st
