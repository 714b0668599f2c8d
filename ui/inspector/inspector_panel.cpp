#include "inspector_panel.hpp"

#include <qcustomplot.h>
#include <QCheckBox>
#include <QGridLayout>
#include <QHBoxLayout>
#include <QLabel>
#include <QRadioButton>
#include <QVBoxLayout>
#include <QtConcurrent>
#include <cmath>

#include "motion_vs_sky.hpp"

namespace st::ui {

InspectorPanel::InspectorPanel(Observation* observation, StackScrubber* scrubber,
                               const CoreServices* services, QWidget* parent)
    : QWidget(parent), m_obs(observation), m_scrubber(scrubber), m_services(services) {
  m_ipsa = new QRadioButton("IPSA", this);
  m_csa = new QRadioButton("CSA", this);
  m_ipsa->setChecked(true);
  m_ipsa->setToolTip("Integrated-pixel shift-and-add: sum of the frames shifted along the velocity");
  m_csa->setToolTip("Cumulative shift-and-add (paper's CSA)");
  m_unfiltered = new QCheckBox("unfiltered", this);
  m_unfiltered->setToolTip("Stack the frames before the matched filter");
  auto* modes = new QHBoxLayout;
  modes->addWidget(new QLabel("Stack:", this));
  modes->addWidget(m_ipsa);
  modes->addWidget(m_csa);
  modes->addSpacing(12);
  modes->addWidget(m_unfiltered);
  modes->addStretch(1);

  m_skyView = new ImageView(this);
  m_trackView = new ImageView(this);
  for (auto* v : {m_skyView, m_trackView}) {
    v->setMinimumSize(140, 140);
    v->setPlaceholder("select a candidate or click the image");
    DisplaySettings d;
    d.colormap = Colormap::Inferno;
    d.limits = LimitsMode::MinMax;
    v->setDisplaySettings(d);
  }
  m_skyLabel = new QLabel("tracking the sky", this);
  m_trackLabel = new QLabel("tracking the candidate", this);
  auto* stamps = new QGridLayout;
  stamps->addWidget(m_skyLabel, 0, 0);
  stamps->addWidget(m_trackLabel, 0, 1);
  stamps->addWidget(m_skyView, 1, 0);
  stamps->addWidget(m_trackView, 1, 1);

  m_profile = new QCustomPlot(this);
  m_profile->setMinimumHeight(170);
  m_profile->addGraph();
  m_profile->graph(0)->setLineStyle(QCPGraph::lsNone);
  m_profile->graph(0)->setScatterStyle(QCPScatterStyle(QCPScatterStyle::ssDisc, QColor(40, 90, 200), 4));
  m_profile->graph(0)->setName("pixels");
  m_profile->addGraph();
  m_profile->graph(1)->setPen(QPen(QColor(220, 60, 40), 2));
  m_profile->graph(1)->setName("Moffat fit");
  m_profile->xAxis->setLabel("radius [px]");
  m_profile->yAxis->setLabel("value");
  m_profile->legend->setVisible(true);
  m_profile->legend->setFont(QFont(font().family(), 8));
  m_profileLabel = new QLabel("Click a point in the image for its radial profile.", this);
  m_profileLabel->setWordWrap(true);

  auto* layout = new QVBoxLayout(this);
  layout->setContentsMargins(2, 2, 2, 2);
  layout->addLayout(modes);
  layout->addLayout(stamps, 1);
  layout->addWidget(m_profile, 1);
  layout->addWidget(m_profileLabel);

  connect(m_ipsa, &QRadioButton::toggled, this, [this](bool ipsa) {
    m_obs->setStackMode(ipsa ? search::StackMode::Ipsa : search::StackMode::Csa);
  });
  connect(m_obs, &Observation::stackModeChanged, this, [this] {
    const QSignalBlocker block(m_ipsa);
    (m_obs->stackMode() == search::StackMode::Ipsa ? m_ipsa : m_csa)->setChecked(true);
    requestStamps();
  });
  connect(m_unfiltered, &QCheckBox::toggled, this, [this] {
    emit cubeChoiceChanged();
    requestStamps();
  });
  connect(m_obs, &Observation::velocityChanged, this, &InspectorPanel::requestStamps);
  connect(m_obs, &Observation::preparedChanged, this, [this] {
    const auto& p = m_obs->prepared();
    m_unfiltered->setEnabled(p && p->unfiltered);
    m_skyView->clear();
    m_trackView->clear();
  });
  connect(m_obs, &Observation::selectionChanged, this, [this] {
    if (const auto* c = m_obs->selectedCandidate()) setPoint(c->x, c->y);
  });
  connect(m_scrubber, &StackScrubber::stackReady, this,
          [this](const std::shared_ptr<const Image>& image, const StackRequest& req, double, double) {
            onStack(image, req);
          });
  connect(&m_profileWatcher, &QFutureWatcher<ProfileFit>::finished, this, [this] {
    const ProfileFit fit = m_profileWatcher.result();
    QVector<double> r(fit.radiusPx.begin(), fit.radiusPx.end()), v(fit.value.begin(), fit.value.end());
    QVector<double> fr(fit.fitRadiusPx.begin(), fit.fitRadiusPx.end()),
        fv(fit.fitValue.begin(), fit.fitValue.end());
    m_profile->graph(0)->setData(r, v);
    m_profile->graph(1)->setData(fr, fv);
    m_profile->rescaleAxes();
    m_profile->replot();
    m_profileLabel->setText(fit.ok ? QString("(%1, %2): FWHM %3 px, β %4  %5")
                                         .arg(fit.centreX + m_profileOffset.x(), 0, 'f', 1)
                                         .arg(fit.centreY + m_profileOffset.y(), 0, 'f', 1)
                                         .arg(fit.fwhmPx, 0, 'f', 2)
                                         .arg(fit.beta, 0, 'f', 2)
                                         .arg(QString::fromStdString(fit.message))
                                   : "No fit: " + QString::fromStdString(fit.message));
  });
  m_unfiltered->setEnabled(false);
}

bool InspectorPanel::useUnfiltered() const {
  return m_unfiltered->isChecked() && m_unfiltered->isEnabled();
}

std::shared_ptr<const search::FilteredCube> InspectorPanel::stackCube() const {
  const auto& p = m_obs->prepared();
  if (!p || !p->outOfCore.empty()) return nullptr;  // out of core: no cube in memory to stack
  return useUnfiltered() && p->unfiltered ? p->unfiltered : p->filtered;
}

void InspectorPanel::setPoint(double x, double y) {
  m_px = x;
  m_py = y;
  requestStamps();
}

void InspectorPanel::requestStamps() {
  if (const auto& p = m_obs->prepared(); p && !p->outOfCore.empty()) {
    m_trackLabel->setText("Stamps unavailable out of core (they need the cube in memory)");
    return;
  }
  const auto cube = stackCube();
  if (!cube || m_px < 0) return;
  m_scrubber->request(cube, m_obs->skyRate(), m_obs->stackMode(), kSkyTag);
  m_scrubber->request(cube, m_obs->velocity(), m_obs->stackMode(), kTrackTag);
  const Velocity v = toShownVsSky(*m_obs, m_obs->velocity());  // as the table and the map (motion_vs_sky.hpp)
  m_trackLabel->setText(QString("tracking (%1, %2) %3 vs sky")
                            .arg(v.vx, 0, 'g', 3)
                            .arg(v.vy, 0, 'g', 3)
                            .arg(unitLabel(shownUnit(*m_obs))));
}

std::shared_ptr<const Image> InspectorPanel::cutout(const Image& full) const {
  const int cx = static_cast<int>(std::lround(m_px));
  const int cy = static_cast<int>(std::lround(m_py));
  auto out = std::make_shared<Image>(2 * kStampHalf + 1, 2 * kStampHalf + 1, 0.0f);
  for (int y = 0; y < out->height; ++y)
    for (int x = 0; x < out->width; ++x) {
      const int sx = cx - kStampHalf + x;
      const int sy = cy - kStampHalf + y;
      if (full.contains(sx, sy)) out->at(x, y) = full.at(sx, sy);
    }
  return out;
}

void InspectorPanel::onStack(const std::shared_ptr<const Image>& image, const StackRequest& req) {
  if ((req.tag != kSkyTag && req.tag != kTrackTag) || !image || m_px < 0) return;
  auto stamp = cutout(*image);
  (req.tag == kSkyTag ? m_skyView : m_trackView)->setImage(stamp);
  if (req.tag == kTrackTag)
    showProfile(stamp, kStampHalf, kStampHalf, std::lround(m_px) - kStampHalf,
                std::lround(m_py) - kStampHalf);
}

void InspectorPanel::showProfile(std::shared_ptr<const Image> image, double x, double y, double offsetX,
                                 double offsetY) {
  if (!m_services->radialProfile || !image || m_profileWatcher.isRunning()) return;
  m_profileOffset = QPointF(offsetX, offsetY);
  auto fn = m_services->radialProfile;
  m_profileWatcher.setFuture(QtConcurrent::run([fn, image, x, y]() -> ProfileFit {
    try {
      return fn(*image, x, y);
    } catch (const std::exception& e) {
      ProfileFit f;
      f.message = e.what();
      return f;
    }
  }));
}

}  // namespace st::ui
