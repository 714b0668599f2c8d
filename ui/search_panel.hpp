#pragma once
// Search parameters with units (px/s, "/min, deg/day), a live estimate of trials, memory and time, the
// threshold by SNR or by false-alarm probability (estimate and FAP from st::search / st::stats), the backend
// (auto/CPU/GPU), and Run/Cancel. The search itself runs in the main window's JobRunner.
#include <QWidget>
#include <optional>

#include "core_services.hpp"
#include "observation.hpp"

class QComboBox;
class QDoubleSpinBox;
class QSpinBox;
class QLabel;
class QLineEdit;
class QPushButton;
class QRadioButton;

namespace st::ui {

class SearchPanel : public QWidget {
  Q_OBJECT
 public:
  SearchPanel(Observation* observation, const std::vector<std::string>& gpuNames, QWidget* parent = nullptr);

  [[nodiscard]] search::VelocityGrid grid() const;
  [[nodiscard]] search::SearchParams params() const;
  [[nodiscard]] BackendKind backendKind() const;
  void setRunning(bool running);
  void setReady(bool ready);
  void setProgress(double fraction, const QString& stage, double elapsedS);
  void setBackendMessage(const QString& text);
  /// Seconds one velocity's stack took, measured by the scrubber (feeds the time estimate).
  void setMeasuredStackSeconds(double seconds);
  /// Grid defaults for the observation: step 1 px over the time span (paper §4), range +-12 deg/day or the
  /// pixel equivalent, centred on the sky rate.
  void setDefaultsFor(const FrameCube& cube, Velocity skyRate);
  /// Sets centre and half-range in px/s.
  void setGridPxS(Velocity centre, double halfRange, double step);

 signals:
  void runRequested();
  void cancelRequested();

 private:
  void onUnitChanged();
  void onRawChanged();
  void refresh();
  void setSpinUnits();

  Observation* m_obs;
  VelocityUnit m_shownUnit = VelocityUnit::PxPerS;
  QComboBox* m_unit;
  QDoubleSpinBox* m_cx;
  QDoubleSpinBox* m_cy;
  QDoubleSpinBox* m_half;
  QDoubleSpinBox* m_step;
  QLabel* m_gridSize;
  QRadioButton* m_bySnr;
  QRadioButton* m_byFap;
  QDoubleSpinBox* m_snr;
  QLineEdit* m_fap;
  QComboBox* m_backend;
  QLabel* m_backendInfo;
  QLabel* m_estimate;
  QPushButton* m_run;
  QPushButton* m_cancel;
  QLabel* m_status;
  std::optional<double> m_stackSeconds;
  bool m_ready = false;
};

}  // namespace st::ui
