#include "header_dialog.hpp"

#include <QHeaderView>
#include <QLineEdit>
#include <QTableWidget>
#include <QVBoxLayout>

namespace st::ui {

HeaderDialog::HeaderDialog(const FitsHeader& header, const QString& title, QWidget* parent)
    : QDialog(parent) {
  setWindowTitle("Header — " + title);
  resize(720, 560);
  auto* filter = new QLineEdit(this);
  filter->setPlaceholderText("filter keywords, values or comments…");
  auto* table = new QTableWidget(static_cast<int>(header.cards.size()), 3, this);
  table->setHorizontalHeaderLabels({"Keyword", "Value", "Comment"});
  table->verticalHeader()->setVisible(false);
  table->verticalHeader()->setDefaultSectionSize(20);
  table->setEditTriggers(QAbstractItemView::NoEditTriggers);
  table->horizontalHeader()->setStretchLastSection(true);
  QFont mono("monospace");
  mono.setStyleHint(QFont::TypeWriter);
  table->setFont(mono);
  for (int r = 0; r < static_cast<int>(header.cards.size()); ++r) {
    const FitsCard& c = header.cards[static_cast<std::size_t>(r)];
    const QString value =
        c.isString ? "'" + QString::fromStdString(c.value) + "'" : QString::fromStdString(c.value);
    table->setItem(r, 0, new QTableWidgetItem(QString::fromStdString(c.key)));
    table->setItem(r, 1, new QTableWidgetItem(value));
    table->setItem(r, 2, new QTableWidgetItem(QString::fromStdString(c.comment)));
  }
  table->resizeColumnsToContents();
  auto* layout = new QVBoxLayout(this);
  layout->addWidget(filter);
  layout->addWidget(table, 1);
  connect(filter, &QLineEdit::textChanged, this, [table](const QString& text) {
    for (int r = 0; r < table->rowCount(); ++r) {
      bool match = text.isEmpty();
      for (int c = 0; c < 3 && !match; ++c)
        match = table->item(r, c)->text().contains(text, Qt::CaseInsensitive);
      table->setRowHidden(r, !match);
    }
  });
}

}  // namespace st::ui
