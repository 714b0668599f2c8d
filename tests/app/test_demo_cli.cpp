// `synthtrack-cli demo --timings`: when each step ended, the pre-processing stages, and the seconds after
// the simulation (issue 16's demo target counts those), in order on stderr; nothing of it without the flag.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "cli_runner.hpp"
#include "test_support.hpp"

namespace st {
namespace {

using test::cliPath;
using test::quoted;
using test::readText;
using test::runCli;

TEST(DemoCli, TimingsListEveryStepAndTheSecondsAfterTheSimulation) {
  const auto cli = cliPath();
  if (cli.empty()) GTEST_SKIP() << "synthtrack-cli not built";
  test::TempDir dir;
  const auto err = dir / "err.txt";
  const std::string demo =
      "demo --preset small --vmax-deg-day 40 --backend cpu --fits 1 --out " + quoted(dir / "out");
  // Exit 0: the small preset's objects found (as cli.demo_small asks of the full preset).
  ASSERT_EQ(runCli(cli, demo + " --timings > /dev/null 2> " + quoted(err)), 0) << readText(err);
  const std::vector<std::string> steps = test::timingLines(err);
  const std::vector<std::string> order = {"simulated and written", "backend ready",   "frame backgrounds",
                                          "matched filter",        "pre-processed",   "searched",
                                          "candidates fitted",     "outputs written", "after the simulation"};
  EXPECT_EQ(test::stepsInOrder(steps, order), order.size()) << readText(err);
  // The seconds after the simulation are the last mark's less the simulation's.
  auto seconds = [&](const std::string& what) {
    for (const auto& s : steps)
      if (s.find(what) != std::string::npos) return std::stod(s.substr(s.rfind(' ', s.size() - 3)));
    return -1.0;
  };
  const double after = seconds("after the simulation");
  EXPECT_GT(after, 0.0);
  EXPECT_NEAR(after, seconds("outputs written") - seconds("simulated and written"), 0.002);
  ASSERT_EQ(runCli(cli, demo + " > /dev/null 2> " + quoted(err)), 0);
  EXPECT_EQ(readText(err).find("timings:"), std::string::npos);
}

// With stderr not a terminal (a log, a pipe) the progress is a plain line at most every 30 s once a job has
// run that long (ST_PROGRESS_LINE_S sets the interval): none at 1000 s, and with an interval of 1e-9 s one
// per report after the first, each "progress: P% after S s[ (about L s left)]: stage" with 0 <= P <= 100.
TEST(DemoCli, ProgressLinesInALogOnlyForLongJobs) {
  const auto cli = cliPath();
  if (cli.empty()) GTEST_SKIP() << "synthtrack-cli not built";
  test::TempDir dir;
  const auto err = dir / "err.txt";
  const std::string demo =
      "demo --preset small --vmax-deg-day 40 --backend cpu --fits 0 --out " + quoted(dir / "out");
  auto run = [&](const char* interval) {
    ::setenv("ST_PROGRESS_LINE_S", interval, 1);
    const int rc = runCli(cli, demo + " > /dev/null 2> " + quoted(err));
    ::unsetenv("ST_PROGRESS_LINE_S");
    return rc;
  };
  ASSERT_EQ(run("1000"), 0) << readText(err);
  EXPECT_EQ(readText(err).find("progress: "), std::string::npos) << readText(err);
  ASSERT_EQ(run("1e-9"), 0) << readText(err);
  const std::string text = readText(err);
  std::size_t lines = 0;
  for (std::size_t at = text.find("progress: "); at != std::string::npos;
       at = text.find("progress: ", at + 1)) {
    ++lines;
    const std::string line = text.substr(at, text.find('\n', at) - at);
    double percent = -1.0, seconds = -1.0;
    ASSERT_EQ(std::sscanf(line.c_str(), "progress: %lf%% after %lf s", &percent, &seconds), 2) << line;
    EXPECT_GE(percent, 0.0) << line;
    EXPECT_LE(percent, 100.0) << line;
    EXPECT_GE(seconds, 0.0) << line;
    EXPECT_NE(line.find(": ", line.find(" s")), std::string::npos) << line;  // the stage follows
  }
  EXPECT_GE(lines, 3u) << text;
}

}  // namespace
}  // namespace st
