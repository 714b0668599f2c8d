#include "search_panel.hpp"

#include <QComboBox>
#include <QDoubleSpinBox>
#include <QDoubleValidator>
#include <QFormLayout>
#include <QGroupBox>
#include <QHBoxLayout>
#include <QLabel>
#include <QLineEdit>
#include <QPushButton>
#include <QRadioButton>
#include <QStandardItemModel>
#include <QVBoxLayout>
#include <QtConcurrent/QtConcurrentRun>
#include <cmath>

#include "grid_description.hpp"
#include "session_snapshot.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/search/default_grid.hpp"
#include "st/search/velocity_grid.hpp"
#include "st/stats/false_alarm.hpp"

namespace st::ui {

namespace {
QDoubleSpinBox* velocitySpin(QWidget* parent, double min) {
  auto* s = new QDoubleSpinBox(parent);
  s->setRange(min, 1e6);
  s->setDecimals(4);
  s->setKeyboardTracking(false);
  return s;
}
QString humanBytes(double b) {
  if (b >= 1e9) return QString::number(b / 1e9, 'f', 2) + " GB";
  return QString::number(b / 1e6, 'f', 0) + " MB";
}
QString humanSeconds(double s) {
  if (s < 1) return QString::number(s * 1000, 'f', 0) + " ms";
  if (s < 120) return QString::number(s, 'f', 1) + " s";
  return QString::number(s / 60, 'f', 1) + " min";
}

const char* const kMethodHelp =
    "Auto: the tree search where it is estimated at least 2× faster than exact and at least 1 s quicker, "
    "else exact (small grids and cubes, where the tree's overhead or its SNR loss does not pay).\n"
    "Exact: every frame at its exact integer shift (IPSA, the paper's method): N_pix·N_f·N_v additions, no "
    "SNR loss.\n"
    "Tree: hierarchical search, about N_pix·N_v work instead of N_pix·N_f·N_v (the paper's 1500 frames × "
    "512² px × 100² velocities: 322× fewer additions). Every sample stays within 1 px of the exact shift; "
    "SNR loss on injected objects: median ~1%, worst ~5%.\n"
    "The backend must support the method (the CPU and CUDA backends have both).";

const char* const kGridHelp =
    "Defaults for an opened observation, from its data: steps of 1 px of motion over the time span (the "
    "paper's rule, §4.4) around the sky rate, over the smallest of the paper's ±12 deg/day (±12 steps "
    "without a plate scale), what can stay in the frame (an object faster than the frame size over half the "
    "span is in fewer than half the frames) and what the backend searches in about a minute (exact method; "
    "the estimate below is shown before the search runs). synthtrack-cli search keeps the paper's ±12 "
    "deg/day. The demo observation opens with a coarser demo setting so that it runs quickly: ±8 deg/day in "
    "1.5 px steps, as synthtrack-cli demo.";

QString gpuLabel(const std::vector<std::string>& names) {
  if (names.empty()) return "GPU (none found)";
  QString label = "GPU: " + QString::fromStdString(names.front());
  if (names.size() > 1) label += QString(" (+%1 more)").arg(names.size() - 1);
  return label;
}
}  // namespace

SearchPanel::SearchPanel(Observation* observation, const std::vector<std::string>& gpuNames, QWidget* parent)
    : QWidget(parent), m_obs(observation) {
  connect(&m_estimateWatcher, &QFutureWatcher<KeyedEstimate>::finished, this,
          &SearchPanel::onEstimateFinished);
  auto* gridBox = new QGroupBox("Velocity grid", this);
  gridBox->setToolTip(kGridHelp);
  auto* form = new QFormLayout(gridBox);
  m_unit = new QComboBox(gridBox);
  m_unit->addItem("px/s", static_cast<int>(VelocityUnit::PxPerS));
  m_unit->addItem("\"/min", static_cast<int>(VelocityUnit::ArcsecPerMin));
  m_unit->addItem("deg/day", static_cast<int>(VelocityUnit::DegPerDay));
  m_cx = velocitySpin(gridBox, -1e6);
  m_cy = velocitySpin(gridBox, -1e6);
  m_half = velocitySpin(gridBox, 0);
  m_step = velocitySpin(gridBox, 0);
  m_step->setMinimum(1e-6);
  m_half->setToolTip(
      "Half-width of the square grid around the centre: a whole number of steps, at least the range asked "
      "for (the demo's ±8 deg/day in 1.5 px steps is ±8.08 deg/day)");
  m_step->setToolTip("Grid spacing; the paper's default is 1 pixel over the observation's time span");
  auto* centre = new QHBoxLayout;
  centre->addWidget(m_cx);
  centre->addWidget(m_cy);
  m_gridSize = new QLabel(gridBox);
  m_gridSize->setWordWrap(true);
  m_gridSize->setTextInteractionFlags(Qt::TextSelectableByMouse);
  m_gridOriginLabel = new QLabel(gridBox);
  m_gridOriginLabel->setWordWrap(true);
  m_gridOriginLabel->setStyleSheet("color: palette(placeholder-text); font-style: italic");
  m_gridOriginLabel->hide();
  form->addRow("Units", m_unit);
  form->addRow("Centre vx, vy", centre);
  form->addRow("Half-range", m_half);
  form->addRow("Step", m_step);
  form->addRow("Grid", m_gridSize);
  form->addRow(m_gridOriginLabel);

  auto* thrBox = new QGroupBox("Detection threshold", this);
  auto* thr = new QFormLayout(thrBox);
  m_bySnr = new QRadioButton("SNR ≥", thrBox);
  m_byFap = new QRadioButton("FAP ≤", thrBox);
  m_bySnr->setChecked(true);
  m_snr = new QDoubleSpinBox(thrBox);
  m_snr->setRange(1, 100);
  m_snr->setDecimals(2);
  m_hiddenParams = defaultPanelSearchParams();
  m_snr->setValue(m_hiddenParams.snrThreshold);
  m_snr->setToolTip("Paper §4.4: SNR 7, about 0.34% false alarms for 512² pixels × 100² velocities");
  m_fap = new QLineEdit("0.01", thrBox);
  m_fap->setValidator(new QDoubleValidator(1e-300, 1, 30, m_fap));
  m_fap->setToolTip("False-alarm probability over all trials (paper, Prob_false)");
  thr->addRow(m_bySnr, m_snr);
  thr->addRow(m_byFap, m_fap);

  QGroupBox* runBox = makeRunBox(gpuNames);

  auto* layout = new QVBoxLayout(this);
  layout->setContentsMargins(2, 2, 2, 2);
  layout->addWidget(gridBox);
  layout->addWidget(thrBox);
  layout->addWidget(runBox);
  layout->addStretch(1);

  connect(m_unit, &QComboBox::currentIndexChanged, this, &SearchPanel::onUnitChanged);
  for (auto* s : {m_cx, m_cy, m_half, m_step})
    connect(s, &QDoubleSpinBox::valueChanged, this, &SearchPanel::onGridEdited);
  connect(m_snr, &QDoubleSpinBox::valueChanged, this, &SearchPanel::refresh);
  connect(m_fap, &QLineEdit::textChanged, this, &SearchPanel::refresh);
  connect(m_bySnr, &QRadioButton::toggled, this, &SearchPanel::refresh);
  connect(m_method, &QComboBox::currentIndexChanged, this, &SearchPanel::refresh);
  connect(m_backend, &QComboBox::currentIndexChanged, this, &SearchPanel::refresh);
  connect(m_obs, &Observation::resultChanged, this, &SearchPanel::onResultChanged);
  connect(m_run, &QPushButton::clicked, this, &SearchPanel::runRequested);
  connect(m_cancel, &QPushButton::clicked, this, &SearchPanel::cancelRequested);
  connect(m_obs, &Observation::rawChanged, this, &SearchPanel::onRawChanged);
  setGridPxS({}, 0.5, 0.01);
  if (m_obs->raw()) onRawChanged();
}

QGroupBox* SearchPanel::makeRunBox(const std::vector<std::string>& gpuNames) {
  auto* runBox = new QGroupBox("Run", this);
  auto* run = new QFormLayout(runBox);
  m_method = new QComboBox(runBox);
  // Item data: the method's stable name, as sessions and the command line carry it.
  for (const auto& [text, method] :
       {std::pair{"Auto", search::SearchMethod::Auto}, std::pair{"Exact", search::SearchMethod::Exact},
        std::pair{"Tree", search::SearchMethod::Tree}})
    m_method->addItem(text, QString::fromUtf8(search::searchMethodName(method)));
  m_method->setToolTip(kMethodHelp);
  m_backend = new QComboBox(runBox);
  m_backend->addItem("Auto", static_cast<int>(BackendKind::Auto));
  m_backend->addItem("CPU", static_cast<int>(BackendKind::Cpu));
  m_backend->addItem(gpuLabel(gpuNames), static_cast<int>(BackendKind::Gpu));
  QString backendHelp = "Auto: the GPU when one is usable, else the CPU.";
  for (const auto& n : gpuNames)
    backendHelp += "\nGPU: " + QString::fromStdString(n);
  m_backend->setToolTip(backendHelp);
  m_hasGpu = !gpuNames.empty();
  m_backendInfo = new QLabel(gpuNames.empty() ? "CPU (no GPU in this build or machine)" : "", runBox);
  m_backendInfo->setWordWrap(true);
  m_estimate = new QLabel(runBox);
  m_estimate->setWordWrap(true);
  m_run = new QPushButton(QIcon::fromTheme("system-search"), "Search", runBox);
  m_cancel = new QPushButton("Cancel", runBox);
  m_cancel->setEnabled(false);
  m_run->setEnabled(false);
  auto* buttons = new QHBoxLayout;
  buttons->addWidget(m_run, 1);
  buttons->addWidget(m_cancel);
  m_status = new QLabel(runBox);
  m_status->setWordWrap(true);
  run->addRow("Method", m_method);
  run->addRow("Backend", m_backend);
  run->addRow("", m_backendInfo);
  run->addRow("Estimate", m_estimate);
  run->addRow(buttons);
  run->addRow(m_status);
  return runBox;
}

void SearchPanel::onRawChanged() {
  const bool angular = m_obs->plateScale().has_value();
  for (int i = 1; i < 3; ++i) {
    auto* item = qobject_cast<QStandardItemModel*>(m_unit->model());
    if (item) item->item(i)->setEnabled(angular);
  }
  // Astronomers think in deg/day (the paper's unit) when the plate scale allows it.
  m_unit->setCurrentIndex(angular ? 2 : 0);
  onUnitChanged();
}

void SearchPanel::setGrid(const search::VelocityGrid& grid, const QString& origin) {
  m_exactGrid = grid;
  m_origin = origin;
  const auto scale = m_obs->plateScale();
  const double half = 0.5 * (std::max(grid.nvx, grid.nvy) - 1) * grid.stepPxS;
  const QSignalBlocker b1(m_cx), b2(m_cy), b3(m_half), b4(m_step);
  m_cx->setValue(fromPxPerS(grid.centre.vx, m_shownUnit, scale));
  m_cy->setValue(fromPxPerS(grid.centre.vy, m_shownUnit, scale));
  m_half->setValue(fromPxPerS(half, m_shownUnit, scale));
  m_step->setValue(fromPxPerS(grid.stepPxS, m_shownUnit, scale));
  refresh();
}

void SearchPanel::setGridPxS(Velocity centre, double halfRange, double step) {
  search::VelocityGrid g;
  g.centre = centre;
  g.stepPxS = step;
  g.nvx = g.nvy = 2 * static_cast<int>(std::ceil(halfRange / step - 1e-9)) + 1;
  setGrid(g, {});
}

void SearchPanel::onGridEdited() {
  m_exactGrid.reset();
  m_origin = "edited by hand";
  refresh();
}

void SearchPanel::setDefaultsFor(const FrameCube& cube, Velocity skyRate) {
  // The data-derived grid (st/search/default_grid.hpp): 1 px steps over the span, half-range the smallest of
  // the paper's ±12 deg/day, what can stay in the frame and what the chosen backend's exact search does in
  // about a minute. The GPU's model where the search will run on one, else the CPU's with this machine's
  // workers; pure arithmetic (microseconds), so it runs here.
  search::DefaultGridInput in;
  in.width = cube.width();
  in.height = cube.height();
  in.frames = cube.frameCount();
  in.timeSpanS = std::max(cube.timeSpanS(), 1e-3);
  in.plateScaleArcsecPerPx = cube.plateScaleArcsecPerPx;
  in.centre = skyRate;
  in.minFrameFraction = m_hiddenParams.minFrameFraction > 0.0 ? m_hiddenParams.minFrameFraction : 0.5;
  const bool gpu = m_hasGpu && backendKind() != BackendKind::Cpu;
  in.model = gpu ? search::cudaCostModel() : search::cpuCostModel(workerCount());
  if (in.width <= 0 || in.height <= 0 || in.frames == 0) return;
  try {
    const search::DefaultGrid d = search::defaultVelocityGrid(in);
    setGrid(d.grid, QString("data default: %1 on the %2")
                        .arg(QString::fromStdString(search::describeDefaultGrid(d, in.plateScaleArcsecPerPx)))
                        .arg(gpu ? "GPU" : QString("CPU (%1 threads)").arg(workerCount())));
  } catch (const InputError& e) {  // an empty cube: the previous grid stays
    m_origin = QString("no default grid: ") + e.what();
    refresh();
  }
}

void SearchPanel::onUnitChanged() {
  const auto scale = m_obs->plateScale();
  const auto next = static_cast<VelocityUnit>(m_unit->currentData().toInt());
  const QSignalBlocker b1(m_cx), b2(m_cy), b3(m_half), b4(m_step);
  for (auto* s : {m_cx, m_cy, m_half, m_step}) {
    const double px = toPxPerS(s->value(), m_shownUnit, scale);
    s->setValue(fromPxPerS(px, next, scale));
  }
  m_shownUnit = scale ? next : VelocityUnit::PxPerS;
  if (m_exactGrid) {  // shown from the exact grid, not from the values rounded in the previous unit
    const search::VelocityGrid& g = *m_exactGrid;
    m_cx->setValue(fromPxPerS(g.centre.vx, m_shownUnit, scale));
    m_cy->setValue(fromPxPerS(g.centre.vy, m_shownUnit, scale));
    m_half->setValue(fromPxPerS(0.5 * (std::max(g.nvx, g.nvy) - 1) * g.stepPxS, m_shownUnit, scale));
    m_step->setValue(fromPxPerS(g.stepPxS, m_shownUnit, scale));
  }
  setSpinUnits();
  m_obs->setUnit(m_shownUnit);
  refresh();
}

void SearchPanel::setSpinUnits() {
  for (auto* s : {m_cx, m_cy, m_half, m_step})
    s->setSuffix(" " + unitLabel(m_shownUnit));
}

search::VelocityGrid SearchPanel::grid() const {
  if (m_exactGrid) return *m_exactGrid;
  const auto scale = m_obs->plateScale();
  search::VelocityGrid g;
  g.centre = {toPxPerS(m_cx->value(), m_shownUnit, scale), toPxPerS(m_cy->value(), m_shownUnit, scale)};
  g.stepPxS = toPxPerS(m_step->value(), m_shownUnit, scale);
  const double half = toPxPerS(m_half->value(), m_shownUnit, scale);
  const int n = 2 * static_cast<int>(std::ceil(half / g.stepPxS - 1e-9)) + 1;
  g.nvx = g.nvy = std::max(1, n);
  return g;
}

search::SearchParams SearchPanel::params() const {
  search::SearchParams p = m_hiddenParams;
  p.snrThreshold = m_snr->value();
  p.targetFap.reset();
  if (m_byFap->isChecked()) p.targetFap = m_fap->text().toDouble();
  p.method = method();
  return p;
}

void SearchPanel::setParams(const search::SearchParams& params) {
  m_hiddenParams = params;
  m_snr->setValue(params.snrThreshold);
  if (params.targetFap) m_fap->setText(QString::number(*params.targetFap, 'g', 12));
  (params.targetFap ? m_byFap : m_bySnr)->setChecked(true);
  setMethod(params.method);
  refresh();
}

void SearchPanel::setBackendKind(BackendKind kind) {
  if (kind == BackendKind::Gpu && !m_hasGpu) kind = BackendKind::Auto;  // e.g. a session from a GPU machine
  const int index = m_backend->findData(static_cast<int>(kind));
  if (index >= 0) m_backend->setCurrentIndex(index);
}

void SearchPanel::setUnit(VelocityUnit unit) {
  if (unit != VelocityUnit::PxPerS && !m_obs->plateScale()) return;
  const int index = m_unit->findData(static_cast<int>(unit));
  if (index >= 0) m_unit->setCurrentIndex(index);
}

QString SearchPanel::gridText() const {
  return m_gridSize->text();
}

search::SearchMethod SearchPanel::method() const {
  const QByteArray name = m_method->currentData().toString().toUtf8();
  return search::parseSearchMethod(std::string_view(name.constData(), static_cast<std::size_t>(name.size())))
      .value_or(search::SearchMethod::Auto);
}

void SearchPanel::setMethod(search::SearchMethod method) {
  const int index = m_method->findData(QString::fromUtf8(search::searchMethodName(method)));
  if (index >= 0 && method != search::SearchMethod::Unknown) m_method->setCurrentIndex(index);
}

QString SearchPanel::estimateText() const {
  return m_estimate->text();
}

QString SearchPanel::statusText() const {
  return m_status->text();
}

BackendKind SearchPanel::backendKind() const {
  return static_cast<BackendKind>(m_backend->currentData().toInt());
}

void SearchPanel::refresh() {
  setSpinUnits();
  const search::VelocityGrid g = grid();
  m_gridSize->setText(
      gridDescription(g, m_shownUnit, m_obs->plateScale(), m_obs->raw() ? m_obs->raw()->timeSpanS() : 0.0));
  m_gridOriginLabel->setText(m_origin);
  m_gridOriginLabel->setVisible(!m_origin.isEmpty());
  const search::SearchParams p = params();
  QString settings = QString::fromUtf8(p.method.name());
  for (double v : {g.centre.vx, g.centre.vy, g.stepPxS, 1.0 * g.nvx, 1.0 * g.nvy, p.snrThreshold,
                   p.targetFap.value_or(-1.0), 1.0 * static_cast<int>(backendKind())})
    settings += ' ' + QString::number(v, 'g', 17);
  if (settings != m_lastSettings) {
    m_lastSettings = settings;
    emit settingsChanged();
  }
  if (m_obs->grid().nvx != g.nvx || m_obs->grid().stepPxS != g.stepPxS || !(m_obs->grid().centre == g.centre))
    m_obs->setGrid(g);
  const auto& raw = m_obs->raw();
  if (!raw) {
    m_estimate->setText("open an observation first");
    return;
  }
  // Throughput from the last live stack (w * h * frames additions), when one was measured.
  std::optional<double> rate;
  if (m_stackSeconds && *m_stackSeconds > 0)
    rate = static_cast<double>(raw->width()) * raw->height() * static_cast<double>(raw->frameCount()) /
           *m_stackSeconds;
  const double trials = search::trialCounts(raw->width(), raw->height(), g).total();
  QString text = QString("%1 trials\n").arg(trials, 0, 'e', 2);
  if (g.count() > search::GridSpec{}.maxVelocities) {
    text += QString("over the limit of %1 velocities: use a coarser step or a smaller range")
                .arg(search::GridSpec{}.maxVelocities);
  } else {
    try {
      text += methodEstimateText(*raw, g, rate);
    } catch (const std::exception& ex) {
      text += QString::fromStdString(ex.what());
    }
  }
  try {
    if (m_byFap->isChecked())
      text += QString("\nFAP %1 ⇒ SNR ≥ %2")
                  .arg(m_fap->text())
                  .arg(stats::snrThresholdForFap(m_fap->text().toDouble(), trials), 0, 'f', 2);
    else
      text += QString("\nSNR %1 ⇒ FAP %2")
                  .arg(m_snr->value())
                  .arg(stats::expectedFalseAlarms(m_snr->value(), trials), 0, 'e', 1);
  } catch (const std::exception& ex) {
    text += "\n" + QString::fromStdString(ex.what());
  }
  m_estimate->setText(text);
}

QString SearchPanel::methodEstimateText(const FrameCube& raw, const search::VelocityGrid& g,
                                        std::optional<double> rate) {
  const EstimateKey key{&raw, raw.width(), raw.height(), g.nvx, g.nvy, raw.frameCount(), g.stepPxS};
  // The choice uses the CPU backend's own model, as the search will (searchWithMethod); the times shown use
  // the live stack's measured throughput when there is one.
  const search::MethodCostModel standard = search::cpuCostModel(workerCount());
  if (!m_estimateCache || !(m_estimateCache->first == key)) {
    startEstimate(raw, g, key);
    return "estimating both methods…";
  }
  search::MethodEstimate& e = m_estimateCache->second;
  search::priceMethods(e, standard);
  const search::MethodChoice c = search::chooseMethod(method(), e, true, "cpu");
  search::priceMethods(e, search::cpuCostModel(workerCount(), rate));
  const bool tree = c.method == search::SearchMethod::Tree;
  if (tree && !(e.treeAdditions > 0.0))
    return "tree: no tree plan for these frames (they need 2 distinct times)";
  QString text = method() == search::SearchMethod::Auto ? "Auto → " + QString::fromUtf8(c.method.name())
                                                        : QString::fromUtf8(c.method.name());
  text += QString(": %1 additions · %2 (+%3 cube) · ~%4")
              .arg(tree ? e.treeAdditions : e.exactAdditions, 0, 'e', 2)
              .arg(humanBytes(static_cast<double>(tree ? e.treeWorkingBytes : e.exactWorkingBytes)))
              .arg(humanBytes(static_cast<double>(e.cubeBytes)))
              .arg(humanSeconds(tree ? e.treeSeconds : e.exactSeconds));
  if (tree)
    text += QString(" (exact ~%1, %2× the additions)")
                .arg(humanSeconds(e.exactSeconds))
                .arg(e.exactAdditions / e.treeAdditions, 0, 'f', 0);
  else if (e.treeAdditions > 0.0)
    text += QString(" (tree ~%1)").arg(humanSeconds(e.treeSeconds));
  if (!rate) text += " (assumed speed)";
  if (m_hasGpu && backendKind() != BackendKind::Cpu)
    text += "\nCPU figures; on a GPU the method is resolved when the search starts";
  return text;
}

void SearchPanel::startEstimate(const FrameCube& raw, const search::VelocityGrid& g, const EstimateKey& key) {
  m_estimatePending = true;
  if (m_estimateWatcher.isRunning()) return;  // onEstimateFinished refreshes, which starts the latest
  // The worker gets copies (frame times, grid, sizes): the cube may be replaced while it runs; the key
  // then no longer matches and the result is only cached, never shown for the new cube.
  m_estimateWatcher.setFuture(
      QtConcurrent::run([key, g, width = raw.width(), height = raw.height(), dt = raw.timeOffsetsS(),
                         offsets = raw.frameOffsets()]() -> KeyedEstimate {
        const unsigned threads = workerCount();
        return {key, search::estimateMethods(width, height, dt, g, search::cpuCostModel(threads), threads, 0,
                                             offsets)};
      }));
}

void SearchPanel::onEstimateFinished() {
  m_estimateCache = m_estimateWatcher.result();
  m_estimatePending = false;
  refresh();  // starts the latest request when the grid or cube changed meanwhile
}

void SearchPanel::onResultChanged() {
  const auto& r = m_obs->result();
  if (!r) return;
  const QString why =
      r->methodReason == "requested" ? QString("as selected") : QString::fromStdString(r->methodReason);
  QString text = QString("%1 search on %2: %3 in %4 (%5)")
                     .arg(QString::fromUtf8(r->method.name()))
                     .arg(QString::fromStdString(r->backend))
                     .arg(candidateSummary(*r))
                     .arg(humanSeconds(r->elapsedS))
                     .arg(why);
  // The statistic's spread on this cube (search/statistic_noise.hpp): how far its SNRs are the paper's unit.
  if (r->statisticNoise.measured())
    text +=
        QString("\nnoise of the statistic on this cube: %1 x the unit, mean %2 (the paper assumes 1 and 0)")
            .arg(r->statisticNoise.scale, 0, 'f', 3)
            .arg(r->statisticNoise.mean, 0, 'f', 2);
  // What the user must see (e.g. the GPU failed and the CPU searched instead) goes first.
  for (auto it = r->warnings.rbegin(); it != r->warnings.rend(); ++it)
    text.prepend("Warning: " + QString::fromStdString(*it) + "\n");
  m_status->setText(text);
  // How the backend ran it (memory tiling, devices, time per phase), on hover.
  m_status->setToolTip(QString::fromStdString(r->backendNote));
}

QString candidateSummary(const search::SearchResult& result) {
  const std::size_t n = result.candidates.size();
  QString text = QString("%1 candidate%2 above SNR %3")
                     .arg(n)
                     .arg(n == 1 ? "" : "s")
                     .arg(result.snrThreshold, 0, 'f', 2);
  if (result.sidelobesMerged > 0)
    text += QString(" (%1 sidelobe%2 merged)")
                .arg(result.sidelobesMerged)
                .arg(result.sidelobesMerged == 1 ? "" : "s");
  if (!result.staticSources.empty())
    text += QString("; %1 static source%2 at the sky rate set aside (not movers)")
                .arg(result.staticSources.size())
                .arg(result.staticSources.size() == 1 ? "" : "s");
  return text;
}

void SearchPanel::setMeasuredStackSeconds(double seconds) {
  if (m_stackSeconds && std::abs(*m_stackSeconds - seconds) < 0.2 * seconds) return;
  m_stackSeconds = seconds;
  refresh();
}

void SearchPanel::setReady(bool ready) {
  m_ready = ready;
  m_run->setEnabled(ready);
}

void SearchPanel::setRunning(bool running) {
  m_run->setEnabled(!running && m_ready);
  m_cancel->setEnabled(running);
}

void SearchPanel::setProgress(double fraction, const QString& stage, double elapsedS) {
  m_status->setText(
      QString("%1 %2% · %3 s").arg(stage).arg(fraction * 100, 0, 'f', 0).arg(elapsedS, 0, 'f', 1));
}

void SearchPanel::setStatusText(const QString& text) {
  m_status->setText(text);
}

void SearchPanel::setBackendMessage(const QString& text) {
  m_backendInfo->setText(text);
}

}  // namespace st::ui
