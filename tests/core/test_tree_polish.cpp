// Exact re-scoring of the tree's candidates (tree_polish.hpp). Oracle: the exact CPU search of the same cube
// and its reference sum (ipsaReference). A candidate moved 2 grid steps and 1 px off its cell comes back to
// the exact search's best cell with its SNR to float precision; one on noise alone is dropped; two that land
// on one cell leave one; a tree search through searchWithChoice reports the exact search's cell and SNR for
// an injected mover (the tree's own cell and SNR may differ).
#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <string>

#include "search_test_cubes.hpp"
#include "st/psf/moffat.hpp"
#include "st/search/cpu_backend.hpp"
#include "st/search/ipsa.hpp"
#include "st/search/method_choice.hpp"
#include "st/search/tree_polish.hpp"

namespace st::search {
namespace {

struct Quiet final : ProgressSink {
  void report(double, std::string_view) override {}
};

/// 64 x 64 px, 48 frames at 0.1 s, unit noise, a Moffat mover of FWHM 2.5 px at (30.3, 33.6) moving
/// (2.6, -1.7) px/s, matched-filtered; grid 21 x 21 velocities 1 px over the span apart around (2.5, -1.5).
struct MoverCube {
  FilteredCube fc;
  VelocityGrid grid;
};

MoverCube moverCube(double alpha) {
  MoverCube m;
  const psf::Moffat psf = psf::Moffat::fromFwhm(2.5, 3.0);
  m.fc.frames = test::noiseCube(64, 64, test::unevenTimes(48, 0.1, 7), 1.0, 11);
  test::injectMoffat(m.fc.frames, psf, alpha, 30.3, 33.6, {2.6, -1.7});
  test::matchedFilter(m.fc.frames, psf, 4);
  m.fc.sigmaF = std::sqrt(test::sumP2(psf, 4));
  m.fc.psfFwhmPx = 2.5;
  const double span = m.fc.frames.timeSpanS();
  m.grid = {{2.5, -1.5}, 1.0 / span, 21, 21};
  return m;
}

SearchResult exactSearch(const MoverCube& m) {
  Quiet q;
  CancelToken c;
  SearchParams p;
  p.method = SearchMethod::Exact;
  return makeCpuBackend()->search(m.fc, m.grid, p, q, c);
}

double referenceSnr(const FilteredCube& fc, const Candidate& c) {
  const IpsaCell cell = ipsaReference(fc.frames, fc.frames.timeOffsetsS(), c.x, c.y, c.v);
  return cell.sum / (fc.sigmaF * std::sqrt(static_cast<double>(cell.nIn)));
}

TEST(TreePolish, ACandidateOffItsCellComesBackToTheExactBest) {
  const MoverCube m = moverCube(3.0);
  const SearchResult exact = exactSearch(m);
  ASSERT_FALSE(exact.candidates.empty());
  const Candidate best = exact.candidates.front();
  ASSERT_GT(best.snr, 15.0);
  SearchResult off = exact;
  Candidate& c = off.candidates.front();
  c.ivx += 2;
  c.ivy -= 2;
  c.v = m.grid.at(c.ivx, c.ivy);
  c.x += 1;
  c.snr = 99.0;  // and every other measured field stale
  c.sum = -1.0;
  c.nIn = 0;
  c.fap = 1.0;
  CancelToken cancel;
  const PolishSummary s = polishTreeCandidates(m.fc, off, 64, cancel);
  EXPECT_GE(s.moved, 1);
  ASSERT_FALSE(off.candidates.empty());
  const Candidate& p = off.candidates.front();
  EXPECT_EQ(p.x, best.x);
  EXPECT_EQ(p.y, best.y);
  EXPECT_EQ(p.ivx, best.ivx);
  EXPECT_EQ(p.ivy, best.ivy);
  EXPECT_NEAR(p.snr, best.snr, 1e-4 * best.snr);
  EXPECT_NEAR(p.snr, referenceSnr(m.fc, p), 1e-4 * best.snr);
  EXPECT_EQ(p.nIn, best.nIn);
  EXPECT_NEAR(p.sum, best.sum, 1e-4 * std::abs(best.sum));
  EXPECT_NEAR(p.fap, best.fap, 1e-3 * best.fap + 1e-300);
  EXPECT_LT(p.fap, 1e-6);
}

// The out-of-core path re-scores each candidate on the tile that owns it (polishCandidate with the tile's
// origin): on a crop whose pixel (0, 0) is image pixel (5, 7) and which holds every track of the window, the
// same cell, sums and SNR as on the whole cube.
TEST(TreePolish, OnACropTheSameCellAsOnTheWholeCube) {
  const MoverCube m = moverCube(3.0);
  SearchResult r = exactSearch(m);
  ASSERT_FALSE(r.candidates.empty());
  Candidate c = r.candidates.front();
  c.ivx -= 1;
  c.ivy += 2;
  c.v = m.grid.at(c.ivx, c.ivy);
  c.y -= 1;
  CancelToken cancel;
  const std::optional<Candidate> whole = polishCandidate(m.fc, r, c, 0, 0, cancel);
  ASSERT_TRUE(whole.has_value());
  FilteredCube crop = m.fc;
  const int x0 = 5, y0 = 7, cw = 56, ch = 55;
  crop.frames = FrameCube(cw, ch, m.fc.frames.frameCount());
  crop.frames.info() = m.fc.frames.info();
  for (std::size_t n = 0; n < crop.frames.frameCount(); ++n)
    for (int y = 0; y < ch; ++y)
      for (int x = 0; x < cw; ++x)
        crop.frames.frame(n)[static_cast<std::size_t>(y) * cw + x] =
            m.fc.frames.frame(n)[static_cast<std::size_t>(y + y0) * m.fc.frames.width() + x + x0];
  const std::optional<Candidate> part = polishCandidate(crop, r, c, x0, y0, cancel);
  ASSERT_TRUE(part.has_value());
  EXPECT_EQ(part->x, whole->x);
  EXPECT_EQ(part->y, whole->y);
  EXPECT_EQ(part->ivx, whole->ivx);
  EXPECT_EQ(part->ivy, whole->ivy);
  EXPECT_EQ(part->nIn, whole->nIn);
  EXPECT_DOUBLE_EQ(part->sum, whole->sum);
  EXPECT_DOUBLE_EQ(part->snr, whole->snr);
  EXPECT_EQ(whole->x, r.candidates.front().x);
  EXPECT_EQ(whole->ivy, r.candidates.front().ivy);
}

TEST(TreePolish, NoiseAloneIsDroppedAndOneCellKeepsOneCandidate) {
  const MoverCube m = moverCube(3.0);
  SearchResult r = exactSearch(m);
  ASSERT_FALSE(r.candidates.empty());
  const Candidate best = r.candidates.front();
  // A second copy of the mover one step off (it lands on the same cell) and a candidate on empty sky.
  Candidate twin = best;
  twin.ivx -= 1;
  twin.v = m.grid.at(twin.ivx, twin.ivy);
  twin.snr = best.snr - 1.0;
  Candidate empty = best;
  empty.x = 8;
  empty.y = 52;
  empty.snr = 7.5;
  r.candidates = {best, twin, empty};
  CancelToken cancel;
  const PolishSummary s = polishTreeCandidates(m.fc, r, 64, cancel);
  EXPECT_EQ(s.rescored, 3);
  EXPECT_EQ(s.dropped, 2);
  ASSERT_EQ(r.candidates.size(), 1u);
  EXPECT_EQ(r.candidates.front().x, best.x);
  EXPECT_EQ(r.candidates.front().ivx, best.ivx);
}

TEST(TreePolish, ATreeSearchReportsTheExactSearchsCellAndSnr) {
  const MoverCube m = moverCube(1.5);
  const SearchResult exact = exactSearch(m);
  ASSERT_FALSE(exact.candidates.empty());
  const auto backend = makeCpuBackend();
  ASSERT_TRUE(backend->supports(SearchMethod::Tree));
  Quiet q;
  CancelToken c;
  SearchParams p;
  const SearchResult tree =
      searchWithChoice(*backend, m.fc, m.grid, p, {SearchMethod::Tree, "requested"}, q, c);
  ASSERT_FALSE(tree.candidates.empty());
  const Candidate& t = tree.candidates.front();
  const Candidate& e = exact.candidates.front();
  std::printf("exact (%d, %d) cell (%d, %d) SNR %.3f; tree, re-scored: (%d, %d) cell (%d, %d) SNR %.3f\n%s\n",
              e.x, e.y, e.ivx, e.ivy, e.snr, t.x, t.y, t.ivx, t.ivy, t.snr, tree.backendNote.c_str());
  EXPECT_EQ(t.x, e.x);
  EXPECT_EQ(t.y, e.y);
  EXPECT_EQ(t.ivx, e.ivx);
  EXPECT_EQ(t.ivy, e.ivy);
  EXPECT_NEAR(t.snr, e.snr, 1e-4 * e.snr);
  EXPECT_NE(tree.backendNote.find("re-scored by the exact search"), std::string::npos);
}

}  // namespace
}  // namespace st::search
