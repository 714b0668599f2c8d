// The GUI's report export and `synthtrack-cli report` call the same core function (report::writeReports):
// for the same session they write byte-identical candidates JSON and CSV, DS9 regions, ADES PSV and MPC
// 80-column files. The session is main's format-1 file of tests/data (a real candidate with a fit and sky
// position, an artifact, a note with a quote and a comma, the submission settings).
#include <gtest/gtest.h>

#include <QCoreApplication>
#include <filesystem>

#include "../app/cli_runner.hpp"
#include "report_dialog.hpp"
#include "st/report/submission_settings.hpp"
#include "st/session/session.hpp"
#include "test_support.hpp"
#include "ui_test_support.hpp"

namespace st::ui {
namespace {

namespace fs = std::filesystem;

TEST(ReportParity, GuiExportAndCliReportWriteTheSameBytes) {
  const fs::path cli = test::cliPath();
  if (cli.empty()) GTEST_SKIP() << "synthtrack-cli not built";
  test::TempDir tmp;
  const fs::path sessionFile = tmp / "s.synthtrack-session.json";
  fs::copy_file(fs::path(ST_SOURCE_DIR) / "tests" / "data" / "session_v1_main_20261125.json", sessionFile);
  // The frames named in the file are not here (as on CI): both front ends place the regions without them.
  session::Session s = session::SessionStore(sessionFile.string()).load();
  s.inputs = {(tmp / "absent.fits").string()};
  session::SessionStore(sessionFile.string()).save(s);

  // The GUI: the Reports dialog on this session.
  ReportDialog::Context ctx;
  ctx.makeSession = [s](const nlohmann::json&) { return s; };
  ReportDialog dialog(ctx);
  dialog.setSubmissionSettings(report::submissionFromJson(s.settings));
  dialog.setOutput(QString::fromStdString((tmp / "gui").string()), "run");
  dialog.setOutputs(true, true, true, false, true, true);
  bool done = false, ok = false;
  QObject::connect(&dialog, &ReportDialog::exportFinished, [&](bool good, const QString&) {
    done = true;
    ok = good;
  });
  ASSERT_TRUE(dialog.exportReports()) << dialog.resultText().toStdString();
  ASSERT_TRUE(test::waitFor([&] { return done; }, 20000));
  ASSERT_TRUE(ok) << dialog.resultText().toStdString();

  // The CLI: the same session file, the same settings (kept in it).
  const fs::path out = tmp / "cli";
  fs::create_directories(out);
  const std::string args = "report " + test::quoted(tmp / "gui" / "run_candidates.json") + " --session " +
                           test::quoted(sessionFile) + " --candidates-json " +
                           test::quoted(out / "run_candidates.json") + " --csv " +
                           test::quoted(out / "run_candidates.csv") + " --ds9 " + test::quoted(out / "run.reg") +
                           " --ades " + test::quoted(out / "run.psv") + " --mpc " +
                           test::quoted(out / "run_mpc.txt") + " > " + test::quoted(tmp / "cli.log") + " 2>&1";
  ASSERT_EQ(test::runCli(cli, args), 0) << test::readText(tmp / "cli.log");

  for (const char* name : {"run_candidates.json", "run_candidates.csv", "run.reg", "run.psv", "run_mpc.txt"}) {
    const std::string gui = test::readText(tmp / "gui" / name);
    EXPECT_FALSE(gui.empty()) << name;
    EXPECT_EQ(gui, test::readText(out / name)) << name;
  }
  // The ADES file holds the real candidate only, with the catalogue and the telescope aperture.
  const std::string psv = test::readText(out / "run.psv");
  EXPECT_NE(psv.find("st00001"), std::string::npos);
  EXPECT_EQ(psv.find("st00002"), std::string::npos);
  EXPECT_NE(psv.find("Gaia2"), std::string::npos);
  EXPECT_NE(psv.find("! aperture 0.500"), std::string::npos);
}

}  // namespace
}  // namespace st::ui

ST_UI_TEST_MAIN_ISOLATED()
