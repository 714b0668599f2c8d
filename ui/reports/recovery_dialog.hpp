#pragma once
// "Injection recovery…" (Run menu): scores a search of frames with injected movers against the injection's
// truth file, as `synthtrack-cli recovery` does for one pair. The matching, the completeness bins, the text
// summary, the JSON/CSV writers and the SVG plot are the core's (st/inject/recovery.hpp,
// st/inject/completeness_svg.hpp); this dialog only reads the two files, shows the result and saves it.
//
// The candidates come from a search's JSON (`synthtrack-cli search --json`, the Reports dialog's candidates
// JSON) or from the window's current search, converted by the same writer (report::searchResultToJson, then
// inject::candidatesFromJson). Reading two small JSON files and matching take milliseconds, so it runs on the
// GUI thread, again on every change of an input or a tolerance. Bad input (a file that cannot be read,
// invalid JSON, a missing key) is shown in the dialog with the core's message, naming the file; nothing is
// thrown out of a slot.
#include <QDialog>
#include <QString>
#include <optional>

#include "st/inject/recovery.hpp"

class QDoubleSpinBox;
class QLabel;
class QLineEdit;
class QPlainTextEdit;
class QPushButton;
class QRadioButton;

namespace st::ui {

class Observation;
class CompletenessPlot;

class RecoveryDialog : public QDialog {
  Q_OBJECT
 public:
  enum class CandidateSource { File, CurrentSearch };

  /// `observation` (may be null) offers its search result as the "current search".
  explicit RecoveryDialog(Observation* observation, QWidget* parent = nullptr);

  /// The truth file (truth.json of `synthtrack-cli inject`). Does not recompute.
  void setTruthPath(const QString& path);
  /// The candidates file; selects CandidateSource::File. Does not recompute.
  void setCandidatesPath(const QString& path);
  /// Where the candidates come from; CurrentSearch is refused (false) while the window has no search result.
  bool setCandidateSource(CandidateSource source);
  [[nodiscard]] CandidateSource candidateSource() const;
  /// The window has a search result to score.
  [[nodiscard]] bool currentSearchAvailable() const;
  /// Match tolerances: position at the truth's t_ref (px), each velocity component (grid steps of the
  /// search). Does not recompute.
  void setTolerances(double matchPx, double matchVSteps);

  /// The last successful scoring, or none (before the first, or after an error).
  [[nodiscard]] const std::optional<inject::RecoveryResult>& result() const { return m_result; }
  /// The error of the last recompute() or save, naming the file at fault; empty when none.
  [[nodiscard]] QString errorText() const { return m_error; }
  /// The summary shown (inject::recoveryText), empty without a result.
  [[nodiscard]] QString summaryText() const;
  /// The plot shown (inject::completenessSvg), empty without a result.
  [[nodiscard]] const QString& svg() const { return m_svg; }
  /// The plot rendered at `width` px (height from the SVG's aspect ratio) on white; null without a result.
  [[nodiscard]] QImage renderPlot(int width) const;
  /// What the last save wrote, or empty.
  [[nodiscard]] QString savedText() const { return m_saved; }

  /// Writes recovery.json, completeness.csv, objects.csv, unmatched.csv, completeness.svg and
  /// completeness.png (the plot at 1280 px wide) into `folder` (created), as `synthtrack-cli recovery --out`
  /// does plus the PNG. False with errorText() when there is no result or a file cannot be written.
  bool saveTo(const QString& folder);

 public slots:
  /// Reads the inputs and scores them; false with errorText() set when an input is missing or bad.
  bool recompute();

 signals:
  void recomputed(bool ok);

 private:
  struct Scored {
    inject::RecoveryResult result;
    nlohmann::json set;  ///< the "sets" entry of recovery.json (files, counts, time shift)
  };
  QWidget* buildInputs();
  Scored score() const;
  inject::CandidateSet currentSearchCandidates() const;
  [[nodiscard]] QString candidatesName() const;
  void refreshCurrentSearch();
  void showMessage(const QString& text, bool error);
  void clearResult();
  void chooseSaveFolder();

  Observation* m_obs;
  QLineEdit* m_truth = nullptr;
  QLineEdit* m_candidates = nullptr;
  QPushButton* m_browseCandidates = nullptr;
  QRadioButton* m_fromFile = nullptr;
  QRadioButton* m_fromSearch = nullptr;
  QDoubleSpinBox* m_matchPx = nullptr;
  QDoubleSpinBox* m_matchVSteps = nullptr;
  CompletenessPlot* m_plot = nullptr;
  QPlainTextEdit* m_text = nullptr;
  QLabel* m_message = nullptr;
  QPushButton* m_save = nullptr;
  std::optional<inject::RecoveryResult> m_result;
  nlohmann::json m_set;
  QString m_svg;
  QString m_error;
  QString m_saved;
};

}  // namespace st::ui
