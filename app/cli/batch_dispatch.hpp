#pragma once
// The queue of a batch, run in one process or over MPI ranks (issue 17). Rank 0 hands out observations one
// at a time (largest first), watches every worker's heartbeat, and records how each ended; the workers run
// them (batch_runner.hpp). No MPI type here: mpi_cluster.hpp is the transport.
#include <functional>
#include <vector>

#include "batch_runner.hpp"
#include "mpi_cluster.hpp"

namespace st::app {

struct DispatchSettings {
  double workerTimeoutS = 120.0;  ///< a worker silent this long (no heartbeat) is declared dead
  double heartbeatS = 1.0;
};

/// Called at rank 0 as each observation ends (done, failed or skipped), for the progress line.
/// `index` is the observation's index in the list.
using OnOutcome = std::function<void(const RunOutcome&, int rank, std::size_t index)>;

/// Runs the observations `order` (indices into `observations`) to completion and returns one outcome per
/// index of `order`, at rank 0 (other ranks get an empty list once rank 0 lets them go). Without an active
/// cluster the queue runs in this process. An observation whose worker died is NotDone with the reason.
/// `stopRequested` is polled at rank 0: when it turns true the rest are NotDone.
std::vector<batch::Outcome> runQueue(Cluster& cluster, const std::vector<batch::Observation>& observations,
                                     const std::vector<std::size_t>& order, const BatchSettings& settings,
                                     const DispatchSettings& dispatch, const OnOutcome& onOutcome,
                                     const std::function<bool()>& stopRequested);

}  // namespace st::app
