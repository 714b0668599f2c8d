#pragma once
// The one unit that talks MPI (issue 17; ARCHITECTURE.md "Beyond one machine"). Everything else sees this
// small interface, with no MPI type in it, and a build without MPI gets a one-process cluster.
//
// Rules of the road:
// - MPI is started only when a launcher (mpirun, srun) started this process (its environment says so), so
//   a plain `synthtrack-cli batch` never touches MPI.
// - MPI_THREAD_SERIALIZED: every call below takes one mutex, so a worker's heartbeat thread and its main
//   thread may both send.
// - MPI_ERRORS_RETURN on MPI_COMM_WORLD: a failed call to a dead rank returns false instead of aborting.
// - Receives poll (MPI_Iprobe) with a timeout, so rank 0 never waits forever on a dead worker.
#include <mutex>
#include <string>
#include <vector>

namespace st::app {

class Cluster {
 public:
  /// Starts MPI when launched by mpirun/srun and MPI was compiled in; otherwise one process (rank 0 of 1).
  Cluster();
  /// MPI_Finalize when MPI was started (and not aborted).
  ~Cluster();
  Cluster(const Cluster&) = delete;
  Cluster& operator=(const Cluster&) = delete;

  [[nodiscard]] bool active() const noexcept { return m_active; }  ///< MPI running with more than 1 rank
  [[nodiscard]] int rank() const noexcept { return m_rank; }
  [[nodiscard]] int size() const noexcept { return m_size; }
  [[nodiscard]] int localRank() const noexcept { return m_localRank; }  ///< among the ranks on this node
  [[nodiscard]] int localSize() const noexcept { return m_localSize; }
  [[nodiscard]] const std::string& host() const noexcept { return m_host; }
  /// Whether rank 0 runs on this node (it hands out work and takes no device of its own).
  [[nodiscard]] bool nodeHasRoot() const noexcept { return m_nodeHasRoot; }

  /// Sends `bytes` with `tag` to `dest`; false when MPI reports an error (a dead peer).
  bool send(int dest, int tag, const std::string& bytes);
  /// Waits up to `timeoutS` for a message from `source` (-1: anyone); false on timeout.
  bool receive(int& source, int& tag, std::string& bytes, double timeoutS, int fromSource = -1);
  /// Every rank's `mine` at rank 0 (in rank order); other ranks get an empty list. Collective.
  std::vector<std::string> gather(const std::string& mine);
  /// Ends every rank of the job with `code` (MPI_Abort); a plain exit without MPI.
  [[noreturn]] void abort(int code);
  /// Rank 0 declared `rank` dead (it stopped answering). MPI_Finalize waits for every rank of the job, the
  /// dead one included, so a job that lost a rank must end by finishRank() instead of a plain return.
  void notePeerLost(int rank) noexcept { m_lostPeers.push_back(rank); }
  [[nodiscard]] const std::vector<int>& lostPeers() const noexcept { return m_lostPeers; }
  /// Returns `code` for a normal end (MPI_Finalize in the destructor). When a peer was lost, rank 0 ends the
  /// whole job with `code` (MPI_Abort) instead: the survivors, their work done and reported, would otherwise
  /// wait in MPI_Finalize for the dead rank forever, and so would mpirun.
  int finishRank(int code);
  /// Whether MPI support was compiled in.
  static bool compiledIn();

 private:
  std::mutex m_mutex;
  bool m_started = false;
  bool m_active = false;
  int m_rank = 0;
  int m_size = 1;
  int m_localRank = 0;
  int m_localSize = 1;
  bool m_nodeHasRoot = true;
  std::string m_host;
  std::vector<int> m_lostPeers;
};

}  // namespace st::app
