#include "st/search/row_split.hpp"

#include <algorithm>
#include <chrono>
#include <cstring>

#include "ipsa_kernel.hpp"
#include "st/common/error.hpp"
#include "st/search/search_run.hpp"

namespace st::search {

RowRange rowShare(int nvy, int part, int parts) {
  if (parts < 1 || part < 0 || part >= parts)
    throw InputError("row share " + std::to_string(part) + " of " + std::to_string(parts) + " is not a part");
  const int base = nvy / parts;
  const int extra = nvy % parts;
  const int begin = part * base + std::min(part, extra);
  return {begin, begin + base + (part < extra ? 1 : 0)};
}

RowSearch searchRows(const FilteredCube& cube, const VelocityGrid& grid, const SearchParams& params,
                     RowRange rows, ProgressSink& progress, CancelToken& cancel) {
  const SearchResult start = startSearchResult(cube, grid, params, "cpu", SearchMethod::Exact);
  RowSearch out;
  out.rows = rows;
  if (rows.end <= rows.begin) return out;
  detail::KernelParams kp;
  kp.sigmaF = cube.sigmaF;
  kp.snrThreshold = start.snrThreshold;
  kp.minFrames = start.minFrames;
  kp.maxHits = params.maxCandidates;
  kp.ivyBegin = rows.begin;
  kp.ivyEnd = rows.end;
  const detail::Roi roi{0, 0, cube.frames.width(), cube.frames.height()};
  detail::KernelOutput k = detail::runIpsaKernel(cube.frames, grid, roi, kp, progress, cancel);
  out.hits = std::move(k.hits);
  out.hitsTotal = k.hitsTotal;
  const auto b = static_cast<std::size_t>(rows.begin) * grid.nvx;
  const auto e = static_cast<std::size_t>(rows.end) * grid.nvx;
  out.maxSnr.assign(k.map.maxSnr.begin() + b, k.map.maxSnr.begin() + e);
  out.argX.assign(k.map.argX.begin() + b, k.map.argX.begin() + e);
  out.argY.assign(k.map.argY.begin() + b, k.map.argY.begin() + e);
  return out;
}

SearchResult mergeRowSearches(const FilteredCube& cube, const VelocityGrid& grid, const SearchParams& params,
                              std::vector<RowSearch> parts, std::string backend) {
  const auto start = std::chrono::steady_clock::now();
  SearchResult result = startSearchResult(cube, grid, params, std::move(backend), SearchMethod::Exact);
  result.map = detail::emptyVelocityMap(grid);
  std::vector<int> covered(static_cast<std::size_t>(grid.nvy), 0);
  std::vector<CellHit> hits;
  for (RowSearch& p : parts) {
    if (p.rows.begin < 0 || p.rows.end > grid.nvy) throw InputError("a search part lies outside the grid");
    const std::size_t n = static_cast<std::size_t>(p.rows.end - p.rows.begin) * grid.nvx;
    if (p.rows.end > p.rows.begin && (p.maxSnr.size() != n || p.argX.size() != n || p.argY.size() != n))
      throw InputError("a search part's map has the wrong size");
    for (int r = p.rows.begin; r < p.rows.end; ++r)
      ++covered[r];
    const std::size_t off = static_cast<std::size_t>(p.rows.begin) * grid.nvx;
    std::copy(p.maxSnr.begin(), p.maxSnr.end(), result.map.maxSnr.begin() + off);
    std::copy(p.argX.begin(), p.argX.end(), result.map.argX.begin() + off);
    std::copy(p.argY.begin(), p.argY.end(), result.map.argY.begin() + off);
    result.cellsAboveThreshold += p.hitsTotal;
    hits.insert(hits.end(), p.hits.begin(), p.hits.end());
  }
  if (std::any_of(covered.begin(), covered.end(), [](int c) { return c != 1; }))
    throw InputError("the search parts do not cover the grid's rows exactly once");
  setCandidates(result, std::move(hits), cube, params);
  result.elapsedS = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

namespace {

template <typename T>
void put(std::string& out, const T& v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof v);
}

template <typename T>
void putVector(std::string& out, const std::vector<T>& v) {
  put(out, static_cast<std::uint64_t>(v.size()));
  out.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

struct Reader {
  const std::string& bytes;
  std::size_t pos = 0;
  template <typename T>
  T get() {
    if (pos + sizeof(T) > bytes.size()) throw InputError("a search part's bytes are truncated");
    T v;
    std::memcpy(&v, bytes.data() + pos, sizeof v);
    pos += sizeof v;
    return v;
  }
  template <typename T>
  std::vector<T> getVector() {
    const auto n = get<std::uint64_t>();
    if (n > (bytes.size() - pos) / sizeof(T)) throw InputError("a search part's bytes are truncated");
    std::vector<T> v(n);
    std::memcpy(v.data(), bytes.data() + pos, n * sizeof(T));
    pos += n * sizeof(T);
    return v;
  }
};

}  // namespace

std::string toBytes(const RowSearch& p) {
  std::string out;
  put(out, p.rows.begin);
  put(out, p.rows.end);
  put(out, p.hitsTotal);
  putVector(out, p.hits);
  putVector(out, p.maxSnr);
  putVector(out, p.argX);
  putVector(out, p.argY);
  return out;
}

RowSearch rowSearchFromBytes(const std::string& bytes) {
  Reader r{bytes};
  RowSearch p;
  p.rows.begin = r.get<int>();
  p.rows.end = r.get<int>();
  p.hitsTotal = r.get<std::int64_t>();
  p.hits = r.getVector<CellHit>();
  p.maxSnr = r.getVector<float>();
  p.argX = r.getVector<int>();
  p.argY = r.getVector<int>();
  if (r.pos != bytes.size()) throw InputError("a search part's bytes have trailing data");
  return p;
}

}  // namespace st::search
