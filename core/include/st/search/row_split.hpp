#pragma once
// The exact velocity search split by rows of vy (issue 17, `search --mpi`): each part searches its rows
// with the CPU kernel, the parts are merged into the result one search over the whole grid gives. The
// transport between processes is not here (app/cli/mpi_cluster.cpp); the parts travel as bytes.
#include <cstdint>
#include <string>
#include <vector>

#include "st/search/candidates.hpp"
#include "st/search/types.hpp"

namespace st::search {

/// Rows [begin, end) of a grid's vy axis.
struct RowRange {
  int begin = 0;
  int end = 0;
};

/// Part `part` of `parts` of nvy rows: contiguous, sizes differing by at most one, the first parts the
/// larger; empty (begin == end) when there are more parts than rows. Pure.
RowRange rowShare(int nvy, int part, int parts);

/// What one part found: its cells above threshold (grid indices of the whole grid), their count before the
/// cap, and its rows of the velocity map.
struct RowSearch {
  RowRange rows;
  std::vector<CellHit> hits;
  std::int64_t hitsTotal = 0;
  std::vector<float> maxSnr;  ///< (rows.end - rows.begin) x nvx
  std::vector<int> argX, argY;
};

/// The exact CPU search (the CPU backend's kernel) over `rows` of `grid` only, with the threshold and
/// minimum frames of the whole grid (startSearchResult). An empty range gives an empty part. Throws
/// st::InputError, st::Cancelled.
RowSearch searchRows(const FilteredCube& cube, const VelocityGrid& grid, const SearchParams& params,
                     RowRange rows, ProgressSink& progress, CancelToken& cancel);

/// The parts, covering the grid's rows, merged into one result: hits pooled and clustered as the CPU
/// backend does (setCandidates), map rows put in place. Identical to the CPU backend's exact search over
/// the whole grid whenever the cells above threshold are at most params.maxCandidates (else the same up to
/// ties at the cap). `backend` names it in the result. Throws st::InputError when the parts do not cover the
/// rows exactly once.
SearchResult mergeRowSearches(const FilteredCube& cube, const VelocityGrid& grid, const SearchParams& params,
                              std::vector<RowSearch> parts, std::string backend);

/// A part as bytes (native layout: the ranks of one job share an architecture) and back. fromBytes throws
/// st::InputError when the bytes are truncated or inconsistent.
std::string toBytes(const RowSearch& part);
RowSearch rowSearchFromBytes(const std::string& bytes);

}  // namespace st::search
