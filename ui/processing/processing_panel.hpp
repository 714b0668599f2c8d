#pragma once
// The pre-processing stages (calibration, background, static sources, PSF, matched filter) with their
// parameters at the paper's defaults, built from CoreServices::preprocessStages, and a Run button. After a
// run it lists what the result exposes; the central view's "Show" selector displays any of it.
// A stage's file lists (the calibration's bias, flat and dark frames) are rows of "; "-separated paths with
// Files…/Folder…/Clear; folders offered from beside the science frames carry a note the user can clear.
#include <QStringList>
#include <QWidget>
#include <map>
#include <vector>

#include "core_services.hpp"

class QPushButton;
class QLabel;
class QDoubleSpinBox;
class QGroupBox;
class QLineEdit;

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
  /// Back to the paper's defaults (file lists are data, not parameters: they are kept).
  void resetDefaults();

  /// The paths of file list `key` (e.g. "bias"), as shown.
  [[nodiscard]] QStringList files(const std::string& key) const;
  /// Sets file list `key` (a list no stage has is ignored); the offer note no longer covers it.
  void setFiles(const std::string& key, const QStringList& paths);
  /// Fills the lists in `offered` (key -> paths) and shows `note` above them until the user clears the offer
  /// or edits every offered list.
  void offerFiles(const std::map<std::string, QStringList>& offered, const QString& note);
  /// Empties the lists that still hold what was offered and hides the note.
  void clearOffer();
  /// Empties every file list and hides the note (a new observation).
  void clearFiles();
  /// The offer note while shown, else "".
  [[nodiscard]] QString offerNote() const;

 signals:
  void runRequested();

 private:
  std::vector<StageSpec> m_defaults;
  std::vector<QGroupBox*> m_boxes;
  std::vector<std::vector<QDoubleSpinBox*>> m_spins;
  bool eventFilter(QObject* watched, QEvent* event) override;
  QWidget* fileRow(QWidget* parent, const StageFiles& files);
  QLineEdit* fileEdit(const std::string& key) const;
  void onFilesEdited(const std::string& key);

  std::vector<std::vector<QLineEdit*>> m_fileEdits;  ///< per stage, one per StageFiles (objectName = key)
  std::map<std::string, QLineEdit*> m_fileEditByKey;
  std::map<std::string, QStringList> m_offered;      ///< what offerFiles() put in and is still there
  QWidget* m_viewport = nullptr;  ///< the scroll area's, whose width the offer note wraps to
  QWidget* m_offerBox = nullptr;
  QLabel* m_offerNote = nullptr;
  QPushButton* m_run;
  QLabel* m_summary;
};

}  // namespace st::ui
