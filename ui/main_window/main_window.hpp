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
class QAction;
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
  /// The observation is open out of core (a prepared cube over the memory budget; out_of_core_controller.hpp).
  [[nodiscard]] bool outOfCore() const;
  void runSearch();
  /// Esc (Run > Cancel): closes an open drop-down or menu and nothing else; otherwise cancels the running
  /// job, after asking when a search has run for kAskBeforeCancelS or more (the question is non-modal).
  void cancelFromKey();
  /// Seconds a search runs before Esc asks instead of cancelling at once.
  static constexpr double kAskBeforeCancelS = 10.0;
  /// The open "Cancel the search?" question, or null.
  [[nodiscard]] QMessageBox* cancelQuestion() const { return m_cancelQuestion; }
  /// Plate solving (main_window_plate_solve.cpp): starts a job that finds the WCS of frames without one with
  /// astrometry.net (PlateSolveSettings), from the pre-processing's star catalogue when there is one, else
  /// from the first frame's sources; on success the WCS is attached to the observation (wcsChanged). False
  /// (with a status message) without frames or while another job runs.
  bool runPlateSolve();
  /// The last successful solution, one line (centre, scale, index, stars, time); empty before one.
  [[nodiscard]] const QString& plateSolveSummary() const noexcept { return m_plateSolveSummary; }
  /// Adds pre-processing's movers (PreparedView::products->movers) that the search did not find to the
  /// result as candidates (candidate::moverCandidates; flag "pre-processing mover", a note with the shift
  /// and SNR), keeping every label and the session file. Returns how many were added.
  int addMoversAsCandidates();
  /// The movers addMoversAsCandidates() would add, with their notes.
  [[nodiscard]] std::vector<std::pair<search::Candidate, std::string>> pendingMovers() const;
  /// Selects candidate `index` (0-based, in the result's order): centres the view, sets the velocity.
  void selectCandidate(int index);
  void showSource(Source source, int layer = 0);
  /// Saves the window as PNG (maximum compression), scaled down to `maxWidth` when it is > 0 and reduced to
  /// `colours` colours when that is > 0, with the screenshot overlay (if shown) drawn centred on top.
  bool saveScreenshot(const QString& path, int maxWidth = 0, int colours = 0);
  /// A dialog drawn centred over the window on screenshots (the script's --dialog); null for none.
  void setScreenshotOverlay(QWidget* overlay) { m_screenshotOverlay = overlay; }
  /// A scripted run (ui/script/script_runner.hpp): errors go to the status bar and the script, never to a
  /// modal message box.
  void setScripted(bool scripted) { m_scripted = scripted; }
  [[nodiscard]] bool scripted() const noexcept { return m_scripted; }
  /// Run > "Pre-process after loading": a finished load starts the pre-processing by itself.
  [[nodiscard]] bool autoPreprocess() const noexcept { return m_autoPreprocess; }

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
  /// The window's size on a first start (no saved geometry) on a screen whose available area (without
  /// taskbars) is `available`: 1500 x 940 where it fits, else that area less a title bar and frame (a
  /// 1366 x 768 laptop with a 40 px taskbar: 1350 x 688). The minimum size stays below 1366 x 728.
  [[nodiscard]] static QSize firstSize(const QSize& available);
  /// Latency (ms) of the last live stack shown in the central view, input to pixels.
  [[nodiscard]] double lastStackLatencyMs() const noexcept { return m_lastLatencyMs; }

 signals:
  /// A central-view stack reached the screen.
  void centralStackShown(double latencyMs);

 protected:
  void closeEvent(QCloseEvent* event) override;
  void dragEnterEvent(QDragEnterEvent* event) override;
  void dropEvent(QDropEvent* event) override;

 private:
  void buildMenus();
  void buildExportMenu(QMenu* menu);
  void buildDocks();
  void buildVettingDocks(QDockWidget* besideInspector, QDockWidget* candidates);
  QWidget* buildCentral();
  void buildStatusBar();
  /// Says in the status bar that another job runs (a request refused).
  void sayBusy();
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
  void showError(const QString& title, const QString& message);
  void buildSessionMenu(QMenu* file);
  void buildSession();
  /// The banner above the image while the session is read-only (open in another window or process).
  void buildReadOnlyBanner();
  /// The banner above the image while the frames have no WCS, with "Plate solve" (main_window_plate_solve.cpp).
  void buildWcsBanner();
  void buildPlateSolveActions(QMenu* run);
  void updateWcsBanner();
  /// Asks for a file and saves the current state there (the way out of read-only); false when not saved.
  bool saveSessionCopy();
  /// Closing a read-only window with unsaved changes: asks to save a copy, discard or stay. True to close.
  bool confirmCloseReadOnly();
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
  QWidget* m_readOnlyBanner = nullptr;  ///< objectName "session.readOnlyBanner"
  QWidget* m_wcsBanner = nullptr;       ///< objectName "wcs.banner": no WCS, "Plate solve"
  QLabel* m_wcsText = nullptr;
  QPushButton* m_wcsSolve = nullptr;
  QAction* m_plateSolveAction = nullptr;
  QString m_plateSolveError;    ///< the last plate solve's failure, shown in the banner
  QString m_plateSolveSummary;  ///< the last plate solve's success
  std::vector<StageSpec> m_preparedStages;  ///< the stages the current pre-processed cube was made with
  bool m_scripted = false;
  QStringList m_loadingPaths;  ///< the inputs of the load job in flight (none for the demo)
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
