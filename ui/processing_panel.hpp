#pragma once
// The pre-processing stages (calibration, background, static sources, PSF, matched filter) with their
// parameters at the paper's defaults, built from CoreServices::preprocessStages, and a Run button. After a
// run it lists what the result exposes; the central view's "Show" selector displays any of it.
#include <QWidget>
#include <vector>

#include "core_services.hpp"

class QPushButton;
class QLabel;
class QDoubleSpinBox;
class QGroupBox;

namespace st::ui {

class ProcessingPanel : public QWidget {
  Q_OBJECT
 public:
  ProcessingPanel(std::vector<StageSpec> stages, QWidget* parent = nullptr);
  /// The stages as the user set them.
  [[nodiscard]] std::vector<StageSpec> stages() const;
  void setRunEnabled(bool enabled);
  void setSummary(const QString& text);
  /// Shows these stages (same names and order as the panel's, e.g. from a session); others are ignored.
  void setStages(const std::vector<StageSpec>& stages);
  /// Back to the paper's defaults.
  void resetDefaults();

 signals:
  void runRequested();

 private:
  std::vector<StageSpec> m_defaults;
  std::vector<QGroupBox*> m_boxes;
  std::vector<std::vector<QDoubleSpinBox*>> m_spins;
  QPushButton* m_run;
  QLabel* m_summary;
};

}  // namespace st::ui
