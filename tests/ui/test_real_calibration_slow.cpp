// Issue 15 item 4, as a new user tries it: the GUI, scripted (`synthtrack SCIENCE_FOLDER --search --quit`,
// its command-line script mode, offscreen), opens the shared Lowell 42-inch frames of (5945) Roachapproach
// (../shared/data/real/lowell42-5945: science/, bias/, flat/; skipped when absent), offers the bias/ and flat/
// folders beside science/, calibrates with them inside the pre-processing job, picks the data-derived default
// grid (about a minute of search) and finds 5945 with defaults only: within 2 px of (673, 723.5) (0-based,
// trimmed frame, t_ref) and with a velocity within 20% of (-0.00087, -0.0021) px/s, as
// tests/core/test_pipeline_real_slow.cpp. About 2 minutes on 2 cores (load, calibration, pre-processing ~30 s,
// search ~60 s).
#include <gtest/gtest.h>

#include <QApplication>
#include <QRegularExpression>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "gui_process.hpp"
#include "test_support.hpp"
#include "ui_test_support.hpp"

namespace st::test {
namespace {

constexpr double kX = 673.0, kY = 723.5, kVx = -0.00087, kVy = -0.0021;

struct PrintedCandidate {
  int rank = 0, x = 0, y = 0;
  double vx = 0, vy = 0, snr = 0;
};

std::vector<PrintedCandidate> candidatesIn(const QString& out) {
  std::vector<PrintedCandidate> list;
  static const QRegularExpression re(
      R"(candidate (\d+): x (-?\d+) y (-?\d+) vx (\S+) vy (\S+) px/s snr (\S+))");
  for (auto it = re.globalMatch(out); it.hasNext();) {
    const auto m = it.next();
    list.push_back({m.captured(1).toInt(), m.captured(2).toInt(), m.captured(3).toInt(),
                    m.captured(4).toDouble(), m.captured(5).toDouble(), m.captured(6).toDouble()});
  }
  return list;
}

TEST(RealCalibration, ScriptedGuiCalibratesLowellFramesAndFinds5945WithDefaults) {
  const auto root = realDataDir();
  if (root.empty() || !std::filesystem::is_directory(root / "lowell42-5945" / "science"))
    GTEST_SKIP() << "no real data";
  const QString gui = guiPath();
  if (gui.isEmpty()) GTEST_SKIP() << "synthtrack (the GUI) was not built";
  TempDir home;
  const QString science = QString::fromStdString((root / "lowell42-5945" / "science").string());
  const GuiRun run = runGui(gui, {science, "--search", "--quit"}, QString::fromStdString(home.path().string()),
                            1500);
  std::printf("%s\n%s\n(%.1f s)\n", run.out.toLocal8Bit().constData(), run.err.toLocal8Bit().constData(),
              run.seconds);
  ASSERT_TRUE(run.finished) << "the GUI did not finish in 1500 s";
  EXPECT_EQ(run.exitCode, 0) << run.err.toStdString();
  // Offered (visible note) and used: bias/ and flat/ from beside science/.
  EXPECT_TRUE(run.out.contains("calibration: Offered: bias/ and flat/ found beside science/"))
      << run.out.toStdString();
  EXPECT_TRUE(run.out.contains(QRegularExpression("calibration bias: \\S*lowell42-5945/bias")));
  EXPECT_TRUE(run.out.contains(QRegularExpression("calibration flat: \\S*lowell42-5945/flat")));
  EXPECT_TRUE(run.out.contains("calibrated with bias (bias), flat (flat)")) << run.out.toStdString();
  // The data-derived grid, not the paper's 19.5 M velocities.
  EXPECT_TRUE(run.out.contains("grid: data default:")) << run.out.toStdString();
  const auto list = candidatesIn(run.out);
  ASSERT_FALSE(list.empty()) << "no candidate";
  const auto found = std::find_if(list.begin(), list.end(), [](const PrintedCandidate& c) {
    return std::hypot(c.x - kX, c.y - kY) <= 2.0;
  });
  ASSERT_NE(found, list.end()) << "5945 is not among " << list.size() << " candidates";
  EXPECT_LE(std::hypot(found->vx - kVx, found->vy - kVy), 0.2 * std::hypot(kVx, kVy))
      << "velocity (" << found->vx << ", " << found->vy << ")";
  std::printf("5945: candidate %d of %zu, SNR %.1f\n", found->rank, list.size(), found->snr);
  EXPECT_EQ(found->rank, 1) << "5945 is not the best candidate";
}

}  // namespace
}  // namespace st::test

ST_UI_TEST_MAIN()
