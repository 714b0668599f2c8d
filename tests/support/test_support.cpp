#include "test_support.hpp"

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

}  // namespace st::test
