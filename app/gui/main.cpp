// synthtrack: the desktop application.
//   synthtrack [INPUT…] [--demo] [--search] [--select N] [--screenshot FILE.png] [--quit]
//              [--export-figure FILE] [--figure-dpi DPI] [--export-reports DIR] [--dialog figure|reports]
// opens the inputs (FITS cubes, frames or folders) or the simulated demo observation, pre-processes it,
// optionally runs the search and selects candidate N, saves a screenshot of the main window and quits.
#include <QApplication>
#include <QCommandLineParser>
#include <cstdio>

#include "core_adapter.hpp"
#include "main_window.hpp"

int main(int argc, char** argv) {
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
  const QCommandLineOption search("search", "Run the search after pre-processing.");
  const QCommandLineOption select("select", "Select candidate N (1-based) after the search.", "N");
  const QCommandLineOption screenshot("screenshot", "Save a screenshot of the window when done, then quit.",
                                      "FILE");
  const QCommandLineOption width("screenshot-width", "Scale the screenshot down to this width.", "PIXELS");
  const QCommandLineOption quit("quit", "Quit when done.");
  const QCommandLineOption figure("export-figure",
                                  "Write a figure when done (.png/.svg/.pdf): the sky/object preset of the "
                                  "selected candidate, else the central view.",
                                  "FILE");
  const QCommandLineOption dpi("figure-dpi", "Resolution of --export-figure PNGs (default 150).", "DPI");
  const QCommandLineOption reports("export-reports", "Write the candidates JSON/CSV and DS9 regions to DIR.",
                                   "DIR");
  const QCommandLineOption dialog("dialog", "Open a dialog (figure or reports), shown on the screenshot.",
                                  "NAME");
  parser.addOptions({demo, search, select, screenshot, width, quit, figure, dpi, reports, dialog});
  parser.process(app);

  st::ui::ScriptOptions script;
  script.inputs = parser.positionalArguments();
  script.demo = parser.isSet(demo);
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

  st::ui::MainWindow window(st::app::makeCoreServices());
  window.show();
  if (script.demo || !script.inputs.isEmpty() || script.quit || !script.screenshot.isEmpty())
    window.runScript(script);
  return QApplication::exec();
}
