// `synthtrack-cli demo --timings`: when each step ended, the pre-processing stages, and the seconds after
// the simulation (issue 16's demo target counts those), in order on stderr; nothing of it without the flag.
#include <gtest/gtest.h>

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
// run that long (ST_PROGRESS_LINE_S shortens it here): the small demo, ~2 s, writes none by default and
// several at 0.05 s, each with its percentage, the seconds so far and the stage.
TEST(DemoCli, ProgressLinesInALogOnlyForLongJobs) {
  const auto cli = cliPath();
  if (cli.empty()) GTEST_SKIP() << "synthtrack-cli not built";
  test::TempDir dir;
  const auto err = dir / "err.txt";
  const std::string demo =
      "demo --preset small --vmax-deg-day 40 --backend cpu --fits 0 --out " + quoted(dir / "out");
  ASSERT_EQ(runCli(cli, demo + " > /dev/null 2> " + quoted(err)), 0) << readText(err);
  EXPECT_EQ(readText(err).find("progress: "), std::string::npos) << readText(err);
  ::setenv("ST_PROGRESS_LINE_S", "0.05", 1);
  const int rc = runCli(cli, demo + " > /dev/null 2> " + quoted(err));
  ::unsetenv("ST_PROGRESS_LINE_S");
  ASSERT_EQ(rc, 0) << readText(err);
  const std::string text = readText(err);
  std::size_t lines = 0;
  for (std::size_t at = text.find("progress: "); at != std::string::npos;
       at = text.find("progress: ", at + 1)) {
    ++lines;
    const std::string line = text.substr(at, text.find('\n', at) - at);
    EXPECT_NE(line.find("% after "), std::string::npos) << line;
    EXPECT_NE(line.find(" s"), std::string::npos) << line;
  }
  EXPECT_GE(lines, 3u) << text;
}

}  // namespace
}  // namespace st
