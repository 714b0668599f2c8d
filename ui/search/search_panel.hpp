#pragma once
// Search parameters with units (px/s, "/min, deg/day), a live estimate of trials, memory and time, the
// threshold by SNR or by false-alarm probability (estimate and FAP from st::search / st::stats), the method
// (auto/exact/tree, st/search/method_choice.hpp: the estimate follows it), the backend (auto/CPU/GPU with
// the device's name), Run/Cancel, and what the last search ran (method, why, backend). The search itself
// runs in the main window's JobRunner (through st::search::searchWithMethod).
#include <QFutureWatcher>
#include <QWidget>
#include <optional>
#include <string>

#include "core_services.hpp"
#include "st/search/method_choice.hpp"
#include "observation.hpp"

class QComboBox;
class QDoubleSpinBox;
class QGroupBox;
class QSpinBox;
class QLabel;
class QLineEdit;
class QPushButton;
class QRadioButton;

namespace st::ui {

/// "1 candidate above SNR 7.00" / "3 candidates above SNR 7.00", with "(2 sidelobes merged)" when the search
/// merged sidelobes of bright candidates into them (st/search/sidelobes.hpp).
QString candidateSummary(const search::SearchResult& result);

class SearchPanel : public QWidget {
  Q_OBJECT
 public:
  SearchPanel(Observation* observation, const std::vector<std::string>& gpuNames, QWidget* parent = nullptr);

  /// The grid in use: exactly the one last given to setGrid() (or a default), until a value is edited by
  /// hand; then the shown values, 2 * ceil(half-range / step) + 1 points per axis (as makeVelocityGrid).
  [[nodiscard]] search::VelocityGrid grid() const;
  /// The threshold, method and the parameters the panel does not show (kept from setParams()).
  [[nodiscard]] search::SearchParams params() const;
  [[nodiscard]] BackendKind backendKind() const;
  /// Shows `params`: SNR or FAP threshold, method; maxCandidates and minFrameFraction are kept for params().
  void setParams(const search::SearchParams& params);
  /// Selects the backend choice (GPU only where one was found, else Auto: a session saved on a GPU machine
  /// opens on a laptop).
  void setBackendKind(BackendKind kind);
  /// Shows the grid in `unit` (angular units only when the observation has a plate scale).
  void setUnit(VelocityUnit unit);
  /// The grid in words with units (gridDescription()), and where the setting came from ("" when not known).
  [[nodiscard]] QString gridText() const;
  [[nodiscard]] QString gridOrigin() const { return m_origin; }
  /// The method selected: Auto (default), Exact or Tree (also in params().method).
  [[nodiscard]] search::SearchMethod method() const;
  /// Selects the method (SearchMethod::Unknown is ignored).
  void setMethod(search::SearchMethod method);
  /// The estimate text shown (for tests and the status bar).
  [[nodiscard]] QString estimateText() const;
  /// True while the method estimate (its tree plan) is being computed in a worker.
  [[nodiscard]] bool estimating() const { return m_estimatePending; }
  /// The summary of the last search shown under Run (method, reason, backend, candidates, time).
  [[nodiscard]] QString statusText() const;
  void setRunning(bool running);
  void setReady(bool ready);
  /// Replaces the progress line (e.g. after a cancelled search).
  void setStatusText(const QString& text);
  void setProgress(double fraction, const QString& stage, double elapsedS);
  void setBackendMessage(const QString& text);
  /// Seconds one velocity's stack took, measured by the scrubber (feeds the time estimate).
  void setMeasuredStackSeconds(double seconds);
  /// Grid defaults for the observation (`cube`: the frames the search runs on), derived from the data
  /// (st/search/default_grid.hpp): step 1 px over the time span (paper §4.4), centred on the sky rate,
  /// half-range the smallest of +-12 deg/day (+-12 steps without a plate scale), what can stay in the frame
  /// and what the selected backend's exact search does in about a minute. gridOrigin() says which.
  void setDefaultsFor(const FrameCube& cube, Velocity skyRate);
  /// Uses exactly `grid` (px/s); `origin` says where it came from (shown under the grid, "" for none).
  void setGrid(const search::VelocityGrid& grid, const QString& origin);
  /// Sets centre, half-range and step in px/s (2 * ceil(halfRange / step) + 1 points per axis).
  void setGridPxS(Velocity centre, double halfRange, double step);

 signals:
  /// The grid, threshold, method or backend changed (by hand or by a setter): the session saves it.
  void settingsChanged();
  void runRequested();
  void cancelRequested();

 private:
  /// The last method estimate and what it was computed for (the tree plan takes milliseconds to build; a new
  /// measured throughput only re-prices it).
  struct EstimateKey {
    const FrameCube* cube = nullptr;
    int width = 0, height = 0, nvx = 0, nvy = 0;
    std::size_t frames = 0;
    double step = 0.0;
    bool operator==(const EstimateKey&) const = default;
  };
  using KeyedEstimate = std::pair<EstimateKey, search::MethodEstimate>;

  void onUnitChanged();
  void onRawChanged();
  /// A grid value was edited by hand: the shown values are the grid from now on.
  void onGridEdited();
  void refresh();
  void setSpinUnits();
  void onResultChanged();
  /// The "Run" box: method, backend (with the GPUs' names), estimate, buttons, status.
  QGroupBox* makeRunBox(const std::vector<std::string>& gpuNames);
  [[nodiscard]] QString methodEstimateText(const FrameCube& raw, const search::VelocityGrid& g,
                                           std::optional<double> rate);
  /// Starts the worker that estimates both methods for the current cube and grid (while one is running, a
  /// new request waits: the refresh after it finishes starts the latest).
  void startEstimate(const FrameCube& raw, const search::VelocityGrid& g, const EstimateKey& key);
  void onEstimateFinished();

  Observation* m_obs;
  VelocityUnit m_shownUnit = VelocityUnit::PxPerS;
  QComboBox* m_unit;
  QDoubleSpinBox* m_cx;
  QDoubleSpinBox* m_cy;
  QDoubleSpinBox* m_half;
  QDoubleSpinBox* m_step;
  QLabel* m_gridSize;
  QLabel* m_gridOriginLabel;
  std::optional<search::VelocityGrid> m_exactGrid;  ///< the grid as given, until a value is edited
  QString m_origin;
  search::SearchParams m_hiddenParams;  ///< what params() returns beyond the shown threshold and method
  QString m_lastSettings;               ///< the settings settingsChanged() last announced, as text
  QRadioButton* m_bySnr;
  QRadioButton* m_byFap;
  QDoubleSpinBox* m_snr;
  QLineEdit* m_fap;
  QComboBox* m_method;
  QComboBox* m_backend;
  QLabel* m_backendInfo;
  QLabel* m_estimate;
  QPushButton* m_run;
  QPushButton* m_cancel;
  QLabel* m_status;
  std::optional<double> m_stackSeconds;
  std::optional<KeyedEstimate> m_estimateCache;
  /// The tree plan behind an estimate is built in a worker (tens of ms for a paper-sized grid); the text
  /// says "estimating…" until it is back.
  QFutureWatcher<KeyedEstimate> m_estimateWatcher;
  bool m_estimatePending = false;  ///< started and its result not yet taken (finished is a queued signal)
  bool m_ready = false;
  bool m_hasGpu = false;
};

}  // namespace st::ui
