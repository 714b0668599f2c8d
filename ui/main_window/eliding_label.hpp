#pragma once
// A status-bar label that never widens the window: its text (a session path can be 100 characters) is drawn
// elided in the middle when the label is narrower than it, text() stays whole, and the tooltip shows it all.
// A plain QLabel's minimum width is its whole text, which pushed the window past a 1366 px screen.
#include <QLabel>
#include <QPainter>
#include <QStyle>

namespace st::ui {

class ElidingLabel : public QLabel {
 public:
  /// `minimumWidthPx`: the least width it asks of the status bar; `preferredWidthPx`: the most it asks.
  ElidingLabel(const QString& text, int minimumWidthPx, int preferredWidthPx, QWidget* parent = nullptr)
      : QLabel(text, parent), m_min(minimumWidthPx), m_preferred(preferredWidthPx) {
    setSizePolicy(QSizePolicy::Preferred, QSizePolicy::Preferred);
  }
  QSize minimumSizeHint() const override { return {m_min, QLabel::minimumSizeHint().height()}; }
  QSize sizeHint() const override {
    const QSize full = QLabel::sizeHint();
    return {std::min(full.width(), m_preferred), full.height()};
  }

 protected:
  void paintEvent(QPaintEvent*) override {
    QPainter painter(this);
    const QRect r = contentsRect();
    const QString shown = fontMetrics().elidedText(text(), Qt::ElideMiddle, r.width());
    style()->drawItemText(&painter, r, Qt::AlignLeft | Qt::AlignVCenter, palette(), isEnabled(), shown,
                          foregroundRole());
  }

 private:
  int m_min;
  int m_preferred;
};

}  // namespace st::ui
