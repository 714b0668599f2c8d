#include "mpi_cluster.hpp"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <thread>

#include "st/config.hpp"
#if ST_HAVE_MPI
#include <mpi.h>
#endif

namespace st::app {

namespace {

#if ST_HAVE_MPI
bool launchedByMpi() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE", "MPI_LOCALNRANKS"}) {
    if (std::getenv(v) != nullptr) return true;
  }
  return false;
}
#endif

std::string hostName() {
  char buf[256] = {};
  if (::gethostname(buf, sizeof buf - 1) != 0) return "?";
  return buf;
}

}  // namespace

bool Cluster::compiledIn() {
  return ST_HAVE_MPI != 0;
}

Cluster::Cluster() : m_host(hostName()) {
#if ST_HAVE_MPI
  if (!launchedByMpi()) return;
  int provided = 0;
  MPI_Init_thread(nullptr, nullptr, MPI_THREAD_SERIALIZED, &provided);
  m_started = true;
  MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
  MPI_Comm_rank(MPI_COMM_WORLD, &m_rank);
  MPI_Comm_size(MPI_COMM_WORLD, &m_size);
  MPI_Comm local;
  MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, m_rank, MPI_INFO_NULL, &local);
  MPI_Comm_rank(local, &m_localRank);
  MPI_Comm_size(local, &m_localSize);
  int rootOfNode = m_rank;  // the world rank of this node's first rank
  MPI_Bcast(&rootOfNode, 1, MPI_INT, 0, local);
  m_nodeHasRoot = rootOfNode == 0;
  MPI_Comm_free(&local);
  m_active = m_size > 1;
#endif
}

Cluster::~Cluster() {
#if ST_HAVE_MPI
  if (m_started) MPI_Finalize();
#endif
}

bool Cluster::send(int dest, int tag, const std::string& bytes) {
#if ST_HAVE_MPI
  if (!m_started) return false;
  const std::lock_guard<std::mutex> lock(m_mutex);
  return MPI_Send(bytes.data(), static_cast<int>(bytes.size()), MPI_BYTE, dest, tag, MPI_COMM_WORLD) ==
         MPI_SUCCESS;
#else
  (void)dest, (void)tag, (void)bytes;
  return false;
#endif
}

bool Cluster::receive(int& source, int& tag, std::string& bytes, double timeoutS, int fromSource) {
#if ST_HAVE_MPI
  if (!m_started) return false;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeoutS);
  for (;;) {
    {
      const std::lock_guard<std::mutex> lock(m_mutex);
      int flag = 0;
      MPI_Status st;
      if (MPI_Iprobe(fromSource < 0 ? MPI_ANY_SOURCE : fromSource, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &st) !=
          MPI_SUCCESS) {
        return false;
      }
      if (flag) {
        int count = 0;
        MPI_Get_count(&st, MPI_BYTE, &count);
        bytes.assign(static_cast<std::size_t>(count), '\0');
        if (MPI_Recv(bytes.data(), count, MPI_BYTE, st.MPI_SOURCE, st.MPI_TAG, MPI_COMM_WORLD,
                     MPI_STATUS_IGNORE) != MPI_SUCCESS) {
          return false;
        }
        source = st.MPI_SOURCE;
        tag = st.MPI_TAG;
        return true;
      }
    }
    if (std::chrono::steady_clock::now() >= deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
#else
  (void)source, (void)tag, (void)bytes, (void)timeoutS, (void)fromSource;
  return false;
#endif
}

std::vector<std::string> Cluster::gather(const std::string& mine) {
  if (!m_started) return {mine};
#if ST_HAVE_MPI
  const std::lock_guard<std::mutex> lock(m_mutex);
  int n = static_cast<int>(mine.size());
  std::vector<int> sizes(m_rank == 0 ? m_size : 0);
  MPI_Gather(&n, 1, MPI_INT, sizes.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  std::vector<int> offsets(sizes.size(), 0);
  int total = 0;
  for (std::size_t i = 0; i < sizes.size(); ++i) {
    offsets[i] = total;
    total += sizes[i];
  }
  std::string all(static_cast<std::size_t>(total), '\0');
  MPI_Gatherv(mine.data(), n, MPI_BYTE, all.data(), sizes.data(), offsets.data(), MPI_BYTE, 0,
              MPI_COMM_WORLD);
  std::vector<std::string> out;
  for (std::size_t i = 0; i < sizes.size(); ++i)
    out.push_back(all.substr(offsets[i], sizes[i]));
  return out;
#else
  return {mine};
#endif
}

int Cluster::finishRank(int code) {
  if (!m_started || m_rank != 0 || m_lostPeers.empty()) return code;
  std::string ranks;
  for (const int r : m_lostPeers)
    ranks += (ranks.empty() ? "" : ", ") + std::to_string(r);
  std::fprintf(stderr,
               "batch: everything is written; ending the MPI job with MPI_Abort(%d), since MPI_Finalize would "
               "wait for the lost rank(s) %s\n",
               code, ranks.c_str());
  std::fflush(stdout);
  std::fflush(stderr);
  abort(code);
}

void Cluster::abort(int code) {
#if ST_HAVE_MPI
  if (m_started) MPI_Abort(MPI_COMM_WORLD, code);
#endif
  std::_Exit(code);
}

}  // namespace st::app
