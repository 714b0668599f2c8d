#pragma once
// Calibration frames beside the science frames: a science folder ".../night/science" with sibling folders
// ".../night/bias", ".../night/flat" (or "flats") and ".../night/dark" (or "darks"), any case, is what many
// observatories' and pipelines' layouts look like (the shared Lowell 42-inch frames among them). The GUI
// offers such folders in the Calibration stage, with a note the user can clear; nothing is applied unseen.
#include <QString>
#include <QStringList>
#include <map>
#include <string>

namespace st::ui {

/// Keys of the calibration stage's file lists (StageFiles::key), as `synthtrack-cli preprocess --bias/--flat
/// /--dark` takes them.
inline constexpr const char* kBiasFiles = "bias";
inline constexpr const char* kFlatFiles = "flat";
inline constexpr const char* kDarkFiles = "dark";

struct CalibrationOffer {
  std::map<std::string, QStringList> folders;  ///< key (bias, flat, dark) -> the sibling folder found
  QString note;  ///< "Offered: bias/ and flat/ beside science/ …", empty when nothing was found
};

/// The calibration folders beside the science frames: `inputs` is what was opened (one folder, or files that
/// all sit in one folder); their folder's siblings named bias/biases/zero, flat/flats, dark/darks (any case)
/// are offered. Nothing when the inputs are spread over folders or a sibling holds no file. Reads directory
/// listings only (no FITS file is opened).
CalibrationOffer offerCalibrationFolders(const QStringList& inputs);

}  // namespace st::ui
