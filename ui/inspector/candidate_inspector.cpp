#include "candidate_inspector.hpp"

#include <QCheckBox>
#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QFileInfo>
#include <QGroupBox>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QPushButton>
#include <QSettings>
#include <QSlider>
#include <QStyle>
#include <QToolButton>
#include <QTreeWidget>
#include <QVBoxLayout>
#include <QtConcurrent>
#include <exception>

#include "motion_vs_sky.hpp"
#include "stamp_strip.hpp"
#include "st/common/error.hpp"

namespace st::ui {
namespace {

QString kindLabel(vet::ArtifactKind kind) {
  switch (kind) {
    case vet::ArtifactKind::ChargeLeakage:
      return "charge leakage";
    case vet::ArtifactKind::BrightStar:
      return "bright star";
    case vet::ArtifactKind::Diffraction:
      return "diffraction spike";
    case vet::ArtifactKind::Edge:
      return "edge";
    case vet::ArtifactKind::Masked:
      return "masked pixels";
    case vet::ArtifactKind::Transient:
      return "transient";
    case vet::ArtifactKind::KnownObject:
      return "known object";
    case vet::ArtifactKind::StaticSource:
      return "static source (sky-rate SNR)";
  }
  return "?";
}

QGroupBox* group(const QString& title, QWidget* parent) {
  auto* g = new QGroupBox(title, parent);
  g->setFlat(true);
  return g;
}

}  // namespace

CandidateInspector::CandidateInspector(Observation* observation, const CoreServices* services,
                                       QWidget* parent)
    : QWidget(parent), m_obs(observation), m_services(services) {
  m_title = new QLabel("No candidate selected.", this);
  m_title->setWordWrap(true);
  m_stamps = new StampStrip(this);
  m_stamps->setObjectName("candidate stamps");  // the figure dialog lists strips by these names
  m_stamps->setPlaceholder("select a candidate");
  m_stamps->setMinimumHeight(120);
  m_stamps->setToolTip(
      "Stacks around the candidate in SNR units, on one scale: at the sky rate (a moving "
      "source streaks) and at the candidate's velocity (it is a point).");
  m_segments = new StampStrip(this);
  m_segments->setObjectName("segment strip");
  m_segments->setMinimumHeight(110);
  m_segments->setToolTip(
      "K = 4 equal-time stacks at the candidate's velocity (paper §4.4, fig_4epoch); a "
      "red frame marks a segment that misses the signal a steady source would give.");
  m_segmentLabel = new QLabel(this);
  m_segmentLabel->setWordWrap(true);
  m_movie = new StampStrip(this);
  m_movie->setObjectName("frame movie");
  m_movie->setMinimumHeight(120);
  m_slider = new QSlider(Qt::Horizontal, this);
  m_slider->setEnabled(false);
  m_play = new QToolButton(this);
  // The style's icons: the "⏸" glyph is missing from common fonts and showed as an empty box.
  m_play->setIcon(style()->standardIcon(QStyle::SP_MediaPlay));
  m_play->setObjectName("inspector.play");
  m_play->setCheckable(true);
  m_play->setToolTip("Play / pause the frames along the track");
  m_frameLabel = new QLabel(this);
  m_status = new QLabel(this);
  m_status->setWordWrap(true);

  auto* stampBox = group("Sky rate | candidate velocity", this);
  (new QVBoxLayout(stampBox))->addWidget(m_stamps);
  auto* segBox = group("Segments", this);
  auto* segLayout = new QVBoxLayout(segBox);
  segLayout->addWidget(m_segments);
  segLayout->addWidget(m_segmentLabel);
  auto* movieBox = group("Frames along the track", this);
  auto* movieLayout = new QVBoxLayout(movieBox);
  movieLayout->addWidget(m_movie, 1);
  auto* controls = new QHBoxLayout;
  controls->addWidget(m_play);
  controls->addWidget(m_slider, 1);
  controls->addWidget(m_frameLabel);
  movieLayout->addLayout(controls);
  QGroupBox* flagBox = buildFlagBox();

  auto* layout = new QVBoxLayout(this);
  layout->setContentsMargins(2, 2, 2, 2);
  layout->addWidget(m_title);
  layout->addWidget(stampBox, 2);
  layout->addWidget(segBox, 2);
  layout->addWidget(movieBox, 2);
  layout->addWidget(flagBox, 2);
  layout->addWidget(m_status);
  connectSignals();
}

QGroupBox* CandidateInspector::buildFlagBox() {
  m_flags = new QTreeWidget(this);
  m_flags->setColumnCount(3);
  m_flags->setHeaderLabels({"check", "result", "evidence"});
  m_flags->setRootIsDecorated(false);
  m_flags->setWordWrap(true);
  m_flags->header()->setSectionResizeMode(0, QHeaderView::ResizeToContents);
  m_flags->header()->setSectionResizeMode(1, QHeaderView::ResizeToContents);
  m_flags->setMinimumHeight(120);
  m_store = new QCheckBox("Store on candidate", this);
  m_store->setToolTip(
      "Keep the flags of every inspected candidate with it (saved in the session). Off: the "
      "flags are shown only, and inspecting changes nothing in the session.");
  m_store->setChecked(QSettings().value("inspector/storeFlags", true).toBool());
  m_evidence = new QLabel(this);
  m_evidence->setWordWrap(true);
  m_evidence->setTextInteractionFlags(Qt::TextSelectableByMouse);
  m_loadKnown = new QPushButton("Load known objects…", this);
  m_loadKnown->setToolTip("CSV with name, ra_deg, dec_deg, epoch_mjd and rates (arcsec/min or deg/day)");
  m_radius = new QDoubleSpinBox(this);
  m_radius->setRange(0.1, 3600.0);
  m_radius->setDecimals(1);
  m_radius->setValue(10.0);
  m_radius->setSuffix(" arcsec");
  m_radius->setToolTip("A known object closer than this to the candidate's sky position at t_ref flags it");
  auto* flagBox = group("Artifact checks", this);
  auto* flagLayout = new QVBoxLayout(flagBox);
  flagLayout->addWidget(m_flags);
  flagLayout->addWidget(m_evidence);
  auto* knownRow = new QHBoxLayout;
  knownRow->addWidget(m_loadKnown);
  knownRow->addWidget(new QLabel("within", this));
  knownRow->addWidget(m_radius);
  knownRow->addStretch(1);
  flagLayout->addWidget(m_store);
  flagLayout->addLayout(knownRow);
  return flagBox;
}

void CandidateInspector::connectSignals() {
  m_playTimer.setInterval(60);
  connect(&m_playTimer, &QTimer::timeout, this,
          [this] { m_slider->setValue((m_slider->value() + 1) % (m_slider->maximum() + 1)); });
  connect(m_play, &QToolButton::toggled, this, &CandidateInspector::setPlaying);
  connect(m_slider, &QSlider::valueChanged, this, &CandidateInspector::showFrame);
  connect(m_flags, &QTreeWidget::currentItemChanged, this, [this](QTreeWidgetItem* item) {
    if (item) m_evidence->setText(item->text(0) + ": " + item->text(2));
  });
  connect(m_loadKnown, &QPushButton::clicked, this, &CandidateInspector::chooseKnownObjects);
  connect(m_store, &QCheckBox::toggled, this, [this](bool on) {
    QSettings().setValue("inspector/storeFlags", on);
    if (on) storeFlags();
  });
  connect(m_radius, &QDoubleSpinBox::valueChanged, this, [this] {
    if (m_known) refresh();
  });
  connect(&m_watcher, &QFutureWatcher<Outcome>::finished, this, &CandidateInspector::onFinished);
  connect(m_obs, &Observation::selectionChanged, this, &CandidateInspector::refresh);
  connect(m_obs, &Observation::unitChanged, this, &CandidateInspector::updateTitle);
  connect(m_obs, &Observation::resultChanged, this, [this] {
    m_shown.reset();
    m_shownIndex = -1;
    m_stamps->clear();
    m_segments->clear();
    m_movie->clear();
    m_flags->clear();
    m_slider->setEnabled(false);
    setPlaying(false);
    m_title->setText("No candidate selected.");
    m_evidence->clear();
  });
}

CandidateInspector::~CandidateInspector() {
  // The worker holds its inputs through shared pointers and never touches this widget: no need to wait.
  if (m_cancel) m_cancel->cancel();
}

QString CandidateInspector::titleText() const {
  return m_title->text();
}

QString CandidateInspector::statusText() const {
  return m_status->text();
}

void CandidateInspector::refresh() {
  if (m_watcher.isRunning()) {
    m_restart = true;
    if (m_cancel) m_cancel->cancel();
    return;
  }
  start();
}

void CandidateInspector::updateTitle() {
  const auto* c = m_obs->selectedCandidate();
  if (!c) return;
  // The motion relative to the stars, in the Search dock's unit, as the candidates table (motion_vs_sky.hpp).
  m_title->setText(QString("Candidate %1: SNR %2, %3, at (%4, %5) px")
                       .arg(*m_obs->selected() + 1)
                       .arg(c->snr, 0, 'f', 1)
                       .arg(describeMotionWithComponents(motionVsSky(*m_obs, c->x, c->y, c->v)))
                       .arg(c->x)
                       .arg(c->y));
}

void CandidateInspector::start() {
  m_restart = false;
  const auto* c = m_obs->selectedCandidate();
  const auto& prepared = m_obs->prepared();
  if (!c || !prepared || !prepared->filtered) return;
  if (!prepared->outOfCore.empty()) {
    m_status->setText("Unavailable out of core: the segment check, artifact flags and movie need the cube in "
                      "memory.");
    return;
  }
  InspectionInput in;
  in.filtered = prepared->filtered;
  if (prepared->unfiltered)
    in.movieFrames = std::shared_ptr<const FrameCube>(prepared->unfiltered, &prepared->unfiltered->frames);
  in.candidate = *c;
  if (prepared->products) in.stars = prepared->products->stars;
  in.knownObjects = m_known;
  in.knownObjectRadiusArcsec = m_radius->value();
  // The sky position of the candidate at t_ref: a FITS WCS belongs to the first frame, the stars have moved
  // by the sky rate since then and sit at that frame's registration offset (dithers; as
  // st::astro::skyMeasurement). One call: cheap on this thread.
  const auto& raw = m_obs->raw();
  if (m_known && raw && m_services && m_services->pixelToSky && raw->frameCount() > 0 &&
      !prepared->filtered->frames.info().empty()) {
    const double first = raw->timeOffsetsS().front();
    const Velocity sky = m_obs->skyRate();
    const FrameInfo& registered = prepared->filtered->frames.info().front();
    try {
      in.skyPosition = m_services->pixelToSky(*raw, c->x + sky.vx * first + registered.offsetXPx,
                                              c->y + sky.vy * first + registered.offsetYPx);
    } catch (const std::exception&) {
      // outside the projection: the known-object check says the candidate has no sky position
    }
  }
  const int index = *m_obs->selected();
  updateTitle();
  m_status->setText("Inspecting…");
  m_clock.start();
  m_cancel = std::make_shared<CancelToken>();
  auto cancel = m_cancel;
  m_pending = true;
  m_watcher.setFuture(QtConcurrent::run([in = std::move(in), cancel, index]() -> Outcome {
    Outcome out;
    out.index = index;
    try {
      out.inspection = std::make_shared<const Inspection>(candidate::inspectCandidate(in, *cancel));
    } catch (const Cancelled&) {
      out.cancelled = true;
    } catch (const std::exception& e) {
      out.error = QString::fromStdString(e.what());
    }
    return out;
  }));
}

void CandidateInspector::onFinished() {
  const Outcome out = m_watcher.result();
  m_pending = false;
  if (m_restart) {
    start();
    return;
  }
  if (out.cancelled) return;
  if (!out.error.isEmpty()) {
    m_status->setText("Inspection failed: " + out.error);
    return;
  }
  if (!out.inspection || !m_obs->selected() || *m_obs->selected() != out.index) return;
  m_shown = out.inspection;
  m_shownIndex = out.index;
  showInspection(*m_shown);
  const bool stored = m_store->isChecked() && storeFlags();
  int fired = 0;
  for (const auto& f : m_shown->flags)
    fired += f.triggered ? 1 : 0;
  const QString took = QString(" (%1 s)").arg(m_clock.elapsed() / 1000.0, 0, 'f', 2);
  m_status->setText(
      (fired ? QString("%1 artifact check(s) fired").arg(fired) : QString("No artifact check fired")) +
      (stored ? "; stored on the candidate" : "") + took);
  emit inspected(out.index);
}

bool CandidateInspector::storeFlags() {
  if (!m_shown || m_shownIndex < 0) return false;
  const std::vector<vet::ArtifactFlag>& flags = m_shown->flags;
  const auto* state = m_obs->candidateState(m_shownIndex);
  if (!state) return false;
  if (state->artifacts != flags) m_obs->setCandidateArtifacts(m_shownIndex, flags);
  return true;
}

void CandidateInspector::setStoreFlags(bool on) {
  m_store->setChecked(on);
}

bool CandidateInspector::storesFlags() const {
  return m_store->isChecked();
}

void CandidateInspector::showInspection(const Inspection& in) {
  auto shared = [](const Image& im) { return std::make_shared<const Image>(im); };
  m_stamps->setTiles(
      {{shared(in.skyStamp), QString("sky rate\nSNR %1").arg(in.skySnr, 0, 'f', 1), false},
       {shared(in.trackStamp), QString("candidate\nSNR %1").arg(in.trackSnr, 0, 'f', 1), false}});
  std::vector<StampStrip::Tile> tiles;
  for (const auto& s : in.segments.segments)
    tiles.push_back({shared(s.stack),
                     QString("#%1 SNR %2\nexp. %3")
                         .arg(s.index + 1)
                         .arg(s.forcedSnr, 0, 'f', 1)
                         .arg(s.expectedSnr, 0, 'f', 1),
                     s.missing});
  m_segments->setTiles(std::move(tiles));
  QString seg = QString("Flux consistency: χ² %1 for %2 dof, p = %3.")
                    .arg(in.segments.fluxChi2, 0, 'f', 1)
                    .arg(in.segments.fluxDof)
                    .arg(in.segments.fluxProbability, 0, 'g', 2);
  for (const auto& r : in.segments.reasons)
    seg += "\n⚠ " + QString::fromStdString(r);
  m_segmentLabel->setText(seg);

  std::vector<const Image*> frames;
  for (const auto& m : in.movie)
    frames.push_back(&m);
  m_movie->setFixedLimits(commonLimits(
      frames, DisplaySettings{Stretch::Linear, LimitsMode::Percentile, 99.5, Colormap::Inferno}));
  const QSignalBlocker block(m_slider);
  m_slider->setRange(0, std::max(0, static_cast<int>(in.movie.size()) - 1));
  m_slider->setValue(0);
  m_slider->setEnabled(!in.movie.empty());
  showFrame(0);

  m_flags->clear();
  QStringList fired;
  for (const auto& f : in.flags) {
    if (f.triggered) fired << "⚠ " + kindLabel(f.kind) + ": " + QString::fromStdString(f.evidence);
    auto* item = new QTreeWidgetItem(
        m_flags, {kindLabel(f.kind), f.triggered ? "⚠ flagged" : "ok", QString::fromStdString(f.evidence)});
    item->setToolTip(2, QString::fromStdString(f.evidence));
    if (f.triggered) item->setForeground(1, QColor(220, 40, 40));
  }
  m_evidence->setText(fired.isEmpty() ? "Every check passed; select one for its evidence."
                                      : fired.join('\n'));
}

void CandidateInspector::showFrame(int k) {
  if (!m_shown || k < 0 || k >= static_cast<int>(m_shown->movie.size())) return;
  // A strip of kMovieTiles consecutive cutouts with frame k in it (in the middle away from the ends).
  const int n = static_cast<int>(m_shown->movie.size());
  const int count = std::min(n, kMovieTiles);
  const int first = std::clamp(k - count / 2, 0, n - count);
  std::vector<StampStrip::Tile> tiles;
  for (int j = first; j < first + count; ++j) {
    const auto i = static_cast<std::size_t>(j);
    tiles.push_back({std::make_shared<const Image>(m_shown->movie[i]),
                     QString("%1%2\n%3 s")
                         .arg(j == k ? "▶ " : "")
                         .arg(m_shown->movieFrameIndex[i])
                         .arg(m_shown->movieTimeS[i], 0, 'f', 2),
                     false});
  }
  m_movie->setTiles(std::move(tiles));
  m_movieCurrent = k - first;
  m_frameLabel->setText(QString("%1 / %2").arg(k + 1).arg(n));
}

void CandidateInspector::setPlaying(bool on) {
  if (on && (!m_shown || m_shown->movie.empty())) on = false;
  if (on)
    m_playTimer.start();
  else
    m_playTimer.stop();
  const QSignalBlocker block(m_play);
  m_play->setChecked(on);
  m_play->setIcon(style()->standardIcon(on ? QStyle::SP_MediaPause : QStyle::SP_MediaPlay));
  m_play->setToolTip(on ? "Pause the frames along the track" : "Play the frames along the track");
}

void CandidateInspector::chooseKnownObjects() {
  const QString path = QFileDialog::getOpenFileName(this, "Load known objects",
                                                    QSettings().value("knownObjectsDir").toString(),
                                                    "CSV (*.csv *.txt);;All files (*)");
  if (path.isEmpty()) return;
  QSettings().setValue("knownObjectsDir", QFileInfo(path).absolutePath());
  loadKnownObjects(path);
}

void CandidateInspector::loadKnownObjects(const QString& path) {
  m_status->setText("Reading " + path + "…");
  auto* watcher =
      new QFutureWatcher<std::pair<std::shared_ptr<std::vector<vet::KnownObject>>, QString>>(this);
  connect(watcher, &QFutureWatcherBase::finished, this, [this, watcher, path] {
    const auto [objects, error] = watcher->result();
    watcher->deleteLater();
    if (!objects) {
      m_status->setText("Known objects not loaded: " + error);
      emit knownObjectsFailed(error);
      return;
    }
    m_known = objects;
    m_knownPath = path;
    m_status->setText(
        QString("%1 known objects from %2").arg(objects->size()).arg(QFileInfo(path).fileName()));
    emit knownObjectsLoaded(static_cast<int>(objects->size()));
    refresh();
  });
  watcher->setFuture(QtConcurrent::run([p = path.toStdString()] {
    std::pair<std::shared_ptr<std::vector<vet::KnownObject>>, QString> out;
    try {
      out.first = std::make_shared<std::vector<vet::KnownObject>>(vet::readKnownObjects(p));
    } catch (const std::exception& e) {
      out.second = QString::fromStdString(e.what());
    }
    return out;
  }));
}

}  // namespace st::ui
