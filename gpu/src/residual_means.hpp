#pragma once
// stats::removeResidualMeans (core/stats/noise_model.cpp) on a cube already on the device (issue 16): each
// frame's clipped mean per mesh cell (one block per cell and frame: the start's median and MAD by a sort of
// the strided samples in shared memory, the same selection as the CPU's nth_element; the clip passes reduced
// in a fixed order, so the means differ from the CPU's sequential double sums by their rounding only), the
// per-frame fill and rms on the host as the CPU, and the bilinear subtraction per pixel in the CPU's double
// arithmetic (no fused multiply-adds). Plain structs only (C++17).
#include <cuda_runtime.h>

#include <cstddef>

namespace st::gpu {

struct ResidualMeansLaunch {
  const float* pix;  ///< nf frames of width x height
  int width, height, nf;
  int mesh;          ///< cell side (>= 8)
  int nx, ny;        ///< cells per row / column
  double clipSigma;  ///< k
  int minCount;      ///< max(32, mesh^2 / 16)
  double* means;     ///< out: [nf][ny][nx], NaN where fewer than minCount values
};

/// The clipped mean of every (frame, cell).
void launchResidualCellMeans(const ResidualMeansLaunch& p, cudaStream_t s);

/// Subtracts the bilinear interpolation of each frame's filled cell means (`means`, [nf][ny][nx]) from its
/// non-zero finite pixels; frames with `skip[n]` != 0 (no finite cell mean) are left alone.
void launchResidualSubtract(float* pix, int width, int height, int nf, int mesh, int nx, int ny,
                            const double* means, const unsigned char* skip, cudaStream_t s);

}  // namespace st::gpu
