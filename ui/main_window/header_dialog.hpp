#pragma once
// The FITS header of the observation's first frame, one card per row (keyword, value, comment), filterable.
#include <QDialog>

#include "st/common/fits_header.hpp"

namespace st::ui {

class HeaderDialog : public QDialog {
  Q_OBJECT
 public:
  HeaderDialog(const FitsHeader& header, const QString& title, QWidget* parent = nullptr);
};

}  // namespace st::ui
