#pragma once
// SEP's per-frame background (sep_background + sep_bkg_subarray of SEP 1.2, background.c), step by step in
// its arithmetic (float where SEP is float, double where it promotes), so that every pixel equals libsep's
// (tests/core/test_sep_background.cpp compares them; libsep stays the oracle). Why not libsep itself: its
// backguess walks the histogram (up to 4096 bins) on each of up to 100 clip iterations, which made SEP
// half of the frame backgrounds' 4.8 s for 1500 x 512^2 on the 2-core VM; here its sums are integers, exact
// in any order, taken from prefix sums, and its two-sided median walk from the prefix counts (the walk
// advances the low side past bin i exactly when P_i + P_(i+1) < T, P the prefix counts of the range and T
// their total). The clipped mean and sigma (backstat) keep SEP's sequential double sums, four meshes
// interleaved. Plain structs (the GPU twin, gpu/src/frame_backgrounds*, shares the host steps and tables;
// C++17 for nvcc). Compiled without fused multiply-adds, as SEP is.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace st::stats::sep {

inline constexpr double kBig = 1e+30;           ///< SEP's BIG (sepcore.h)
inline constexpr int kMaxLevels = 4096;         ///< QUANTIF_NMAXLEVELS
inline constexpr double kPi = 3.1415926535898;  ///< SEP's PI

/// SEP's histogram step sqrt(2 / PI) * QUANTIF_NSIGMA / QUANTIF_AMIN.
double histogramStep();

/// The mesh grid of a width x height frame for SEP's bw x bh boxes (the last column and row take what is
/// left).
struct MeshGrid {
  int width = 0, height = 0, bw = 0, bh = 0, nx = 0, ny = 0;
  int meshes() const { return nx * ny; }
};
MeshGrid meshGrid(int width, int height, int meshPx);

/// backstat + backhisto + backguess of every mesh of one frame (mask: non-zero = masked, or null): the
/// mesh's mode into back[ny][nx] and its sigma into sigma[ny][nx], -BIG for a mesh with fewer than half
/// its pixels usable.
void meshStatistics(const float* frame, const std::uint8_t* mask, const MeshGrid& g, float* back,
                    float* sigma);

/// SEP's fqmedian (util.c): sorts `ra`, the middle value or the mean of the two middle ones.
float fqmedian(float* ra, int n);

/// SEP's filterback with fthresh = 0: bad meshes filled from their nearest valid ones, the fw x fh median
/// filter of back and sigma, the global level and rms.
void filterback(int nx, int ny, int fw, int fh, float* back, float* sigma, float& global, float& globalrms);

/// SEP's makebackspline: the second derivatives along y of `map` ([ny][nx]) into `dmap`.
void makebackspline(int nx, int ny, const float* map, float* dmap);

/// bkg_line_flt_internal's y constants of one row.
struct SplineRow {
  int yl;
  float dy, cdy, dy3, cdy3;
};

/// bkg_line_flt_internal's x steps of one column (its dx accumulates in float along the row);
/// a = cdx^2 - 1, b = dx^2 - 1 in float.
struct SplineColumn {
  int node;
  float dx, cdx, a, b;
};

std::vector<SplineRow> rowTable(int height, int bh, int ny);
std::vector<SplineColumn> columnTable(int width, int bw, int nx);

/// One frame's background model: SEP's filtered mesh and its y second derivatives, the global level and
/// rms.
struct FrameModel {
  std::vector<float> back, sigma, dback;
  float global = 0.0f, globalrms = 0.0f;
};

/// sep_background(frame, bw = bh = the grid's, fw = fh = filterCells, fthresh = 0) for one frame.
FrameModel model(const float* frame, const std::uint8_t* mask, const MeshGrid& g, int filterCells);

/// frame = (frame - SEP's background spline) + restored, row by row as sep_bkg_subarray subtracts it and
/// the caller adds the level back (float).
void subtract(float* frame, const MeshGrid& g, const FrameModel& m, const std::vector<SplineRow>& rows,
              const std::vector<SplineColumn>& cols, float restored);

}  // namespace st::stats::sep
