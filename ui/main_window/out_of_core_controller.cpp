#include "out_of_core_controller.hpp"

#include <QDir>
#include <QElapsedTimer>
#include <QFrame>
#include <QHBoxLayout>
#include <QInputDialog>
#include <QLabel>
#include <QMenu>
#include <QMenuBar>
#include <QMessageBox>
#include <QPushButton>
#include <QSettings>
#include <QStatusBar>
#include <QVBoxLayout>
#include <QtConcurrent>
#include <atomic>
#include <filesystem>

#include "job_runner.hpp"
#include "main_window.hpp"
#include "observation.hpp"
#include "search_panel.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/io/fits_reader.hpp"
#include "st/pipeline/memory_plan.hpp"
#include "st/pipeline/out_of_core_cube.hpp"
#include "st/pipeline/raw_out_of_core.hpp"
#include "st/search/default_grid.hpp"

namespace st::ui {
namespace {

/// The display cube of an out-of-core observation: one frame, the mean of all frames (summed in strips),
/// with the cube's header, WCS and reference epoch.
FrameCube meanFrame(const pipeline::OutOfCoreCube& ooc, std::size_t budget, ProgressSink& progress,
                    CancelToken& cancel) {
  const Image sum = pipeline::stackOutOfCore(ooc, {}, budget, progress, cancel);
  FrameCube out(ooc.shape.width, ooc.shape.height, 1);
  const float n = static_cast<float>(std::max<std::size_t>(ooc.shape.frames, 1));
  for (std::size_t k = 0; k < sum.size(); ++k)
    out.frame(0)[k] = sum.data()[k] / n;
  out.header = ooc.meta.frames.header;
  out.wcs = ooc.meta.frames.wcs;
  out.plateScaleArcsecPerPx = ooc.meta.frames.plateScaleArcsecPerPx;
  out.info()[0].mjdMid = ooc.meta.frames.tRefMjd();
  return out;
}

QString bytesText(double bytes) { return QString::fromStdString(formatBytes(bytes)); }

}  // namespace

OutOfCoreController::OutOfCoreController(MainWindow* window) : QObject(window), m_window(window) {
  setObjectName("outOfCoreController");
  m_label = new QLabel(window);
  m_label->setObjectName("memory.label");
  window->statusBar()->addPermanentWidget(m_label);
  for (QMenu* menu : window->menuBar()->findChildren<QMenu*>())
    if (menu->title() == "&Run")
      menu->addAction("&Memory limit…", this, &OutOfCoreController::askMemoryLimit);
  m_banner = new QFrame(window->centralWidget());
  m_banner->setObjectName("memory.outOfCoreBanner");
  m_banner->setStyleSheet("#memory\\.outOfCoreBanner { background: #f1e6ff; border-bottom: 1px solid #8a63c7; } "
                          "QLabel { color: #3b1f66; }");
  m_bannerText = new QLabel(m_banner);
  m_bannerText->setObjectName("memory.outOfCoreText");
  m_bannerText->setWordWrap(true);
  m_bannerText->setTextInteractionFlags(Qt::TextSelectableByMouse);
  auto* limit = new QPushButton("Memory limit…", m_banner);
  limit->setObjectName("memory.limitButton");
  connect(limit, &QPushButton::clicked, this, &OutOfCoreController::askMemoryLimit);
  auto* row = new QHBoxLayout(m_banner);
  row->setContentsMargins(8, 4, 8, 4);
  row->addWidget(m_bannerText, 1);
  row->addWidget(limit);
  if (auto* layout = qobject_cast<QVBoxLayout*>(window->centralWidget()->layout())) layout->insertWidget(0, m_banner);
  m_banner->hide();
  connect(&m_stackWatcher, &QFutureWatcher<StackOutcome>::finished, this, [this] {
    const StackOutcome out = m_stackWatcher.result();
    if (!m_cube) return;
    if (!out.sum) {
      if (!out.error.isEmpty()) m_window->statusBar()->showMessage("Out-of-core stack failed: " + out.error, 15000);
      return;
    }
    emit stackReady(out.sum, out.v, out.elapsedS);
  });
  // Another observation (loaded, a session, the demo) ends out-of-core mode.
  connect(window->observation(), &Observation::preparedChanged, this, [this] {
    const auto& p = m_window->observation()->prepared();
    if (m_cube && (!p || p->outOfCore.empty())) clear();
  });
  update();
}

/// openRaw's filtered cube: removed when dropped unless the controller took it (applied).
struct OutOfCoreController::ScratchFile {
  std::string path;
  bool taken = false;
  ~ScratchFile() {
    if (taken || path.empty()) return;
    std::error_code ec;
    std::filesystem::remove(path, ec);
  }
};

OutOfCoreController::~OutOfCoreController() {
  cancelStack();
  removeScratch();
}

void OutOfCoreController::removeScratch() {
  if (m_scratch.empty()) return;
  std::error_code ec;
  std::filesystem::remove(m_scratch, ec);
  m_scratch.clear();
}

QString OutOfCoreController::scratchDir() {
  const QString set = QSettings().value("memory/scratch").toString().trimmed();
  return set.isEmpty() ? QDir::tempPath() : set;
}

void OutOfCoreController::askMemoryLimit() {
  bool ok = false;
  const QString text = QInputDialog::getText(
      m_window, "Memory limit",
      "Memory the GUI may hold (8G, 500M; empty: 70% of the memory available).\nA pre-processed cube larger "
      "than this opens out of core; raw frames whose pre-processing needs more are pre-processed out of core "
      "in strips of rows.\nApplies to the next cube opened "
      "and the next search.",
      QLineEdit::Normal, QSettings().value("memory/limit").toString(), &ok);
  if (!ok) return;
  try {
    setMemoryLimit(text);
  } catch (const std::exception& e) {
    QMessageBox::warning(m_window, "Memory limit", QString::fromStdString(e.what()));
  }
}

OutOfCoreController* OutOfCoreController::of(const MainWindow* window) {
  return window->findChild<OutOfCoreController*>("outOfCoreController", Qt::FindDirectChildrenOnly);
}

MemoryBudget OutOfCoreController::budget() const {
  const QString limit = QSettings().value("memory/limit").toString().trimmed();
  MemoryBudget b =
      resolveMemoryBudget(limit.isEmpty() ? std::nullopt : std::optional<std::string>(limit.toStdString()));
  if (!limit.isEmpty()) b.source = "Run > Memory limit " + limit.toStdString();
  return b;
}

void OutOfCoreController::setMemoryLimit(const QString& limit) {
  if (!limit.trimmed().isEmpty()) (void)parseMemorySize(limit.trimmed().toStdString(), "memory limit");
  QSettings().setValue("memory/limit", limit.trimmed());
  update();
}

void OutOfCoreController::clear() {
  cancelStack();
  m_cube.reset();
  removeScratch();
  m_needBytes = 0.0;
  update();
}

void OutOfCoreController::update() {
  const MemoryBudget b = budget();
  m_label->setText(QString("memory budget %1%2").arg(bytesText(static_cast<double>(b.bytes))).arg(m_cube ? " · OUT OF CORE" : ""));
  m_label->setToolTip(QString::fromStdString(b.source) + " (Run > Memory limit…)");
  m_banner->setVisible(m_cube != nullptr);
  if (!m_cube) return;
  const auto& s = m_cube->shape;
  m_bannerText->setText(
      QString("<b>Out of core:</b> %1 frames of %2 × %3 px need %4 in memory, over the memory budget of %5. "
              "The cube stays on disk and is read in strips: the view shows the mean of all frames, Search runs "
              "in tiles on the CPU (as synthtrack-cli search --preprocessed), a candidate's stack is summed in "
              "strips. The inspector, co-moving fits and live stacks need the cube in memory: unavailable.")
          .arg(s.frames)
          .arg(s.width)
          .arg(s.height)
          .arg(bytesText(m_needBytes))
          .arg(bytesText(static_cast<double>(b.bytes))));
}

std::function<void()> OutOfCoreController::open(const std::vector<std::string>& inputs, std::size_t budgetBytes,
                                                const QString& label, const pipeline::OpenPlan& plan,
                                                ProgressSink& progress, CancelToken& cancel) {
  return openCube(inputs, budgetBytes, label, plan.reason, plan.need.total(), {}, nullptr, progress, cancel);
}

std::function<void()> OutOfCoreController::openRaw(const std::vector<std::string>& inputs, std::size_t budgetBytes,
                                                   const QString& label,
                                                   const std::map<std::string, QStringList>& calibration,
                                                   ProgressSink& progress, CancelToken& cancel) {
  const auto files = [&](const char* key) {
    std::vector<std::string> out;
    if (const auto it = calibration.find(key); it != calibration.end())
      for (const QString& f : it->second)
        out.push_back(f.toStdString());
    return out;
  };
  pipeline::RawObservationFiles raw;
  raw.inputs = inputs;
  raw.bias = files("bias");
  raw.dark = files("dark");
  raw.flat = files("flat");
  const io::InputSummary summary = io::summarizeInputs(raw.inputs, raw.load);
  pipeline::RawOutOfCoreOptions options;
  options.scratchDir = scratchDir().toStdString();
  const MemoryBudget budget{budgetBytes, "the GUI's memory budget (Run > Memory limit…)"};
  const unsigned threads = workerCount();
  pipeline::RawOutOfCorePlan plan = pipeline::planRawOutOfCore(raw, summary, options, budget, threads);
  // The process's cube name (STEM.synthtrack-filtered.PID.fits) numbered per open: the same frames opened
  // again never write over, nor have removed, the cube that the observation open now reads.
  static std::atomic<int> opened{0};
  const std::string suffix = ".fits";
  if (plan.path.size() > suffix.size() && plan.path.ends_with(suffix))
    plan.path.insert(plan.path.size() - suffix.size(), "." + std::to_string(++opened));
  auto scratch = std::make_shared<ScratchFile>();
  scratch->path = plan.path;  // removed if anything below throws (the closure is never made)
  SubProgress sub(progress, 0.0, 0.85);
  const pipeline::OutOfCorePrepared prepared = pipeline::preprocessRawOutOfCore(raw, summary, plan, sub, cancel);
  std::vector<std::string> notes{plan.description};
  if (!raw.bias.empty() || !raw.dark.empty() || !raw.flat.empty())
    notes.push_back("calibrated with the frames offered beside the science frames: " +
                    std::to_string(raw.bias.size()) + " bias, " + std::to_string(raw.dark.size()) + " dark, " +
                    std::to_string(raw.flat.size()) + " flat input(s)");
  notes.insert(notes.end(), prepared.notes.begin(), prepared.notes.end());
  for (const auto& w : prepared.warnings)
    notes.push_back("warning: " + w);
  const double need = pipeline::estimatePreprocessPeak(plan.shape, true, threads).total();
  const std::string why = std::to_string(plan.shape.frames) + " raw frames of " + std::to_string(plan.shape.width) +
                          " x " + std::to_string(plan.shape.height) + " px need " + formatBytes(need) +
                          " to pre-process in memory, over the budget of " + formatBytes(double(budgetBytes)) +
                          "; pre-processed out of core in " + std::to_string(plan.strips.strips.size()) +
                          " strips of rows into " + prepared.path;
  SubProgress rest(progress, 0.85, 1.0);
  return openCube({prepared.path}, budgetBytes, label, why, need, notes, scratch, rest, cancel);
}

std::function<void()> OutOfCoreController::openCube(const std::vector<std::string>& inputs, std::size_t budgetBytes,
                                                    const QString& label, const std::string& why, double need,
                                                    const std::vector<std::string>& notes,
                                                    std::shared_ptr<ScratchFile> scratch, ProgressSink& progress,
                                                    CancelToken& cancel) {
  SubProgress head(progress, 0.0, 0.05);
  auto ooc = std::make_shared<const pipeline::OutOfCoreCube>(pipeline::openOutOfCore(inputs, {}, head, cancel));
  SubProgress strips(progress, 0.05, 1.0);
  auto display = std::make_shared<const FrameCube>(meanFrame(*ooc, budgetBytes, strips, cancel));
  search::DefaultGridInput g;
  g.width = ooc->shape.width;
  g.height = ooc->shape.height;
  g.frames = ooc->shape.frames;
  g.timeSpanS = ooc->meta.frames.timeSpanS();
  g.plateScaleArcsecPerPx = ooc->meta.frames.plateScaleArcsecPerPx;
  g.centre = ooc->meta.skyRate;
  g.model = search::cpuCostModel(workerCount());
  const search::VelocityGrid grid = search::defaultVelocityGrid(g).grid;
  return [this, ooc, display, label, grid, why, need, notes, scratch] {
    Observation* obs = m_window->observation();
    obs->setRaw(display, label + " (out of core)");  // leaves an earlier out-of-core observation (clear())
    removeScratch();
    m_cube = ooc;
    m_needBytes = need;
    if (scratch) {
      m_scratch = scratch->path;
      scratch->taken = true;
    }
    auto view = std::make_shared<PreparedView>();
    view->filtered = std::make_shared<const search::FilteredCube>(ooc->meta);  // times, sigma_F, sky rate
    view->outOfCore = "opened out of core: " + why;
    view->summary = "Opened out of core (" + why + "): " +
                    (scratch ? std::string("pre-processed out of core just now (the strips' filtered cube)")
                             : std::string("pre-processed already, not pre-processed again")) +
                    "; sigma_F " + std::to_string(ooc->meta.sigmaF) + ", PSF FWHM " +
                    std::to_string(ooc->meta.psfFwhmPx) + " px from the header";
    for (const auto& n : notes)
      view->summary += "\n• " + n;
    for (const auto& n : ooc->notes)
      view->summary += "\n• " + n;
    obs->setPrepared(view);
    update();
    m_window->searchPanel()->setGrid(grid, "out of core: the data's default grid for the whole frame");
    m_window->statusBar()->showMessage(
        QString("Opened out of core: %1 frames of %2 × %3 px, over the memory budget of %4")
            .arg(ooc->shape.frames)
            .arg(ooc->shape.width)
            .arg(ooc->shape.height)
            .arg(bytesText(static_cast<double>(budget().bytes))),
        30000);
  };
}

bool OutOfCoreController::runSearch() {
  auto ooc = m_cube;
  if (!ooc) return false;
  const search::VelocityGrid grid = m_window->searchPanel()->grid();
  const search::SearchParams params = m_window->searchPanel()->params();
  const std::size_t bytes = budget().bytes;
  MainWindow* window = m_window;
  return m_window->jobs()->start(JobKind::Search, [window, ooc, grid, params, bytes](ProgressSink& progress,
                                                                                   CancelToken& cancel) {
    auto done = std::make_shared<const pipeline::OutOfCoreSearch>(
        pipeline::searchOutOfCore(*ooc, grid, params, bytes, progress, cancel));
    return std::function<void()>([window, done] {
      auto result = std::make_shared<const search::SearchResult>(done->result);
      window->observation()->setResult(result);
      window->searchPanel()->setBackendMessage(
          QString("out of core on the CPU: %1 tiles, %2 px overlap, per tile %3")
              .arg(done->tiles)
              .arg(done->overlapPx)
              .arg(QString::fromStdString(done->perTile.describe())));
      window->statusBar()->showMessage(QString("Search out of core: %1 candidates, %2 tiles (overlap %3 px), "
                                               "%4 s (%5)")
                                           .arg(result->candidates.size())
                                           .arg(done->tiles)
                                           .arg(done->overlapPx)
                                           .arg(result->elapsedS, 0, 'f', 1)
                                           .arg(QString::fromStdString(std::string(result->method.name()))),
                                       30000);
      if (!result->candidates.empty()) window->selectCandidate(0);
    });
  });
}

void OutOfCoreController::cancelStack() {
  if (m_stackCancel) m_stackCancel->cancel();
  m_stackCancel.reset();
}

void OutOfCoreController::requestStack(Velocity v) {
  auto ooc = m_cube;
  if (!ooc) return;
  cancelStack();
  auto cancel = std::make_shared<CancelToken>();
  m_stackCancel = cancel;
  const std::size_t bytes = budget().bytes;
  // The watcher follows the newest request only; an older one still running stops at its next strip.
  m_stackWatcher.setFuture(QtConcurrent::run([ooc, v, bytes, cancel]() {
    StackOutcome out;
    out.v = v;
    QElapsedTimer clock;
    clock.start();
    try {
      NullProgress quiet;
      out.sum = std::make_shared<const Image>(pipeline::stackOutOfCore(*ooc, v, bytes / 2, quiet, *cancel));
    } catch (const Cancelled&) {
    } catch (const std::exception& e) {
      out.error = QString::fromStdString(e.what());
    }
    out.elapsedS = clock.elapsed() / 1000.0;
    return out;
  }));
}

}  // namespace st::ui
