#pragma once
// Helpers shared by the test suites: temporary folders, the real-data location.
#include <filesystem>
#include <string>

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

}  // namespace st::test
