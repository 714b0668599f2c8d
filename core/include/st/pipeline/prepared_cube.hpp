#pragma once
// A pre-processed cube on disk and how it is read back. `preprocess` writes the zero-biased cube (background
// subtracted, static sources, cosmic rays and masked pixels zeroed; NOT matched-filtered) and, on request,
// the matched-filtered cube. Both carry keywords that say which one they are, so that a search or a stack
// of the file cannot treat the zero-biased cube as filtered (that halves the SNR and leaves no warning) or
// filter the filtered cube again:
//   STPREP = 1            the file was written by synthtrack preprocess (version of these keywords)
//   STFILT = T | F        the frames are matched-filtered (T) or zero-biased (F)
//   PSFFWHM, PSFBETA      the Moffat PSF of the observation (px; beta), the matched filter's PSF
//   SIGMAN                noise of one pixel of one zero-biased frame, counts
//   SIGMAF                noise of one filtered frame, counts (filtered cubes only)
//   SKYVX, SKYVY          sky rate, px/s
//   BGWINS, BGNFRM, BGMINOUT, BGCLIP   how the per-pixel background was taken (zero-biased cubes whose
//                         Prepared::backgroundWindows is set): the window (s) around each frame left out of
//                         its background, the evenly spaced frames of the clip, the fewest frames that must
//                         remain outside the window, and the clip's xi (stats::PixelBackgroundWindows); the
//                         co-moving fit models a slow mover's own flux in its background from them
// Files written before STFILT existed are still read: SIGMAF (written only on filtered cubes) means
// filtered; STEP = 'preprocess' with PSFFWHM and no SIGMAF means zero-biased.
#include <optional>
#include <string>
#include <vector>

#include "st/common/fits_header.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/psf/moffat.hpp"
#include "st/search/types.hpp"

namespace st::pipeline {

/// Which of preprocess's two cubes a file holds.
enum class PreparedState {
  ZeroBiased,  ///< preprocess -o: must be matched-filtered before a search
  Filtered,    ///< preprocess --filtered: searched as is
};

inline constexpr const char* kPreparedKeyword = "STPREP";
inline constexpr const char* kFilteredKeyword = "STFILT";
inline constexpr int kPreparedVersion = 1;
/// Moffat beta assumed when a prepared header has PSFFWHM but no PSFBETA (the paper's, §3.3).
inline constexpr double kDefaultPsfBeta = 4.0;

/// The cards preprocess writes on a cube it produced: provenance (io::provenanceCards("preprocess")),
/// SIGMAN, SKYVX/SKYVY, PSFFWHM/PSFBETA, and STPREP/STFILT for `state`; SIGMAF too when `state` is
/// Filtered (prepared.filtered.sigmaF). Without `state` (e.g. for the background image, which is no cube
/// to search) STPREP, STFILT and SIGMAF are left out.
FitsHeader preparedCubeCards(const Prepared& prepared, std::optional<PreparedState> state);

/// The per-pixel background's windows as a prepared cube's header records them (BGWINS, BGNFRM, BGMINOUT,
/// BGCLIP; stats::PixelBackgroundWindows::evenlyOver).
struct PreparedBackgroundWindows {
  double windowS = 0.0;
  std::size_t setSize = 0;
  std::size_t minOutside = 0;
  double clipXi = 0.0;
};

/// What a prepared cube's header says.
struct PreparedHeader {
  PreparedState state = PreparedState::ZeroBiased;
  std::optional<psf::Moffat> psf;  ///< from PSFFWHM (+ PSFBETA, else kDefaultPsfBeta); none without PSFFWHM
  std::optional<double> sigmaF;    ///< SIGMAF, counts
  std::optional<double> sigmaN;    ///< SIGMAN, counts
  Velocity skyRate;                ///< SKYVX/SKYVY, px/s; 0 when absent
  std::string evidence;            ///< the keywords that decided the state, e.g. "STFILT = F"
  std::optional<PreparedBackgroundWindows> backgroundWindows;  ///< BGWINS...; none in files before 2026-12-05
};

/// Recognises a prepared cube from `header`: nullopt when nothing in it says so (no STPREP, no STFILT, no
/// SIGMAF, no STEP = 'preprocess'). Throws st::InputError naming `source` and the keyword when the header
/// says prepared but is inconsistent (STPREP without STFILT, STFILT not T/F, a keyword that is not a
/// number, a PSF of FWHM <= 0 or beta <= 1).
std::optional<PreparedHeader> recognisePreparedHeader(const FitsHeader& header, const std::string& source);

/// As recognisePreparedHeader, but a header that is not a prepared one is an st::InputError naming
/// `source` and the missing keyword (STFILT) and telling what to run instead.
PreparedHeader readPreparedHeader(const FitsHeader& header, const std::string& source);

/// Values the user gives that win over the header's.
struct PreparedOverrides {
  std::optional<double>
      psfFwhmPx;                 ///< the matched filter's FWHM (zero-biased cubes; beta stays the header's)
  std::optional<double> sigmaF;  ///< noise of one filtered frame
};

/// The search's input made from a loaded prepared cube.
struct PreparedSearchInput {
  search::FilteredCube cube;
  PreparedHeader header;
  bool filteredHere = false;          ///< the cube was zero-biased and was matched-filtered on loading
  std::vector<std::string> warnings;  ///< the loader's warnings (FrameCube::warnings), moved here
  std::vector<std::string> notes;     ///< what was done with the cube, for the user
};

/// Turns `loaded` (io::loadFrames of a prepared cube; moved in, filtered in place, no copy) into the
/// search's input. A zero-biased cube (STFILT = F) is matched-filtered with the header's PSF
/// (stack::makeFilteredCube; sigma_F measured from the filtered frames, as for raw input); a filtered
/// cube (STFILT = T) is taken as is with SIGMAF, else sigma_F measured from it (1.4826 MAD). `overrides`
/// win over the header. Throws st::InputError naming the file (the first frame's) and keyword when the
/// header cannot be interpreted (readPreparedHeader), when a zero-biased cube has no PSF (PSFFWHM) and no
/// override, or when sigma_F cannot be measured; st::Cancelled.
PreparedSearchInput searchInputFromPrepared(FrameCube loaded, const PreparedOverrides& overrides,
                                            ProgressSink& progress, CancelToken& cancel);

/// For raw input about to be pre-processed: throws st::InputError when `raw`'s header says it is already a
/// prepared cube (recognisePreparedHeader), naming the file and the keyword and ending with `whatToDo`.
/// Pre-processing a zero-biased cube again finds no stars or background to remove, and a filtered one would
/// be filtered twice.
void checkNotPrepared(const FrameCube& raw, const std::string& whatToDo);

/// The per-pixel background's windows of prepared cube `frames` (its header's BGWINS...) for the co-moving
/// fit (Prepared::backgroundWindows): empty, with a note in `notes` saying why the fit keeps the paper's
/// model, when the header records none, when BGNFRM exceeds the cube's frames, or when a window is recorded
/// but the frames' times are not in order (the subtraction took none then).
stats::PixelBackgroundWindows preparedBackgroundWindows(const PreparedHeader& header, const FrameCube& frames,
                                                        std::vector<std::string>& notes);

/// The sidecar (prepared_json.hpp) that `preprocess -o FILE` writes beside FILE: FILE with extension .json.
std::string preparedSidecarPath(const std::string& cubePath);

/// "FILE" of a cube's first frame (for messages), or "the input" for an empty cube.
std::string cubeSource(const FrameCube& cube);

}  // namespace st::pipeline
