// synthtrack: the desktop application.
//   synthtrack [INPUT…] [--demo] [--session FILE] [--search] [--select N] [--fit] [--plate-solve] [--screenshot FILE.png]
//   [--quit] [--export-figure FILE] [--figure-dpi DPI] [--export-reports DIR] [--dialog figure|reports]
//   [--accept-fit] [--label N=LABEL]... [--bias PATH]... [--flat PATH]... [--dark PATH]...
//   [--no-calibration-offer]
// opens the inputs (FITS cubes, frames or folders) or the simulated demo observation, pre-processes it,
// optionally runs the search and selects candidate N, saves a screenshot of the main window and quits.
// --session reopens a session file instead: its inputs, parameters, result and vetting, without searching.
// Calibration frames: bias/, flat/ (flats/), dark/ folders beside a science folder are offered (printed as
// "calibration: ..."); --bias/--flat/--dark set them, --no-calibration-offer drops the offered ones.
#include <QApplication>
#include <QCommandLineParser>
#include <cstdio>
#include <string>

#include "core_adapter.hpp"
#include "main_window.hpp"
#include "script_runner.hpp"

namespace {

/// Takes `--session FILE` / `--session=FILE` out of argv before QApplication sees it: Qt reads "-session" as
/// the X11 session-management id and removes it. Returns FILE ("" when absent).
QString takeSessionOption(int& argc, char** argv) {
  QString file;
  int out = 1;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if ((arg == "--session" || arg == "-session") && i + 1 < argc) {
      file = QString::fromLocal8Bit(argv[++i]);
    } else if (arg.rfind("--session=", 0) == 0) {
      file = QString::fromLocal8Bit(arg.substr(10).c_str());
    } else {
      argv[out++] = argv[i];
    }
  }
  argc = out;
  argv[argc] = nullptr;
  return file;
}

}  // namespace

int main(int argc, char** argv) {
  const QString sessionFile = takeSessionOption(argc, argv);
  QApplication app(argc, argv);
  QApplication::setApplicationName("synthtrack");
  QApplication::setOrganizationName("synthtrack");
  QApplication::setApplicationVersion("0.1.0");

  QCommandLineParser parser;
  parser.setApplicationDescription("Synthetic tracking of faint fast-moving asteroids");
  parser.addHelpOption();
  parser.addVersionOption();
  parser.addPositionalArgument("inputs", "FITS cubes, frames or folders to open", "[INPUT…]");
  const QCommandLineOption demo("demo", "Open the demo observation (simulated paper-neo).");
  const QCommandLineOption session("session",
                                   "Reopen a session file (result and labels restored, no search).", "FILE");
  const QCommandLineOption search("search", "Run the search after pre-processing.");
  const QCommandLineOption select("select", "Select candidate N (1-based) after the search.", "N");
  const QCommandLineOption fit("fit", "Run the co-moving fit of the selected candidate before finishing.");
  const QCommandLineOption screenshot("screenshot", "Save a screenshot of the window when done, then quit.",
                                      "FILE");
  const QCommandLineOption width("screenshot-width", "Scale the screenshot down to this width.", "PIXELS");
  const QCommandLineOption quit("quit", "Quit when done.");
  const QCommandLineOption figure("export-figure",
                                  "Write a figure when done (.png/.svg/.pdf): the sky/object preset of the "
                                  "selected candidate, else the central view.",
                                  "FILE");
  const QCommandLineOption dpi("figure-dpi", "Resolution of --export-figure PNGs (default 150).", "DPI");
  const QCommandLineOption reports("export-reports", "Write the candidates JSON/CSV and DS9 regions to DIR, and ADES/MPC 80-column when a candidate is labelled real and a station is set.",
                                   "DIR");
  const QCommandLineOption dialog("dialog", "Open a dialog (figure or reports), shown on the screenshot.",
                                  "NAME");
  const QCommandLineOption colours("screenshot-colours", "Reduce the screenshot to N colours (small PNGs).",
                                   "N");
  const QCommandLineOption acceptFit("accept-fit", "Accept the --fit result into the selected candidate.");
  const QCommandLineOption label("label", "Label candidate N: real, unsure, unvetted or artifact[:REASON].",
                                 "N=LABEL");
  const QCommandLineOption bias("bias", "Bias frames (file or folder; repeat for several) for the Calibration "
                                "stage, as synthtrack-cli preprocess --bias.", "PATH");
  const QCommandLineOption flat("flat", "Flat frames (file or folder; repeatable).", "PATH");
  const QCommandLineOption dark("dark", "Dark frames (file or folder; repeatable).", "PATH");
  const QCommandLineOption noOffer("no-calibration-offer",
                                   "Do not use the bias/, flat/, dark/ folders found beside the science folder.");
  const QCommandLineOption plateSolve("plate-solve",
                                      "Plate-solve frames without a WCS (astrometry.net) after pre-processing.");
  const QCommandLineOption solveField("solve-field", "The solve-field program (kept in the settings).", "PROGRAM");
  const QCommandLineOption indexDir("index-dir", "A folder of astrometry.net index files (repeatable; kept).",
                                    "DIR");
  parser.addOptions({demo, session, search, select, fit, screenshot, width, quit, figure, dpi, reports,
                     dialog, acceptFit, label, colours, bias, flat, dark, noOffer, plateSolve, solveField,
                     indexDir});
  parser.process(app);

  st::ui::ScriptOptions script;
  script.inputs = parser.positionalArguments();
  script.demo = parser.isSet(demo);
  script.session = sessionFile;
  script.search = parser.isSet(search);
  if (parser.isSet(select)) {
    bool ok = false;
    script.select = parser.value(select).toInt(&ok);
    if (!ok || *script.select < 1) {
      std::fprintf(stderr, "synthtrack: --select needs a positive integer, got '%s'\n",
                   parser.value(select).toLocal8Bit().constData());
      return 2;
    }
  }
  script.fit = parser.isSet(fit);
  script.screenshot = parser.value(screenshot);
  script.screenshotWidth = parser.value(width).toInt();
  script.quit = parser.isSet(quit);
  script.exportFigure = parser.value(figure);
  if (parser.isSet(dpi)) {
    script.figureDpi = parser.value(dpi).toInt();
    if (script.figureDpi < 50 || script.figureDpi > 2400) {
      std::fprintf(stderr, "synthtrack: --figure-dpi needs 50 to 2400, got '%s'\n",
                   parser.value(dpi).toLocal8Bit().constData());
      return 2;
    }
  }
  script.exportReports = parser.value(reports);
  script.dialog = parser.value(dialog);
  script.screenshotColours = parser.value(colours).toInt();
  script.acceptFit = parser.isSet(acceptFit);
  script.labels = parser.values(label);
  script.bias = parser.values(bias);
  script.flat = parser.values(flat);
  script.dark = parser.values(dark);
  script.noCalibrationOffer = parser.isSet(noOffer);
  script.plateSolve = parser.isSet(plateSolve);
  script.solveField = parser.value(solveField);
  script.indexDirs = parser.values(indexDir);

  st::ui::MainWindow window(st::app::makeCoreServices());
  window.show();
  auto* runner = new st::ui::ScriptRunner(&window);  // owned by the window
  if (script.demo || !script.inputs.isEmpty() || !script.session.isEmpty() || script.quit ||
      !script.screenshot.isEmpty())
    runner->run(script);
  return QApplication::exec();
}
