#pragma once
// What the GUI's "Plate solve" passes to astrometry.net (st::astro::PlateSolveParams), kept in QSettings
// ("plateSolve/..."): the solve-field program, index folders, time limit, and scale and pointing hints for
// headers that have none. Edited in Run > Plate solve settings… and by the script's --solve-field and
// --index-dir.
#include <QString>
#include <QStringList>
#include <optional>

#include "st/astro/plate_solve.hpp"

class QWidget;

namespace st::ui {

struct PlateSolveSettings {
  QString solveField = "solve-field";  ///< a program on PATH, or a path
  QStringList indexDirs;               ///< empty: astrometry.net's configuration (/etc/astrometry.cfg)
  double timeLimitS = 120.0;
  std::optional<double> scaleArcsecPerPx;  ///< hint when the header has none
  std::optional<double> raDeg;             ///< pointing hint when the header has none
  std::optional<double> decDeg;

  [[nodiscard]] static PlateSolveSettings load();
  void save() const;
  [[nodiscard]] astro::PlateSolveParams params() const;
};

/// A modal dialog editing `settings` (Run > Plate solve settings…); true when accepted.
bool editPlateSolveSettings(PlateSolveSettings& settings, QWidget* parent);

}  // namespace st::ui
