#include "test_support.hpp"

#include <algorithm>
#include <string>
#include <vector>

#include "st/common/progress.hpp"
#include "st/io/fits_reader.hpp"

#include <atomic>
#include <cstdlib>
#include <random>
#include <system_error>

namespace st::test {

TempDir::TempDir() {
  static std::atomic<int> counter{0};
  std::random_device rd;
  const auto base = std::filesystem::temp_directory_path();
  for (;;) {
    auto candidate = base / ("synthtrack-test-" + std::to_string(rd()) + "-" + std::to_string(counter++));
    if (std::filesystem::create_directory(candidate)) {
      m_path = candidate;
      return;
    }
  }
}

TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::remove_all(m_path, ec);
}

std::filesystem::path realDataDir() {
  std::filesystem::path dir = ST_REAL_DATA_DIR;
  if (const char* env = std::getenv("ST_REAL_DATA")) dir = env;
  std::error_code ec;
  if (std::filesystem::is_directory(dir, ec)) return dir;
  return {};
}

void setTanWcs(FitsHeader& h, double raDeg, double decDeg, double crpix1, double crpix2, double arcsecPerPx) {
  h.setString("CTYPE1", "RA---TAN");
  h.setString("CTYPE2", "DEC--TAN");
  h.setNumber("CRVAL1", raDeg);
  h.setNumber("CRVAL2", decDeg);
  h.setNumber("CRPIX1", crpix1);
  h.setNumber("CRPIX2", crpix2);
  h.setNumber("CD1_1", -arcsecPerPx / 3600.0);
  h.setNumber("CD1_2", 0.0);
  h.setNumber("CD2_1", 0.0);
  h.setNumber("CD2_2", arcsecPerPx / 3600.0);
}

std::vector<std::string> filesIn(const std::filesystem::path& dir) {
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  return files;
}

FrameCube loadFiles(const std::vector<std::string>& files, bool science) {
  io::LoadOptions opt;
  if (!science) {
    opt.startMjd = 0.0;
    opt.frameRateHz = 1.0;
  }
  NullProgress p;
  CancelToken c;
  return io::loadFrames(files, opt, p, c);
}

FrameCube loadFolder(const std::filesystem::path& dir, bool science) {
  return loadFiles(filesIn(dir), science);
}

Lowell5945 loadLowell5945() {
  Lowell5945 out;
  const auto root = realDataDir();
  if (root.empty() || !std::filesystem::is_directory(root / "lowell42-5945")) return out;
  const auto dir = root / "lowell42-5945";
  out.found = true;
  out.science = loadFolder(dir / "science", true);
  out.bias = loadFolder(dir / "bias", false);
  out.flat = loadFolder(dir / "flat", false);
  return out;
}

ScopedThreads::ScopedThreads(const std::string& threads) {
  if (const char* old = std::getenv("ST_THREADS")) m_old = old;
  ::setenv("ST_THREADS", threads.c_str(), 1);
}

ScopedThreads::~ScopedThreads() {
  if (m_old)
    ::setenv("ST_THREADS", m_old->c_str(), 1);
  else
    ::unsetenv("ST_THREADS");
}

}  // namespace st::test
