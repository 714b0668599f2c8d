#include "processing_panel.hpp"

#include <QDoubleSpinBox>
#include <QEvent>
#include <algorithm>
#include <QFileDialog>
#include <QFormLayout>
#include <QGroupBox>
#include <QHBoxLayout>
#include <QLabel>
#include <QLineEdit>
#include <QMenu>
#include <QPushButton>
#include <QScrollArea>
#include <QToolButton>
#include <QVBoxLayout>

namespace st::ui {
namespace {

constexpr const char* kSeparator = "; ";

QStringList splitPaths(const QString& text) {
  QStringList out;
  for (const QString& part : text.split(';', Qt::SkipEmptyParts)) {
    const QString p = part.trimmed();
    if (!p.isEmpty()) out << p;
  }
  return out;
}

QStringList toQt(const std::vector<std::string>& paths) {
  QStringList out;
  for (const auto& p : paths)
    out << QString::fromStdString(p);
  return out;
}

}  // namespace

ProcessingPanel::ProcessingPanel(std::vector<StageSpec> stages, QWidget* parent)
    : QWidget(parent), m_defaults(std::move(stages)) {
  auto* inner = new QWidget;
  auto* innerLayout = new QVBoxLayout(inner);
  innerLayout->setContentsMargins(2, 2, 2, 2);
  for (const StageSpec& stage : m_defaults) {
    auto* box = new QGroupBox(QString::fromStdString(stage.name), inner);
    if (!stage.help.empty()) box->setToolTip(QString::fromStdString(stage.help));
    box->setCheckable(stage.optional);
    box->setChecked(stage.enabled);
    auto* form = new QFormLayout(box);
    form->setContentsMargins(6, 4, 6, 4);
    form->setRowWrapPolicy(QFormLayout::WrapLongRows);
    std::vector<QLineEdit*> edits;
    if (!stage.files.empty() && !m_offerBox) {
      m_offerBox = new QWidget(box);
      auto* row = new QVBoxLayout(m_offerBox);
      row->setContentsMargins(0, 0, 0, 0);
      row->setSpacing(2);
      m_offerNote = new QLabel(m_offerBox);
      m_offerNote->setWordWrap(true);
      m_offerNote->setObjectName("calibrationOfferNote");
      m_offerNote->setStyleSheet("color: palette(highlight)");
      auto* clear = new QPushButton("Clear", m_offerBox);
      clear->setObjectName("clearCalibrationOffer");
      clear->setToolTip("Do not use the offered folders (pre-process without them)");
      row->addWidget(m_offerNote);
      row->addWidget(clear, 0, Qt::AlignLeft);
      connect(clear, &QPushButton::clicked, this, &ProcessingPanel::clearOffer);
      m_offerBox->hide();
      form->addRow(m_offerBox);
    }
    for (const StageFiles& f : stage.files) {
      // "Bias frames: [Add…]" above the field: paths are long and the dock is narrow (nothing at its edge).
      QWidget* field = fileRow(box, f);
      auto* head = new QWidget(box);
      auto* headLayout = new QHBoxLayout(head);
      headLayout->setContentsMargins(0, 0, 0, 0);
      headLayout->addWidget(new QLabel(QString::fromStdString(f.label) + ":", head));
      headLayout->addWidget(field->findChild<QToolButton*>());
      headLayout->addStretch(1);
      form->addRow(head);
      form->addRow(field);
      edits.push_back(m_fileEditByKey.at(f.key));
    }
    std::vector<QDoubleSpinBox*> spins;
    for (const StageParam& p : stage.params) {
      auto* spin = new QDoubleSpinBox(box);
      spin->setRange(p.minimum, p.maximum);
      spin->setDecimals(p.decimals);
      spin->setValue(p.value);
      if (!p.unit.empty()) spin->setSuffix(" " + QString::fromStdString(p.unit));
      spin->setToolTip(QString::fromStdString(p.help));
      form->addRow(QString::fromStdString(p.label), spin);
      spins.push_back(spin);
    }
    if (stage.params.empty() && stage.files.empty()) form->addRow(new QLabel("(no parameters)", box));
    innerLayout->addWidget(box);
    m_boxes.push_back(box);
    m_spins.push_back(std::move(spins));
    m_fileEdits.push_back(std::move(edits));
  }
  if (m_defaults.empty())
    innerLayout->addWidget(new QLabel("Pre-processing is not available in this build.", inner));
  innerLayout->addStretch(1);
  auto* scroll = new QScrollArea(this);
  m_viewport = scroll->viewport();
  m_viewport->installEventFilter(this);
  scroll->setWidget(inner);
  scroll->setWidgetResizable(true);
  scroll->setFrameShape(QFrame::NoFrame);

  m_run = new QPushButton(QIcon::fromTheme("media-playback-start"), "Run pre-processing", this);
  m_run->setEnabled(false);
  auto* reset = new QPushButton("Defaults", this);
  reset->setToolTip("Back to the paper's values (calibration frames are kept)");
  m_summary = new QLabel(this);
  m_summary->setWordWrap(true);
  auto* buttons = new QHBoxLayout;
  buttons->addWidget(m_run, 1);
  buttons->addWidget(reset);
  auto* layout = new QVBoxLayout(this);
  layout->setContentsMargins(2, 2, 2, 2);
  layout->addWidget(scroll, 1);
  layout->addLayout(buttons);
  layout->addWidget(m_summary);
  connect(m_run, &QPushButton::clicked, this, &ProcessingPanel::runRequested);
  connect(reset, &QPushButton::clicked, this, &ProcessingPanel::resetDefaults);
}

bool ProcessingPanel::eventFilter(QObject* watched, QEvent* event) {
  // The offer note wraps within what is visible: other rows (long stage titles) may make the panel wider
  // than the dock, and a note cut off at the right edge would hide its end.
  if (watched == m_viewport && event->type() == QEvent::Resize && m_offerBox) {
    const int width = std::max(120, m_viewport->width() - 24);
    m_offerBox->setMaximumWidth(width);
    // The form sized the note for the full row; without text heightForWidth is -1.
    m_offerNote->setMinimumHeight(std::max(0, m_offerNote->heightForWidth(width)));
  }
  return QWidget::eventFilter(watched, event);
}

QWidget* ProcessingPanel::fileRow(QWidget* parent, const StageFiles& files) {
  auto* row = new QWidget(parent);
  auto* layout = new QHBoxLayout(row);
  layout->setContentsMargins(0, 0, 0, 0);
  layout->setSpacing(2);
  auto* edit = new QLineEdit(QStringList(toQt(files.paths)).join(kSeparator), row);
  edit->setObjectName(QString::fromStdString(files.key));
  m_fileEditByKey[files.key] = edit;
  edit->setPlaceholderText("none (files or folders, ; between)");
  const QString help = QString::fromStdString(files.help);
  edit->setToolTip(help);
  connect(edit, &QLineEdit::textChanged, edit, [edit, help](const QString& text) {
    // The whole list on hover: the field is narrower than a path.
    const QStringList paths = splitPaths(text);
    edit->setToolTip(paths.isEmpty() ? help : help + "\n\n" + paths.join("\n"));
  });
  edit->setClearButtonEnabled(true);
  edit->setMinimumWidth(80);
  auto* add = new QToolButton(row);
  add->setText("Add…");
  add->setToolTip("Add FITS files or a folder of them");
  add->setPopupMode(QToolButton::InstantPopup);
  auto* menu = new QMenu(add);
  const std::string key = files.key;
  const QString label = QString::fromStdString(files.label);
  auto append = [this, edit, key](const QStringList& more) {
    if (more.isEmpty()) return;
    QStringList paths = splitPaths(edit->text());
    for (const QString& p : more)
      if (!paths.contains(p)) paths << p;
    edit->setText(paths.join(kSeparator));
    onFilesEdited(key);
  };
  menu->addAction("Files…", this, [this, append, label] {
    append(QFileDialog::getOpenFileNames(this, label + ": files", {},
                                         "FITS (*.fits *.fit *.fts *.fits.fz *.fz *.fits.gz);;All files (*)"));
  });
  menu->addAction("Folder…", this, [this, append, label] {
    const QString dir = QFileDialog::getExistingDirectory(this, label + ": folder");
    if (!dir.isEmpty()) append({dir});
  });
  add->setMenu(menu);
  layout->addWidget(edit, 1);
  connect(edit, &QLineEdit::textEdited, this, [this, key] { onFilesEdited(key); });
  return row;
}

QLineEdit* ProcessingPanel::fileEdit(const std::string& key) const {
  const auto it = m_fileEditByKey.find(key);
  return it == m_fileEditByKey.end() ? nullptr : it->second;
}

void ProcessingPanel::onFilesEdited(const std::string& key) {
  if (m_offered.erase(key) && m_offered.empty() && m_offerBox) m_offerBox->hide();
}

QStringList ProcessingPanel::files(const std::string& key) const {
  const QLineEdit* edit = fileEdit(key);
  return edit ? splitPaths(edit->text()) : QStringList{};
}

void ProcessingPanel::setFiles(const std::string& key, const QStringList& paths) {
  QLineEdit* edit = fileEdit(key);
  if (!edit) return;
  edit->setText(paths.join(kSeparator));
  onFilesEdited(key);
}

void ProcessingPanel::offerFiles(const std::map<std::string, QStringList>& offered, const QString& note) {
  for (const auto& [key, paths] : offered) {
    QLineEdit* edit = fileEdit(key);
    if (!edit) continue;
    edit->setText(paths.join(kSeparator));
    m_offered[key] = paths;
  }
  if (m_offerBox && !m_offered.empty()) {
    m_offerNote->setText(note);
    if (m_offerBox->maximumWidth() < QWIDGETSIZE_MAX)
      m_offerNote->setMinimumHeight(std::max(0, m_offerNote->heightForWidth(m_offerBox->maximumWidth())));
    m_offerBox->show();
  }
}

void ProcessingPanel::clearOffer() {
  for (const auto& [key, paths] : m_offered)
    if (QLineEdit* edit = fileEdit(key); edit && splitPaths(edit->text()) == paths) edit->clear();
  m_offered.clear();
  if (m_offerBox) m_offerBox->hide();
}

void ProcessingPanel::clearFiles() {
  for (const auto& edits : m_fileEdits)
    for (QLineEdit* e : edits)
      e->clear();
  m_offered.clear();
  if (m_offerBox) m_offerBox->hide();
}

QString ProcessingPanel::offerNote() const {
  return m_offerBox && !m_offered.empty() ? m_offerNote->text() : QString();
}

std::vector<StageSpec> ProcessingPanel::stages() const {
  std::vector<StageSpec> out = m_defaults;
  for (std::size_t s = 0; s < out.size(); ++s) {
    out[s].enabled = !m_boxes[s]->isCheckable() || m_boxes[s]->isChecked();
    for (std::size_t p = 0; p < out[s].params.size(); ++p)
      out[s].params[p].value = m_spins[s][p]->value();
    for (std::size_t f = 0; f < out[s].files.size(); ++f) {
      out[s].files[f].paths.clear();
      for (const QString& path : splitPaths(m_fileEdits[s][f]->text()))
        out[s].files[f].paths.push_back(path.toStdString());
    }
  }
  return out;
}

void ProcessingPanel::resetDefaults() {
  for (std::size_t s = 0; s < m_defaults.size(); ++s) {
    m_boxes[s]->setChecked(m_defaults[s].enabled);
    for (std::size_t p = 0; p < m_defaults[s].params.size(); ++p)
      m_spins[s][p]->setValue(m_defaults[s].params[p].value);
  }
}

void ProcessingPanel::setStages(const std::vector<StageSpec>& stages) {
  for (std::size_t s = 0; s < m_defaults.size() && s < stages.size(); ++s) {
    if (stages[s].name != m_defaults[s].name || stages[s].params.size() != m_spins[s].size()) continue;
    if (m_boxes[s]->isCheckable()) m_boxes[s]->setChecked(stages[s].enabled);
    for (std::size_t p = 0; p < m_spins[s].size(); ++p)
      m_spins[s][p]->setValue(stages[s].params[p].value);
    for (const StageFiles& f : stages[s].files)
      setFiles(f.key, toQt(f.paths));
  }
}

void ProcessingPanel::setRunEnabled(bool enabled) {
  m_run->setEnabled(enabled);
}
void ProcessingPanel::setSummary(const QString& text) {
  m_summary->setText(text);
}

}  // namespace st::ui
