#include "candidate_table.hpp"

#include <QComboBox>
#include <QDoubleSpinBox>
#include <QDoubleValidator>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QProxyStyle>
#include <QStyleOptionHeader>
#include <QLineEdit>
#include <QTableView>
#include <QVBoxLayout>
#include <cmath>

#include "candidate_vetting.hpp"
#include "motion_vs_sky.hpp"
#include "st/candidate/movers.hpp"

namespace st::ui {

CandidateModel::CandidateModel(Observation* observation, QObject* parent)
    : QAbstractTableModel(parent), m_obs(observation) {}

int CandidateModel::rowCount(const QModelIndex& parent) const {
  if (parent.isValid() || !m_obs->result()) return 0;
  return static_cast<int>(m_obs->result()->candidates.size());
}

int CandidateModel::columnCount(const QModelIndex& parent) const {
  return parent.isValid() ? 0 : ColumnCount;
}

QString CandidateModel::flagsOf(const search::Candidate& c) const {
  QStringList flags;
  if (candidate::isMover(c)) flags << "pre-processing mover";  // not from the search (its SNR: the stack's)
  const auto& raw = m_obs->raw();
  const auto& prepared = m_obs->prepared();
  if (raw) {
    const double fwhm = prepared && prepared->filtered ? prepared->filtered->psfFwhmPx : 3.0;
    const double margin = 2.0 * std::max(fwhm, 1.0);
    if (c.x < margin || c.y < margin || c.x > raw->width() - 1 - margin || c.y > raw->height() - 1 - margin)
      flags << "edge";
    if (c.nIn < static_cast<int>(raw->frameCount())) flags << "partial";
  }
  if (const auto& result = m_obs->result(); result && !result->candidates.empty()) {
    const std::ptrdiff_t i = &c - result->candidates.data();
    if (i >= 0 && static_cast<std::size_t>(i) < m_crossesBrighter.size() && m_crossesBrighter[i])
      flags << "crosses brighter";
  }
  return flags.join(", ");
}

QVariant CandidateModel::vettingData(const session::CandidateState& state, int column, int role) const {
  if (role == Qt::BackgroundRole) {
    const QColor tint = labelColour(state.label, column == Label);
    return tint.isValid() ? QVariant(tint) : QVariant();
  }
  if (role == Qt::DecorationRole && column == Label) {  // a swatch that stays visible on a selected row
    const QColor swatch = labelColour(state.label, true);
    return swatch.isValid() ? QVariant(swatch) : QVariant();
  }
  if (role == Qt::ToolTipRole && column == Note && !state.note.empty())
    return QString::fromStdString(state.note);
  if (role == Qt::ToolTipRole) return vettingShortcutHelp();
  if (role != Qt::DisplayRole && role != Qt::UserRole && role != Qt::EditRole) return {};
  switch (column) {
    case Label:
      return labelText(state.label);
    case Reason:
      return reasonText(state.reason);
    case Note:
      return QString::fromStdString(state.note);
    default:
      return {};
  }
}

Qt::ItemFlags CandidateModel::flags(const QModelIndex& index) const {
  Qt::ItemFlags f = QAbstractTableModel::flags(index);
  if (index.isValid() && index.column() == Note) f |= Qt::ItemIsEditable;
  return f;
}

bool CandidateModel::setData(const QModelIndex& index, const QVariant& value, int role) {
  if (!index.isValid() || index.column() != Note || role != Qt::EditRole) return false;
  m_obs->setCandidateNote(index.row(), value.toString().toStdString());  // candidateStateChanged -> reloadRow
  return true;
}

void CandidateModel::reloadRow(int row) {
  if (row < 0 || row >= rowCount()) return;
  emit dataChanged(index(row, 0), index(row, ColumnCount - 1));
}

QVariant CandidateModel::data(const QModelIndex& index, int role) const {
  if (!index.isValid() || !m_obs->result()) return {};
  if (index.column() == FitSnr) {  // the accepted fit's SNR, where the eye compares it with the search's
    const auto* state = m_obs->candidateState(index.row());
    const bool fitted = state && state->fitted();
    const double fitSnr = fitted ? state->fit->snr : -1.0;
    if (role == Qt::UserRole) return fitSnr;
    if (role == Qt::DisplayRole) return fitted ? QVariant(QString::number(fitSnr, 'f', 2)) : QVariant();
    if (role == Qt::TextAlignmentRole) return static_cast<int>(Qt::AlignRight | Qt::AlignVCenter);
    if (role == Qt::ToolTipRole && !fitted) return QString("no accepted co-moving fit (F fits one)");
    if (role == Qt::ToolTipRole) {
      const double searchSnr = m_obs->result()->candidates[static_cast<std::size_t>(index.row())].snr;
      return QString("SNR of the accepted co-moving fit (search: %1)").arg(searchSnr, 0, 'f', 2);
    }
    if (role != Qt::BackgroundRole) return {};
  }
  if (const auto* state = m_obs->candidateState(index.row());
      state && (index.column() >= Label || role == Qt::BackgroundRole || role == Qt::ToolTipRole ||
                role == Qt::DecorationRole))
    return vettingData(*state, index.column(), role);
  const auto& c = m_obs->result()->candidates[static_cast<std::size_t>(index.row())];
  // The motion that matters to an astronomer is relative to the stars (the sky rate), as in the paper and
  // the reports (rate_deg_day, pa_deg): components, rate and position angle (motion_vs_sky.hpp, the GUI's one
  // convention). The position angle needs a WCS call: only for its own column.
  const Velocity rel = toShownVsSky(*m_obs, c.v);
  const double vx = rel.vx;
  const double vy = rel.vy;
  const double rate = std::hypot(rel.vx, rel.vy);
  const auto pa = [&]() -> std::optional<double> { return motionVsSky(*m_obs, c.x, c.y, c.v).paDeg; };
  if (role == Qt::UserRole) {  // sort key
    switch (index.column()) {
      case Index:
        return index.row();
      case X:
        return c.x;
      case Y:
        return c.y;
      case Vx:
        return vx;
      case Vy:
        return vy;
      case Rate:
        return rate;
      case Pa:
        return pa().value_or(-1.0);
      case Snr:
        return c.snr;
      case Fap:
        return c.fap;
      case NIn:
        return c.nIn;
      case Cells:
        return c.clusterCells;
      case Flags:
        return flagsOf(c);
      default:
        return {};
    }
  }
  if (role == Qt::DisplayRole) {
    switch (index.column()) {
      case Index:
        return index.row() + 1;
      case X:
        return c.x;
      case Y:
        return c.y;
      case Vx:
        return QString::number(vx, 'g', 4);
      case Vy:
        return QString::number(vy, 'g', 4);
      case Rate:
        return QString::number(rate, 'g', 4);
      case Pa: {
        const auto angle = pa();
        return angle ? QVariant(QString::number(*angle, 'f', 1)) : QVariant();
      }
      case Snr:
        return QString::number(c.snr, 'f', 2);
      case Fap:
        return QString::number(c.fap, 'e', 2);
      case NIn:
        return c.nIn;
      case Cells:
        return c.clusterCells;
      case Flags:
        return flagsOf(c);
      default:
        return {};
    }
  }
  if (role == Qt::TextAlignmentRole && index.column() != Flags)
    return static_cast<int>(Qt::AlignRight | Qt::AlignVCenter);
  return {};
}

QVariant CandidateModel::headerData(int section, Qt::Orientation orientation, int role) const {
  if (orientation == Qt::Horizontal && role == Qt::ToolTipRole && section == Fap)
    return QString("Expected number of false alarms at this SNR over all trials (the paper's Prob_false); "
                   "a count, not a probability: values above 1 are common for faint candidates");
  const bool motion = section == Vx || section == Vy || section == Rate || section == Pa;
  if (orientation == Qt::Horizontal && role == Qt::ToolTipRole && motion)
    return QString("Motion relative to the stars (the search's velocity minus the sky rate), in the unit "
                   "chosen in the Search dock; PA: direction of that motion, degrees east of north (needs a "
                   "WCS)");
  if (orientation == Qt::Horizontal && role == Qt::ToolTipRole && section == FitSnr)
    return QString("SNR of the accepted co-moving fit; empty without one");
  if (orientation != Qt::Horizontal || role != Qt::DisplayRole)
    return QAbstractTableModel::headerData(section, orientation, role);
  const QString u = unitLabel(shownUnit(*m_obs));
  switch (section) {
    case Index:
      return "#";
    case X:
      return "x [px]";
    case Y:
      return "y [px]";
    case Vx:
      return "vx vs sky [" + u + "]";
    case Vy:
      return "vy vs sky [" + u + "]";
    case Rate:
      return "rate vs sky [" + u + "]";
    case Pa:
      return "PA [deg]";
    case FitSnr:
      return "fit SNR";
    case Snr:
      return "SNR";
    case Fap:
      return "false alarms";
    case NIn:
      return "N_in";
    case Cells:
      return "cells";
    case Flags:
      return "flags";
    case Label:
      return "label";
    case Reason:
      return "reason";
    case Note:
      return "note";
    default:
      return {};
  }
}

void CandidateModel::reload() {
  beginResetModel();
  m_crossesBrighter.clear();
  const auto& result = m_obs->result();
  const auto& prepared = m_obs->prepared();
  if (result && prepared && prepared->filtered)
    m_crossesBrighter = candidate::crossesBrighter(*prepared->filtered, result->grid, result->candidates);
  endResetModel();
}

void CandidateFilter::setMinSnr(double snr) {
  m_minSnr = snr;
  invalidateFilter();
}
void CandidateFilter::setMaxFap(double fap) {
  m_maxFap = fap;
  invalidateFilter();
}
void CandidateFilter::setFlagText(const QString& text) {
  m_flagText = text.trimmed();
  invalidateFilter();
}
void CandidateFilter::setLabelFilter(LabelFilter filter) {
  m_label = filter;
  invalidateFilter();
}

bool CandidateFilter::filterAcceptsRow(int row, const QModelIndex& parent) const {
  auto value = [&](int column) { return sourceModel()->index(row, column, parent).data(Qt::UserRole); };
  if (value(CandidateModel::Snr).toDouble() < m_minSnr) return false;
  if (value(CandidateModel::Fap).toDouble() > m_maxFap) return false;
  if (m_label != LabelFilter::All) {
    const QString label = value(CandidateModel::Label).toString();
    const char* wanted = m_label == LabelFilter::Real       ? "real"
                         : m_label == LabelFilter::Artifact ? "artifact"
                         : m_label == LabelFilter::Unsure   ? "unsure"
                                                            : "";
    if (label != QLatin1String(wanted)) return false;
  }
  if (!m_flagText.isEmpty()) {
    const QString flags = value(CandidateModel::Flags).toString();
    if (m_flagText == "-") return flags.isEmpty();  // "-" keeps only unflagged candidates
    if (!flags.contains(m_flagText, Qt::CaseInsensitive)) return false;
  }
  return true;
}

namespace {

/// QHeaderView hands the style SortDown for an ascending sort and SortUp for a descending one, so the table
/// sorted by SNR, largest first, showed an up arrow (issue 18 §6: "the sort indicator is inverted"). This
/// style swaps them: a down arrow when the largest values come first, as spreadsheets and file managers do.
class SortArrowStyle : public QProxyStyle {
 public:
  using QProxyStyle::QProxyStyle;
  void drawPrimitive(PrimitiveElement element, const QStyleOption* option, QPainter* painter,
                     const QWidget* widget) const override {
    if (element == PE_IndicatorHeaderArrow) {
      if (const auto* header = qstyleoption_cast<const QStyleOptionHeader*>(option)) {
        QStyleOptionHeader swapped(*header);
        if (header->sortIndicator == QStyleOptionHeader::SortUp)
          swapped.sortIndicator = QStyleOptionHeader::SortDown;
        else if (header->sortIndicator == QStyleOptionHeader::SortDown)
          swapped.sortIndicator = QStyleOptionHeader::SortUp;
        QProxyStyle::drawPrimitive(element, &swapped, painter, widget);
        return;
      }
    }
    QProxyStyle::drawPrimitive(element, option, painter, widget);
  }
};

}  // namespace

CandidatePanel::CandidatePanel(Observation* observation, QWidget* parent)
    : QWidget(parent), m_obs(observation) {
  m_model = new CandidateModel(observation, this);
  m_filter = new CandidateFilter(this);
  m_filter->setSourceModel(m_model);
  m_filter->setSortRole(Qt::UserRole);
  m_table = new QTableView(this);
  m_table->setModel(m_filter);
  m_table->setSortingEnabled(true);
  m_table->sortByColumn(CandidateModel::Snr, Qt::DescendingOrder);
  auto* arrows = new SortArrowStyle;
  arrows->setParent(m_table->horizontalHeader());
  m_table->horizontalHeader()->setStyle(arrows);
  m_table->setSelectionBehavior(QAbstractItemView::SelectRows);
  // Several rows may be selected (Ctrl/Shift+click) for a sheet of candidates (Export figure); the current
  // row is the Observation's selected candidate, as before.
  m_table->setSelectionMode(QAbstractItemView::ExtendedSelection);
  m_table->setEditTriggers(QAbstractItemView::DoubleClicked | QAbstractItemView::EditKeyPressed);
  m_table->verticalHeader()->setVisible(false);
  m_table->verticalHeader()->setDefaultSectionSize(20);
  m_table->horizontalHeader()->setStretchLastSection(true);
  // What the eye needs when reviewing first, even in a narrow dock (issue 18 §6): "#", SNR, rate, PA, flags,
  // label, reason, fit SNR; then positions, components and counts; the note stretches last.
  QHeaderView* header = m_table->horizontalHeader();
  for (int i = 0; i < static_cast<int>(std::size(kLeadingColumns)); ++i)
    header->moveSection(header->visualIndex(kLeadingColumns[i]), i);
  m_table->setAlternatingRowColors(true);
  m_table->installEventFilter(this);  // the vetting keys (candidate_panel_vetting.cpp)
  m_table->setContextMenuPolicy(Qt::CustomContextMenu);
  connect(m_table, &QWidget::customContextMenuRequested, this, &CandidatePanel::showVettingMenu);
  buildFilterBar();

  connect(m_obs, &Observation::resultChanged, this, [this] {
    onResult();
    updateCount();
  });
  connect(m_obs, &Observation::candidateStateChanged, this, [this](int index) {
    m_model->reloadRow(index);
    updateCount();
  });
  connect(m_obs, &Observation::unitChanged, m_model, &CandidateModel::reload);
  connect(m_obs, &Observation::selectionChanged, this, &CandidatePanel::onSelectionFromObservation);
  connect(m_table->selectionModel(), &QItemSelectionModel::currentRowChanged, this,
          [this](const QModelIndex& current) {
            if (m_syncing || !current.isValid()) return;
            m_obs->setSelected(m_filter->mapToSource(current).row());
          });
  updateCount();
}

void CandidatePanel::buildFilterBar() {
  m_minSnr = new QDoubleSpinBox(this);
  m_minSnr->setRange(0, 1000);
  m_minSnr->setDecimals(1);
  m_minSnr->setPrefix("SNR ≥ ");
  m_maxFap = new QLineEdit("1", this);
  m_maxFap->setValidator(new QDoubleValidator(0, 1, 20, m_maxFap));
  m_maxFap->setMaximumWidth(80);
  m_maxFap->setToolTip("Show candidates whose false-alarm probability is at most this");
  m_flags = new QLineEdit(this);
  m_flags->setPlaceholderText("flag contains… ('-' = none)");
  m_labelFilter = new QComboBox(this);
  m_labelFilter->addItems({"All", "Unvetted", "Real", "Artifact", "Unsure"});
  m_labelFilter->setToolTip("Show candidates with this label");
  auto* keys = new QLabel("⌨ keys", this);
  keys->setToolTip(vettingShortcutHelp());
  m_count = new QLabel(this);
  auto* bar = new QHBoxLayout;
  bar->addWidget(m_minSnr);
  bar->addWidget(new QLabel("false alarms ≤", this));
  bar->addWidget(m_maxFap);
  bar->addWidget(m_flags, 1);
  bar->addWidget(m_labelFilter);
  bar->addWidget(keys);
  bar->addWidget(m_count);
  auto* layout = new QVBoxLayout(this);
  layout->setContentsMargins(2, 2, 2, 2);
  layout->addLayout(bar);
  layout->addWidget(m_table, 1);

  connect(m_minSnr, &QDoubleSpinBox::valueChanged, this, [this](double v) {
    m_filter->setMinSnr(v);
    updateCount();
  });
  connect(m_maxFap, &QLineEdit::textChanged, this, [this](const QString& t) {
    bool ok = false;
    const double v = t.toDouble(&ok);
    m_filter->setMaxFap(ok ? v : 1.0);
    updateCount();
  });
  connect(m_flags, &QLineEdit::textChanged, this, [this](const QString& t) {
    m_filter->setFlagText(t);
    updateCount();
  });
  connect(m_labelFilter, &QComboBox::currentIndexChanged, this, [this](int i) {
    m_filter->setLabelFilter(static_cast<CandidateFilter::LabelFilter>(i));
    updateCount();
  });
}

void CandidatePanel::updateCount() {
  int vetted = 0;
  for (const auto& s : m_obs->candidateStates())
    vetted += s.label != session::Label::Unvetted ? 1 : 0;
  m_count->setText(
      QString("%1 of %2, %3 vetted").arg(m_filter->rowCount()).arg(m_model->rowCount()).arg(vetted));
  std::vector<bool> shown(static_cast<std::size_t>(m_model->rowCount()), false);
  for (int r = 0; r < m_filter->rowCount(); ++r) {
    const int source = m_filter->mapToSource(m_filter->index(r, 0)).row();
    if (source >= 0 && source < static_cast<int>(shown.size())) shown[static_cast<std::size_t>(source)] = true;
  }
  m_obs->setCandidatesShown(std::move(shown));
}

void CandidatePanel::onResult() {
  m_model->reload();
  m_table->resizeColumnsToContents();
}

std::vector<int> CandidatePanel::selectedCandidates() const {
  std::vector<int> out;
  for (int r = 0; r < m_filter->rowCount(); ++r)
    if (m_table->selectionModel()->isRowSelected(r, {}))
      out.push_back(m_filter->mapToSource(m_filter->index(r, 0)).row());
  return out;
}

void CandidatePanel::selectCandidate(int index) {
  m_obs->setSelected(index);
}

void CandidatePanel::onSelectionFromObservation() {
  const auto sel = m_obs->selected();
  m_syncing = true;
  if (!sel || *sel >= m_model->rowCount()) {
    m_table->clearSelection();
  } else {
    const QModelIndex proxy = m_filter->mapFromSource(m_model->index(*sel, 0));
    const QModelIndex current = m_table->selectionModel()->currentIndex();
    if (proxy.isValid() && current.isValid() && current.row() == proxy.row() &&
        m_table->selectionModel()->hasSelection()) {
      // The table's own click made it current: the click applies its selection itself (Ctrl+click adds the
      // row and keeps the others).
      m_table->scrollTo(proxy);
    } else if (proxy.isValid()) {
      m_table->selectionModel()->setCurrentIndex(
          proxy, QItemSelectionModel::ClearAndSelect | QItemSelectionModel::Rows);
      m_table->scrollTo(proxy);
    }
  }
  m_syncing = false;
}

}  // namespace st::ui
