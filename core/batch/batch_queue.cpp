#include "st/batch/batch_queue.hpp"

#include <cmath>
#include <cstdio>

namespace st::batch {

BatchQueue::BatchQueue(const std::vector<std::size_t>& order) : m_pending(order.begin(), order.end()) {}

std::optional<std::size_t> BatchQueue::next(int worker) {
  if (m_pending.empty()) return std::nullopt;
  const std::size_t i = m_pending.front();
  m_pending.pop_front();
  m_held[worker] = i;
  return i;
}

void BatchQueue::finished(int worker) {
  m_held.erase(worker);
}

std::optional<std::size_t> BatchQueue::lose(int worker) {
  const auto it = m_held.find(worker);
  if (it == m_held.end()) return std::nullopt;
  const std::size_t i = it->second;
  m_held.erase(it);
  return i;
}

std::optional<std::size_t> BatchQueue::heldBy(int worker) const {
  const auto it = m_held.find(worker);
  if (it == m_held.end()) return std::nullopt;
  return it->second;
}

std::string progressLine(std::size_t done, std::size_t total, std::size_t skipped, std::size_t failed,
                         std::size_t processed, double elapsedS) {
  char buf[200];
  int n = std::snprintf(buf, sizeof buf, "%zu/%zu observations", done, total);
  if (skipped > 0 || failed > 0)
    n += std::snprintf(buf + n, sizeof buf - n, " (%zu skipped, %zu failed)", skipped, failed);
  if (processed == 0 || !(elapsedS > 0.0)) {
    std::snprintf(buf + n, sizeof buf - n, ", ETA -");
    return buf;
  }
  const double perHour = 3600.0 * static_cast<double>(processed) / elapsedS;
  const double etaS = static_cast<double>(total - done) * elapsedS / static_cast<double>(processed);
  const long eta = std::lround(etaS);
  if (eta >= 3600) {
    std::snprintf(buf + n, sizeof buf - n, ", %.1f/h, ETA %ldh%02ldm", perHour, eta / 3600,
                  (eta % 3600) / 60);
  } else {
    std::snprintf(buf + n, sizeof buf - n, ", %.1f/h, ETA %ldm%02lds", perHour, eta / 60, eta % 60);
  }
  return buf;
}

}  // namespace st::batch
