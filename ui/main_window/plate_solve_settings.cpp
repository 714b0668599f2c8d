#include "plate_solve_settings.hpp"

#include <QDialog>
#include <QDialogButtonBox>
#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QLineEdit>
#include <QSettings>

namespace st::ui {
namespace {

std::optional<double> optionalNumber(const QSettings& s, const char* key) {
  bool ok = false;
  const double v = s.value(key).toDouble(&ok);
  return ok && s.contains(key) ? std::optional<double>(v) : std::nullopt;
}

void setOptional(QSettings& s, const char* key, std::optional<double> v) {
  if (v)
    s.setValue(key, *v);
  else
    s.remove(key);
}

// A spin box whose minimum stands for "none" (shown as `none`).
QDoubleSpinBox* optionalSpin(QWidget* parent, double lo, double hi, int decimals, std::optional<double> v,
                             const QString& none) {
  auto* box = new QDoubleSpinBox(parent);
  box->setRange(lo, hi);
  box->setDecimals(decimals);
  box->setSpecialValueText(none);
  box->setValue(v.value_or(lo));
  return box;
}

std::optional<double> optionalValue(const QDoubleSpinBox* box) {
  return box->value() > box->minimum() ? std::optional<double>(box->value()) : std::nullopt;
}

}  // namespace

PlateSolveSettings PlateSolveSettings::load() {
  const QSettings s;
  PlateSolveSettings out;
  out.solveField = s.value("plateSolve/solveField", out.solveField).toString();
  out.indexDirs = s.value("plateSolve/indexDirs").toStringList();
  out.timeLimitS = s.value("plateSolve/timeLimitS", out.timeLimitS).toDouble();
  out.scaleArcsecPerPx = optionalNumber(s, "plateSolve/scaleArcsecPerPx");
  out.raDeg = optionalNumber(s, "plateSolve/raDeg");
  out.decDeg = optionalNumber(s, "plateSolve/decDeg");
  return out;
}

void PlateSolveSettings::save() const {
  QSettings s;
  s.setValue("plateSolve/solveField", solveField);
  s.setValue("plateSolve/indexDirs", indexDirs);
  s.setValue("plateSolve/timeLimitS", timeLimitS);
  setOptional(s, "plateSolve/scaleArcsecPerPx", scaleArcsecPerPx);
  setOptional(s, "plateSolve/raDeg", raDeg);
  setOptional(s, "plateSolve/decDeg", decDeg);
}

astro::PlateSolveParams PlateSolveSettings::params() const {
  astro::PlateSolveParams p;
  p.solveField = solveField.trimmed().isEmpty() ? std::string("solve-field") : solveField.trimmed().toStdString();
  for (const QString& d : indexDirs)
    if (!d.trimmed().isEmpty()) p.indexDirs.push_back(d.trimmed().toStdString());
  p.timeLimitS = timeLimitS;
  p.scaleArcsecPerPx = scaleArcsecPerPx;
  p.raDeg = raDeg;
  p.decDeg = decDeg;
  return p;
}

bool editPlateSolveSettings(PlateSolveSettings& settings, QWidget* parent) {
  QDialog d(parent);
  d.setWindowTitle("Plate solve settings");
  auto* form = new QFormLayout(&d);
  auto* program = new QLineEdit(settings.solveField, &d);
  program->setToolTip("astrometry.net's solve-field (Debian package astrometry.net): a name on PATH or a path");
  auto* dirs = new QLineEdit(settings.indexDirs.join(';'), &d);
  dirs->setPlaceholderText("from /etc/astrometry.cfg");
  dirs->setToolTip("Folders of index files (index-*.fits), separated by ';'");
  auto* limit = new QDoubleSpinBox(&d);
  limit->setRange(5, 3600);
  limit->setSuffix(" s");
  limit->setValue(settings.timeLimitS);
  auto* scale = optionalSpin(&d, 0.0, 100.0, 4, settings.scaleArcsecPerPx, "from the header");
  scale->setSuffix(" \"/px");
  auto* ra = optionalSpin(&d, -1.0, 360.0, 5, settings.raDeg, "from the header");
  auto* dec = optionalSpin(&d, -91.0, 90.0, 5, settings.decDeg, "from the header");
  form->addRow("solve-field", program);
  form->addRow("Index folders", dirs);
  form->addRow("Time limit", limit);
  form->addRow("Plate scale hint", scale);
  form->addRow("RA hint [deg]", ra);
  form->addRow("Dec hint [deg]", dec);
  auto* buttons = new QDialogButtonBox(QDialogButtonBox::Ok | QDialogButtonBox::Cancel, &d);
  form->addRow(buttons);
  QObject::connect(buttons, &QDialogButtonBox::accepted, &d, &QDialog::accept);
  QObject::connect(buttons, &QDialogButtonBox::rejected, &d, &QDialog::reject);
  if (d.exec() != QDialog::Accepted) return false;
  settings.solveField = program->text();
  settings.indexDirs = dirs->text().split(';', Qt::SkipEmptyParts);
  settings.timeLimitS = limit->value();
  settings.scaleArcsecPerPx = optionalValue(scale);
  settings.raDeg = optionalValue(ra);
  settings.decDeg = optionalValue(dec);
  settings.save();
  return true;
}

}  // namespace st::ui
