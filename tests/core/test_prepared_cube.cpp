// A pre-processed cube read back (core/pipeline/prepared_cube): which of preprocess's two cubes a header
// describes, and the search input made from it. A zero-biased cube taken for a filtered one is searched at
// about half its SNR without a word, so every header that cannot be told apart is refused.
#include <gtest/gtest.h>

#include "search_test_cubes.hpp"
#include "st/common/error.hpp"
#include "st/pipeline/prepared_cube.hpp"
#include "st/stack/matched_filter.hpp"

namespace st::pipeline {
namespace {

FitsHeader cards(std::initializer_list<std::pair<const char*, const char*>> kv) {
  FitsHeader h;
  for (const auto& [k, v] : kv)
    h.set(k, v, {}, std::string(k) == "STEP" || std::string(k) == "IMAGETYP");
  return h;
}

std::string messageOf(const FitsHeader& h) {
  try {
    readPreparedHeader(h, "p.fits");
  } catch (const InputError& e) {
    return e.what();
  }
  return {};
}

TEST(PreparedCube, HeaderSaysWhichCube) {
  const auto zero = recognisePreparedHeader(
      cards({{"STPREP", "1"}, {"STFILT", "F"}, {"PSFFWHM", "3.5"}, {"PSFBETA", "2.5"}, {"SKYVX", "16.4"}}),
      "p.fits");
  ASSERT_TRUE(zero);
  EXPECT_EQ(zero->state, PreparedState::ZeroBiased);
  ASSERT_TRUE(zero->psf);
  EXPECT_NEAR(zero->psf->fwhm(), 3.5, 1e-12);
  EXPECT_DOUBLE_EQ(zero->psf->beta, 2.5);
  EXPECT_DOUBLE_EQ(zero->skyRate.vx, 16.4);
  EXPECT_DOUBLE_EQ(zero->skyRate.vy, 0.0);
  const auto filt = recognisePreparedHeader(cards({{"STFILT", "T"}, {"SIGMAF", "2.25"}}), "p.fits");
  ASSERT_TRUE(filt);
  EXPECT_EQ(filt->state, PreparedState::Filtered);
  EXPECT_EQ(filt->sigmaF, 2.25);
  EXPECT_FALSE(filt->psf);
  // Files written before STFILT: SIGMAF only on the filtered cube; preprocess's STEP and PSF on both.
  EXPECT_EQ(recognisePreparedHeader(cards({{"SIGMAF", "1"}, {"PSFFWHM", "3"}}), "p.fits")->state,
            PreparedState::Filtered);
  const auto legacy = recognisePreparedHeader(cards({{"STEP", "preprocess"}, {"PSFFWHM", "3"}}), "p.fits");
  ASSERT_TRUE(legacy);
  EXPECT_EQ(legacy->state, PreparedState::ZeroBiased);
  EXPECT_DOUBLE_EQ(legacy->psf->beta, kDefaultPsfBeta);
}

TEST(PreparedCube, HeaderThatCannotBeToldIsRefusedNamingFileAndKeyword) {
  EXPECT_FALSE(recognisePreparedHeader(cards({{"IMAGETYP", "Light"}, {"PSFFWHM", "3"}}), "p.fits"));
  const std::string raw = messageOf(cards({{"IMAGETYP", "Light"}, {"PSFFWHM", "3"}}));
  EXPECT_NE(raw.find("p.fits"), std::string::npos) << raw;
  EXPECT_NE(raw.find("STFILT"), std::string::npos) << raw;
  EXPECT_NE(raw.find("synthtrack-cli preprocess"), std::string::npos) << raw;
  const std::string noState = messageOf(cards({{"STPREP", "1"}, {"PSFFWHM", "3"}}));
  EXPECT_NE(noState.find("STFILT"), std::string::npos) << noState;
  const std::string badState = messageOf(cards({{"STFILT", "yes"}}));
  EXPECT_NE(badState.find("STFILT = 'yes'"), std::string::npos) << badState;
  const std::string badPsf = messageOf(cards({{"STFILT", "F"}, {"PSFFWHM", "-1"}}));
  EXPECT_NE(badPsf.find("PSFFWHM"), std::string::npos) << badPsf;
}

TEST(PreparedCube, CardsWrittenByPreprocessReadBack) {
  Prepared p;
  p.psf = psf::Moffat::fromFwhm(3.56, 3.2);
  p.sigmaN = 4.5;
  p.skyRate = {16.4, -0.25};
  p.filtered.sigmaF = 7.75;
  const auto zero = recognisePreparedHeader(preparedCubeCards(p, PreparedState::ZeroBiased), "p.fits");
  ASSERT_TRUE(zero);
  EXPECT_EQ(zero->state, PreparedState::ZeroBiased);
  EXPECT_FALSE(zero->sigmaF) << "SIGMAF describes filtered frames only";
  EXPECT_NEAR(zero->psf->fwhm(), 3.56, 1e-12);
  EXPECT_NEAR(zero->psf->beta, 3.2, 1e-12);
  EXPECT_EQ(zero->sigmaN, 4.5);
  EXPECT_DOUBLE_EQ(zero->skyRate.vy, -0.25);
  const auto filt = recognisePreparedHeader(preparedCubeCards(p, PreparedState::Filtered), "p.fits");
  ASSERT_TRUE(filt);
  EXPECT_EQ(filt->state, PreparedState::Filtered);
  EXPECT_EQ(filt->sigmaF, 7.75);
  const FitsHeader background = preparedCubeCards(p, std::nullopt);  // the background image: no cube
  EXPECT_FALSE(background.has("STPREP") || background.has("STFILT") || background.has("SIGMAF"));
}

// The zero-biased cube is filtered exactly as makeFilteredCube filters the raw path's frames; the filtered
// cube is searched as is with its SIGMAF.
TEST(PreparedCube, SearchInputFiltersTheZeroBiasedCubeOnly) {
  const psf::Moffat psf = psf::Moffat::fromFwhm(3.0, 4.0);
  FrameCube zero = test::noiseCube(48, 40, test::unevenTimes(12, 0.5, 3), 1.0, 5);
  test::injectMoffat(zero, psf, 2.0, 20.0, 18.0, Velocity{0.3, 0.1});
  Prepared p;
  p.psf = psf;
  p.skyRate = {0.5, 0.0};
  zero.header = preparedCubeCards(p, PreparedState::ZeroBiased);
  NullProgress progress;
  CancelToken cancel;
  const search::FilteredCube oracle = stack::makeFilteredCube(zero, psf, p.skyRate, progress, cancel);
  const PreparedSearchInput in = searchInputFromPrepared(zero, {}, progress, cancel);
  EXPECT_TRUE(in.filteredHere);
  EXPECT_EQ(in.cube.frames.pixels(), oracle.frames.pixels());
  EXPECT_DOUBLE_EQ(in.cube.sigmaF, oracle.sigmaF);
  EXPECT_DOUBLE_EQ(in.cube.psfFwhmPx, psf.fwhm());
  EXPECT_DOUBLE_EQ(in.cube.skyRate.vx, 0.5);
  ASSERT_EQ(in.notes.size(), 1u);
  EXPECT_NE(in.notes[0].find("matched-filtered"), std::string::npos) << in.notes[0];

  FrameCube filtered = oracle.frames;
  p.filtered.sigmaF = 0.123;
  filtered.header = preparedCubeCards(p, PreparedState::Filtered);
  const PreparedSearchInput asIs = searchInputFromPrepared(filtered, {}, progress, cancel);
  EXPECT_FALSE(asIs.filteredHere);
  EXPECT_EQ(asIs.cube.frames.pixels(), oracle.frames.pixels());
  EXPECT_DOUBLE_EQ(asIs.cube.sigmaF, 0.123);
  EXPECT_DOUBLE_EQ(searchInputFromPrepared(filtered, {std::nullopt, 0.5}, progress, cancel).cube.sigmaF, 0.5);

  FrameCube noPsf = zero;
  noPsf.header = cards({{"STPREP", "1"}, {"STFILT", "F"}});
  try {
    searchInputFromPrepared(noPsf, {}, progress, cancel);
    ADD_FAILURE() << "a zero-biased cube without PSFFWHM was searched";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("PSFFWHM"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(searchInputFromPrepared(noPsf, {3.0, std::nullopt}, progress, cancel).filteredHere);
  FrameCube unknown = zero;
  unknown.header = {};
  EXPECT_THROW(searchInputFromPrepared(unknown, {}, progress, cancel), InputError);
}

}  // namespace
}  // namespace st::pipeline
