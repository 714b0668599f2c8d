#pragma once
// The candidates of a search as a sortable, filterable table (QAbstractTableModel + QSortFilterProxyModel).
// Selecting a row selects the candidate in the Observation (the main window centres the view on it and sets
// the velocity). Columns carry units in their headers; the sort uses the numbers, not the text.
#include <QAbstractTableModel>
#include <QSortFilterProxyModel>
#include <QWidget>

#include "observation.hpp"

class QTableView;
class QDoubleSpinBox;
class QLineEdit;
class QLabel;

namespace st::ui {

class CandidateModel : public QAbstractTableModel {
  Q_OBJECT
 public:
  enum Column { Index, X, Y, Vx, Vy, Rate, Snr, Fap, NIn, Cells, Flags, ColumnCount };
  explicit CandidateModel(Observation* observation, QObject* parent = nullptr);

  int rowCount(const QModelIndex& parent = {}) const override;
  int columnCount(const QModelIndex& parent = {}) const override;
  QVariant data(const QModelIndex& index, int role) const override;
  QVariant headerData(int section, Qt::Orientation orientation, int role) const override;
  /// Flags shown for a candidate: "edge" within 2 PSF widths of the border, "partial" when fewer than all
  /// frames contributed.
  QString flagsOf(const search::Candidate& c) const;
  void reload();

 private:
  Observation* m_obs;
};

class CandidateFilter : public QSortFilterProxyModel {
  Q_OBJECT
 public:
  using QSortFilterProxyModel::QSortFilterProxyModel;
  void setMinSnr(double snr);
  void setMaxFap(double fap);
  void setFlagText(const QString& text);

 protected:
  bool filterAcceptsRow(int row, const QModelIndex& parent) const override;

 private:
  double m_minSnr = 0.0;
  double m_maxFap = 1.0;
  QString m_flagText;
};

class CandidatePanel : public QWidget {
  Q_OBJECT
 public:
  CandidatePanel(Observation* observation, QWidget* parent = nullptr);
  [[nodiscard]] QTableView* table() const noexcept { return m_table; }
  [[nodiscard]] CandidateFilter* filter() const noexcept { return m_filter; }
  /// Selects the candidate with this index in the search result (source row).
  void selectCandidate(int index);

 private:
  void onResult();
  void onSelectionFromObservation();

  Observation* m_obs;
  CandidateModel* m_model;
  CandidateFilter* m_filter;
  QTableView* m_table;
  QDoubleSpinBox* m_minSnr;
  QLineEdit* m_maxFap;
  QLineEdit* m_flags;
  QLabel* m_count;
  bool m_syncing = false;
};

}  // namespace st::ui
