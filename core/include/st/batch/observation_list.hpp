#pragma once
// The observations of a batch (issue 17): from inputs on the command line, from a manifest (JSON or CSV),
// or cut from a night of frames into overlapping cubes. Pure description: nothing here reads pixels.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace st::batch {

/// One observation: what `synthtrack-cli search --fit` would be given for it.
struct Observation {
  std::string name;                 ///< unique within the batch; the name of its output folder
  std::vector<std::string> inputs;  ///< a cube file, a folder of frames, or frame files (io::loadFrames)
  std::vector<std::string> bias, dark, flat;  ///< calibration frames (none: overscan/trim only)
  /// Search options by their CLI name without "--" ("vmax-deg-day" -> "40"); they override the batch's.
  std::map<std::string, std::string> params;
  /// Observations of one group (the cubes cut from one night, or a manifest's "group") share a field:
  /// the catalogue merges their detections of the same object. Empty: a group of its own.
  std::string group;
  std::uintmax_t inputBytes = 0;  ///< total size of the input files (largest first); 0 when unknown
};

/// The FITS files of `folder` (.fits .fit .fts, optionally .gz or .fz), sorted by name, as io::loadFrames
/// expands a folder. Throws st::InputError when it is not a readable folder.
std::vector<std::string> framesInFolder(const std::string& folder);

/// Total size in bytes of the files of `inputs` (folders expanded); missing files count 0.
std::uintmax_t inputBytes(const std::vector<std::string>& inputs);

/// One observation per input (a cube file or a folder), named after the file's stem or the folder's
/// name; names made unique by "-2", "-3", ... Inputs need not exist (a missing one fails when processed).
std::vector<Observation> observationsFromInputs(const std::vector<std::string>& inputs);

/// Reads a manifest. JSON: an array of objects (or {"observations": [...]}) with "inputs" (string or
/// array), optional "name", "bias", "dark", "flat" (string or array), "group" and "params" (object of
/// search options, e.g. {"vmax-deg-day": 40}; '_' in a key reads as '-'). CSV: a header line naming the
/// columns (inputs, name, bias, dark, flat, group; any other column is a search option), one observation
/// per line, several files in one field separated by ';', lines starting with '#' ignored. Relative paths
/// are taken relative to the manifest's folder. Throws st::InputError naming the line or entry at fault.
std::vector<Observation> readManifest(const std::string& path);

/// Cuts an observation whose input is one folder of frames (or a list of frame files) into cubes of
/// `framesPerCube` frames, consecutive cubes sharing `overlap` frames (so a mover crossing a cut is whole
/// in one cube); the last cube ends at the last frame (it overlaps its predecessor more when the frames do
/// not divide evenly). Cubes are named NAME_c000, NAME_c001, ... and share the group NAME (or the
/// observation's group). Frames are taken in name order, the order of their times for the usual numbered
/// file names. Throws st::InputError when framesPerCube < 2, overlap < 0 or overlap >= framesPerCube, or the
/// input is a single cube file.
std::vector<Observation> splitObservation(const Observation& obs, int framesPerCube, int overlap);

/// The cube boundaries splitObservation uses for `frames` frames: [begin, end) pairs. Pure.
std::vector<std::pair<int, int>> splitRanges(int frames, int framesPerCube, int overlap);

/// Indices of `observations` ordered largest input first (ties: list order), the order work is handed out.
std::vector<std::size_t> largestFirst(const std::vector<Observation>& observations);

/// `text` reduced to a folder name: letters, digits, '-', '_' and '.' kept, others '_'; never empty.
std::string safeName(const std::string& text);

}  // namespace st::batch
