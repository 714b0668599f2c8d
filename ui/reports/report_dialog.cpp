#include "report_dialog.hpp"

#include <filesystem>

#include <QCheckBox>
#include <QComboBox>
#include <QDialogButtonBox>
#include <QDir>
#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QLabel>
#include <QLineEdit>
#include <QPlainTextEdit>
#include <QPushButton>
#include <QSettings>
#include <QTabWidget>
#include <QVBoxLayout>
#include <QtConcurrent>

#include "st/common/error.hpp"
#include "st/report/star_catalogues.hpp"

namespace st::ui {

nlohmann::json loadReportSettings() {
  const QString text = QSettings().value("report/settings").toString();
  if (text.isEmpty()) return toJson(report::SubmissionSettings{});
  try {
    return nlohmann::json::parse(text.toStdString());
  } catch (const nlohmann::json::exception&) {
    return toJson(report::SubmissionSettings{});
  }
}

void saveReportSettings(const nlohmann::json& settings) {
  QSettings().setValue("report/settings", QString::fromStdString(settings.dump()));
}

ReportDialog::ReportDialog(Context context, QWidget* parent) : QDialog(parent), m_ctx(std::move(context)) {
  setWindowTitle("Reports");
  auto* tabs = new QTabWidget(this);
  tabs->addTab(buildOutputsPage(), "Outputs");
  tabs->addTab(buildObservatoryPage(), "Observatory (ADES / MPC)");
  m_warning = new QLabel(this);
  m_warning->setWordWrap(true);
  m_warning->setStyleSheet("QLabel { color: #b00000; font-weight: bold; }");
  m_warning->hide();
  m_result = new QPlainTextEdit(this);
  m_result->setReadOnly(true);
  m_result->setMaximumBlockCount(500);
  m_result->setPlaceholderText("The files written and any warnings appear here.");
  auto* buttons = new QDialogButtonBox(QDialogButtonBox::Close, this);
  m_export = buttons->addButton("Export", QDialogButtonBox::AcceptRole);
  auto* layout = new QVBoxLayout(this);
  layout->addWidget(tabs);
  layout->addWidget(m_warning);
  layout->addWidget(m_result, 1);
  layout->addWidget(buttons);
  connect(buttons, &QDialogButtonBox::rejected, this, &QDialog::reject);
  connect(m_export, &QPushButton::clicked, this, &ReportDialog::exportReports);
  connect(&m_watcher, &QFutureWatcher<Result>::finished, this, &ReportDialog::onFinished);
  if (m_ctx.observation) {
    // Only while shown: the check builds a session, not worth doing on every label of a hidden dialog.
    const auto refresh = [this] {
      if (isVisible()) refreshWarnings();
    };
    connect(m_ctx.observation, &Observation::candidateStateChanged, this, refresh);
    connect(m_ctx.observation, &Observation::resultChanged, this, refresh);
  }
  m_loading = true;
  setSubmissionSettings(report::submissionFromJson(loadReportSettings()));
  m_loading = false;
}

QWidget* ReportDialog::buildOutputsPage() {
  auto* page = new QWidget(this);
  auto* form = new QFormLayout(page);
  QSettings settings;
  m_folder = new QLineEdit(
      settings.value("report/folder", QDir::homePath() + "/synthtrack-reports").toString(), page);
  auto* browse = new QPushButton("Browse…", page);
  auto* row = new QHBoxLayout;
  row->addWidget(m_folder, 1);
  row->addWidget(browse);
  m_base = new QLineEdit(settings.value("report/base", "synthtrack").toString(), page);
  m_json = new QCheckBox("candidates JSON (with fits, labels, notes)", page);
  m_csv = new QCheckBox("candidates CSV", page);
  m_ds9 = new QCheckBox("DS9 regions (fk5 with a WCS, else image coordinates)", page);
  m_stacks = new QCheckBox("FITS stacks tracking the sky and the object, with WCS and provenance", page);
  m_stackChoice = new QComboBox(page);
  m_stackChoice->addItem("of the candidates labelled real", static_cast<int>(StackChoice::Real));
  m_stackChoice->addItem("of the selected candidate", static_cast<int>(StackChoice::Selected));
  m_stackChoice->addItem("of every candidate", static_cast<int>(StackChoice::All));
  m_ades = new QCheckBox("ADES 2022 PSV astrometry (candidates labelled real only)", page);
  m_mpc = new QCheckBox("MPC 80-column astrometry (candidates labelled real only)", page);
  for (QCheckBox* c : {m_json, m_csv, m_ds9})
    c->setChecked(true);
  form->addRow("Folder", row);
  form->addRow("Base name", m_base);
  form->addRow("Candidates", m_json);
  form->addRow("", m_csv);
  form->addRow("Regions", m_ds9);
  form->addRow("Stacks", m_stacks);
  form->addRow("", m_stackChoice);
  form->addRow("Astrometry", m_ades);
  form->addRow("", m_mpc);
  for (QCheckBox* c : {m_ades, m_mpc})
    connect(c, &QCheckBox::toggled, this, [this] {
      if (isVisible()) refreshWarnings();
    });
  connect(browse, &QPushButton::clicked, this, [this] {
    const QString dir = QFileDialog::getExistingDirectory(this, "Report folder", m_folder->text());
    if (!dir.isEmpty()) m_folder->setText(dir);
  });
  return page;
}

QWidget* ReportDialog::buildObservatoryPage() {
  auto* page = new QWidget(this);
  auto* form = new QFormLayout(page);
  m_station = new QLineEdit(page);
  m_station->setMaxLength(3);
  m_station->setToolTip("MPC observatory code, 3 characters (e.g. 291, I41, X05)");
  m_observers = new QLineEdit(page);
  m_observers->setToolTip("Observer names, comma-separated (A. Smith, B. Jones)");
  m_measurer = new QLineEdit(page);
  m_measurer->setPlaceholderText("the first observer");
  m_submitter = new QLineEdit(page);
  m_submitter->setPlaceholderText("the measurer");
  m_contactEmail = new QLineEdit(page);
  m_contactEmail->setPlaceholderText("name@host");
  m_contactEmail->setToolTip(
      "Where the MPC sends its acknowledgment of an 80-column submission (the AC2 line)");
  m_telescope = new QLineEdit(page);
  m_telescope->setToolTip("ADES telescope design: reflector, refractor, Schmidt, ... (required)");
  m_aperture = new QDoubleSpinBox(page);
  m_aperture->setToolTip("Telescope aperture in metres (ADES requires it)");
  m_aperture->setRange(0.0, 50.0);
  m_aperture->setDecimals(2);
  m_aperture->setSuffix(" m");
  m_aperture->setSpecialValueText("not given");
  m_detector = new QComboBox(page);
  m_detector->addItems({"CCD", "CMO"});
  m_detector->setToolTip("Detector: CCD, or CMO for CMOS (the ADES mode and 80-column note 2)");
  m_astCat = new QLineEdit(page);
  m_astCat->setToolTip(
      "ADES astCat: the reference catalogue of the WCS solution as the MPC spells it (Gaia3, Gaia2, UCAC4, "
      "PS1_DR2, ATLAS2, ...); required. Filled from the frames' header when it names one.");
  m_mpcCat = new QLineEdit(page);
  m_mpcCat->setMaxLength(1);
  m_mpcCat->setPlaceholderText("from the catalogue");
  m_mpcCat->setToolTip(
      "The catalogue by its MPC code (e.g. W for Gaia DR3, V for Gaia DR2) for the 80-column NET line; "
      "empty: the catalogue above. Column 72 itself is left blank: the MPC fills it");
  m_safeSnr = new QDoubleSpinBox(page);
  m_safeSnr->setRange(0.0, 100.0);
  m_safeSnr->setDecimals(1);
  m_safeSnr->setToolTip(
      "Positions below this SNR get a warning (the paper's threshold is 7): a segment position's SNR is its "
      "segment's own, about the whole fit's over the square root of the number of segments");
  m_positions = new QComboBox(page);
  m_positions->addItem("one per segment (a tracklet)", "segments");
  m_positions->addItem("the whole fit's one", "fit");
  m_positions->setToolTip(
      "Positions per object labelled real. The MPC links a new object from a tracklet of two or more "
      "positions: one per segment gives each segment's own fit, at the mean time of its frames (2 to 4 "
      "segments, as many as keep each near SNR 7). The whole fit's one position is the most precise, but "
      "alone");
  form->addRow("Station code", m_station);
  form->addRow("Observers", m_observers);
  form->addRow("Measurer", m_measurer);
  form->addRow("Submitter", m_submitter);
  form->addRow("Contact e-mail", m_contactEmail);
  form->addRow("Telescope design", m_telescope);
  form->addRow("Aperture", m_aperture);
  form->addRow("Detector", m_detector);
  form->addRow("Catalogue (astCat)", m_astCat);
  form->addRow("80-column catalogue code", m_mpcCat);
  form->addRow("Safe SNR", m_safeSnr);
  form->addRow("Positions per object", m_positions);
  for (QLineEdit* e :
       {m_station, m_observers, m_measurer, m_submitter, m_contactEmail, m_telescope, m_astCat, m_mpcCat})
    connect(e, &QLineEdit::editingFinished, this, &ReportDialog::onSettingsEdited);
  connect(m_aperture, &QDoubleSpinBox::valueChanged, this, &ReportDialog::onSettingsEdited);
  connect(m_safeSnr, &QDoubleSpinBox::valueChanged, this, &ReportDialog::onSettingsEdited);
  connect(m_detector, &QComboBox::currentIndexChanged, this, &ReportDialog::onSettingsEdited);
  connect(m_positions, &QComboBox::currentIndexChanged, this, &ReportDialog::onSettingsEdited);
  return page;
}

report::SubmissionSettings ReportDialog::submissionSettings() const {
  report::SubmissionSettings s;
  s.stationCode = m_station->text().trimmed().toStdString();
  s.observers = m_observers->text().trimmed().toStdString();
  s.measurer = m_measurer->text().trimmed().toStdString();
  s.submitter = m_submitter->text().trimmed().toStdString();
  s.contactEmail = m_contactEmail->text().trimmed().toStdString();
  s.telescopeDesign = m_telescope->text().trimmed().toStdString();
  s.apertureM = m_aperture->value();
  s.detector = m_detector->currentText().toStdString();
  s.astCat = m_astCat->text().trimmed().toStdString();
  const QString code = m_mpcCat->text();
  s.mpcCatalogCode = code.size() == 1 ? code[0].toLatin1() : ' ';
  s.safeSnr = m_safeSnr->value();
  s.positions = report::trackletPositionsFromString(m_positions->currentData().toString().toStdString());
  return s;
}

void ReportDialog::setSubmissionSettings(const report::SubmissionSettings& s) {
  const bool wasLoading = m_loading;
  m_loading = true;
  m_station->setText(QString::fromStdString(s.stationCode));
  m_observers->setText(QString::fromStdString(s.observers));
  m_measurer->setText(QString::fromStdString(s.measurer));
  m_submitter->setText(QString::fromStdString(s.submitter));
  m_contactEmail->setText(QString::fromStdString(s.contactEmail));
  m_telescope->setText(QString::fromStdString(s.telescopeDesign));
  m_aperture->setValue(s.apertureM);
  m_detector->setCurrentText(QString::fromStdString(s.detector));
  m_astCat->setText(QString::fromStdString(s.astCat));
  m_mpcCat->setText(s.mpcCatalogCode == ' ' ? QString() : QString(QChar(s.mpcCatalogCode)));
  m_safeSnr->setValue(s.safeSnr);
  m_positions->setCurrentIndex(m_positions->findData(QString(report::toString(s.positions))));
  m_loading = wasLoading;
  onSettingsEdited();
}

void ReportDialog::onSettingsEdited() {
  if (m_loading) return;
  const nlohmann::json j = toJson(submissionSettings());
  saveReportSettings(j);
  refreshWarnings();
  emit settingsChanged(j);
}

void ReportDialog::setOutput(const QString& folder, const QString& baseName) {
  m_folder->setText(folder);
  m_base->setText(baseName);
}

void ReportDialog::setOutputs(bool json, bool csv, bool ds9, bool stacks, bool ades, bool mpc) {
  m_json->setChecked(json);
  m_csv->setChecked(csv);
  m_ds9->setChecked(ds9);
  m_stacks->setChecked(stacks);
  m_ades->setChecked(ades);
  m_mpc->setChecked(mpc);
}

void ReportDialog::setStackChoice(StackChoice choice) {
  m_stackChoice->setCurrentIndex(m_stackChoice->findData(static_cast<int>(choice)));
}

void ReportDialog::showEvent(QShowEvent* event) {
  // The catalogue of the WCS solution, when the frames' header names it and none is set.
  if (m_astCat->text().trimmed().isEmpty() && m_ctx.observation && m_ctx.observation->raw()) {
    if (const auto cat = report::astCatFromHeader(m_ctx.observation->raw()->header)) {
      m_astCat->setText(QString::fromStdString(*cat));
      onSettingsEdited();
    }
  }
  refreshWarnings();
  QDialog::showEvent(event);
}

void ReportDialog::refreshWarnings() {
  QStringList lines;
  // What a valid submission still needs (the export refuses until it is given).
  const report::SubmissionSettings settings = submissionSettings();
  for (const auto& [box, format] : {std::pair{m_ades, report::SubmissionFormat::Ades},
                                    std::pair{m_mpc, report::SubmissionFormat::Mpc80}}) {
    if (!box->isChecked()) continue;
    if (const auto problems = report::submissionProblems(settings, format); !problems.empty())
      lines << "⚠ " + QString::fromStdString(report::problemsText(problems, format)) + " (Observatory page)";
  }
  if (m_ctx.makeSession && m_ctx.observation && m_ctx.observation->result()) {
    try {
      const auto s = m_ctx.makeSession(toJson(submissionSettings()));
      for (const auto& w : report::submissionWarnings(s, submissionSettings()))
        lines << "⚠ " + QString::fromStdString(w);
    } catch (const std::exception& e) {
      lines << "⚠ " + QString::fromStdString(e.what());
    }
  }
  m_warning->setText(lines.join("\n"));
  m_warning->setVisible(!lines.isEmpty());
}

QString ReportDialog::warningText() const {
  return m_warning->text();
}
bool ReportDialog::warningVisible() const {
  return !m_warning->isHidden();
}
QString ReportDialog::resultText() const {
  return m_result->toPlainText();
}

bool ReportDialog::exportReports() {
  report::ReportRequest r;
  try {
    if (busy()) throw InputError("reports are being written");
    if (!m_ctx.makeSession) throw InputError("no session to report on");
    r.session = m_ctx.makeSession(toJson(submissionSettings()));
  } catch (const std::exception& e) {
    m_result->setPlainText("Failed: " + QString::fromStdString(e.what()));
    emit exportFinished(false, m_result->toPlainText());
    return false;
  }
  r.raw = m_ctx.observation ? m_ctx.observation->raw() : nullptr;
  // The loaded frames carry no registration; the prepared ones do (dithers, guiding drift).
  if (m_ctx.observation && r.raw && m_ctx.observation->prepared() &&
      m_ctx.observation->prepared()->filtered) {
    const FrameCube& registered = m_ctx.observation->prepared()->filtered->frames;
    if (registered.frameCount() == r.raw->frameCount() && registered.hasFrameOffsets())
      r.frameOffsets = registered.frameOffsets();
  }
  const std::string folder = m_folder->text().trimmed().toStdString();
  const std::string base =
      m_base->text().trimmed().isEmpty() ? "synthtrack" : m_base->text().trimmed().toStdString();
  if (folder.empty()) {
    m_result->setPlainText("Failed: reports: no output folder given");
    emit exportFinished(false, m_result->toPlainText());
    return false;
  }
  using report::ReportFile;
  for (const auto& [box, file] : {std::pair{m_json, ReportFile::CandidatesJson},
                                  std::pair{m_csv, ReportFile::CandidatesCsv}, std::pair{m_ds9, ReportFile::Ds9},
                                  std::pair{m_ades, ReportFile::AdesPsv}, std::pair{m_mpc, ReportFile::Mpc80}})
    if (box->isChecked()) r.files[file] = report::defaultFileName(folder, base, file);
  r.regions = report::regionContext(r.raw.get(), r.session, r.frameOffsets);
  if (m_stacks->isChecked()) r.stacksStem = (std::filesystem::path(folder) / base).string();
  r.stackChoice = static_cast<StackChoice>(m_stackChoice->currentData().toInt());
  r.selected = m_ctx.observation ? m_ctx.observation->selected() : std::nullopt;
  r.submission = submissionSettings();
  QSettings().setValue("report/folder", m_folder->text());
  QSettings().setValue("report/base", m_base->text());
  m_export->setEnabled(false);
  m_result->setPlainText("Writing reports to " + m_folder->text() + "…");
  m_watcher.setFuture(QtConcurrent::run([r = std::move(r)]() -> Result {
    Result out;
    try {
      NullProgress progress;
      CancelToken cancel;
      out.outcome = report::writeReports(r, progress, cancel);
    } catch (const std::exception& e) {
      out.error = QString::fromStdString(e.what());
    }
    return out;
  }));
  return true;
}

void ReportDialog::onFinished() {
  const Result r = m_watcher.result();
  m_export->setEnabled(true);
  QStringList lines;
  if (!r.error.isEmpty()) lines << "Failed: " + r.error;
  for (const auto& p : r.outcome.written)
    lines << "wrote " + QString::fromStdString(p);
  for (const auto& p : r.outcome.notWritten)
    lines << "not written (no detection to submit): " + QString::fromStdString(p);
  for (const auto& w : r.outcome.warnings)
    lines << "⚠ " + QString::fromStdString(w);
  m_result->setPlainText(lines.join("\n"));
  refreshWarnings();
  // Files asked for and not written (an empty submission) fail the export, as the CLI's exit 1.
  emit exportFinished(r.error.isEmpty() && r.outcome.notWritten.empty(), m_result->toPlainText());
}

}  // namespace st::ui
