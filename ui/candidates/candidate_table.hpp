#pragma once
// The candidates of a search as a sortable, filterable table (QAbstractTableModel + QSortFilterProxyModel).
// Selecting a row selects the candidate in the Observation (the main window centres the view on it and sets
// the velocity). Columns carry units in their headers; the sort uses the numbers, not the text.
//
// Vetting (issue 8 §2): label, reason and note columns from the Observation's candidate states, rows tinted
// by label, a filter by label, and single-key shortcuts on the table (candidate_vetting.hpp) that label the
// selected candidate and move to the next unvetted one. N (or a double click on the note) edits the note.
#include <QAbstractTableModel>
#include <QSortFilterProxyModel>
#include <QWidget>

#include "observation.hpp"

class QTableView;
class QDoubleSpinBox;
class QLineEdit;
class QLabel;
class QComboBox;

namespace st::ui {

class CandidateModel : public QAbstractTableModel {
  Q_OBJECT
 public:
  /// Logical columns. Velocities are relative to the stars (the sky rate), in the unit chosen in the Search
  /// dock (Observation::unit); Pa is the position angle of that motion, east of north (needs a WCS).
  /// FitSnr is the accepted co-moving fit's SNR (empty without one). The panel shows SNR, rate, PA, flags and
  /// the vetting columns first (CandidatePanel::kLeadingColumns).
  enum Column {
    Index,
    X,
    Y,
    Vx,
    Vy,
    Rate,
    Pa,
    Snr,
    Fap,
    NIn,
    Cells,
    Flags,
    FitSnr,
    Label,
    Reason,
    Note,
    ColumnCount
  };
  explicit CandidateModel(Observation* observation, QObject* parent = nullptr);

  int rowCount(const QModelIndex& parent = {}) const override;
  int columnCount(const QModelIndex& parent = {}) const override;
  QVariant data(const QModelIndex& index, int role) const override;
  QVariant headerData(int section, Qt::Orientation orientation, int role) const override;
  /// Only the note is editable (it goes to Observation::setCandidateNote).
  Qt::ItemFlags flags(const QModelIndex& index) const override;
  bool setData(const QModelIndex& index, const QVariant& value, int role) override;
  /// Flags shown for a candidate: "pre-processing mover" for one added from pre-processing's movers
  /// (candidate::isMover), "edge" within 2 PSF widths of the border, "partial" when fewer than all frames
  /// contributed, "crosses brighter" when its track meets a 10 times brighter candidate's
  /// (candidate::crossesBrighter).
  QString flagsOf(const search::Candidate& c) const;
  /// Reloads every row, and works out the flags that depend on the other candidates.
  void reload();
  /// One candidate's row changed (its vetting state).
  void reloadRow(int row);

 private:
  QVariant vettingData(const session::CandidateState& state, int column, int role) const;
  Observation* m_obs;
  std::vector<char> m_crossesBrighter;  ///< per candidate of the result, made by reload()
};

class CandidateFilter : public QSortFilterProxyModel {
  Q_OBJECT
 public:
  using QSortFilterProxyModel::QSortFilterProxyModel;
  void setMinSnr(double snr);
  void setMaxFap(double fap);
  void setFlagText(const QString& text);
  /// Which labels are shown.
  enum class LabelFilter { All, Unvetted, Real, Artifact, Unsure };
  void setLabelFilter(LabelFilter filter);
  [[nodiscard]] LabelFilter labelFilter() const noexcept { return m_label; }

 protected:
  bool filterAcceptsRow(int row, const QModelIndex& parent) const override;

 private:
  double m_minSnr = 0.0;
  double m_maxFap = 1.0;
  QString m_flagText;
  LabelFilter m_label = LabelFilter::All;
};

class CandidatePanel : public QWidget {
  Q_OBJECT
 public:
  /// The columns shown first, in this order (the rest follow in CandidateModel's order).
  static constexpr CandidateModel::Column kLeadingColumns[] = {
      CandidateModel::Index, CandidateModel::Snr,   CandidateModel::Rate,   CandidateModel::Pa,
      CandidateModel::Flags, CandidateModel::Label, CandidateModel::Reason, CandidateModel::FitSnr};
  CandidatePanel(Observation* observation, QWidget* parent = nullptr);
  [[nodiscard]] QTableView* table() const noexcept { return m_table; }
  [[nodiscard]] CandidateFilter* filter() const noexcept { return m_filter; }
  /// Selects the candidate with this index in the search result (source row).
  void selectCandidate(int index);
  /// The candidates whose rows are selected (Ctrl/Shift+click), as indices into the search result, in the
  /// table's order (its sort). The current row, the Observation's selected candidate, is among them.
  [[nodiscard]] std::vector<int> selectedCandidates() const;
  /// Labels the selected candidate (a reason only with Label::Artifact) and selects the next unvetted one
  /// in the table's order (after it, wrapping round; the selection stays when none is left). False when no
  /// candidate is selected.
  bool labelSelected(session::Label label, session::ArtifactReason reason = session::ArtifactReason::None);
  /// Opens the note editor of the selected candidate (false when none is selected).
  bool editSelectedNote();
  /// The row (in the table's order) of the next unvetted candidate after `proxyRow`, wrapping round and
  /// skipping `proxyRow` itself; -1 when there is none.
  [[nodiscard]] int nextUnvettedRow(int proxyRow) const;

 protected:
  bool eventFilter(QObject* watched, QEvent* event) override;

 private:
  void buildFilterBar();
  /// Right click on a row: the same labels as the keys, for the mouse, then the table's own actions.
  void showVettingMenu(const QPoint& pos);
  void onResult();
  void onSelectionFromObservation();
  void updateCount();

  Observation* m_obs;
  CandidateModel* m_model;
  CandidateFilter* m_filter;
  QTableView* m_table;
  QDoubleSpinBox* m_minSnr;
  QLineEdit* m_maxFap;
  QLineEdit* m_flags;
  QComboBox* m_labelFilter;
  QLabel* m_count;
  bool m_syncing = false;
};

}  // namespace st::ui
