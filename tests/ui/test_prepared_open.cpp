// Issue 15 item 4: a cube written as `synthtrack-cli preprocess` writes it (STPREP = 1, STFILT = F, PSFFWHM,
// PSFBETA, SIGMAN, SKYVX/SKYVY, the per-pixel background's windows BGWINS..., and the .json sidecar) opens in
// the GUI as prepared: no second pre-processing, its PSF and sky rate taken from the header, the co-moving
// fit's background model from the windows and the sidecar's movers, and the status bar says so. The cube is
// made with the core API from the simulator's small preset in a temporary folder; the GUI (synthtrack) runs
// in its script mode, offscreen (skipped when it was not built).
#include <gtest/gtest.h>

#include <QRegularExpression>
#include <cstdio>

#include "gui_process.hpp"
#include "st/io/fits_writer.hpp"
#include "st/pipeline/prepared_cube.hpp"
#include "st/pipeline/prepared_json.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/sim/simulator.hpp"
#include "test_support.hpp"
#include "ui_test_support.hpp"

namespace st::test {
namespace {

TEST(PreparedOpen, PreparedCubeOpensAsPreparedWithItsHeaderValues) {
  const QString gui = guiPath();
  if (gui.isEmpty()) GTEST_SKIP() << "synthtrack (the GUI) was not built";
  TempDir tmp;
  NullProgress progress;
  CancelToken cancel;
  FrameCube raw = sim::simulate(sim::preset("small"), 7, progress, cancel).cube;
  const pipeline::Prepared prepared = pipeline::preprocess(std::move(raw), {}, progress, cancel);
  std::filesystem::create_directories(tmp / "night" / "prepared");
  const auto cube = tmp / "night" / "prepared" / "prepared.fits";
  io::writeCube(cube.string(), prepared.frames,
                pipeline::preparedCubeCards(prepared, pipeline::PreparedState::ZeroBiased));
  pipeline::writePreparedSidecar((tmp / "night" / "prepared" / "prepared.json").string(), prepared);
  // A bias/ folder beside it must not be offered for a cube that is calibrated already.
  std::filesystem::create_directories(tmp / "night" / "bias");
  std::fclose(std::fopen((tmp / "night" / "bias" / "b.fits").string().c_str(), "w"));

  const GuiRun run = runGui(gui, {QString::fromStdString(cube.string()), "--quit"},
                            QString::fromStdString((tmp / "home").string()), 300);
  std::printf("%s\n%s\n(%.1f s)\n", run.out.toLocal8Bit().constData(), run.err.toLocal8Bit().constData(),
              run.seconds);
  ASSERT_TRUE(run.finished);
  EXPECT_EQ(run.exitCode, 0) << run.err.toStdString();
  EXPECT_TRUE(run.out.contains("pre-processing: opened as a prepared cube (STFILT = F), not pre-processed "
                               "again"))
      << run.out.toStdString();
  EXPECT_TRUE(run.out.contains("status: Opened as a prepared cube")) << run.out.toStdString();
  EXPECT_FALSE(run.out.contains("calibration bias:")) << run.out.toStdString();
  // The header's PSF and sky rate, not re-measured.
  char psf[64];
  std::snprintf(psf, sizeof psf, "PSF FWHM %.2f px (header)", prepared.psf.fwhm());
  EXPECT_TRUE(run.out.contains(psf)) << psf << "\n" << run.out.toStdString();
  char sky[96];
  std::snprintf(sky, sizeof sky, "sky rate (%.4g, %.4g) px/s (header)", prepared.skyRate.vx,
                prepared.skyRate.vy);
  EXPECT_TRUE(run.out.contains(sky)) << sky << "\n" << run.out.toStdString();
  EXPECT_TRUE(run.out.contains("grid: data default:")) << run.out.toStdString();
  // The co-moving fit models the per-pixel background that the header records, with the sidecar's movers.
  const QString windows = QString::fromStdString(
      "the co-moving fit models the per-pixel background's windows (header BGWINS) and the " +
      std::to_string(prepared.movers.size()) + " mover(s) left out of it");
  EXPECT_TRUE(run.out.contains(windows)) << run.out.toStdString();
}

}  // namespace
}  // namespace st::test

ST_UI_TEST_MAIN()
