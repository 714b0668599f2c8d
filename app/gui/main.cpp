#include <QApplication>

#include "main_window.hpp"

int main(int argc, char** argv) {
  QApplication app(argc, argv);
  st::ui::MainWindow window;
  window.show();
  return QApplication::exec();
}
