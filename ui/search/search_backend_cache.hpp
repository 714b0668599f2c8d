#pragma once
// The search backend kept between the GUI's searches: the CUDA backend keeps its streams and pinned staging
// buffers per device (~25 ms to make, gpu/src/uploader.hpp), so a backend made afresh for every search
// would pay that each time. Used from the search job's worker thread only; the lock also keeps two
// searches from sharing one backend at once (backends are not thread-safe).
#include <memory>
#include <mutex>
#include <string>

#include "core_services.hpp"

namespace st::ui {

class SearchBackendCache {
 public:
  /// Runs `work(backend, message)` with the backend of `kind`, made with `make` when there is none of that
  /// kind yet (or the last one was of another kind); `message` is what `make` said when it made it.
  template <class Make, class Work>
  auto with(BackendKind kind, const Make& make, const Work& work) {
    std::lock_guard lock(m_mutex);
    if (!m_backend || m_kind != kind) {
      m_backend.reset();
      m_message.clear();
      m_backend = make(kind, m_message);
      m_kind = kind;
    }
    return work(*m_backend, m_message);
  }

 private:
  std::mutex m_mutex;
  std::unique_ptr<search::SearchBackend> m_backend;
  BackendKind m_kind = BackendKind::Auto;
  std::string m_message;
};

}  // namespace st::ui
