#pragma once
// "Reports…" (Export menu): candidates CSV and JSON, DS9 regions, FITS stacks (sky-tracked and
// object-tracked, WCS at t_ref, provenance), ADES PSV and MPC 80-column astrometry of the candidates
// labelled real (st/report/report_bundle.hpp, the function `synthtrack-cli report` calls). An "Observatory" page holds the MPC station code, observers, measurer,
// submitter and telescope fields; they are kept in QSettings (reportSettings()) and written into the
// session's settings; the catalogue is filled from the frames' header when it names one. While ADES or MPC
// output is chosen and a value it requires is missing (report::submissionProblems), the warning line says
// which, and the export refuses before writing anything. Candidates labelled real below the safe SNR show a
// visible warning before and after the export. The writing runs on a worker thread; errors name the path at
// fault.
#include <QDialog>
#include <QFutureWatcher>
#include <functional>
#include <memory>

#include <nlohmann/json.hpp>

#include "observation.hpp"
#include "st/report/report_bundle.hpp"

class QCheckBox;
class QComboBox;
class QDoubleSpinBox;
class QLabel;
class QLineEdit;
class QPlainTextEdit;
class QPushButton;

namespace st::ui {

using report::ReportOutcome;
using report::StackChoice;

/// The report settings kept in QSettings ("report/settings", JSON text; keys of toJson(SubmissionSettings)).
[[nodiscard]] nlohmann::json loadReportSettings();
void saveReportSettings(const nlohmann::json& settings);

class ReportDialog : public QDialog {
  Q_OBJECT
 public:
  struct Context {
    Observation* observation = nullptr;
    /// makeSession() of the window's state with `settings` as the session's report settings.
    std::function<session::Session(const nlohmann::json& settings)> makeSession;
  };

  explicit ReportDialog(Context context, QWidget* parent = nullptr);

  /// The settings as the Observatory page holds them.
  [[nodiscard]] report::SubmissionSettings submissionSettings() const;
  void setSubmissionSettings(const report::SubmissionSettings& settings);
  /// Output folder and base name; which outputs (by the ReportRequest flags).
  void setOutput(const QString& folder, const QString& baseName);
  void setOutputs(bool json, bool csv, bool ds9, bool stacks, bool ades, bool mpc);
  void setStackChoice(StackChoice choice);
  /// Starts writing in a worker; false while one runs or when the session cannot be made (exportFinished is
  /// emitted then too, with the reason).
  bool exportReports();
  [[nodiscard]] bool busy() const { return m_watcher.isRunning(); }
  /// The warning line (low SNR, real candidates without a sky position); empty when none.
  [[nodiscard]] QString warningText() const;
  [[nodiscard]] bool warningVisible() const;
  /// What the last export wrote and warned, or why it failed.
  [[nodiscard]] QString resultText() const;
  /// Recomputes the warning from the current labels and safe SNR.
  void refreshWarnings();

 signals:
  /// The settings changed (saved to QSettings already); the window puts them into its session.
  void settingsChanged(const nlohmann::json& settings);
  void exportFinished(bool ok, const QString& message);

 protected:
  void showEvent(QShowEvent* event) override;

 private:
  struct Result {
    ReportOutcome outcome;
    QString error;
  };
  QWidget* buildOutputsPage();
  QWidget* buildObservatoryPage();
  void onSettingsEdited();
  void onFinished();

  Context m_ctx;
  QLineEdit* m_folder = nullptr;
  QLineEdit* m_base = nullptr;
  QCheckBox* m_json = nullptr;
  QCheckBox* m_csv = nullptr;
  QCheckBox* m_ds9 = nullptr;
  QCheckBox* m_stacks = nullptr;
  QComboBox* m_stackChoice = nullptr;
  QCheckBox* m_ades = nullptr;
  QCheckBox* m_mpc = nullptr;
  QLineEdit* m_station = nullptr;
  QLineEdit* m_observers = nullptr;
  QLineEdit* m_measurer = nullptr;
  QLineEdit* m_submitter = nullptr;
  QLineEdit* m_telescope = nullptr;
  QDoubleSpinBox* m_aperture = nullptr;
  QComboBox* m_detector = nullptr;
  QLineEdit* m_astCat = nullptr;
  QLineEdit* m_mpcCat = nullptr;
  QDoubleSpinBox* m_safeSnr = nullptr;
  QComboBox* m_positions = nullptr;
  QLineEdit* m_contactEmail = nullptr;
  QLabel* m_warning = nullptr;
  QPlainTextEdit* m_result = nullptr;
  QPushButton* m_export = nullptr;
  QFutureWatcher<Result> m_watcher;
  bool m_loading = false;
};

}  // namespace st::ui
