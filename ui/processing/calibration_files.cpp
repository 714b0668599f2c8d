#include "calibration_files.hpp"

#include <QDir>
#include <QFileInfo>

#include "core_services.hpp"

namespace st::ui {

std::vector<std::string> stageFiles(const std::vector<StageSpec>& stages, const std::string& key) {
  for (const auto& s : stages)
    for (const auto& f : s.files)
      if (f.key == key) return f.paths;
  return {};
}

namespace {

/// The folder the science frames come from, or empty when they do not come from one folder.
QString scienceFolder(const QStringList& inputs) {
  QString folder;
  for (const QString& input : inputs) {
    const QFileInfo info(input);
    const QString dir = info.isDir() ? info.absoluteFilePath() : info.absolutePath();
    if (!info.exists() || (!folder.isEmpty() && dir != folder)) return {};
    if (info.isDir() && inputs.size() > 1) return {};  // several folders: no single science folder
    folder = dir;
  }
  return folder;
}

}  // namespace

CalibrationOffer offerCalibrationFolders(const QStringList& inputs) {
  CalibrationOffer offer;
  const QString science = scienceFolder(inputs);
  if (science.isEmpty()) return offer;
  QDir parent(science);
  const QString scienceName = parent.dirName();
  if (!parent.cdUp()) return offer;
  static const std::pair<const char*, QStringList> kNames[] = {
      {kBiasFiles, {"bias", "biases", "zero", "zeros"}},
      {kFlatFiles, {"flat", "flats"}},
      {kDarkFiles, {"dark", "darks"}},
  };
  QStringList found;
  const QStringList siblings = parent.entryList(QDir::Dirs | QDir::NoDotAndDotDot, QDir::Name);
  for (const auto& [key, names] : kNames) {
    for (const QString& sibling : siblings) {
      if (!names.contains(sibling.toLower()) || sibling == scienceName) continue;
      const QDir dir(parent.filePath(sibling));
      if (dir.entryList(QDir::Files).isEmpty()) continue;
      offer.folders[key] = QStringList{dir.absolutePath()};
      found << sibling + "/";
      break;
    }
  }
  if (!found.isEmpty()) {
    offer.note = QString("Offered: %1 found beside %2/. Check them, or Clear to pre-process without.")
                     .arg(found.join(found.size() == 2 ? " and " : ", "), scienceName);
  }
  return offer;
}

}  // namespace st::ui
