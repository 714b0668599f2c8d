#include "main_window.hpp"

#include <QLabel>

namespace st::ui {

MainWindow::MainWindow(QWidget* parent) : QMainWindow(parent) {
  setWindowTitle("synthtrack");
  setCentralWidget(new QLabel("synthtrack", this));
  resize(1280, 800);
}

}  // namespace st::ui
