#include "out_of_core_controller.hpp"

#include <QFrame>
#include <QHBoxLayout>
#include <QInputDialog>
#include <QLabel>
#include <QMenu>
#include <QMenuBar>
#include <QMessageBox>
#include <QSettings>
#include <QStatusBar>
#include <QVBoxLayout>

#include "job_runner.hpp"
#include "main_window.hpp"
#include "search_panel.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/pipeline/out_of_core_cube.hpp"
#include "st/search/default_grid.hpp"

namespace st::ui {
namespace {

/// The display cube of an out-of-core observation: one frame, the mean of all frames, with the cube's
/// header, WCS and reference epoch.
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

}  // namespace

OutOfCoreController::OutOfCoreController(MainWindow* window) : QObject(window), m_window(window) {
  setObjectName("outOfCoreController");
  m_label = new QLabel(window);
  m_label->setObjectName("memory.label");
  window->statusBar()->addPermanentWidget(m_label);
  for (QMenu* menu : window->menuBar()->findChildren<QMenu*>())
    if (menu->title() == "&Run")
      menu->addAction("&Memory limit…", this, [this] {
        bool ok = false;
        const QString text = QInputDialog::getText(
            m_window, "Memory limit",
            "Memory the GUI may hold (8G, 500M; empty: 70% of the memory available).\nA pre-processed cube "
            "larger than this is opened out of core.",
            QLineEdit::Normal, QSettings().value("memory/limit").toString(), &ok);
        if (!ok) return;
        try {
          setMemoryLimit(text);
        } catch (const std::exception& e) {
          QMessageBox::warning(m_window, "Memory limit", QString::fromStdString(e.what()));
        }
      });
  m_banner = new QFrame(window->centralWidget());
  m_banner->setObjectName("memory.outOfCoreBanner");
  m_banner->setStyleSheet("#memory\\.outOfCoreBanner { background: #f1e6ff; border-bottom: 1px solid #8a63c7; } "
                          "QLabel { color: #3b1f66; }");
  m_bannerText = new QLabel(m_banner);
  m_bannerText->setObjectName("memory.outOfCoreText");
  m_bannerText->setWordWrap(true);
  (new QHBoxLayout(m_banner))->addWidget(m_bannerText);
  if (auto* layout = qobject_cast<QVBoxLayout*>(window->centralWidget()->layout())) layout->insertWidget(0, m_banner);
  m_banner->hide();
  update();
}

OutOfCoreController* OutOfCoreController::of(const MainWindow* window) {
  return window->findChild<OutOfCoreController*>("outOfCoreController", Qt::FindDirectChildrenOnly);
}

MemoryBudget OutOfCoreController::budget() const {
  const QString limit = QSettings().value("memory/limit").toString().trimmed();
  return resolveMemoryBudget(limit.isEmpty() ? std::nullopt : std::optional<std::string>(limit.toStdString()));
}

void OutOfCoreController::setMemoryLimit(const QString& limit) {
  if (!limit.trimmed().isEmpty()) (void)parseMemorySize(limit.trimmed().toStdString(), "memory limit");
  QSettings().setValue("memory/limit", limit.trimmed());
  update();
}

void OutOfCoreController::clear() {
  m_cube.reset();
  update();
}

void OutOfCoreController::update() {
  const MemoryBudget b = budget();
  m_label->setText(QString("memory budget %1%2")
                       .arg(QString::fromStdString(formatBytes(static_cast<double>(b.bytes))))
                       .arg(m_cube ? " · OUT OF CORE" : ""));
  m_label->setToolTip(QString::fromStdString(b.source) + " (Run > Memory limit…)");
  m_banner->setVisible(m_cube != nullptr);
  if (!m_cube) return;
  const auto& s = m_cube->shape;
  const MemoryEstimate need =
      pipeline::estimateOpenPeak(s, true, m_cube->header.state == pipeline::PreparedState::ZeroBiased);
  m_bannerText->setText(
      QString("<b>Out of core:</b> %1 frames of %2 × %3 px need %4 in memory, over the budget of %5. The view "
              "shows the mean of all frames, read in strips; Search runs out of core in tiles on the CPU (the "
              "CLI's path for pre-processed cubes). Live stacks, the inspector's stamps and fits need the cube "
              "in memory.")
          .arg(s.frames)
          .arg(s.width)
          .arg(s.height)
          .arg(QString::fromStdString(formatBytes(need.total())))
          .arg(QString::fromStdString(formatBytes(static_cast<double>(b.bytes)))));
}

std::function<void()> OutOfCoreController::openIfNeeded(const std::vector<std::string>& inputs,
                                                         std::size_t budget, const QString& label,
                                                         ProgressSink& progress, CancelToken& cancel) {
  const io::InputSummary summary = io::summarizeInputs(inputs);
  const pipeline::CubeShape shape{summary.width, summary.height, summary.frames};
  if (pipeline::estimateOpenPeak(shape, true, true).total() <= static_cast<double>(budget)) return {};
  io::LoadOptions lo;
  lo.crop = io::CropRegion{0, 0, std::min(shape.width, 16), std::min(shape.height, 16)};
  NullProgress quiet;
  const FrameCube corner = io::loadFrames(inputs, lo, quiet, cancel);
  if (!pipeline::recognisePreparedHeader(corner.header, pipeline::cubeSource(corner))) {
    const MemoryEstimate raw = pipeline::estimatePreprocessPeak(shape, true, workerCount());
    if (raw.total() <= static_cast<double>(budget)) return {};
    throw InputError(std::to_string(shape.frames) + " raw frames of " + std::to_string(shape.width) + " x " +
                     std::to_string(shape.height) + " px need " + formatBytes(raw.total()) +
                     " to pre-process in memory, over the budget of " + formatBytes(static_cast<double>(budget)) +
                     ": pre-process them with synthtrack-cli preprocess (out of core) and open the prepared cube "
                     "(it opens out of core), or raise Run > Memory limit");
  }
  auto ooc = std::make_shared<const pipeline::OutOfCoreCube>(pipeline::openOutOfCore(inputs, {}, progress, cancel));
  auto display = std::make_shared<const FrameCube>(meanFrame(*ooc, budget, progress, cancel));
  search::DefaultGridInput g;
  g.width = shape.width;
  g.height = shape.height;
  g.frames = shape.frames;
  g.timeSpanS = ooc->meta.frames.timeSpanS();
  g.plateScaleArcsecPerPx = ooc->meta.frames.plateScaleArcsecPerPx;
  g.centre = ooc->meta.skyRate;
  g.model = search::cpuCostModel(workerCount());
  const search::VelocityGrid grid = search::defaultVelocityGrid(g).grid;
  return [this, ooc, display, label, grid] {
    m_cube = ooc;
    Observation* obs = m_window->observation();
    obs->setRaw(display, label + " (out of core)");
    auto view = std::make_shared<PreparedView>();
    view->filtered = std::make_shared<const search::FilteredCube>(ooc->meta);  // times, sigma_F, sky rate
    view->summary = "opened out of core (larger than the memory budget): not pre-processed again";
    for (const auto& n : ooc->notes)
      view->summary += "\n• " + n;
    obs->setPrepared(view);
    m_window->searchPanel()->setGrid(grid, "out of core: the data's default grid for the whole frame");
    update();
  };
}

void OutOfCoreController::runSearch() {
  auto ooc = m_cube;
  const search::VelocityGrid grid = m_window->searchPanel()->grid();
  const search::SearchParams params = m_window->searchPanel()->params();
  const std::size_t bytes = budget().bytes;
  m_window->jobs()->start(JobKind::Search, [this, ooc, grid, params, bytes](ProgressSink& progress,
                                                                            CancelToken& cancel) {
    auto done = std::make_shared<const pipeline::OutOfCoreSearch>(
        pipeline::searchOutOfCore(*ooc, grid, params, bytes, progress, cancel));
    return std::function<void()>([this, done] {
      auto result = std::make_shared<const search::SearchResult>(done->result);
      m_window->observation()->setResult(result);
      m_window->statusBar()->showMessage(
          QString("Search out of core: %1 candidates, %2 tiles (overlap %3 px), %4 s")
              .arg(result->candidates.size())
              .arg(done->tiles)
              .arg(done->overlapPx)
              .arg(result->elapsedS, 0, 'f', 1),
          30000);
    });
  });
}

}  // namespace st::ui
