#pragma once
// Internal to core/astro: index files made on the fly for one field (PlateSolveParams::fieldIndex).
//
// Why: the Debian index packages are Tycho-2 (V < ~12), whose quads start at 22'. A 26' field such as the
// Lowell 42" frames holds ~6 of their stars, and no four of them form a quad at the packaged scales
// (measured: solve-field with tycho2-07 and -08 finds nothing in 200 s though 5 of the 8 brightest sources
// are index stars). From the same installed stars around the pointing hint we build small index files with
// 3-star quads at the field's own scales (astrometry.net's build-astrometry-index, < 1 s each), which
// solve it in seconds.
#include <string>
#include <vector>

#include "st/astro/plate_solve.hpp"

namespace st::astro::detail {

/// Builds index files for a field of `sideArcmin` (largest side) and `diagonalArcmin` around the pointing
/// hint of `params` into `dir`, from the stars of the installed index with the smallest quads (the densest)
/// within radiusDeg + half the diagonal, with query-starkd and build-astrometry-index (both in the Debian
/// package astrometry.net). Returns the folder holding them, or empty (with the reason in `why`) when it
/// cannot: no hint, the tools missing, too few stars.
std::string buildFieldIndexes(const PlateSolveParams& params, const std::vector<IndexFile>& installed,
                              double sideArcmin, double diagonalArcmin, const std::string& dir,
                              ProgressSink& progress, CancelToken& cancel, std::string& why);

}  // namespace st::astro::detail
