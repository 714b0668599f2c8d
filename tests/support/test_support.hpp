#pragma once
// Helpers shared by the test suites: temporary folders, the real-data location, a simple TAN WCS.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "st/common/fits_header.hpp"
#include "st/common/frame_cube.hpp"

namespace st::test {

/// A fresh temporary folder, removed with everything in it when the object goes away.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  [[nodiscard]] const std::filesystem::path& path() const noexcept { return m_path; }
  [[nodiscard]] std::filesystem::path operator/(const std::string& name) const { return m_path / name; }

 private:
  std::filesystem::path m_path;
};

/// The folder with real telescope data (../shared/data/real, or $ST_REAL_DATA), or empty when absent.
/// Tests that need it call GTEST_SKIP() when this is empty.
std::filesystem::path realDataDir();

/// The files of `dir`, sorted by name.
std::vector<std::string> filesIn(const std::filesystem::path& dir);

/// `files` loaded as one cube; calibration frames (`science` false) get a nominal clock.
FrameCube loadFiles(const std::vector<std::string>& files, bool science);

/// Every file of `dir` (sorted by name) loaded as one cube; calibration frames (`science` false) get a
/// nominal clock, since they need no times.
FrameCube loadFolder(const std::filesystem::path& dir, bool science);

/// The shared Lowell 42-inch sequence of 5945 (realDataDir()/lowell42-5945): 15 science frames, its bias
/// and flat frames as loaded cubes; `found` false (and the cubes empty) when the data are absent.
struct Lowell5945 {
  bool found = false;
  FrameCube science, bias, flat;
};
Lowell5945 loadLowell5945();

/// Writes a TAN WCS into `h`: (raDeg, decDeg) at the 1-based pixel (crpix1, crpix2), north up, east left,
/// `arcsecPerPx` (CD matrix diagonal, no rotation).
void setTanWcs(FitsHeader& h, double raDeg, double decDeg, double crpix1, double crpix2, double arcsecPerPx);

/// ST_THREADS (parallelFor's worker count) set for one scope, then restored (or unset, as it was).
class ScopedThreads {
 public:
  explicit ScopedThreads(const std::string& threads);
  ~ScopedThreads();
  ScopedThreads(const ScopedThreads&) = delete;
  ScopedThreads& operator=(const ScopedThreads&) = delete;

 private:
  std::optional<std::string> m_old;
};

}  // namespace st::test
