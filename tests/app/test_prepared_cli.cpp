// The pre-processed workflow end to end on the simulator's small preset: `preprocess -o P.fits` then
// `search P.fits --preprocessed` finds the object at the SNR of the search of the raw frames (the zero-biased
// cube is matched-filtered with its header's PSF, not searched unfiltered at about half the SNR); a cube
// whose header does not say what it is is refused; `stack --filtered` takes the PSF from the header; a bias
// frame given as a science frame is named in a warning.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "cli_runner.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/fits_writer.hpp"
#include "test_support.hpp"

namespace st {
namespace {

using test::cliPath;
using test::quoted;
using test::readText;
using test::runCli;

// One simulated observation, pre-processed once, shared by the tests of this file.
class PreparedCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    s_dir = new test::TempDir;
    const auto cli = cliPath();
    if (cli.empty()) return;
    std::string args;
    args.append("simulate --preset small --seed 3 -o ")
        .append(quoted(path("raw.fits")))
        .append(" >/dev/null");
    s_ready = runCli(cli, args) == 0;
    args.clear();
    args.append("preprocess ").append(quoted(path("raw.fits"))).append(" -o ").append(quoted(path("P.fits")));
    args.append(" --filtered ").append(quoted(path("F.fits"))).append(" >/dev/null 2>&1");
    s_ready = s_ready && runCli(cli, args) == 0;
    std::ifstream(path("raw.truth.json")) >> s_truth;
  }
  static void TearDownTestSuite() {
    delete s_dir;
    s_dir = nullptr;
  }
  void SetUp() override {
    if (cliPath().empty()) GTEST_SKIP() << "synthtrack-cli not built";
    ASSERT_TRUE(s_ready) << "simulate or preprocess failed";
  }
  static std::filesystem::path path(const std::string& name) { return *s_dir / name; }
  static const nlohmann::json& truthObject() { return s_truth["objects"][0]; }

  /// `search INPUT [extra] --json` on the small preset's grid; the JSON, or null when it failed.
  static nlohmann::json search(const std::string& input, const std::string& extra, const std::string& tag) {
    std::string args;
    args.append("search ").append(quoted(path(input))).append(" ").append(extra);
    args.append(" --vmax-deg-day 40 --backend cpu --method exact --json > ")
        .append(quoted(path(tag + ".json")));
    args.append(" 2> ").append(quoted(path(tag + ".err")));
    if (runCli(cliPath(), args) != 0) return nullptr;
    nlohmann::json j;
    std::ifstream(path(tag + ".json")) >> j;
    return j;
  }

  /// SNR of the candidate at the simulated object (within 2 px and 1.5 grid steps), 0 when none.
  static double snrAtTruth(const nlohmann::json& j) {
    const auto& o = truthObject();
    const double step = j["grid"]["step_px_s"].get<double>();
    double best = 0.0;
    for (const auto& c : j["candidates"]) {
      if (std::hypot(c["x"].get<double>() - o["x_ref_px"].get<double>(),
                     c["y"].get<double>() - o["y_ref_px"].get<double>()) <= 2.0 &&
          std::hypot(c["vx_px_s"].get<double>() - o["vx_px_s"].get<double>(),
                     c["vy_px_s"].get<double>() - o["vy_px_s"].get<double>()) <= 1.5 * step) {
        best = std::max(best, c["snr"].get<double>());
      }
    }
    return best;
  }

  static FitsHeader headerOf(const std::string& name) {
    io::LoadOptions o;  // a 2-D stack has MJD-AVG; the fallback clock is only for files without a time
    o.startMjd = 60000.0;
    o.frameRateHz = 1.0;
    NullProgress progress;
    CancelToken cancel;
    return io::loadFrames({path(name).string()}, o, progress, cancel).header;
  }

  static inline test::TempDir* s_dir = nullptr;
  static inline bool s_ready = false;
  static inline nlohmann::json s_truth;
};

TEST_F(PreparedCli, PreparedCubeIsSearchedAtTheRawSearchSnr) {
  const nlohmann::json raw = search("raw.fits", "", "raw");
  ASSERT_FALSE(raw.is_null()) << readText(path("raw.err"));
  const double rawSnr = snrAtTruth(raw);
  ASSERT_GT(rawSnr, 7.0) << "the raw search finds the object: " << raw["candidates"].dump();

  const nlohmann::json prep = search("P.fits", "--preprocessed", "prep");
  ASSERT_FALSE(prep.is_null()) << readText(path("prep.err"));
  const std::string note = readText(path("prep.err"));
  EXPECT_NE(note.find("zero-biased cube (STFILT = F), matched-filtered"), std::string::npos) << note;
  const double prepSnr = snrAtTruth(prep);
  EXPECT_NEAR(prepSnr, rawSnr, 0.1 * rawSnr) << "zero-biased cube searched unfiltered?";
  EXPECT_EQ(prep["trials"], raw["trials"]) << "same grid: the sky rate came from the header";

  const nlohmann::json filt = search("F.fits", "--preprocessed", "filt");
  ASSERT_FALSE(filt.is_null()) << readText(path("filt.err"));
  EXPECT_NEAR(snrAtTruth(filt), rawSnr, 0.1 * rawSnr);
  std::printf("object SNR: raw search %.2f, preprocess -o + --preprocessed %.2f, --filtered cube %.2f\n",
              rawSnr, prepSnr, snrAtTruth(filt));
}

TEST_F(PreparedCli, CubeThatIsNotPreparedIsRefusedNamingTheKeyword) {
  std::string args;
  args.append("search ").append(quoted(path("raw.fits"))).append(" --preprocessed --backend cpu 2> ");
  args.append(quoted(path("refused.err"))).append(" >/dev/null");
  EXPECT_EQ(runCli(cliPath(), args), 1);
  const std::string err = readText(path("refused.err"));
  EXPECT_NE(err.find("raw.fits"), std::string::npos) << err;
  EXPECT_NE(err.find("STFILT"), std::string::npos) << err;
  EXPECT_NE(err.find("synthtrack-cli preprocess"), std::string::npos) << err;
  // The other way round: a prepared cube searched as raw frames would be pre-processed again.
  args.clear();
  args.append("search ").append(quoted(path("P.fits"))).append(" --backend cpu 2> ");
  args.append(quoted(path("again.err"))).append(" >/dev/null");
  EXPECT_EQ(runCli(cliPath(), args), 1);
  EXPECT_NE(readText(path("again.err")).find("--preprocessed"), std::string::npos)
      << readText(path("again.err"));
}

TEST_F(PreparedCli, StackFilteredTakesThePsfFromTheHeader) {
  const auto& o = truthObject();
  std::string args;
  args.append("stack ").append(quoted(path("P.fits"))).append(" --filtered --vx-px-s ");
  args.append(std::to_string(o["vx_px_s"].get<double>())).append(" --vy-px-s ");
  args.append(std::to_string(o["vy_px_s"].get<double>())).append(" -o ").append(quoted(path("stack.fits")));
  args.append(" >/dev/null 2> ").append(quoted(path("stack.err")));
  ASSERT_EQ(runCli(cliPath(), args), 0) << readText(path("stack.err"));
  EXPECT_NE(readText(path("stack.err")).find("(header of"), std::string::npos) << readText(path("stack.err"));
  const FitsHeader prepared = headerOf("P.fits");
  const FitsHeader stacked = headerOf("stack.fits");
  EXPECT_EQ(stacked.getString("FILTERED"), "T");
  EXPECT_DOUBLE_EQ(*stacked.getDouble("PSFFWHM"), *prepared.getDouble("PSFFWHM"));
  EXPECT_DOUBLE_EQ(*stacked.getDouble("PSFBETA"), *prepared.getDouble("PSFBETA"));
  // The stack at the object's velocity peaks on the object (the stars are zeroed in the prepared cube).
  io::LoadOptions lo;
  lo.startMjd = 60000.0;
  lo.frameRateHz = 1.0;
  NullProgress progress;
  CancelToken cancel;
  const FrameCube image = io::loadFrames({path("stack.fits").string()}, lo, progress, cancel);
  const float* px = image.frame(0);
  const auto peak = std::max_element(px, px + image.framePixels()) - px;
  EXPECT_NEAR(static_cast<double>(peak % image.width()), o["x_ref_px"].get<double>(), 1.5);
  EXPECT_NEAR(static_cast<double>(peak / image.width()), o["y_ref_px"].get<double>(), 1.5);

  // The filtered cube is not filtered a second time.
  args.clear();
  args.append("stack ").append(quoted(path("F.fits"))).append(" --filtered --vx-px-s 0 --vy-px-s 0 -o ");
  args.append(quoted(path("stackf.fits"))).append(" >/dev/null 2> ").append(quoted(path("stackf.err")));
  ASSERT_EQ(runCli(cliPath(), args), 0) << readText(path("stackf.err"));
  EXPECT_NE(readText(path("stackf.err")).find("already matched-filtered"), std::string::npos)
      << readText(path("stackf.err"));
}

// `fit` on the zero-biased cube models its per-pixel background (header BGWINS...) as `search --fit` does on
// frames it pre-processed, and says so; the sidecar beside it says the object was not left out of it. Oracle:
// the simulator's position of the object (the fit within 3 sigma of it).
TEST_F(PreparedCli, FitOfThePreparedCubeModelsItsBackgroundWindows) {
  const auto& o = truthObject();
  const FitsHeader prepared = headerOf("P.fits");
  ASSERT_TRUE(prepared.getDouble("BGWINS") && prepared.getDouble("BGNFRM"))
      << "preprocess records the windows";
  char args[512];
  std::snprintf(args, sizeof args,
                "fit %s --x %.3f --y %.3f --vx-px-s %.5f --vy-px-s %.5f --fwhm %.6f --psf-beta %.6f "
                "--json > %s 2> %s",
                quoted(path("P.fits")).c_str(), o["x_ref_px"].get<double>(), o["y_ref_px"].get<double>(),
                o["vx_px_s"].get<double>(), o["vy_px_s"].get<double>(), *prepared.getDouble("PSFFWHM"),
                *prepared.getDouble("PSFBETA"), quoted(path("fit.json")).c_str(),
                quoted(path("fit.err")).c_str());
  ASSERT_EQ(runCli(cliPath(), args), 0) << readText(path("fit.err"));
  nlohmann::json j;
  std::ifstream(path("fit.json")) >> j;
  ASSERT_EQ(j["notes"].size(), 1u) << j.dump();
  const std::string note = j["notes"][0].get<std::string>();
  EXPECT_NE(note.find("models the per-pixel background's windows (header BGWINS)"), std::string::npos)
      << note;
  EXPECT_NE(note.find("not one of the sidecar's movers"), std::string::npos) << note;
  EXPECT_NE(readText(path("fit.err")).find(note), std::string::npos) << "said on stderr too";
  const auto& f = j["fit"];
  EXPECT_EQ(f["status"], "converged");
  EXPECT_NEAR(f["params"]["x_px"].get<double>(), o["x_ref_px"].get<double>(),
              3.0 * f["sigma_noise_model"]["x_px"].get<double>());
  EXPECT_NEAR(f["params"]["y_px"].get<double>(), o["y_ref_px"].get<double>(),
              3.0 * f["sigma_noise_model"]["y_px"].get<double>());
}

TEST_F(PreparedCli, BiasFrameGivenAsScienceIsNamedInAWarning) {
  Image frame(32, 24);
  for (std::size_t i = 0; i < frame.pixels.size(); ++i)
    frame.pixels[i] = static_cast<float>(100 + i % 7);
  FitsHeader light;
  light.setString("IMAGETYP", "Light Frame");
  light.setNumber("EXPTIME", 1.0);
  FitsHeader bias;
  bias.setString("IMAGETYP", "Bias Frame");
  bias.setNumber("EXPTIME", 0.0);
  io::writeImage(path("light1.fits").string(), frame, light);
  io::writeImage(path("light2.fits").string(), frame, light);
  io::writeImage(path("bias1.fits").string(), frame, bias);
  std::string args;
  args.append("stack ").append(quoted(path("light1.fits"))).append(" ").append(quoted(path("light2.fits")));
  args.append(" ").append(quoted(path("bias1.fits")));
  args.append(" --start-mjd 60000 --frame-rate 1 --vx-px-s 0 --vy-px-s 0 -o ").append(quoted(path("b.fits")));
  args.append(" >/dev/null 2> ").append(quoted(path("bias.err")));
  ASSERT_EQ(runCli(cliPath(), args), 0) << readText(path("bias.err"));
  const std::string err = readText(path("bias.err"));
  const auto at = err.find("warning: " + path("bias1.fits").string());
  ASSERT_NE(at, std::string::npos) << err;
  const std::string line = err.substr(at, err.find('\n', at) - at);
  EXPECT_NE(line.find("IMAGETYP = 'Bias Frame' says a bias frame"), std::string::npos) << line;
  EXPECT_NE(line.find("EXPTIME = 0"), std::string::npos) << line;
  EXPECT_EQ(err.find("light1.fits"), std::string::npos) << "science frames are not warned about: " << err;
}

}  // namespace
}  // namespace st
