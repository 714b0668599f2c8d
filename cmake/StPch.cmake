# Precompiled headers (CI's build time on 2 cores): the GUI's, the CLI's and the tests' translation units
# parsed the same standard, Eigen, JSON, Qt and GoogleTest headers again and again. Each list below is
# precompiled once per target (st_precompile: st_ui, st_app_common) or once per test suite
# (tests/CMakeLists.txt). Measured one file at a time on the idle 2-core dev VM (2026-12-03), wall s without
# -> with: ui/main_window/main_window_jobs.cpp 15.6 -> 10.2, app/common/observation_pipeline.cpp 13.9 -> 8.6,
# tests/ui/test_session.cpp 20.3 -> 15.9, tests/core/test_inject.cpp 15.1 -> 12.9 (both tests at -O1). Not
# st_core: its files include little, and loading the header cost more than it saved. Only third-party
# headers: a change to one of ours never rebuilds a precompiled header. ST_PCH=OFF compiles as before.
option(ST_PCH "Precompile the third-party headers each target uses" ON)

set(ST_PCH_STD
    <algorithm> <array> <atomic> <chrono> <cmath> <condition_variable> <cstddef> <cstdint> <cstdio> <cstdlib>
    <cstring> <deque> <filesystem> <fstream> <functional> <future> <iomanip> <limits> <map> <memory> <mutex>
    <numeric> <optional> <random> <regex> <set> <span> <sstream> <stdexcept> <string> <thread> <tuple>
    <utility> <vector>)
set(ST_PCH_CORE ${ST_PCH_STD} <Eigen/Dense> <nlohmann/json.hpp>)
set(ST_PCH_QT
    <QAction> <QApplication> <QCheckBox> <QComboBox> <QCoreApplication> <QDialog> <QDialogButtonBox> <QDir>
    <QDockWidget> <QDoubleSpinBox> <QElapsedTimer> <QFile> <QFileDialog> <QFileInfo> <QFormLayout> <QFrame>
    <QFutureWatcher> <QGroupBox> <QHBoxLayout> <QHeaderView> <QImage> <QLabel> <QLineEdit> <QMainWindow>
    <QMenu> <QMessageBox> <QObject> <QPainter> <QPointer> <QProcess> <QPushButton> <QRegularExpression>
    <QSettings> <QSpinBox> <QStandardPaths> <QStatusBar> <QString> <QStringList> <QTableView> <QTimer>
    <QVBoxLayout> <QWidget> <QtConcurrent> <qcustomplot.h>)
set(ST_PCH_GUI ${ST_PCH_CORE} ${ST_PCH_QT})

# st_precompile(target HEADERS...): the headers precompiled for the target's sources (C++ targets only).
function(st_precompile target)
  if(ST_PCH)
    target_precompile_headers(${target} PRIVATE ${ARGN})
  endif()
endfunction()
