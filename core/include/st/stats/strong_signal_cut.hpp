#pragma once
// The per-pixel clip's first cut (paper §4.2, "eliminate most of the strong signals"), relative to each
// pixel's own level (core/stats/background.cpp's clipRows calls it on every row buffer).
#include <cstddef>
#include <vector>

namespace st::stats {

/// The strong-signal cut of one row's buffer (nf x w samples, frame-major, NaN where left out): the samples
/// of column x above median_x + offset (median_x: the lower median, element (c - 1) / 2 in order, of the
/// column's c samples left in) become NaN. A pixel bright in every frame (a static star's wing just outside
/// its mask) is then background for itself, where a cut at the global level took away the upper part of its
/// own noise and left its background low (a static positive residual that the search found at near-zero
/// velocity); a source covering the pixel in fewer than half of its samples does not move the median past
/// the background samples and is cut as before. With AVX2 the medians come from a bisection over the floats'
/// integer keys, 16 columns at a time (the same values as nth_element); allowSimd false, or without AVX2,
/// each column is gathered into `scratch` and selected in (tests compare the two).
void cutStrongAboveMedian(float* buf, std::size_t nf, int w, double offset, std::vector<float>& scratch,
                          bool allowSimd = true);

}  // namespace st::stats
