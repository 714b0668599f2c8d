// The line a stopped batch prints naming what it did not do (app/common/batch_runner.hpp notDoneLine): every
// name when they fit; cut to the byte budget (one atomic pipe write beside the "stopped" line: mpirun lost the
// second of two writes in CI) with the rest counted, never over the budget.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "batch_runner.hpp"

namespace st::app {
namespace {

TEST(BatchNotDoneLine, NamesEveryObservationThatFits) {
  EXPECT_EQ(notDoneLine({}, 4000), "batch: every observation had finished\n");
  EXPECT_EQ(notDoneLine({"obs1", "obs2"}, 4000),
            "batch: NOT DONE: obs1, obs2. Rerun the same command to finish them.\n");
}

TEST(BatchNotDoneLine, ManyNamesAreCutToTheBudgetAndCounted) {
  std::vector<std::string> names;
  for (int i = 0; i < 500; ++i)
    names.push_back("night-2026-11-28/cube-" + std::to_string(i));
  for (const std::size_t budget : {std::size_t{4000}, std::size_t{600}, std::size_t{200}}) {
    const std::string line = notDoneLine(names, budget);
    EXPECT_LE(line.size(), budget) << line;
    EXPECT_EQ(line.rfind("batch: NOT DONE: night-2026-11-28/cube-0, ", 0), 0u) << line;
    EXPECT_NE(line.find(" more (the catalogue lists every one). Rerun the same command"), std::string::npos)
        << line;
    // The names shown and the count add up to all of them.
    std::size_t shown = 0;
    for (std::size_t at = line.find("cube-"); at != std::string::npos; at = line.find("cube-", at + 1))
      ++shown;
    const std::size_t and_ = line.rfind(" and ");
    ASSERT_NE(and_, std::string::npos) << line;
    EXPECT_EQ(shown + std::stoul(line.substr(and_ + 5)), names.size()) << line;
  }
  // Not even one name fits: the count alone.
  const std::string line = notDoneLine(names, 130);
  EXPECT_LE(line.size(), 130u);
  EXPECT_EQ(line, "batch: NOT DONE: 500 observations (the catalogue lists every one). Rerun the same command to "
                  "finish them.\n");
}

}  // namespace
}  // namespace st::app
