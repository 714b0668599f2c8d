// search --mpi's arithmetic (issue 17): the exact search split by vy rows and merged gives exactly what the
// CPU backend gives over the whole grid (candidates, cell counts, velocity map), for any number of parts.
#include <gtest/gtest.h>

#include "search_test_cubes.hpp"
#include "st/search/cpu_backend.hpp"
#include "st/search/row_split.hpp"
#include "st/search/search_run.hpp"

namespace st {
namespace {

TEST(RowSplit, SharesCoverTheRowsOnce) {
  for (int parts : {1, 2, 3, 7, 40}) {
    int next = 0;
    for (int p = 0; p < parts; ++p) {
      const auto r = search::rowShare(21, p, parts);
      EXPECT_EQ(r.begin, next);
      EXPECT_GE(r.end, r.begin);
      EXPECT_LE(r.end - r.begin, 21 / parts + 1);
      next = r.end;
    }
    EXPECT_EQ(next, 21);
  }
  EXPECT_THROW(search::rowShare(21, 3, 3), InputError);
}

TEST(RowSplit, MergedPartsEqualOneSearch) {
  const psf::Moffat psf{psf::Moffat::radiusForFwhm(3.0, 4.0), 4.0};
  FrameCube cube = test::noiseCube(48, 40, test::unevenTimes(24, 0.5, 3), 1.0, 5);
  const double span = cube.timeSpanS();
  test::injectMoffat(cube, psf, 6.0, 20.0, 18.0, {5.0 / span, -3.0 / span});
  test::injectMoffat(cube, psf, 4.0, 35.0, 10.0, {-2.0 / span, 4.0 / span});
  test::matchedFilter(cube, psf, 6);
  search::FilteredCube fc{std::move(cube), std::sqrt(test::sumP2(psf, 6)), {}, psf.fwhm()};
  search::VelocityGrid grid{{0.0, 0.0}, 1.0 / span, 15, 13};
  search::SearchParams params;
  params.snrThreshold = 5.0;
  NullProgress progress;
  CancelToken cancel;
  const search::SearchResult one = search::makeCpuBackend()->search(fc, grid, params, progress, cancel);
  ASSERT_GE(one.candidates.size(), 2u);
  for (int parts : {2, 3, 5}) {
    std::vector<search::RowSearch> got;
    for (int p = 0; p < parts; ++p) {
      const auto part =
          search::searchRows(fc, grid, params, search::rowShare(grid.nvy, p, parts), progress, cancel);
      got.push_back(search::rowSearchFromBytes(search::toBytes(part)));  // as it travels between ranks
    }
    const search::SearchResult merged = search::mergeRowSearches(fc, grid, params, got, "cpu (mpi)");
    EXPECT_EQ(merged.cellsAboveThreshold, one.cellsAboveThreshold) << parts;
    EXPECT_EQ(merged.map.maxSnr, one.map.maxSnr) << parts;
    EXPECT_EQ(merged.map.argX, one.map.argX) << parts;
    ASSERT_EQ(merged.candidates.size(), one.candidates.size()) << parts;
    for (std::size_t i = 0; i < one.candidates.size(); ++i) {
      const auto& a = merged.candidates[i];
      const auto& b = one.candidates[i];
      EXPECT_EQ(a.x, b.x);
      EXPECT_EQ(a.y, b.y);
      EXPECT_EQ(a.ivx, b.ivx);
      EXPECT_EQ(a.ivy, b.ivy);
      EXPECT_EQ(a.snr, b.snr);  // bit-identical: the same sums in the same order
      EXPECT_EQ(a.clusterCells, b.clusterCells);
    }
  }
  // Parts that overlap or leave a row out are refused.
  std::vector<search::RowSearch> gap{search::searchRows(fc, grid, params, {0, 5}, progress, cancel)};
  EXPECT_THROW(search::mergeRowSearches(fc, grid, params, gap, "x"), InputError);
  EXPECT_THROW(search::rowSearchFromBytes("abc"), InputError);
}

}  // namespace
}  // namespace st
