// Opening inputs in the main window: a file that does not open says why in the central view, in full (the
// status bar's line is cut short and gone after 10 s, and a scripted run shows no dialog), and it does not
// join the recent files.
#include <gtest/gtest.h>

#include <QSettings>
#include <filesystem>

#include "image_view.hpp"
#include "job_runner.hpp"
#include "main_window.hpp"
#include "st/common/error.hpp"
#include "test_support.hpp"
#include "ui_test_support.hpp"

using namespace st;
using namespace st::ui;

TEST(MainWindowLoad, AFailedOpenIsShownInTheViewAndNotRemembered) {
  test::TempDir dir;
  const std::string missing = (dir / "missing.fits").string();
  CoreServices services = test::fakeServices(test::movingDotCube(64, 64, 20, {8.0, -4.0}, 30, 35));
  services.loadFrames = [](const std::vector<std::string>& inputs, ProgressSink&, CancelToken&) -> FrameCube {
    throw InputError("no such file '" + inputs.front() + "'");
  };
  MainWindow w(services);
  w.setScripted(true);
  w.show();
  const QStringList before = QSettings().value("recentFiles").toStringList();
  w.openInputs({QString::fromStdString(missing)});
  ASSERT_TRUE(test::waitFor(
      [&] { return !w.jobs()->busy() && w.imageView()->placeholder().startsWith("Could not open"); }))
      << w.imageView()->placeholder().toStdString();
  EXPECT_TRUE(w.imageView()->placeholder().contains(QString::fromStdString("no such file '" + missing + "'")))
      << w.imageView()->placeholder().toStdString();
  EXPECT_EQ(QSettings().value("recentFiles").toStringList(), before);
}

ST_UI_TEST_MAIN_ISOLATED()
