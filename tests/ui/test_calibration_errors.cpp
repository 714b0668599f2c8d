// Issue 15 item 4: a calibration frame that does not fit, or cannot be read, stops the GUI's pre-processing
// with the core's message naming the file; nothing crashes. The GUI (synthtrack) runs in its script mode,
// offscreen, on the simulator's small preset written as FITS in a temporary folder (skipped when it was not
// built): the scripted run exits 1 with the message on stderr.
#include <gtest/gtest.h>

#include <cstdio>

#include "gui_process.hpp"
#include "st/io/fits_writer.hpp"
#include "st/sim/simulator.hpp"
#include "test_support.hpp"
#include "ui_test_support.hpp"

namespace st::test {
namespace {

class CalibrationErrors : public ::testing::Test {
 protected:
  void SetUp() override {
    m_gui = guiPath();
    if (m_gui.isEmpty()) GTEST_SKIP() << "synthtrack (the GUI) was not built";
    NullProgress progress;
    CancelToken cancel;
    std::filesystem::create_directories(m_tmp / "science");
    m_science = m_tmp / "science" / "cube.fits";
    io::writeCube(m_science.string(), sim::simulate(sim::preset("small"), 3, progress, cancel).cube);
  }
  GuiRun run(const QStringList& extra) {
    QStringList args{QString::fromStdString(m_science.string()), "--quit"};
    args << extra;
    const GuiRun r = runGui(m_gui, args, QString::fromStdString((m_tmp / "home").string()), 300);
    std::printf("%s\n%s\n(%.1f s)\n", r.out.toLocal8Bit().constData(), r.err.toLocal8Bit().constData(),
                r.seconds);
    return r;
  }
  TempDir m_tmp;
  QString m_gui;
  std::filesystem::path m_science;
};

TEST_F(CalibrationErrors, BiasOfAnotherSizeNamesTheFile) {
  const auto bias = m_tmp / "odd-bias.fits";
  io::writeImage(bias.string(), Image(64, 48, 100.0f));
  const GuiRun r = run({"--bias", QString::fromStdString(bias.string())});
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(r.err.contains("odd-bias.fits")) << r.err.toStdString();
  EXPECT_TRUE(r.err.contains("64")) << r.err.toStdString();
}

TEST_F(CalibrationErrors, UnreadableFlatNamesTheFile) {
  const auto flat = m_tmp / "broken-flat.fits";
  std::FILE* f = std::fopen(flat.string().c_str(), "w");
  std::fputs("SIMPLE  = not a FITS file", f);
  std::fclose(f);
  const auto bias = m_tmp / "bias.fits";
  io::writeImage(bias.string(), Image(128, 128, 100.0f));
  const GuiRun r = run({"--bias", QString::fromStdString(bias.string()), "--flat",
                        QString::fromStdString(flat.string())});
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(r.err.contains("broken-flat.fits")) << r.err.toStdString();
}

}  // namespace
}  // namespace st::test

ST_UI_TEST_MAIN()
