#pragma once
// The main window: the central image view (any frame, intermediate or live stack), docks for processing,
// search, velocity map, candidates and the stack inspector, a status bar with pixel readout, stack latency
// and the progress of the running job (with Cancel). All long work goes through JobRunner (search, load,
// pre-process) or StackScrubber (live stacks); see job_runner.hpp for the threading rules.
#include <QMainWindow>
#include <QMessageBox>
#include <QPointer>
#include <QStringList>
#include <memory>
#include <optional>

#include "core_services.hpp"
#include "search_backend_cache.hpp"
#include "observation.hpp"

class QComboBox;
class QSpinBox;
class QLabel;
class QProgressBar;
class QPushButton;
class QMenu;
class QDockWidget;

namespace st::ui {

class ImageView;
class JobRunner;
enum class JobKind;
class StackScrubber;
class ProcessingPanel;
class SearchPanel;
class VelocityMapWidget;
class CandidatePanel;
class InspectorPanel;
class SessionController;
struct OpenedSession;
class FigureDialog;
class CandidateInspector;
class FitPanel;
class ReportDialog;
class RecoveryDialog;

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
};

class MainWindow : public QMainWindow {
  Q_OBJECT
 public:
  /// What the central view shows.
  enum class Source { RawFrame = 0, FilteredFrame = 1, UnfilteredFrame = 2, Stack = 3, Layer = 100 };
  static constexpr int kCentralTag = 1;

  explicit MainWindow(CoreServices services, QWidget* parent = nullptr);
  ~MainWindow() override;

  /// Opens FITS cubes, frames or folders. The Calibration stage's bias/flat/dark lists are emptied, and
  /// folders named bias/, flat/ (flats/), dark/ beside the science folder are offered there with a note.
  void openInputs(const QStringList& paths);
  /// The pre-processing panel (its calibration frame lists: ProcessingPanel::files/setFiles).
  [[nodiscard]] ProcessingPanel* processingPanel() const noexcept { return m_processing; }
  void openDemo();
  /// Reopens a session file (main_window_session.cpp): reloads its inputs, pre-processes them with the saved
  /// parameters in a worker, then restores the result, the candidates' labels, notes, fits and flags and the
  /// selection without searching again. A corrupted or newer file gets a message naming the backup copy.
  void openSession(const QString& path);
  void runPreprocess();
  /// The loaded cube was written by `synthtrack-cli preprocess` (header STPREP, pipeline/prepared_cube.hpp).
  [[nodiscard]] bool rawIsPrepared() const;
  void runSearch();
  /// Esc (Run > Cancel): closes an open drop-down or menu and nothing else; otherwise cancels the running
  /// job, after asking when a search has run for kAskBeforeCancelS or more (the question is non-modal).
  void cancelFromKey();
  /// Seconds a search runs before Esc asks instead of cancelling at once.
  static constexpr double kAskBeforeCancelS = 10.0;
  /// The open "Cancel the search?" question, or null.
  [[nodiscard]] QMessageBox* cancelQuestion() const { return m_cancelQuestion; }
  /// Selects candidate `index` (0-based, in the result's order): centres the view, sets the velocity.
  void selectCandidate(int index);
  void showSource(Source source, int layer = 0);
  /// Saves the window as PNG (maximum compression), scaled down to `maxWidth` when it is > 0.
  bool saveScreenshot(const QString& path, int maxWidth = 0);
  /// Runs the command-line script; with quit, the application exits when done (code 1 on failure).
  void runScript(const ScriptOptions& options);

  [[nodiscard]] Observation* observation() const noexcept { return m_obs; }
  [[nodiscard]] JobRunner* jobs() const noexcept { return m_jobs; }
  [[nodiscard]] StackScrubber* scrubber() const noexcept { return m_scrubber; }
  [[nodiscard]] ImageView* imageView() const noexcept { return m_view; }
  [[nodiscard]] VelocityMapWidget* velocityMap() const noexcept { return m_velocityMap; }
  [[nodiscard]] CandidatePanel* candidates() const noexcept { return m_candidates; }
  [[nodiscard]] InspectorPanel* inspector() const noexcept { return m_inspector; }
  [[nodiscard]] CandidateInspector* candidateInspector() const noexcept { return m_candidateInspector; }
  [[nodiscard]] FitPanel* fitPanel() const noexcept { return m_fitPanel; }
  [[nodiscard]] SearchPanel* searchPanel() const noexcept { return m_search; }
  /// The session file and its autosave.
  [[nodiscard]] SessionController* session() const noexcept { return m_session; }
  /// The "Export figure…" dialog (made on first use; main_window_export.cpp).
  FigureDialog* figureDialog();
  /// The "Reports…" dialog (made on first use; main_window_export.cpp).
  ReportDialog* reportDialog();
  /// The "Injection recovery…" dialog (Run menu; made on first use).
  RecoveryDialog* recoveryDialog();
  /// Latency (ms) of the last live stack shown in the central view, input to pixels.
  [[nodiscard]] double lastStackLatencyMs() const noexcept { return m_lastLatencyMs; }

 signals:
  /// A central-view stack reached the screen.
  void centralStackShown(double latencyMs);
  void scriptFinished(bool ok);

 protected:
  void closeEvent(QCloseEvent* event) override;
  void dragEnterEvent(QDragEnterEvent* event) override;
  void dropEvent(QDropEvent* event) override;

 private:
  void buildMenus();
  void buildExportMenu(QMenu* menu);
  void buildDocks();
  void buildVettingDocks(QDockWidget* besideInspector, QDockWidget* candidates);
  void runScriptFit();
  QWidget* buildCentral();
  void buildStatusBar();
  void startLoad(const QString& label, std::function<FrameCube(ProgressSink&, CancelToken&)> load);
  void onJobFinished(JobKind kind, bool ok, bool cancelled, const QString& message, double elapsedS);
  void onRawChanged();
  void onPreparedChanged();
  void onSelection();
  void refreshSourceList();
  void refreshCentral();
  void requestCentralStack();
  void updateMarkers();
  void onHover(int x, int y, double value, bool inside);
  void addRecent(const QStringList& paths);
  void rebuildRecentMenu();
  /// The script's inputs, with its --bias/--flat/--dark and --no-calibration-offer applied.
  void openScriptInputs(const ScriptOptions& options);
  /// Prints the Calibration stage's offer note and bias/flat/dark lists on stdout ("calibration ...").
  void printScriptCalibration();
  void advanceScript(JobKind finishedJob, bool ok);
  void finishScript(bool ok, const QString& message);
  /// The script's exports and dialog (main_window_export.cpp); calls `done` with false when one failed.
  void runScriptExports(const ScriptOptions& script, std::function<void(bool ok)> done);
  /// The script's --accept-fit and --label (main_window_export.cpp); false with a message on stderr for a bad
  /// one.
  bool applyScriptVetting(const ScriptOptions& script);
  void showError(const QString& title, const QString& message);
  void buildSessionMenu(QMenu* file);
  void buildSession();
  void applyOpenedSession(const OpenedSession& opened);
  void addRecentSession(const QString& path);
  void rebuildRecentSessionsMenu();

  CoreServices m_services;
  /// The search backend kept between searches (used by the search job's worker thread only).
  std::shared_ptr<SearchBackendCache> m_searchBackends = std::make_shared<SearchBackendCache>();
  Observation* m_obs;
  JobRunner* m_jobs;
  StackScrubber* m_scrubber;
  ImageView* m_view = nullptr;
  QComboBox* m_sourceCombo = nullptr;
  QSpinBox* m_frameSpin = nullptr;
  QComboBox* m_stretch = nullptr;
  QComboBox* m_limits = nullptr;
  QComboBox* m_cmap = nullptr;
  ProcessingPanel* m_processing = nullptr;
  SearchPanel* m_search = nullptr;
  VelocityMapWidget* m_velocityMap = nullptr;
  CandidatePanel* m_candidates = nullptr;
  InspectorPanel* m_inspector = nullptr;
  CandidateInspector* m_candidateInspector = nullptr;
  FitPanel* m_fitPanel = nullptr;
  QLabel* m_pixelLabel = nullptr;
  QLabel* m_stackLabel = nullptr;
  QLabel* m_jobLabel = nullptr;
  QPointer<QMessageBox> m_cancelQuestion;
  double m_jobElapsedS = 0.0;  ///< of the running job, from its progress
  QProgressBar* m_progress = nullptr;
  QPushButton* m_cancel = nullptr;
  QMenu* m_recentMenu = nullptr;
  QMenu* m_recentSessionsMenu = nullptr;
  SessionController* m_session = nullptr;
  QLabel* m_sessionLabel = nullptr;
  std::vector<StageSpec> m_preparedStages;  ///< the stages the current pre-processed cube was made with
  std::optional<ScriptOptions> m_script;
  FigureDialog* m_figureDialog = nullptr;
  ReportDialog* m_reportDialog = nullptr;
  RecoveryDialog* m_recoveryDialog = nullptr;
  QWidget* m_screenshotOverlay = nullptr;  ///< a dialog drawn over the window on screenshots
  std::shared_ptr<search::SearchBackend> m_stackBackend;
  double m_lastLatencyMs = 0.0;
  bool m_autoPreprocess = true;
  bool m_centralShowsStack = false;  ///< the central view's image is a live stack (limits are kept)
  bool m_demoGrid = false;           ///< the demo gets a grid that searches in under a minute on 2 cores
};

}  // namespace st::ui
