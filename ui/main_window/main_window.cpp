#include "main_window.hpp"

#include <QAction>
#include <QApplication>
#include <QCloseEvent>
#include <QComboBox>
#include <QDockWidget>
#include <QGuiApplication>
#include <QScreen>
#include <QDragEnterEvent>
#include <QFileDialog>
#include <QFileInfo>
#include <QHBoxLayout>
#include <QImage>
#include <QLabel>
#include <QMenuBar>
#include <QMessageBox>
#include <QMimeData>
#include <QPainter>
#include <QProgressBar>
#include <QPushButton>
#include <QScrollArea>
#include <QSettings>
#include <QSpinBox>
#include <QStatusBar>
#include <QTableView>
#include <QToolBar>
#include <QVBoxLayout>

#include "candidate_inspector.hpp"
#include "candidate_table.hpp"
#include "figure_export.hpp"
#include "fit_panel.hpp"
#include "header_dialog.hpp"
#include "image_view.hpp"
#include "inspector_panel.hpp"
#include "job_runner.hpp"
#include "motion_vs_sky.hpp"
#include "out_of_core_controller.hpp"
#include "processing_panel.hpp"
#include "recovery_dialog.hpp"
#include "search_panel.hpp"
#include "session_controller.hpp"
#include "stack_scrubber.hpp"
#include "velocity_map_widget.hpp"

namespace st::ui {

MainWindow::MainWindow(CoreServices services, QWidget* parent)
    : QMainWindow(parent), m_services(std::move(services)) {
  setWindowTitle("synthtrack");
  setWindowIcon(QIcon(":/synthtrack.svg"));
  setAcceptDrops(true);
  setDockNestingEnabled(true);
  m_obs = new Observation(this);
  m_jobs = new JobRunner(this);
  m_scrubber = new StackScrubber(this);
  setCentralWidget(buildCentral());
  buildDocks();
  buildSession();  // main_window_session.cpp
  buildMenus();
  buildStatusBar();
  buildWcsBanner();  // main_window_plate_solve.cpp
  auto* ooc = new OutOfCoreController(this);  // Run > Memory limit…, cubes larger than the budget
  connect(ooc, &OutOfCoreController::stackReady, this,
          [this](const std::shared_ptr<const Image>& sum, Velocity v, double elapsedS) {
            if (!outOfCore() || static_cast<Source>(m_sourceCombo->currentData().toInt()) != Source::Stack) return;
            if (v.vx != m_obs->velocity().vx || v.vy != m_obs->velocity().vy) return;  // superseded
            m_view->setImage(sum);
            const Velocity shown = toShownVsSky(*m_obs, v);
            m_view->setOverlayText(QString("IPSA sum at v = (%1, %2) %3 vs sky (out of core: summed in strips)")
                                       .arg(shown.vx, 0, 'g', 4)
                                       .arg(shown.vy, 0, 'g', 4)
                                       .arg(unitLabel(shownUnit(*m_obs))));
            m_stackLabel->setText(QString("IPSA sum out of core: %1 s").arg(elapsedS, 0, 'f', 1));
          });

  connect(m_jobs, &JobRunner::finished, this, &MainWindow::onJobFinished);
  connect(m_obs, &Observation::rawChanged, this, &MainWindow::onRawChanged);
  connect(m_obs, &Observation::preparedChanged, this, &MainWindow::onPreparedChanged);
  connect(m_obs, &Observation::resultChanged, this, &MainWindow::updateMarkers);
  connect(m_obs, &Observation::candidatesShownChanged, this, &MainWindow::updateMarkers);
  connect(m_obs, &Observation::candidateStateChanged, this, &MainWindow::updateMarkers);
  connect(m_obs, &Observation::selectionChanged, this, &MainWindow::onSelection);
  connect(m_obs, &Observation::velocityChanged, this, &MainWindow::requestCentralStack);
  // IPSA/CSA and filtered/unfiltered stacks have different scales: new display limits for those.
  const auto restack = [this] {
    m_centralShowsStack = false;
    requestCentralStack();
  };
  connect(m_obs, &Observation::stackModeChanged, this, restack);
  connect(m_inspector, &InspectorPanel::cubeChoiceChanged, this, restack);
  connect(m_scrubber, &StackScrubber::stackReady, this,
          [this](const std::shared_ptr<const Image>& image, const StackRequest& req, double latencyMs,
                 double computeMs) {
            m_search->setMeasuredStackSeconds(computeMs / 1000.0);
            if (req.tag != kCentralTag) return;
            if (static_cast<Source>(m_sourceCombo->currentData().toInt()) != Source::Stack) return;
            // Keep the display limits while scrubbing (no brightness jumps), but not across a change of
            // what is shown: a raw frame's limits mean nothing for a filtered stack.
            m_view->setImage(image, m_centralShowsStack);
            m_centralShowsStack = true;
            m_lastLatencyMs = latencyMs;
            m_stackLabel->setText(QString("%1 stack: %2 ms (compute %3 ms)")
                                      .arg(req.mode == search::StackMode::Ipsa ? "IPSA" : "CSA")
                                      .arg(latencyMs, 0, 'f', 0)
                                      .arg(computeMs, 0, 'f', 0));
            emit centralStackShown(latencyMs);
          });
  connect(m_scrubber, &StackScrubber::stackFailed, this,
          [this](const QString& message) { statusBar()->showMessage("Stack failed: " + message, 5000); });

  QSettings settings;
  const QScreen* screen = QGuiApplication::primaryScreen();
  resize(firstSize(screen ? screen->availableGeometry().size() : QSize()));
  restoreGeometry(settings.value("window/geometry").toByteArray());
  restoreState(settings.value("window/state").toByteArray());
  rebuildRecentMenu();
  rebuildRecentSessionsMenu();
}

MainWindow::~MainWindow() = default;

QSize MainWindow::firstSize(const QSize& available) {
  // The layout is made for 1500 x 940 (docks at 330 | central | 430, candidates 260 px high); on a smaller
  // screen the window takes what the screen offers less a title bar and frame, the docks scroll (buildDocks).
  constexpr QSize kPreferred(1500, 940);
  constexpr QSize kFrame(16, 40);
  if (!available.isValid() || available.isEmpty()) return kPreferred;
  return kPreferred.boundedTo(available - kFrame);
}

QWidget* MainWindow::buildCentral() {
  auto* central = new QWidget(this);
  auto* bar = new QHBoxLayout;
  bar->setContentsMargins(4, 2, 4, 2);
  m_sourceCombo = new QComboBox(central);
  m_sourceCombo->setMinimumContentsLength(22);
  m_sourceCombo->setToolTip("What the view shows: a raw frame, a pre-processing product, or the live stack");
  m_frameSpin = new QSpinBox(central);
  m_frameSpin->setPrefix("frame ");
  m_frameSpin->setKeyboardTracking(true);
  m_stretch = new QComboBox(central);
  for (Stretch s : {Stretch::Linear, Stretch::Log, Stretch::Asinh})
    m_stretch->addItem(toString(s), static_cast<int>(s));
  m_limits = new QComboBox(central);
  m_limits->addItem("zscale", static_cast<int>(LimitsMode::ZScale));
  m_limits->addItem("99.5 %", 995);
  m_limits->addItem("99 %", 990);
  m_limits->addItem("95 %", 950);
  m_limits->addItem("min/max", static_cast<int>(LimitsMode::MinMax));
  m_cmap = new QComboBox(central);
  for (Colormap c : {Colormap::Gray, Colormap::Viridis, Colormap::Inferno})
    m_cmap->addItem(toString(c), static_cast<int>(c));
  auto* fit = new QPushButton("Fit", central);
  auto* one = new QPushButton("1:1", central);
  fit->setToolTip("Fit the image to the view (key 0)");
  one->setToolTip("One image pixel per screen pixel (key 1)");
  bar->addWidget(new QLabel("Show", central));
  bar->addWidget(m_sourceCombo);
  bar->addWidget(m_frameSpin);
  bar->addSpacing(10);
  bar->addWidget(m_stretch);
  bar->addWidget(m_limits);
  bar->addWidget(m_cmap);
  bar->addWidget(fit);
  bar->addWidget(one);
  bar->addStretch(1);
  m_view = new ImageView(central);
  auto* layout = new QVBoxLayout(central);
  layout->setContentsMargins(0, 0, 0, 0);
  layout->setSpacing(0);
  layout->addLayout(bar);
  layout->addWidget(m_view, 1);

  auto applyDisplay = [this] {
    DisplaySettings d;
    d.stretch = static_cast<Stretch>(m_stretch->currentData().toInt());
    const int lim = m_limits->currentData().toInt();
    if (lim >= 100) {
      d.limits = LimitsMode::Percentile;
      d.percentile = lim / 10.0;
    } else {
      d.limits = static_cast<LimitsMode>(lim);
    }
    d.colormap = static_cast<Colormap>(m_cmap->currentData().toInt());
    m_view->setDisplaySettings(d);
  };
  for (auto* c : {m_stretch, m_limits, m_cmap})
    connect(c, &QComboBox::currentIndexChanged, this, applyDisplay);
  connect(fit, &QPushButton::clicked, m_view, &ImageView::zoomToFit);
  connect(one, &QPushButton::clicked, m_view, &ImageView::zoomOneToOne);
  connect(m_sourceCombo, &QComboBox::currentIndexChanged, this, &MainWindow::refreshCentral);
  connect(m_frameSpin, &QSpinBox::valueChanged, this, &MainWindow::refreshCentral);
  connect(m_view, &ImageView::hovered, this, &MainWindow::onHover);
  connect(m_view, &ImageView::clicked, this, [this](double x, double y) {
    m_inspector->setPoint(x, y);
    if (m_view->image()) m_inspector->showProfile(m_view->image(), x, y);
  });
  refreshSourceList();
  return central;
}

void MainWindow::buildDocks() {
  // Panels with many controls scroll inside their dock, so the window fits a 1366 x 768 laptop screen (issue
  // 18 §6: the docks' minimum sizes made the window 1556 x 1013, the status bar with the warnings cut off).
  auto dock = [this](const QString& title, const QString& name, QWidget* w, Qt::DockWidgetArea area,
                     bool scroll = false) {
    auto* d = new QDockWidget(title, this);
    d->setObjectName(name);
    if (scroll) {
      auto* scrollArea = new QScrollArea(d);
      scrollArea->setWidgetResizable(true);
      scrollArea->setFrameShape(QFrame::NoFrame);
      scrollArea->setWidget(w);
      d->setWidget(scrollArea);
    } else {
      d->setWidget(w);
    }
    addDockWidget(area, d);
    return d;
  };
  m_processing = new ProcessingPanel(m_services.preprocessStages, this);
  m_search = new SearchPanel(m_obs, m_services.gpuNames, this);
  m_velocityMap = new VelocityMapWidget(m_obs, this);
  m_candidates = new CandidatePanel(m_obs, this);
  m_inspector = new InspectorPanel(m_obs, m_scrubber, &m_services, this);
  auto* proc = dock("Processing", "dock.processing", m_processing, Qt::LeftDockWidgetArea, true);
  auto* search = dock("Search", "dock.search", m_search, Qt::LeftDockWidgetArea, true);
  tabifyDockWidget(proc, search);
  proc->raise();
  auto* vmap = dock("Velocity space", "dock.velocity", m_velocityMap, Qt::RightDockWidgetArea);
  auto* insp = dock("Inspector", "dock.inspector", m_inspector, Qt::RightDockWidgetArea, true);
  splitDockWidget(vmap, insp, Qt::Vertical);
  auto* cands = dock("Candidates", "dock.candidates", m_candidates, Qt::BottomDockWidgetArea);
  buildVettingDocks(insp, cands);
  resizeDocks({proc}, {330}, Qt::Horizontal);
  resizeDocks({vmap}, {430}, Qt::Horizontal);

  connect(m_processing, &ProcessingPanel::runRequested, this, &MainWindow::runPreprocess);
  connect(m_search, &SearchPanel::runRequested, this, &MainWindow::runSearch);
  connect(m_search, &SearchPanel::cancelRequested, m_jobs, &JobRunner::cancel);
}

RecoveryDialog* MainWindow::recoveryDialog() {
  if (!m_recoveryDialog) m_recoveryDialog = new RecoveryDialog(m_obs, this);
  return m_recoveryDialog;
}

void MainWindow::buildMenus() {
  QMenu* file = menuBar()->addMenu("&File");
  file->addAction(QIcon::fromTheme("document-open"), "&Open FITS…", QKeySequence::Open, this, [this] {
    const QStringList files = QFileDialog::getOpenFileNames(
        this, "Open FITS cube or frames", QSettings().value("lastDir").toString(),
        "FITS (*.fits *.fit *.fts *.fits.gz *.fits.fz *.fz);;All files (*)");
    if (!files.isEmpty()) openInputs(files);
  });
  file->addAction("Open &folder…", QKeySequence("Ctrl+Shift+O"), this, [this] {
    const QString dir = QFileDialog::getExistingDirectory(this, "Open a folder of frames",
                                                          QSettings().value("lastDir").toString());
    if (!dir.isEmpty()) openInputs({dir});
  });
  file->addAction("Open &demo observation", QKeySequence("Ctrl+D"), this, &MainWindow::openDemo);
  m_recentMenu = file->addMenu("Open &recent");
  buildSessionMenu(file);
  file->addSeparator();
  file->addAction("&Header…", QKeySequence("Ctrl+H"), this, [this] {
    if (!m_obs->raw()) return;
    (new HeaderDialog(m_obs->raw()->header, m_obs->label(), this))->show();
  });
  file->addAction("Save &screenshot…", this, [this] {
    const QString path =
        QFileDialog::getSaveFileName(this, "Save screenshot", "synthtrack.png", "PNG (*.png)");
    if (!path.isEmpty()) saveScreenshot(path);
  });
  file->addSeparator();
  file->addAction("&Quit", QKeySequence::Quit, this, &QWidget::close);

  QMenu* run = menuBar()->addMenu("&Run");
  run->addAction("&Pre-process", QKeySequence("Ctrl+P"), this, &MainWindow::runPreprocess);
  run->addAction("&Search", QKeySequence("Ctrl+R"), this, &MainWindow::runSearch);
  run->addAction("&Cancel", QKeySequence("Esc"), this, &MainWindow::cancelFromKey);
  run->addActions(m_candidates->table()->actions());  // "Fit selected candidate" (F), built with the docks
  buildPlateSolveActions(run);
  auto* autoPre = run->addAction("Pre-process after loading");
  autoPre->setCheckable(true);
  autoPre->setChecked(m_autoPreprocess);
  connect(autoPre, &QAction::toggled, this, [this](bool on) { m_autoPreprocess = on; });
  run->addSeparator();
  run->addAction("&Injection recovery…", this, [this] {
    RecoveryDialog* d = recoveryDialog();
    d->show();
    d->raise();
  });

  QMenu* view = menuBar()->addMenu("&View");
  for (QDockWidget* d : findChildren<QDockWidget*>())
    view->addAction(d->toggleViewAction());
  view->addSeparator();
  view->addAction("Show live &stack", QKeySequence("Ctrl+1"), this, [this] { showSource(Source::Stack); });
  view->addAction("Show &raw frame", QKeySequence("Ctrl+2"), this, [this] { showSource(Source::RawFrame); });
  view->addAction("Toggle IPSA/&CSA", QKeySequence("C"), this, [this] {
    m_obs->setStackMode(m_obs->stackMode() == search::StackMode::Ipsa ? search::StackMode::Csa
                                                                      : search::StackMode::Ipsa);
  });
  view->addAction("Reset &layout", this, [this] {
    QSettings().remove("window/state");
    QMessageBox::information(this, "Layout", "The default layout is used at the next start.");
  });

  buildExportMenu(menuBar()->addMenu("&Export"));

  QMenu* help = menuBar()->addMenu("&Help");
  help->addAction("&About synthtrack", this, [this] {
    QMessageBox::about(this, "synthtrack",
                       "<b>synthtrack</b> — synthetic tracking of faint fast-moving asteroids "
                       "(shift-and-add along trial velocities; Zhai et al. 2014).");
  });
}

void MainWindow::buildStatusBar() {
  m_pixelLabel = new QLabel(this);
  m_pixelLabel->setMinimumWidth(420);
  m_stackLabel = new QLabel(this);
  m_jobLabel = new QLabel(this);
  m_progress = new QProgressBar(this);
  m_progress->setRange(0, 1000);
  m_progress->setMaximumWidth(220);
  m_progress->setTextVisible(false);
  m_progress->hide();
  m_cancel = new QPushButton("Cancel", this);
  m_cancel->hide();
  statusBar()->addWidget(m_pixelLabel);
  statusBar()->addWidget(m_stackLabel);
  statusBar()->addPermanentWidget(m_sessionLabel);
  statusBar()->addPermanentWidget(m_jobLabel);
  statusBar()->addPermanentWidget(m_progress);
  statusBar()->addPermanentWidget(m_cancel);
  connect(m_cancel, &QPushButton::clicked, m_jobs, &JobRunner::cancel);
  connect(m_jobs, &JobRunner::started, this, [this](JobKind kind) {
    m_jobElapsedS = 0.0;
    m_jobLabel->setText(jobName(kind) + "…");
    m_progress->setValue(0);
    m_progress->show();
    m_cancel->show();
    m_processing->setRunEnabled(false);
    m_search->setRunning(true);
  });
  connect(m_jobs, &JobRunner::progress, this, [this](double f, const QString& stage, double elapsed) {
    m_jobElapsedS = elapsed;
    m_progress->setValue(static_cast<int>(f * 1000));
    m_jobLabel->setText(QString("%1: %2 · %3 s").arg(m_jobs->currentName(), stage).arg(elapsed, 0, 'f', 1));
    if (m_jobs->currentKind() == JobKind::Search) m_search->setProgress(f, stage, elapsed);
  });
}

void MainWindow::cancelFromKey() {
  // Esc meant for a drop-down or menu (Qt delivers the shortcut before the popup sees the key): close it only.
  if (QWidget* popup = QApplication::activePopupWidget()) {
    popup->close();
    return;
  }
  if (!m_jobs->busy() || m_cancelQuestion) return;
  if (m_jobs->currentKind() != JobKind::Search || m_jobElapsedS < kAskBeforeCancelS) {
    m_jobs->cancel();
    return;
  }
  auto* box = new QMessageBox(QMessageBox::Question, "Cancel the search?",
                              QString("The search has run for %1 s. Cancel it? The previous result stays.")
                                  .arg(m_jobElapsedS, 0, 'f', 0),
                              QMessageBox::Yes | QMessageBox::No, this);
  box->setDefaultButton(QMessageBox::No);
  box->setAttribute(Qt::WA_DeleteOnClose);
  connect(box, &QMessageBox::finished, this, [this](int answer) {
    if (answer == QMessageBox::Yes && m_jobs->busy() && m_jobs->currentKind() == JobKind::Search)
      m_jobs->cancel();
  });
  m_cancelQuestion = box;
  box->open();
}

void MainWindow::closeEvent(QCloseEvent* event) {
  if (!confirmCloseReadOnly()) {  // changes made in a read-only window are never dropped silently
    event->ignore();
    return;
  }
  m_jobs->cancel();
  m_session->autosaver()->flush(5000);  // the last change reaches the disk before the window goes
  QSettings settings;
  settings.setValue("window/geometry", saveGeometry());
  settings.setValue("window/state", saveState());
  event->accept();
}

void MainWindow::dragEnterEvent(QDragEnterEvent* event) {
  if (event->mimeData()->hasUrls()) event->acceptProposedAction();
}

void MainWindow::dropEvent(QDropEvent* event) {
  QStringList paths;
  for (const QUrl& url : event->mimeData()->urls())
    if (url.isLocalFile()) paths << url.toLocalFile();
  if (!paths.isEmpty()) openInputs(paths);
}

void MainWindow::addRecent(const QStringList& paths) {
  QSettings settings;
  QStringList recent = settings.value("recentFiles").toStringList();
  const QString entry = paths.join('\n');
  recent.removeAll(entry);
  recent.prepend(entry);
  while (recent.size() > 10)
    recent.removeLast();
  settings.setValue("recentFiles", recent);
  settings.setValue("lastDir", QFileInfo(paths.front()).absolutePath());
  rebuildRecentMenu();
}

void MainWindow::rebuildRecentMenu() {
  if (!m_recentMenu) return;
  m_recentMenu->clear();
  const QStringList recent = QSettings().value("recentFiles").toStringList();
  for (const QString& entry : recent) {
    const QStringList paths = entry.split('\n');
    QString text = QFileInfo(paths.front()).fileName();
    if (paths.size() > 1) text += QString(" (+%1)").arg(paths.size() - 1);
    m_recentMenu->addAction(text, this, [this, paths] { openInputs(paths); })->setToolTip(paths.join(", "));
  }
  m_recentMenu->setEnabled(!recent.isEmpty());
}

void MainWindow::showError(const QString& title, const QString& message) {
  statusBar()->showMessage(title + ": " + message, 10000);
  if (m_scripted) return;  // scripted runs report on stderr, never block on a dialog
  QMessageBox::warning(this, title, message);
}

bool MainWindow::saveScreenshot(const QString& path, int maxWidth, int colours) {
  QImage image = grab().toImage();
  if (m_screenshotOverlay && m_screenshotOverlay->isVisible()) {  // a dialog of the script, centred on top
    const QImage top = m_screenshotOverlay->grab().toImage();
    QPainter painter(&image);
    const QPoint at((image.width() - top.width()) / 2, (image.height() - top.height()) / 2);
    painter.drawImage(at, top);
    painter.setPen(QPen(QColor(60, 60, 60), 2));
    painter.drawRect(QRect(at, top.size()).adjusted(-1, -1, 0, 0));
  }
  if (maxWidth > 0 && image.width() > maxWidth)
    image = image.scaledToWidth(maxWidth, Qt::SmoothTransformation);
  if (colours > 0) image = reduceToPalette(image, colours);
  const bool ok = image.save(path, nullptr, 0);
  if (!ok) showError("Screenshot", "could not write " + path);
  return ok;
}

}  // namespace st::ui
