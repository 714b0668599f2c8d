#pragma once
// The GUI's script mode (`synthtrack [INPUT…] --search --select N --fit --screenshot FILE --quit …`, issue 18
// item 4): a second front end on the main window, kept out of it. ScriptRunner drives a MainWindow through
// its public API only (open, pre-process, search, select, fit, label, the figure and report dialogs, the
// screenshot) and follows its jobs through JobRunner::finished; it prints what a scripted run reports on
// stdout/stderr. Like the window it never computes or waits on the GUI thread: each step starts on the
// previous job's signal.
#include <QObject>
#include <QStringList>
#include <functional>
#include <optional>

namespace st::ui {

class MainWindow;
enum class JobKind;

/// What `synthtrack [INPUT…] [--demo] [--session FILE] [--search] [--select N] [--fit] [--screenshot FILE]
/// [--quit]` asks for.
struct ScriptOptions {
  QStringList inputs;
  QString session;  ///< a session file to reopen (its result is restored, never searched again)
  bool demo = false;
  bool search = false;
  std::optional<int> select;  ///< 1-based candidate number
  bool fit = false;           ///< run the co-moving fit of the selected candidate before the screenshot
  QString screenshot;
  int screenshotWidth = 0;    ///< scale the screenshot down to this width (0: as on screen)
  int screenshotColours = 0;  ///< reduce the screenshot to this many colours (0: keep all; docs use 256)
  bool quit = false;
  /// Figure written when done: the paper's sky/object preset for the selected candidate, else the central
  /// view (format from the suffix; 7 in wide at figureDpi).
  QString exportFigure;
  int figureDpi = 150;
  QString exportReports;   ///< folder for the candidates JSON/CSV and DS9 regions, written when done
  QString dialog;          ///< "figure" or "reports": that dialog is opened, and shown on the screenshot
  bool acceptFit = false;  ///< accept the --fit result into the candidate (before the labels and exports)
  QStringList labels;  ///< "N=LABEL" (real, unsure, unvetted, artifact[:REASON]), applied before the exports
  /// Calibration frames (files or folders) for the Calibration stage, as `synthtrack-cli preprocess --bias
  /// /--flat/--dark`; a role given here replaces what was offered from beside the science folder.
  QStringList bias, flat, dark;
  bool noCalibrationOffer = false;  ///< clear the offered bias/, flat/, dark/ folders (given ones stay)
  /// --plate-solve: after pre-processing, frames without a WCS are plate-solved (MainWindow::runPlateSolve)
  /// before the search; a failure ends the script with solve-field's message.
  bool plateSolve = false;
  QString solveField;     ///< --solve-field PROGRAM: kept in the plate-solve settings
  QStringList indexDirs;  ///< --index-dir DIR (repeatable): kept in the plate-solve settings
};

class ScriptRunner : public QObject {
  Q_OBJECT
 public:
  /// A runner for `window` (its parent; the window outlives it).
  explicit ScriptRunner(MainWindow* window);

  /// Runs the script; with quit (or a screenshot) the application exits when done (code 1 on failure).
  /// The window is scripted (MainWindow::setScripted: no modal message boxes) until it finishes.
  void run(const ScriptOptions& options);
  [[nodiscard]] bool running() const noexcept { return m_script.has_value(); }

 signals:
  /// The script is done: every step, export and the screenshot succeeded (ok) or one failed.
  void finished(bool ok);

 private:
  void onJobFinished(JobKind kind, bool ok, bool cancelled, const QString& message);
  /// The script's inputs, with its --bias/--flat/--dark and --no-calibration-offer applied.
  void openInputs(const ScriptOptions& options);
  /// Prints the Calibration stage's offer note and bias/flat/dark lists on stdout ("calibration ...").
  void printCalibration();
  void advance(JobKind finished);
  /// After pre-processing (and plate solving): the search, or the end.
  void searchOrFinish();
  void runFit();
  void finish(bool ok, const QString& message);
  /// --accept-fit and --label; false with a message on stderr for a bad one.
  bool applyVetting(const ScriptOptions& script);
  /// The exports and the dialog; calls `done` with false when one failed.
  void runExports(const ScriptOptions& script, std::function<void(bool ok)> done);

  MainWindow* m_window;
  std::optional<ScriptOptions> m_script;
};

}  // namespace st::ui
