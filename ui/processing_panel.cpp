#include "processing_panel.hpp"

#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QGroupBox>
#include <QHBoxLayout>
#include <QLabel>
#include <QPushButton>
#include <QScrollArea>
#include <QVBoxLayout>

namespace st::ui {

ProcessingPanel::ProcessingPanel(std::vector<StageSpec> stages, QWidget* parent)
    : QWidget(parent), m_defaults(std::move(stages)) {
  auto* inner = new QWidget;
  auto* innerLayout = new QVBoxLayout(inner);
  innerLayout->setContentsMargins(2, 2, 2, 2);
  for (const StageSpec& stage : m_defaults) {
    auto* box = new QGroupBox(QString::fromStdString(stage.name), inner);
    box->setCheckable(stage.optional);
    box->setChecked(stage.enabled);
    auto* form = new QFormLayout(box);
    form->setContentsMargins(6, 4, 6, 4);
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
    if (stage.params.empty()) form->addRow(new QLabel("(no parameters)", box));
    innerLayout->addWidget(box);
    m_boxes.push_back(box);
    m_spins.push_back(std::move(spins));
  }
  if (m_defaults.empty())
    innerLayout->addWidget(new QLabel("Pre-processing is not available in this build.", inner));
  innerLayout->addStretch(1);
  auto* scroll = new QScrollArea(this);
  scroll->setWidget(inner);
  scroll->setWidgetResizable(true);
  scroll->setFrameShape(QFrame::NoFrame);

  m_run = new QPushButton(QIcon::fromTheme("media-playback-start"), "Run pre-processing", this);
  m_run->setEnabled(false);
  auto* reset = new QPushButton("Defaults", this);
  reset->setToolTip("Back to the paper's values");
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

std::vector<StageSpec> ProcessingPanel::stages() const {
  std::vector<StageSpec> out = m_defaults;
  for (std::size_t s = 0; s < out.size(); ++s) {
    out[s].enabled = !m_boxes[s]->isCheckable() || m_boxes[s]->isChecked();
    for (std::size_t p = 0; p < out[s].params.size(); ++p)
      out[s].params[p].value = m_spins[s][p]->value();
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
  }
}

void ProcessingPanel::setRunEnabled(bool enabled) {
  m_run->setEnabled(enabled);
}
void ProcessingPanel::setSummary(const QString& text) {
  m_summary->setText(text);
}

}  // namespace st::ui
