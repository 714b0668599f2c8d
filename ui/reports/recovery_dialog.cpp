#include "recovery_dialog.hpp"

#include <filesystem>

#include <QButtonGroup>
#include <QDialogButtonBox>
#include <QDir>
#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QFileInfo>
#include <QFontDatabase>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QLabel>
#include <QLineEdit>
#include <QPainter>
#include <QPlainTextEdit>
#include <QPushButton>
#include <QRadioButton>
#include <QSettings>
#include <QSplitter>
#include <QSvgRenderer>
#include <QVBoxLayout>

#include "observation.hpp"
#include "st/batch/batch_state.hpp"
#include "st/common/error.hpp"
#include "st/inject/completeness_svg.hpp"
#include "st/report/search_report.hpp"

namespace st::ui {

/// Draws an SVG document scaled to the widget with its aspect ratio kept (QSvgWidget stretches it), or a
/// placeholder line without one.
class CompletenessPlot : public QWidget {
 public:
  explicit CompletenessPlot(QWidget* parent) : QWidget(parent) {
    setMinimumSize(480, 330);
    setSizePolicy(QSizePolicy::Expanding, QSizePolicy::Expanding);
  }
  /// False when `svg` is empty or not valid SVG.
  bool setSvg(const QString& svg) {
    m_valid = !svg.isEmpty() && m_renderer.load(svg.toUtf8());
    update();
    return m_valid;
  }
  [[nodiscard]] bool valid() const { return m_valid; }
  void setPlaceholder(const QString& text) {
    m_placeholder = text;
    update();
  }
  [[nodiscard]] QSize sizeHint() const override { return {640, 440}; }

  /// The plot at `width` px on white; null when there is none.
  [[nodiscard]] QImage render(int width) const {
    if (!m_valid) return {};
    const QSize size = m_renderer.defaultSize().scaled(width, width * 10, Qt::KeepAspectRatio);
    QImage image(size, QImage::Format_RGB32);
    image.fill(Qt::white);
    QPainter p(&image);
    p.setRenderHint(QPainter::Antialiasing);
    m_renderer.render(&p, QRectF(QPointF(0, 0), size));
    return image;
  }

 protected:
  void paintEvent(QPaintEvent*) override {
    QPainter p(this);
    p.fillRect(rect(), palette().base());
    if (!m_valid) {
      p.setPen(palette().color(QPalette::PlaceholderText));
      p.drawText(rect().adjusted(12, 12, -12, -12), Qt::AlignCenter | Qt::TextWordWrap, m_placeholder);
      return;
    }
    p.setRenderHint(QPainter::Antialiasing);
    QSize size = m_renderer.defaultSize().scaled(this->size(), Qt::KeepAspectRatio);
    const QRectF target(QPointF((width() - size.width()) / 2.0, (height() - size.height()) / 2.0), size);
    m_renderer.render(&p, target);
  }

 private:
  mutable QSvgRenderer m_renderer;  // render() is not const in Qt
  bool m_valid = false;
  QString m_placeholder = "Choose a truth file and the candidates to see the completeness.";
};

namespace {

/// The plot's title, as `synthtrack-cli recovery` writes it.

QDoubleSpinBox* toleranceSpin(QWidget* parent, double value, const QString& suffix, const QString& tip) {
  auto* s = new QDoubleSpinBox(parent);
  s->setRange(0.05, 100.0);
  s->setDecimals(2);
  s->setSingleStep(0.25);
  s->setValue(value);
  s->setSuffix(suffix);
  s->setToolTip(tip);
  return s;
}

}  // namespace

RecoveryDialog::RecoveryDialog(Observation* observation, QWidget* parent)
    : QDialog(parent), m_obs(observation) {
  setWindowTitle("Injection recovery");
  m_plot = new CompletenessPlot(this);
  m_text = new QPlainTextEdit(this);
  m_text->setReadOnly(true);
  m_text->setLineWrapMode(QPlainTextEdit::NoWrap);
  m_text->setFont(QFontDatabase::systemFont(QFontDatabase::FixedFont));
  m_text->setPlaceholderText("The recovered fraction per bin of expected SNR and the unmatched candidates.");
  auto* split = new QSplitter(Qt::Vertical, this);
  split->addWidget(m_plot);
  split->addWidget(m_text);
  // The plot at about its own size (640 x 440), the rest for the table and the unmatched candidates.
  split->setStretchFactor(0, 3);
  split->setStretchFactor(1, 2);
  split->setSizes({520, 220});
  split->setChildrenCollapsible(false);
  m_message = new QLabel(this);
  m_message->setWordWrap(true);
  m_message->setTextInteractionFlags(Qt::TextSelectableByMouse);
  auto* buttons = new QDialogButtonBox(QDialogButtonBox::Close, this);
  m_save = buttons->addButton("Save…", QDialogButtonBox::ActionRole);
  m_save->setEnabled(false);
  m_save->setToolTip(
      "Write recovery.json, the CSV tables, completeness.svg and completeness.png into a folder");
  auto* layout = new QVBoxLayout(this);
  layout->addWidget(buildInputs());
  layout->addWidget(split, 1);
  layout->addWidget(m_message);
  layout->addWidget(buttons);
  connect(buttons, &QDialogButtonBox::rejected, this, &QDialog::reject);
  connect(m_save, &QPushButton::clicked, this, &RecoveryDialog::chooseSaveFolder);
  if (m_obs)
    connect(m_obs, &Observation::resultChanged, this, [this] {
      // A new search is scored again; a search that went leaves the file source (and its hint) in view.
      const bool wasSearch = candidateSource() == CandidateSource::CurrentSearch;
      refreshCurrentSearch();
      if (wasSearch && isVisible()) recompute();
    });
  refreshCurrentSearch();
  showMessage("Choose the truth file of the injection (truth.json) and the candidates of its search.", false);
  resize(860, 940);
}

QWidget* RecoveryDialog::buildInputs() {
  auto* box = new QWidget(this);
  auto* form = new QFormLayout(box);
  form->setContentsMargins(0, 0, 0, 0);
  // A file row: line edit and Browse…; a chosen file is scored at once, its folder remembered.
  auto fileRow = [this, box](QLineEdit*& edit, const QString& title, const QString& tip) {
    edit = new QLineEdit(box);
    edit->setPlaceholderText(tip);
    auto* browse = new QPushButton("Browse…", box);
    auto* row = new QHBoxLayout;
    row->addWidget(edit, 1);
    row->addWidget(browse);
    QLineEdit* e = edit;
    connect(e, &QLineEdit::editingFinished, this, [this, e] {
      if (e->isModified()) recompute();
      e->setModified(false);
    });
    connect(browse, &QPushButton::clicked, this, [this, e, title] {
      const QString start =
          e->text().isEmpty() ? QSettings().value("recovery/lastDir").toString() : e->text();
      const QString path = QFileDialog::getOpenFileName(this, title, start, "JSON (*.json);;All files (*)");
      if (path.isEmpty()) return;
      QSettings().setValue("recovery/lastDir", QFileInfo(path).absolutePath());
      e->setText(path);
      if (e == m_candidates) m_fromFile->setChecked(true);
      recompute();
    });
    return std::make_pair(row, browse);
  };
  auto truthRow = fileRow(m_truth, "Truth file of the injection", "truth.json of 'synthtrack-cli inject'");
  auto candRow = fileRow(m_candidates, "Candidates of the search",
                         "the JSON of 'synthtrack-cli search --json' or of Export > Reports");
  m_browseCandidates = candRow.second;
  m_fromFile = new QRadioButton("file", box);
  m_fromSearch = new QRadioButton("current search", box);
  m_fromFile->setChecked(true);
  auto* group = new QButtonGroup(box);
  group->addButton(m_fromFile);
  group->addButton(m_fromSearch);
  candRow.first->insertWidget(0, m_fromFile);
  auto* candidates = new QVBoxLayout;
  candidates->addLayout(candRow.first);
  candidates->addWidget(m_fromSearch);
  connect(m_fromFile, &QRadioButton::toggled, this, [this](bool file) {
    m_candidates->setEnabled(file);
    m_browseCandidates->setEnabled(file);
    recompute();
  });
  m_matchPx = toleranceSpin(box, 2.0, " px",
                            "Largest distance between the candidate and the mover at the truth's t_ref");
  m_matchVSteps =
      toleranceSpin(box, 1.0, " grid steps",
                    "Largest difference of each velocity component, in velocity-grid steps of the "
                    "search (grid.step_px_s of the candidates)");
  auto* tolerances = new QHBoxLayout;
  tolerances->addWidget(new QLabel("position", box));
  tolerances->addWidget(m_matchPx);
  tolerances->addSpacing(16);
  tolerances->addWidget(new QLabel("velocity, each component", box));
  tolerances->addWidget(m_matchVSteps);
  tolerances->addStretch(1);
  for (QDoubleSpinBox* s : {m_matchPx, m_matchVSteps})
    connect(s, &QDoubleSpinBox::valueChanged, this, [this] { recompute(); });
  form->addRow("Truth", truthRow.first);
  form->addRow("Candidates", candidates);
  form->addRow("Match within", tolerances);
  return box;
}

void RecoveryDialog::setTruthPath(const QString& path) {
  m_truth->setText(path);
}

void RecoveryDialog::setCandidatesPath(const QString& path) {
  m_candidates->setText(path);
  const QSignalBlocker block(m_fromFile);
  m_fromFile->setChecked(true);
  m_candidates->setEnabled(true);
  m_browseCandidates->setEnabled(true);
}

bool RecoveryDialog::setCandidateSource(CandidateSource source) {
  if (source == CandidateSource::CurrentSearch && !currentSearchAvailable()) return false;
  const QSignalBlocker a(m_fromFile), b(m_fromSearch);
  (source == CandidateSource::File ? m_fromFile : m_fromSearch)->setChecked(true);
  m_candidates->setEnabled(source == CandidateSource::File);
  m_browseCandidates->setEnabled(source == CandidateSource::File);
  return true;
}

RecoveryDialog::CandidateSource RecoveryDialog::candidateSource() const {
  return m_fromSearch->isChecked() ? CandidateSource::CurrentSearch : CandidateSource::File;
}

bool RecoveryDialog::currentSearchAvailable() const {
  return m_obs && m_obs->result();
}

void RecoveryDialog::setTolerances(double matchPx, double matchVSteps) {
  const QSignalBlocker a(m_matchPx), b(m_matchVSteps);
  m_matchPx->setValue(matchPx);
  m_matchVSteps->setValue(matchVSteps);
}

void RecoveryDialog::refreshCurrentSearch() {
  const bool available = currentSearchAvailable();
  m_fromSearch->setEnabled(available);
  m_fromSearch->setText(
      available ? QString("current search (%1 candidates)").arg(m_obs->result()->candidates.size())
                : QString("current search (run a search first)"));
  if (!available && m_fromSearch->isChecked()) setCandidateSource(CandidateSource::File);
}

QString RecoveryDialog::candidatesName() const {
  if (candidateSource() == CandidateSource::File) return m_candidates->text().trimmed();
  return "current search" + (m_obs && !m_obs->label().isEmpty() ? " of " + m_obs->label() : QString());
}

inject::CandidateSet RecoveryDialog::currentSearchCandidates() const {
  if (!currentSearchAvailable()) throw InputError("current search: the window has no search result");
  // The same JSON the CLI and the Reports dialog write, so the candidates read exactly as from a file.
  const auto& prepared = m_obs->prepared();
  const search::FilteredCube empty;
  const search::FilteredCube& cube = prepared && prepared->filtered ? *prepared->filtered : empty;
  try {
    return inject::candidatesFromJson(report::searchResultToJson(cube, *m_obs->result(), {}));
  } catch (const InputError& e) {
    throw InputError(std::string("current search: ") + e.what());
  }
}

RecoveryDialog::Scored RecoveryDialog::score() const {
  const std::string truthPath = m_truth->text().trimmed().toStdString();
  inject::Truth truth;
  const nlohmann::json truthJson = batch::readJsonFile(truthPath);  // names the file when it fails
  try {
    truth = inject::truthFromJson(truthJson);
  } catch (const InputError& e) {
    throw InputError(truthPath + ": " + e.what());
  }
  const std::string candPath = candidatesName().toStdString();
  inject::CandidateSet cands;
  if (candidateSource() == CandidateSource::CurrentSearch) {
    cands = currentSearchCandidates();
  } else {
    const nlohmann::json candJson = batch::readJsonFile(candPath);
    try {
      cands = inject::candidatesFromJson(candJson);
    } catch (const InputError& e) {
      throw InputError(candPath + ": " + e.what());
    }
  }
  inject::RecoveryParams params;
  params.matchPx = m_matchPx->value();
  params.matchVSteps = m_matchVSteps->value();
  Scored s;
  try {
    s.result = inject::matchRecovery(truth, cands, params);
  } catch (const InputError& e) {
    throw InputError(candPath + ": " + e.what());
  }
  s.set = {{"set", 0},
           {"truth_file", truthPath},
           {"candidates_file", candPath},
           {"injected", s.result.total},
           {"recovered", s.result.recovered},
           {"candidates", cands.candidates.size()},
           {"time_shift_s", s.result.timeShiftS}};
  return s;
}

bool RecoveryDialog::recompute() {
  m_saved.clear();
  const bool noCandidates =
      candidateSource() == CandidateSource::File && m_candidates->text().trimmed().isEmpty();
  if (m_truth->text().trimmed().isEmpty() || noCandidates) {
    // Not an error yet: a hint of what is missing.
    clearResult();
    m_error = m_truth->text().trimmed().isEmpty() ? "Choose the truth file of the injection (truth.json)."
                                                  : "Choose the candidates of the search (its JSON).";
    showMessage(m_error, false);
    m_plot->setPlaceholder("Choose a truth file and the candidates to see the completeness.");
    emit recomputed(false);
    return false;
  }
  try {
    Scored s = score();
    m_svg = QString::fromStdString(inject::completenessSvg(s.result.snrBins, inject::recoveryPlotTitle(s.result)));
    m_text->setPlainText(QString::fromStdString(inject::recoveryText(s.result)));
    m_plot->setSvg(m_svg);
    m_result = std::move(s.result);
    m_set = std::move(s.set);
    m_error.clear();
    m_save->setEnabled(true);
    showMessage(QString("%1 of %2 injected movers recovered.").arg(m_result->recovered).arg(m_result->total),
                false);
    emit recomputed(true);
    return true;
  } catch (const std::exception& e) {
    clearResult();
    m_error = QString::fromStdString(e.what());
    showMessage(m_error, true);
    m_plot->setPlaceholder("No plot: the inputs could not be read (the message below says why).");
    emit recomputed(false);
    return false;
  }
}

void RecoveryDialog::clearResult() {
  m_result.reset();
  m_set = nlohmann::json();
  m_svg.clear();
  m_plot->setSvg({});
  m_text->clear();
  m_save->setEnabled(false);
}

void RecoveryDialog::showMessage(const QString& text, bool error) {
  m_message->setStyleSheet(error ? "QLabel { color: #b00000; font-weight: bold; }" : QString());
  m_message->setText(text);
}

QString RecoveryDialog::summaryText() const {
  return m_text->toPlainText();
}

QImage RecoveryDialog::renderPlot(int width) const {
  return m_result ? m_plot->render(width) : QImage();
}

bool RecoveryDialog::saveTo(const QString& folder) {
  m_saved.clear();
  try {
    // Without a result the error that prevented it stays the one shown.
    if (!m_result)
      throw InputError(m_error.isEmpty() ? "nothing to save: no recovery result" : m_error.toStdString());
    if (folder.isEmpty()) throw InputError("no folder given");
    const std::filesystem::path dir(folder.toStdString());
    // What `synthtrack-cli recovery --out DIR` writes, with the one pair as its "sets".
    inject::writeRecoveryOutputs(*m_result, nlohmann::json::array({m_set}), dir.string());
    const QString pngPath = QDir(folder).filePath("completeness.png");
    const QImage png = renderPlot(1280);
    if (png.isNull() || !png.save(pngPath, "PNG"))
      throw InputError("cannot write '" + pngPath.toStdString() + "'");
    m_saved = QString(
                  "Wrote recovery.json, completeness.csv, objects.csv, unmatched.csv, completeness.svg and "
                  "completeness.png in %1")
                  .arg(QDir::toNativeSeparators(folder));
    m_error.clear();
    showMessage(m_saved, false);
    return true;
  } catch (const std::exception& e) {
    m_error = QString::fromStdString(e.what());
    showMessage(m_error, true);
    return false;
  }
}

void RecoveryDialog::chooseSaveFolder() {
  // Default: recovery/ beside the candidates file, as the CLI; else beside the truth file.
  QString base = candidateSource() == CandidateSource::File ? m_candidates->text().trimmed() : QString();
  if (base.isEmpty()) base = m_truth->text().trimmed();
  const QString start =
      base.isEmpty() ? QSettings().value("recovery/saveDir").toString() : QFileInfo(base).absolutePath();
  const QString folder = QFileDialog::getExistingDirectory(this, "Folder for the recovery outputs", start);
  if (folder.isEmpty()) return;
  QSettings().setValue("recovery/saveDir", folder);
  saveTo(folder);
}

}  // namespace st::ui
