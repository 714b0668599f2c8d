#include "figure_dialog.hpp"

#include <QCheckBox>
#include <QComboBox>
#include <QDialogButtonBox>
#include <QDockWidget>
#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QFileInfo>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QLabel>
#include <QLineEdit>
#include <QPushButton>
#include <QSettings>
#include <QSpinBox>
#include <QVBoxLayout>
#include <QtConcurrent>
#include <qcustomplot.h>
#include <cmath>

#include "candidate_sheet.hpp"
#include "figure_preset.hpp"
#include "motion_vs_sky.hpp"
#include "st/common/error.hpp"
#include "image_view.hpp"
#include "stamp_strip.hpp"

namespace st::ui {
namespace {

constexpr double kPt = 72.0;  // points per inch

QString dockTitle(const QWidget* w) {
  for (const QWidget* p = w; p; p = p->parentWidget())
    if (const auto* d = qobject_cast<const QDockWidget*>(p)) return d->windowTitle();
  return "Window";
}

// The image pixels visible in `view` (clipped to the image), or the whole image.
QRect visibleRect(const ImageView& view, bool crop) {
  const Image& img = *view.image();
  const QRect whole(0, 0, img.width, img.height);
  if (!crop) return whole;
  const QPointF a = view.widgetToImage(QPointF(0, 0));
  const QPointF b = view.widgetToImage(QPointF(view.width(), view.height()));
  const int x0 = static_cast<int>(std::floor(std::min(a.x(), b.x()) + 0.5));
  const int x1 = static_cast<int>(std::ceil(std::max(a.x(), b.x()) - 0.5));
  const int y0 = static_cast<int>(std::floor(std::min(a.y(), b.y()) + 0.5));
  const int y1 = static_cast<int>(std::ceil(std::max(a.y(), b.y()) - 0.5));
  const QRect r = QRect(QPoint(x0, y0), QPoint(x1, y1)).intersected(whole);
  return r.width() >= 4 && r.height() >= 4 ? r : whole;
}

}  // namespace

FigureDialog::FigureDialog(Context context, QWidget* parent) : QDialog(parent), m_ctx(std::move(context)) {
  setWindowTitle("Export figure");
  buildUi();
  connect(&m_watcher, &QFutureWatcher<QString>::finished, this, &FigureDialog::onFinished);
  refreshSources();
}

void FigureDialog::buildUi() {
  auto* form = new QFormLayout;
  m_source = new QComboBox(this);
  m_title = new QLineEdit(this);
  m_units = new QLineEdit(this);
  m_units->setToolTip("Label of the colour bar: the units of the image values");
  m_xLabel = new QLineEdit("x [px]", this);
  m_yLabel = new QLineEdit("y [px]", this);
  auto* checks = new QHBoxLayout;
  m_colourBar = new QCheckBox("colour bar", this);
  m_scaleBar = new QCheckBox("scale bar (arcsec)", this);
  m_compass = new QCheckBox("N/E compass", this);
  m_axes = new QCheckBox("axes", this);
  m_crop = new QCheckBox("visible area only", this);
  for (auto* c : {m_colourBar, m_scaleBar, m_compass, m_axes, m_crop}) {
    c->setChecked(true);
    checks->addWidget(c);
  }
  m_width = new QDoubleSpinBox(this);
  m_width->setRange(1.0, 40.0);
  m_width->setSuffix(" in");
  m_height = new QDoubleSpinBox(this);
  m_height->setRange(0.0, 40.0);
  m_height->setSuffix(" in");
  m_height->setSpecialValueText("from the figure");
  m_dpi = new QSpinBox(this);
  m_dpi->setRange(50, 2400);
  m_dpi->setSuffix(" dpi");
  m_dpi->setToolTip("PNG resolution; SVG and PDF are vector (images keep their pixels)");
  QSettings settings;
  m_width->setValue(settings.value("figure/widthIn", 7.0).toDouble());
  m_height->setValue(0.0);
  m_dpi->setValue(settings.value("figure/dpi", 300).toInt());
  m_stampHalf = new QSpinBox(this);
  m_stampHalf->setRange(8, 500);
  m_stampHalf->setValue(40);
  m_stampHalf->setSuffix(" px");
  m_stampHalf->setToolTip("Preset and candidate sheets: half size of each stamp around the candidate");
  connect(m_stampHalf, &QSpinBox::valueChanged, this, [this](int v) {
    const int i = m_source->currentIndex();
    const bool sheet = i >= 0 && i < static_cast<int>(m_sources.size()) &&
                       m_sources[static_cast<std::size_t>(i)].sheet != Source::Sheet::None;
    (sheet ? m_sheetHalf : m_presetHalf) = v;
  });
  auto* sizeRow = new QHBoxLayout;
  for (QWidget* w : std::initializer_list<QWidget*>{m_width, new QLabel("×", this), m_height, m_dpi})
    sizeRow->addWidget(w);
  m_path = new QLineEdit(settings.value("figure/lastPath", "figure.png").toString(), this);
  auto* browse = new QPushButton("Browse…", this);
  auto* pathRow = new QHBoxLayout;
  pathRow->addWidget(m_path, 1);
  pathRow->addWidget(browse);
  form->addRow("Source", m_source);
  form->addRow("Title", m_title);
  form->addRow("Colour bar units", m_units);
  form->addRow("Axis labels", [&] {
    auto* row = new QHBoxLayout;
    row->addWidget(m_xLabel);
    row->addWidget(m_yLabel);
    return row;
  }());
  form->addRow("Show", checks);
  form->addRow("Size", sizeRow);
  form->addRow("Stamp half size", m_stampHalf);
  form->addRow("File (.png .svg .pdf)", pathRow);
  m_status = new QLabel(this);
  m_status->setWordWrap(true);
  m_status->setTextInteractionFlags(Qt::TextSelectableByMouse);
  auto* buttons = new QDialogButtonBox(QDialogButtonBox::Close, this);
  m_export = buttons->addButton("Export", QDialogButtonBox::AcceptRole);
  auto* layout = new QVBoxLayout(this);
  layout->addLayout(form);
  layout->addWidget(m_status);
  layout->addWidget(buttons);
  connect(m_source, &QComboBox::currentIndexChanged, this, &FigureDialog::onSourceChanged);
  connect(buttons, &QDialogButtonBox::rejected, this, &QDialog::reject);
  connect(m_export, &QPushButton::clicked, this, [this] { exportTo(m_path->text()); });
  connect(browse, &QPushButton::clicked, this, [this] {
    const QString path = QFileDialog::getSaveFileName(this, "Export figure", m_path->text(),
                                                      "PNG (*.png);;SVG (*.svg);;PDF (*.pdf)");
    if (!path.isEmpty()) m_path->setText(path);
  });
}

void FigureDialog::showEvent(QShowEvent* event) {
  refreshSources();
  QDialog::showEvent(event);
}

void FigureDialog::refreshSources() {
  const QString previous = m_source->currentText();
  m_sources.clear();
  if (m_ctx.central) m_sources.push_back({"Central view", m_ctx.central, nullptr, false});
  if (m_ctx.root) {
    std::map<QString, int> counts;
    for (ImageView* v : m_ctx.root->findChildren<ImageView*>())
      if (v != m_ctx.central)
        m_sources.push_back(
            {QString("%1: image %2").arg(dockTitle(v)).arg(++counts[dockTitle(v)]), v, nullptr});
    for (QCustomPlot* p : m_ctx.root->findChildren<QCustomPlot*>())
      m_sources.push_back(
          {QString("%1: plot %2").arg(dockTitle(p)).arg(++counts[dockTitle(p) + "/p"]), nullptr, p});
    for (StampStrip* strip : m_ctx.root->findChildren<StampStrip*>()) {
      if (strip->tileCount() == 0) continue;  // nothing shown yet (no candidate inspected or fitted)
      const QString name = strip->objectName().isEmpty() ? QString("stamps %1").arg(++counts[dockTitle(strip) + "/s"])
                                                          : strip->objectName();
      Source source{QString("%1: %2").arg(dockTitle(strip), name), nullptr, nullptr, false};
      source.strip = strip;
      m_sources.push_back(source);
    }
  }
  if (m_ctx.observation && m_ctx.observation->result()) {
    for (const auto which : {Source::Sheet::Selected, Source::Sheet::Shown}) {
      const auto n = sheetCandidates(which).size();
      Source sheet{which == Source::Sheet::Selected
                       ? QString("Sheet: candidates selected in the table (%1)").arg(n)
                       : QString("Sheet: all candidates shown by the table's filters (%1)").arg(n),
                   {}, {}, false};
      sheet.sheet = which;
      m_sources.push_back(sheet);
    }
  }
  m_sources.push_back({"Preset: sky-tracked beside object-tracked (paper fig_st_sky_and_nea)", {}, {}, true});
  const QSignalBlocker block(m_source);
  m_source->clear();
  for (const auto& s : m_sources)
    m_source->addItem(s.name);
  const int again = m_source->findText(previous);
  m_source->setCurrentIndex(again >= 0 ? again : 0);
  onSourceChanged();
}

QStringList FigureDialog::sourceNames() const {
  QStringList names;
  for (const auto& s : m_sources)
    names << s.name;
  return names;
}

int FigureDialog::presetIndex() const {
  return static_cast<int>(m_sources.size()) - 1;
}

int FigureDialog::sheetIndex(bool shown) const {
  const auto want = shown ? Source::Sheet::Shown : Source::Sheet::Selected;
  for (std::size_t i = 0; i < m_sources.size(); ++i)
    if (m_sources[i].sheet == want) return static_cast<int>(i);
  return -1;
}

void FigureDialog::setStampHalfSize(int px) {
  m_stampHalf->setValue(px);
}

std::vector<int> FigureDialog::sheetCandidates(Source::Sheet which) const {
  const Observation* obs = m_ctx.observation;
  std::vector<int> out;
  if (!obs || !obs->result()) return out;
  const int n = static_cast<int>(obs->result()->candidates.size());
  if (which == Source::Sheet::Selected) {
    for (int i : m_ctx.selectedCandidates ? m_ctx.selectedCandidates() : std::vector<int>{})
      if (i >= 0 && i < n) out.push_back(i);
    if (out.empty() && obs->selected() && *obs->selected() < n) out.push_back(*obs->selected());
  } else if (which == Source::Sheet::Shown) {
    for (int i = 0; i < n; ++i)
      if (obs->candidateShown(i)) out.push_back(i);
  }
  return out;
}

void FigureDialog::setSource(int index) {
  m_source->setCurrentIndex(index);
}

void FigureDialog::setTitle(const QString& title) {
  m_title->setText(title);
}

void FigureDialog::setFigureSize(const FigureSize& size) {
  m_width->setValue(size.widthIn);
  m_height->setValue(size.heightIn);
  m_dpi->setValue(static_cast<int>(std::lround(size.dpi)));
}

FigureSize FigureDialog::figureSize() const {
  return {m_width->value(), m_height->value(), static_cast<double>(m_dpi->value())};
}

QString FigureDialog::lastMessage() const {
  return m_status->text();
}

void FigureDialog::onSourceChanged() {
  const int i = m_source->currentIndex();
  if (i < 0 || i >= static_cast<int>(m_sources.size())) return;
  const Source& s = m_sources[static_cast<std::size_t>(i)];
  const bool sheet = s.sheet != Source::Sheet::None;
  const bool image = s.view || s.preset || s.strip || sheet;
  for (QWidget* w : std::initializer_list<QWidget*>{m_units, m_xLabel, m_yLabel, m_colourBar, m_scaleBar,
                                                    m_compass, m_axes})
    w->setEnabled(image);
  m_crop->setEnabled(s.view != nullptr);
  m_stampHalf->setEnabled(s.preset || sheet);
  {
    const QSignalBlocker block(m_stampHalf);
    m_stampHalf->setValue(sheet ? m_sheetHalf : m_presetHalf);
  }
  const auto& raw = m_ctx.observation ? m_ctx.observation->raw() : nullptr;
  // A compass needs the observation's WCS: say so where the choice is made, not by a figure without one.
  const bool hasWcs = raw && raw->wcs && m_ctx.pixelToSky;
  m_compass->setEnabled(image && hasWcs);
  m_compass->setText(hasWcs ? "N/E compass" : "N/E compass (no WCS)");
  m_compass->setToolTip(hasWcs ? "North and East arrows from the observation's WCS"
                               : "The observation has no WCS (CTYPE, CRVAL, CD or CDELT keywords): no "
                                 "compass can be drawn");
  const QString bunit = raw ? QString::fromStdString(raw->header.getString("BUNIT").value_or("ADU")) : "ADU";
  m_title->setPlaceholderText(s.preset ? "default: Synthetic tracking of candidate #N (SNR …)" : QString());
  if (s.preset) {
    m_title->clear();
    m_units->setText("IPSA sum of " + bunit);
  } else if (sheet) {
    m_title->clear();
    m_units->setText("SNR");  // the sheet's stamps are in SNR units, like the inspector's
  } else if (s.strip) {
    m_title->setText(s.name.section(": ", 1));
    m_units->setText("SNR");  // the inspector's stamps are in SNR units; the fit's in counts (edit here)
  } else if (s.view) {
    const QString overlay = s.view->overlayText();
    m_title->setText(overlay);
    m_units->setText(overlay.contains("stack") ? "sum of " + bunit : bunit);
  } else {
    m_title->clear();
  }
}

std::optional<Compass> FigureDialog::compassNear(double x, double y) const {
  const auto& raw = m_ctx.observation ? m_ctx.observation->raw() : nullptr;
  if (!raw || !m_ctx.pixelToSky) return std::nullopt;
  auto toSky = m_ctx.pixelToSky;
  return ui::compassAt([&](double px, double py) { return toSky(*raw, px, py); }, x, y);
}

std::function<ImageFigure()> FigureDialog::imageBuilder(const ImageView& view) {
  ImagePanel p;
  const QRect rect = visibleRect(view, m_crop->isChecked());
  std::tie(p.lo, p.hi) = view.limits();
  p.display = view.displaySettings();
  p.units = m_units->text();
  p.xLabel = m_xLabel->text();
  p.yLabel = m_yLabel->text();
  p.origin = rect.topLeft();
  p.showColourBar = m_colourBar->isChecked();
  p.showScaleBar = m_scaleBar->isChecked();
  p.showCompass = m_compass->isChecked();
  p.showAxes = m_axes->isChecked();
  p.plateScaleArcsecPerPx = m_ctx.observation ? m_ctx.observation->plateScale() : std::nullopt;
  const auto& raw = m_ctx.observation ? m_ctx.observation->raw() : nullptr;
  // The central view shows frame pixels; elsewhere (stamps) the directions at the frame's centre are used.
  const QPointF at = &view == m_ctx.central ? QPointF(rect.center())
                     : raw                  ? QPointF(raw->width() / 2.0, raw->height() / 2.0)
                                            : QPointF();
  p.compass = compassNear(at.x(), at.y());
  for (ImageMarker m : view.markers()) {
    m.pixel -= QPointF(rect.topLeft());
    p.markers.push_back(m);
  }
  const QString title = m_title->text();
  return [p, rect, image = view.image(), title]() mutable {
    p.image = std::make_shared<const Image>(cropImage(*image, rect));
    ImageFigure fig;
    fig.panels.push_back(std::move(p));
    fig.title = title;
    return fig;
  };
}

std::function<ImageFigure()> FigureDialog::presetBuilder(QString& error) {
  const Observation* obs = m_ctx.observation;
  const search::Candidate* c = obs ? obs->selectedCandidate() : nullptr;
  auto cube = m_ctx.stackCube ? m_ctx.stackCube() : nullptr;
  if (!c || !cube) {
    error = "The preset needs a search result with a selected candidate.";
    return {};
  }
  SkyAndObjectOptions o;
  o.halfSizePx = m_stampHalf->value();
  o.display.limits = LimitsMode::ZScale;
  o.plateScaleArcsecPerPx = m_scaleBar->isChecked() ? obs->plateScale() : std::nullopt;
  o.compass = m_compass->isChecked() ? compassNear(c->x, c->y) : std::nullopt;
  o.units = m_units->text();
  o.candidateNumber = *obs->selected() + 1;
  // The accepted fit's track when there is one (its stack, title SNR and motion), else the search cell's.
  const ShownTrack shown = shownTrack(*obs, *obs->selected(), *c);
  o.motion = describeMotion(motionVsSky(*obs, shown.x, shown.y, shown.v));
  o.snrLabel = shown.fitted ? "fit SNR" : "search SNR";
  search::Candidate track = *c;
  track.x = static_cast<int>(std::lround(shown.x));
  track.y = static_cast<int>(std::lround(shown.y));
  track.v = shown.v;
  track.snr = shown.snr;
  const Velocity sky = obs->skyRate();
  const QString title = m_title->text();
  const bool bar = m_colourBar->isChecked(), axes = m_axes->isChecked();
  return [cube, cand = track, sky, o, title, bar, axes] {
    ImageFigure fig = skyAndObjectFigure(*cube, cand, sky, o);
    if (!title.isEmpty()) fig.title = title;
    for (auto& p : fig.panels) {
      p.showColourBar = bar;
      p.showAxes = axes;
    }
    return fig;
  };
}

std::function<ImageFigure()> FigureDialog::stripBuilder(const StampStrip& strip) {
  ImageFigure fig;
  const auto [lo, hi] = strip.limits();
  for (int i = 0; i < strip.tileCount(); ++i) {
    const StampStrip::Tile& tile = strip.tile(i);
    if (!tile.image) continue;
    ImagePanel p;
    p.image = tile.image;
    p.lo = lo;
    p.hi = hi;
    p.display = strip.displaySettings();
    p.title = tile.flagged ? tile.caption + " (flagged)" : tile.caption;
    p.title.replace('\n', ", ");
    p.units = m_units->text();
    p.xLabel = m_xLabel->text();
    p.yLabel = m_yLabel->text();
    p.showColourBar = m_colourBar->isChecked();  // on every panel: the layout gives each the same room
    p.showScaleBar = m_scaleBar->isChecked() && i == 0;
    p.showAxes = m_axes->isChecked();
    p.plateScaleArcsecPerPx = m_ctx.observation ? m_ctx.observation->plateScale() : std::nullopt;
    if (m_compass->isChecked() && i == 0 && m_ctx.observation && m_ctx.observation->selectedCandidate()) {
      const search::Candidate* c = m_ctx.observation->selectedCandidate();
      p.compass = compassNear(c->x, c->y);
    }
    fig.panels.push_back(std::move(p));
  }
  fig.title = m_title->text();
  const Observation* obs = m_ctx.observation;
  if (const search::Candidate* c = obs ? obs->selectedCandidate() : nullptr) {
    const ShownTrack shown = shownTrack(*obs, *obs->selected(), *c);
    fig.caption = QString("Candidate #%1 at (%2, %3) px: %4.")
                      .arg(*obs->selected() + 1)
                      .arg(shown.x, 0, 'f', shown.fitted ? 2 : 0)
                      .arg(shown.y, 0, 'f', shown.fitted ? 2 : 0)
                      .arg(describeShownTrack(*obs, shown));
  }
  return [fig] { return fig; };
}

std::function<ImageFigure()> FigureDialog::sheetBuilder(Source::Sheet which, QString& error) {
  const Observation* obs = m_ctx.observation;
  auto cube = obs && obs->prepared() ? obs->prepared()->filtered : nullptr;
  const std::vector<int> chosen = sheetCandidates(which);
  if (!cube || !obs->result()) {
    error = "A sheet of candidates needs a search result.";
    return {};
  }
  if (!obs->prepared()->outOfCore.empty()) {
    error = "A sheet of candidate stamps needs the cube in memory: unavailable out of core.";
    return {};
  }
  if (chosen.empty()) {
    error = which == Source::Sheet::Selected
                ? "No candidate is selected in the candidates table (Ctrl+click or Shift+click rows)."
                : "The candidates table's filters show no candidate.";
    return {};
  }
  // Names and motions are read here, on the GUI thread (the Observation is the GUI's); the worker stacks.
  std::vector<SheetEntry> entries;
  for (int i : chosen) {
    const search::Candidate& c = obs->result()->candidates[static_cast<std::size_t>(i)];
    const session::CandidateState* state = obs->candidateState(i);
    // The sheet's stamps are stacked at each candidate's search cell: its motion is the cell's too.
    entries.push_back({i + 1, c, describeMotion(motionVsSky(*obs, c.x, c.y, c.v)),
                       state ? QString(session::toString(state->label)) : QString("unvetted")});
  }
  CandidateSheetOptions o;
  o.halfSizePx = m_stampHalf->value();
  o.display.limits = LimitsMode::ZScale;
  o.display.colormap = Colormap::Inferno;
  o.plateScaleArcsecPerPx = m_scaleBar->isChecked() ? obs->plateScale() : std::nullopt;
  o.units = m_units->text();
  o.colourBar = m_colourBar->isChecked();
  o.axes = m_axes->isChecked();
  const QString title = m_title->text();
  return [cube, entries, o, title] {
    CancelToken never;
    ImageFigure fig = candidateSheetFigure(*cube, entries, o, never);
    if (!title.isEmpty()) fig.title = title;
    return fig;
  };
}

std::function<void()> FigureDialog::makeJob(const Source& source, const QString& path, QString& error) {
  const FigureFormat format = figureFormatForPath(path);
  FigureSize size = figureSize();
  if (source.plot) {
    // A plot is a widget: it paints itself here, on the GUI thread (milliseconds), at the screen's DPI its
    // layout was measured at; the worker only reports the outcome.
    QCustomPlot& plot = *source.plot;
    if (size.heightIn <= 0) size.heightIn = size.widthIn * plot.height() / std::max(plot.width(), 1);
    const QString title = m_title->text();
    std::string failure;
    try {
      exportFigure(
          path, format, size, [&](QCPPainter& p, const QSizeF& s) { paintPlot(p, s, plot, title); }, title,
          plot.logicalDpiX());
    } catch (const std::exception& e) {
      failure = e.what();
    }
    return [failure] {
      if (!failure.empty()) throw InputError(failure);
    };
  }
  std::function<ImageFigure()> build;
  if (source.preset)
    build = presetBuilder(error);
  else if (source.view && source.view->image())
    build = imageBuilder(*source.view);
  else if (source.strip && source.strip->tileCount() > 0)
    build = stripBuilder(*source.strip);
  else if (source.sheet != Source::Sheet::None)
    build = sheetBuilder(source.sheet, error);
  else
    error = "The view shows no image.";
  if (!build) return {};
  return [path, format, size, build]() mutable {
    const ImageFigure fig = build();
    if (size.heightIn <= 0) size.heightIn = naturalFigureSize(fig, size.widthIn * kPt).height() / kPt;
    exportFigure(
        path, format, size, [&fig](QCPPainter& p, const QSizeF& pt) { paintImageFigure(p, pt, fig); },
        fig.title);
  };
}

bool FigureDialog::exportTo(const QString& path) {
  const int i = m_source->currentIndex();
  QString error;
  std::function<void()> job;
  if (busy()) {
    error = "An export is running.";
  } else if (i < 0 || i >= static_cast<int>(m_sources.size())) {
    error = "Nothing to export.";
  } else {
    try {
      job = makeJob(m_sources[static_cast<std::size_t>(i)], path, error);
    } catch (const std::exception& e) {
      error = QString::fromStdString(e.what());
    }
  }
  if (!job) {
    m_status->setText("⚠ " + error);
    emit exportFinished(path, false, error);
    return false;
  }
  QSettings settings;
  settings.setValue("figure/lastPath", path);
  settings.setValue("figure/widthIn", m_width->value());
  settings.setValue("figure/dpi", m_dpi->value());
  m_runningPath = path;
  m_path->setText(path);
  m_export->setEnabled(false);
  m_status->setText("Exporting " + path + "…");
  m_watcher.setFuture(QtConcurrent::run([job]() -> QString {
    try {
      job();
      return {};
    } catch (const std::exception& e) {
      return QString::fromStdString(e.what());
    }
  }));
  return true;
}

void FigureDialog::onFinished() {
  const QString error = m_watcher.result();
  m_export->setEnabled(true);
  const bool ok = error.isEmpty();
  const QString message = ok ? "Wrote " + m_runningPath : error;
  m_status->setText(ok ? message : "⚠ " + message);
  emit exportFinished(m_runningPath, ok, message);
}

}  // namespace st::ui
