// `synthtrack-cli preprocess` on frames whose headers describe another readout (issue 15): a NEOSSat-like
// series with BIASSEC [1:4,1:1020] and TRIMSEC [5:1064,1:1020] on 64 x 48 frames, loaded whole and with
// --crop, must pre-process (exit 0) and warn naming the file and the keyword; --ignore-sections silences
// the sections. Before, it stopped at "BIASSEC [1:16,1:1020] does not fit frames of 1078x700".
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "../core/test_io_fixtures.hpp"
#include "test_support.hpp"

namespace st {
namespace {

std::filesystem::path cliPath() {
  for (const char* p : {"../app/synthtrack-cli", "app/synthtrack-cli", "../../app/synthtrack-cli"}) {
    if (std::filesystem::exists(p)) return std::filesystem::absolute(p);
  }
  return {};
}

// Runs the CLI; returns its exit status and puts its stderr in `err`.
int runCli(const std::filesystem::path& cli, const std::string& args, const std::filesystem::path& errFile,
           std::string* err) {
  std::string cmd;
  cmd.append("\"").append(cli.string()).append("\" ").append(args).append(" > /dev/null 2> \"");
  cmd.append(errFile.string()).append("\"");
  const int status = std::system(cmd.c_str());
  std::ifstream in(errFile);
  std::stringstream s;
  s << in.rdbuf();
  *err = s.str();
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

class PreprocessCliSections : public ::testing::Test {
 protected:
  void SetUp() override {
    m_cli = cliPath();
    if (m_cli.empty()) GTEST_SKIP() << "synthtrack-cli not built";
    std::mt19937 rng(3);
    std::normal_distribution<double> noise(0.0, 5.0);
    std::filesystem::create_directories(m_dir / "in");
    for (int n = 0; n < 16; ++n) {
      char date[64];
      std::snprintf(date, sizeof date, "2023-11-07T00:58:%06.3f", 10.0 + 0.5 * n);
      test::FixtureImage img = test::timedFrame(date, 0.5, 0.0, 64, 48);
      for (int y = 0; y < 48; ++y)
        for (int x = 0; x < 64; ++x)
          img.raw[static_cast<std::size_t>(y * 64 + x)] = 500.0 + (x >= 4 ? 300.0 : 0.0) + noise(rng);
      img.cards.push_back({"BIASSEC", "'[1:4,1:1020]'", "overscan of the full readout"});
      img.cards.push_back({"TRIMSEC", "'[5:1064,1:1020]'", "data of the full readout"});
      char name[32];
      std::snprintf(name, sizeof name, "neo_%02d.fits", n);
      test::writeFixture(m_dir / "in" / name, img);
    }
  }
  std::string run(const std::string& options, int* status) {
    std::string args = "preprocess \"" + (m_dir / "in").string() + "\" -o \"" +
                       (m_dir / "out.fits").string() + "\" " + options;
    std::string err;
    *status = runCli(m_cli, args, m_dir / "err.txt", &err);
    return err;
  }
  std::filesystem::path m_cli;
  test::TempDir m_dir;
};

TEST_F(PreprocessCliSections, SectionsPastTheFrameAreClippedWithWarnings) {
  int status = -1;
  const std::string err = run("", &status);
  EXPECT_EQ(status, 0) << err;
  EXPECT_NE(err.find("neo_00.fits: BIASSEC [1:4,1:1020] does not fit frames of 64x48; clipped to [1:4,1:48]"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("TRIMSEC [5:1064,1:1020]"), std::string::npos) << err;
  EXPECT_NE(err.find("--ignore-sections"), std::string::npos) << "the hint: " << err;
}

TEST_F(PreprocessCliSections, CropMovesAndClipsTheSections) {
  int status = -1;
  const std::string err = run("--crop [1:60,3:42]", &status);
  EXPECT_EQ(status, 0) << err;
  EXPECT_NE(err.find("neo_00.fits: BIASSEC [1:4,1:1020] reaches outside the crop [1:60,3:42]; clipped to "
                     "[1:4,3:42]"),
            std::string::npos)
      << err;
}

TEST_F(PreprocessCliSections, IgnoreSectionsAndNoOverscan) {
  int status = -1;
  std::string err = run("--ignore-sections", &status);
  EXPECT_EQ(status, 0) << err;
  EXPECT_EQ(err.find("BIASSEC"), std::string::npos) << err;
  EXPECT_EQ(err.find("TRIMSEC"), std::string::npos) << err;
  err = run("--no-overscan", &status);
  EXPECT_EQ(status, 0) << err;
  EXPECT_EQ(err.find("BIASSEC"), std::string::npos) << err;
  EXPECT_NE(err.find("TRIMSEC [5:1064,1:1020]"), std::string::npos) << err;
}

}  // namespace
}  // namespace st
