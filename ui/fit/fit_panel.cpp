#include "fit_panel.hpp"

#include <qcustomplot.h>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QPushButton>
#include <QTableWidget>
#include <QVBoxLayout>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <mutex>
#include <vector>

#include "job_runner.hpp"
#include "motion_vs_sky.hpp"
#include "stamp_strip.hpp"
#include "st/fit/uncertainty.hpp"
#include "st/stats/false_alarm.hpp"

namespace st::ui {

/// What the worker hands to the GUI while the fit runs: guarded by a mutex, drained on the GUI thread.
struct FitPanel::Live {
  std::mutex mutex;
  std::vector<std::pair<int, double>> points;  ///< (iteration, cost) not yet plotted
  std::shared_ptr<const Image> residual;       ///< latest, not yet shown
  std::chrono::steady_clock::time_point lastPost{};
  bool posted = false;  ///< a drain is queued
};

namespace {

QString num(double v, int precision = 4) {
  if (!std::isfinite(v)) return "—";
  return QString::number(v, 'g', precision);
}

/// One row of the parameter table: name, value, noise-model sigma, Hessian sigma, the paper's column.
void appendRow(QTableWidget* table, const QString& name, const QString& value, const QString& noiseModel = {},
               const QString& hessian = {}, const QString& paper = {}) {
  const int i = table->rowCount();
  table->insertRow(i);
  const QString cells[] = {name, value, noiseModel, hessian, paper};
  for (int c = 0; c < 5; ++c)
    table->setItem(i, c, new QTableWidgetItem(cells[c]));
}

/// The fitted motion relative to the stars in the Search dock's unit (motion_vs_sky.hpp, as the candidates
/// table): rate, position angle and components with their noise-model sigmas (the sky rate is taken as
/// exact). The fit's own parameters above stay in px/s, the unit it fits in.
void appendMotionRows(QTableWidget* table, const Observation& obs, double x, double y, Velocity v,
                      double sigmaVxPxS, double sigmaVyPxS) {
  const MotionVsSky m = motionVsSky(obs, x, y, v);
  const QString unit = unitLabel(m.unit);
  const auto inUnit = [&](double pxPerS) { return fromPxPerS(pxPerS, m.unit, obs.plateScale()); };
  const auto add = [table](const QString& name, const QString& value, const QString& sigma = {}) {
    appendRow(table, name, value, sigma);
  };
  add("rate vs sky [" + unit + "]", num(m.rate));
  add("PA [deg] (east of north)", m.paDeg ? QString::number(*m.paDeg, 'f', 1) : "— (no WCS)");
  add("vx vs sky [" + unit + "]", num(m.vx), num(inUnit(sigmaVxPxS)));
  add("vy vs sky [" + unit + "]", num(m.vy), num(inUnit(sigmaVyPxS)));
}

// The segment check's verdict and each segment's own position: the tracklet a report submits (one position
// per segment by default, report::realDetections).
void appendSegmentRows(QTableWidget* table, const std::optional<candidate::SegmentSummary>& seg) {
  if (!seg) return;
  appendRow(table, QString("segments (K = %1)").arg(seg->snr.size()), seg->flagged ? "flagged" : "consistent",
            {}, {},
            QString("tracklet: %1 position%2 of %3 segments")
                .arg(seg->positions.size())
                .arg(seg->positions.size() == 1 ? "" : "s")
                .arg(seg->positionSegments));
  for (const auto& q : seg->positions) {
    QString note = QString("SNR %1").arg(q.snr, 0, 'f', 1);
    if (q.raDeg && q.decDeg)
      note += QString(", RA %1 Dec %2 deg").arg(*q.raDeg, 0, 'f', 6).arg(*q.decDeg, 0, 'f', 6);
    appendRow(table,
              QString::asprintf("segment %d/%d (x, y) [px] at t_ref %+.1f s", q.segment,
                                seg->positionSegments, q.tOffsetS),
              QString("%1, %2").arg(q.x, 0, 'f', 3).arg(q.y, 0, 'f', 3),
              QString("%1, %2").arg(q.sigmaXPx, 0, 'g', 3).arg(q.sigmaYPx, 0, 'g', 3), {}, note);
  }
}

}  // namespace

FitPanel::FitPanel(Observation* observation, const CoreServices* services, QWidget* parent)
    : QWidget(parent), m_obs(observation), m_services(services) {
  m_jobs = new JobRunner(this);
  m_title = new QLabel(this);
  m_title->setWordWrap(true);
  m_fit = new QPushButton("Fit (F)", this);
  m_fit->setToolTip("Co-moving PSF fit of the selected candidate (paper §3.2)");
  m_cancel = new QPushButton("Cancel", this);
  m_cancel->setEnabled(false);
  m_accept = new QPushButton("Accept", this);
  m_accept->setEnabled(false);
  m_accept->setToolTip("Store this fit on the candidate (saved with the session)");
  m_status = new QLabel(this);
  m_status->setWordWrap(true);
  auto* buttons = new QHBoxLayout;
  buttons->addWidget(m_fit);
  buttons->addWidget(m_cancel);
  buttons->addWidget(m_accept);
  buttons->addStretch(1);

  m_cost = new QCustomPlot(this);
  m_cost->setMinimumHeight(150);
  m_cost->addGraph();
  m_cost->graph(0)->setPen(QPen(QColor(40, 90, 200), 2));
  m_cost->graph(0)->setScatterStyle(QCPScatterStyle(QCPScatterStyle::ssDisc, 5));
  m_cost->xAxis->setLabel("iteration");
  // The change from the first cost, in per cent: a fit on noise-dominated data moves C (~2e8 on the demo) by
  // a fraction of a per cent, which absolute ticks could not tell apart (they all read 2.048e+08).
  m_cost->yAxis->setLabel("ΔC / C0 [%]");
  m_cost->yAxis->setNumberFormat("g");
  m_cost->yAxis->setNumberPrecision(3);
  m_residual = new StampStrip(this);
  m_residual->setObjectName("fit data, model, residual");  // a figure source under this name
  m_residual->setMinimumHeight(130);
  m_residual->setPlaceholder("residual (data − model, summed along the track)");
  DisplaySettings d;
  d.limits = LimitsMode::MinMax;
  d.colormap = Colormap::Viridis;
  m_residual->setDisplaySettings(d);
  m_table = new QTableWidget(0, 5, this);
  m_table->setHorizontalHeaderLabels({"parameter", "value", "σ noise model", "σ Hessian", "σ paper"});
  m_table->verticalHeader()->hide();
  m_table->verticalHeader()->setDefaultSectionSize(fontMetrics().height() + 6);
  m_table->horizontalHeader()->setSectionResizeMode(QHeaderView::ResizeToContents);
  m_table->setEditTriggers(QAbstractItemView::NoEditTriggers);

  // Wide and short (a bottom dock): controls and cost | residual | parameters.
  auto* left = new QVBoxLayout;
  left->addWidget(m_title);
  left->addLayout(buttons);
  left->addWidget(m_status);
  left->addWidget(m_cost, 1);
  auto* layout = new QHBoxLayout(this);
  layout->setContentsMargins(2, 2, 2, 2);
  layout->addLayout(left, 3);
  layout->addWidget(m_residual, 3);
  layout->addWidget(m_table, 4);

  resetPlots();
  connect(m_fit, &QPushButton::clicked, this, &FitPanel::fitSelected);
  connect(m_cancel, &QPushButton::clicked, this, &FitPanel::cancel);
  connect(m_accept, &QPushButton::clicked, this, &FitPanel::accept);
  connect(m_jobs, &JobRunner::finished, this,
          [this](JobKind, bool ok, bool cancelled, const QString& message, double elapsedS) {
            m_fit->setEnabled(true);
            m_cancel->setEnabled(false);
            m_runningIndex = -1;
            if (cancelled) m_status->setText("Fit cancelled.");
            if (!ok && !cancelled) m_status->setText("Fit failed: " + message);
            if (ok) m_status->setText(m_status->text() + QString(" (%1 s)").arg(elapsedS, 0, 'f', 1));
            updateTitle();
            emit fitFinished(ok, cancelled, message);
          });
  connect(m_obs, &Observation::resultChanged, this, [this] {
    m_outcome.reset();
    m_fittedIndex = -1;
    m_accept->setEnabled(false);
    updateTitle();
  });
  connect(m_obs, &Observation::selectionChanged, this, &FitPanel::updateTitle);
  connect(m_obs, &Observation::selectionChanged, this, &FitPanel::showSelectedFit);
  connect(m_obs, &Observation::candidateStateChanged, this, &FitPanel::updateTitle);
  connect(m_obs, &Observation::preparedChanged, this, &FitPanel::updateTitle);
  connect(m_obs, &Observation::unitChanged, this, &FitPanel::updateTitle);  // the motion is in that unit
  connect(m_obs, &Observation::unitChanged, this, &FitPanel::showSelectedFit);
  updateTitle();
}

QString FitPanel::titleText() const {
  return m_title->text();
}

void FitPanel::updateTitle() {
  const auto& result = m_obs->result();
  const search::Candidate* c = m_obs->selectedCandidate();
  QString text;
  if (m_runningIndex >= 0) {
    text = QString("Candidate %1: fitting… (Cancel stops it)").arg(m_runningIndex + 1);
  } else if (!result) {
    text = "No candidates yet: run the search, then select a candidate and press Fit (F).";
  } else if (result->candidates.empty()) {
    text = "The search found no candidate to fit.";
  } else if (!c) {
    text = QString("Select one of the %1 candidates and press Fit (F).").arg(result->candidates.size());
  } else {
    const int index = *m_obs->selected();
    const auto& states = m_obs->candidateStates();
    const bool stored = index < static_cast<int>(states.size()) && states[index].fit.has_value();
    // The accepted fit's values once there is one (they supersede the search cell's), else the search's.
    const ShownTrack shown = shownTrack(*m_obs, index, *c);
    text = QString("Candidate %1 selected: %2, at (%3, %4) px — ")
               .arg(index + 1)
               .arg(describeShownTrack(*m_obs, shown))
               .arg(shown.x, 0, 'f', shown.fitted ? 2 : 0)
               .arg(shown.y, 0, 'f', shown.fitted ? 2 : 0);
    if (m_outcome && m_fittedIndex == index)
      text += stored && m_outcome->summary == *states[index].fit
                  ? "fit done and stored on the candidate."
                  : QString("fit done (%1): Accept stores it.")
                        .arg(QString::fromStdString(fit::toString(m_outcome->result.status)));
    else if (stored)
      text += "a fit is stored on it; Fit (F) fits it again.";
    else
      text += "ready to fit: press Fit (F).";
    if (m_outcome && m_fittedIndex >= 0 && m_fittedIndex != index)
      text += QString(" (The plots show candidate %1's fit.)").arg(m_fittedIndex + 1);
  }
  m_title->setText(text);
}

FitPanel::~FitPanel() {
  // The runner joins its thread: the worker ends (cancelled) before the members it posts to go away.
  delete m_jobs;
}

bool FitPanel::running() const {
  return m_jobs->busy();
}

int FitPanel::costPoints() const {
  return m_cost->graph(0)->dataCount();
}

QString FitPanel::statusText() const {
  return m_status->text();
}

void FitPanel::cancel() {
  m_jobs->cancel();
}

void FitPanel::rescaleCost() {
  m_cost->rescaleAxes();
  // From the first cost (0) down to the lowest, with a margin; a flat fit still gets a readable range.
  const QCPRange r = m_cost->yAxis->range();
  const double span = std::max(r.upper - r.lower, 0.01);  // per cent
  m_cost->yAxis->setRange(r.lower - 0.05 * span, std::max(r.upper, 0.0) + 0.05 * span);
  m_cost->xAxis->setRange(-0.3, std::max(2.0, m_cost->xAxis->range().upper + 0.3));
}

void FitPanel::resetPlots() {
  m_cost->graph(0)->data()->clear();
  m_cost0 = 0.0;
  m_cost->xAxis->setRange(0, 5);
  m_cost->yAxis->setRange(-1, 0.1);
  m_cost->replot();
  m_residual->clear();
  m_table->setRowCount(0);
}

void FitPanel::fitSelected() {
  const auto* c = m_obs->selectedCandidate();
  const auto prepared = m_obs->prepared();
  if (!c || !prepared || m_jobs->busy()) return;
  if (!prepared->outOfCore.empty()) {
    m_status->setText("Co-moving fits need the cube in memory: unavailable out of core.");
    return;
  }
  if (!m_services || !m_services->fitCandidate) {
    m_status->setText("This build has no co-moving fit.");
    return;
  }
  m_runningIndex = *m_obs->selected();
  updateTitle();
  m_status->setText(QString("Fitting candidate %1 from (%2, %3) px, %4…")
                        .arg(m_runningIndex + 1)
                        .arg(c->x)
                        .arg(c->y)
                        .arg(describeMotion(motionVsSky(*m_obs, c->x, c->y, c->v))));
  resetPlots();
  m_accept->setEnabled(false);
  m_fit->setEnabled(false);
  m_cancel->setEnabled(true);
  m_live = std::make_shared<Live>();
  auto live = m_live;
  const auto fn = m_services->fitCandidate;
  const search::Candidate candidate = *c;
  const int index = m_runningIndex;
  // Called on the worker for every accepted iteration: store, and queue one drain per kLiveIntervalMs.
  FitStepCallback onStep = [this, live](const FitStep& step) {
    std::lock_guard lock(live->mutex);
    live->points.emplace_back(step.iteration.iteration, step.iteration.cost);
    if (step.residual) live->residual = step.residual;
    const auto now = std::chrono::steady_clock::now();
    if (live->posted || now - live->lastPost < std::chrono::milliseconds(kLiveIntervalMs)) return;
    live->posted = true;
    live->lastPost = now;
    QMetaObject::invokeMethod(
        this, [this] { drainLive(); }, Qt::QueuedConnection);
  };
  m_jobs->start(JobKind::Fit,
                [this, fn, prepared, candidate, index, onStep](ProgressSink&, CancelToken& cancel) {
                  auto outcome = std::make_shared<const FitOutcome>(fn(*prepared, candidate, cancel, onStep));
                  return std::function<void()>([this, outcome, index] {
                    m_outcome = outcome;
                    m_fittedIndex = index;
                    showOutcome(*outcome);
                  });
                });
}

void FitPanel::drainLive() {
  if (!m_live) return;
  std::vector<std::pair<int, double>> points;
  std::shared_ptr<const Image> residual;
  {
    std::lock_guard lock(m_live->mutex);
    points.swap(m_live->points);
    residual = std::move(m_live->residual);
    m_live->residual.reset();
    m_live->posted = false;
  }
  for (const auto& [it, cost] : points) {
    if (m_cost->graph(0)->dataCount() == 0) m_cost0 = cost;
    m_cost->graph(0)->addData(it, m_cost0 > 0.0 ? 100.0 * (cost / m_cost0 - 1.0) : 0.0);
  }
  rescaleCost();
  m_cost->replot(QCustomPlot::rpQueuedReplot);
  if (residual) m_residual->setTiles({{residual, "residual (live)", false}});
  if (!points.empty())
    m_status->setText(
        QString("Fitting… iteration %1, cost %2").arg(points.back().first).arg(num(points.back().second)));
}

void FitPanel::showOutcome(const FitOutcome& out) {
  drainLive();
  m_live.reset();
  const fit::FitResult& r = out.result;
  // The complete history (the live points were throttled, never dropped, but this is the reference).
  QVector<double> x, y;
  if (!r.costHistory.empty()) m_cost0 = r.costHistory.front();
  for (std::size_t i = 0; i < r.costHistory.size(); ++i) {
    x.push_back(static_cast<double>(i));
    y.push_back(m_cost0 > 0.0 ? 100.0 * (r.costHistory[i] / m_cost0 - 1.0) : 0.0);
  }
  if (!r.costHistory.empty()) m_cost->graph(0)->setData(x, y, true);
  rescaleCost();
  m_cost->replot();
  auto shared = [](const Image& im) { return std::make_shared<const Image>(im); };
  if (!r.residualStack.empty())
    m_residual->setTiles({{shared(r.dataStack), "data", false},
                          {shared(r.modelStack), "model", false},
                          {shared(r.residualStack), "residual", false}});
  fillTable(out);
  QString status = QString("%1 after %2 iterations").arg(fit::toString(r.status)).arg(r.iterations);
  if (!r.message.empty()) status += ": " + QString::fromStdString(r.message);
  for (const auto& w : r.warnings)
    status += "\n⚠ " + QString::fromStdString(w);
  m_status->setText(status);
  m_accept->setEnabled(true);
}

void FitPanel::fillTable(const FitOutcome& out) {
  const fit::FitResult& r = out.result;
  const auto& p = r.params;
  m_table->setRowCount(0);
  auto row = [this](const QString& name, const QString& value, const QString& nm = {},
                    const QString& hess = {},
                    const QString& paper = {}) { appendRow(m_table, name, value, nm, hess, paper); };
  const auto& nm = r.sigmaNoiseModel;
  const auto& h = r.sigma;
  row("vx [px/s]", num(p.v.vx, 6), num(nm[fit::kVx]), num(h[fit::kVx]), num(r.sigmaVelPaper) + " (vel_snr)");
  row("vy [px/s]", num(p.v.vy, 6), num(nm[fit::kVy]), num(h[fit::kVy]), num(r.sigmaVelPaper) + " (vel_snr)");
  row("x [px] at t_ref", num(p.xc, 7), num(nm[fit::kXc]), num(h[fit::kXc]),
      num(r.sigmaPosPaper) + " (eq:sig)");
  row("y [px] at t_ref", num(p.yc, 7), num(nm[fit::kYc]), num(h[fit::kYc]),
      num(r.sigmaPosPaper) + " (eq:sig)");
  appendMotionRows(m_table, *m_obs, p.xc, p.yc, p.v, nm[fit::kVx], nm[fit::kVy]);
  row("α [counts/frame]", num(p.alpha), num(nm[fit::kAlpha]), num(h[fit::kAlpha]));
  row("I0 [counts]", num(p.i0), num(nm[fit::kI0]), num(h[fit::kI0]));
  row("σ_xy from SNR [px]", "", "", "", num(r.sigmaPosSnr) + " (cent_snr)");
  row("photons / frame", num(r.photonsPerFrame));
  row("SNR (detection_snr)", num(r.snr));
  const auto& result = m_obs->result();
  if (result && result->trials.total() > 0) {
    const auto& t = result->trials;
    row("FAP: expected false alarms (Prob_false)", num(stats::detectionFap(r.snr, t.nx, t.ny, t.nvx, t.nvy), 3), "", "",
        QString("%1 trials").arg(t.total(), 0, 'g', 3));
  }
  row("frames inside / used", QString("%1 / %2").arg(r.framesInside).arg(r.framesUsed));
  row("reduced χ²", num(r.reducedChi2));
  appendSegmentRows(m_table, out.summary.segments);
  if (const auto& sky = out.summary.sky) {
    row("RA [deg] at t_ref", QString::number(sky->raDeg, 'f', 6));
    row("Dec [deg] at t_ref", QString::number(sky->decDeg, 'f', 6));
    row("rate [arcsec/min]", num(sky->rateArcsecPerMin));
  }
}

void FitPanel::showSelectedFit() {
  if (m_runningIndex >= 0 || !m_obs->selected()) return;
  const int index = *m_obs->selected();
  if (m_outcome && m_fittedIndex == index) return fillTable(*m_outcome);
  const session::CandidateState* state = m_obs->candidateState(index);
  if (state && state->fit) fillStoredTable(index, *state->fit);
}

void FitPanel::fillStoredTable(int index, const candidate::FitSummary& fit) {
  m_table->setRowCount(0);
  auto row = [this](const QString& name, const QString& value, const QString& nm = {},
                    const QString& paper = {}) { appendRow(m_table, name, value, nm, {}, paper); };
  const auto& s = fit.sigma;
  row("vx [px/s]", num(fit.v.vx, 6), num(s.vxPxS), num(s.velPaperPxS) + " (vel_snr)");
  row("vy [px/s]", num(fit.v.vy, 6), num(s.vyPxS), num(s.velPaperPxS) + " (vel_snr)");
  row("x [px] at t_ref", num(fit.x, 7), num(s.xPx), num(s.posPaperPx) + " (eq:sig)");
  row("y [px] at t_ref", num(fit.y, 7), num(s.yPx), num(s.posPaperPx) + " (eq:sig)");
  appendMotionRows(m_table, *m_obs, fit.x, fit.y, fit.v, s.vxPxS, s.vyPxS);
  row("photons / frame", num(fit.photonsPerFrame));
  row("SNR (detection_snr)", num(fit.snr));
  appendSegmentRows(m_table, fit.segments);
  if (const auto& sky = fit.sky) {
    row("RA [deg] at t_ref", QString::number(sky->raDeg, 'f', 6));
    row("Dec [deg] at t_ref", QString::number(sky->decDeg, 'f', 6));
    row("rate [arcsec/min]", num(sky->rateArcsecPerMin));
  }
  m_status->setText(QString("The fit accepted on candidate %1 (%2, %3 iterations), as kept in the session; "
                            "Fit (F) fits it again for the plots.")
                        .arg(index + 1)
                        .arg(QString::fromStdString(fit::toString(fit.status)))
                        .arg(fit.iterations));
}

void FitPanel::accept() {
  if (!m_outcome || m_fittedIndex < 0) return;
  m_obs->setCandidateFit(m_fittedIndex, m_outcome->summary);
  m_status->setText(QString("Fit stored on candidate %1.").arg(m_fittedIndex + 1));
  updateTitle();
  emit accepted(m_fittedIndex);
}

}  // namespace st::ui
