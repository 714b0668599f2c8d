// A pre-processed cube read back (core/pipeline/prepared_cube): which of preprocess's two cubes a header
// describes, and the search input made from it. A zero-biased cube taken for a filtered one is searched at
// about half its SNR without a word, so every header that cannot be told apart is refused.
#include <gtest/gtest.h>

#include <fstream>

#include "search_test_cubes.hpp"
#include "st/common/error.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/fits_writer.hpp"
#include "st/pipeline/prepared_cube.hpp"
#include "st/pipeline/prepared_json.hpp"
#include "st/stats/background.hpp"
#include "test_support.hpp"
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

// The per-pixel background's windows (the co-moving fit's model of a slow mover's own flux in its
// background) travel in the zero-biased cube's header and are rebuilt exactly: oracle, the windows that
// pre-processing took (stats::pixelBackgroundWindows), member by member and frame n's left-out range for
// every n. 40 frames with the clip on 25 of them, so the evenly spaced set is not every frame.
TEST(PreparedCube, BackgroundWindowsRecordedInTheHeaderAreRebuiltExactly) {
  FrameCube zero = test::noiseCube(16, 12, test::unevenTimes(40, 2.0, 9), 1.0, 5);
  stats::BackgroundParams bp;
  bp.maxFrames = 25;
  Prepared p;
  p.psf = psf::Moffat::fromFwhm(3.0, 4.0);
  p.backgroundWindows = stats::pixelBackgroundWindows(zero, bp);
  const stats::PixelBackgroundWindows& oracle = p.backgroundWindows;
  ASSERT_EQ(oracle.frames.size(), 25u);
  ASSERT_GT(oracle.windowS, 0.0);
  zero.header = preparedCubeCards(p, PreparedState::ZeroBiased);
  const auto h = recognisePreparedHeader(zero.header, "p.fits");
  ASSERT_TRUE(h && h->backgroundWindows);
  std::vector<std::string> notes;
  const stats::PixelBackgroundWindows w = preparedBackgroundWindows(*h, zero, notes);
  EXPECT_TRUE(notes.empty());
  EXPECT_EQ(w.frames, oracle.frames);
  EXPECT_EQ(w.windowS, oracle.windowS);
  EXPECT_EQ(w.minOutside, oracle.minOutside);
  EXPECT_EQ(w.clipXi, oracle.clipXi);
  const std::vector<double> t = zero.timeOffsetsS();
  for (std::size_t n = 0; n < zero.frameCount(); ++n)
    EXPECT_EQ(w.leftOut(n, t), oracle.leftOut(n, t)) << "frame " << n;
  // Through a FITS file, as the GUI and `fit` read it.
  test::TempDir tmp;
  const std::string path = (tmp / "p.fits").string();
  io::writeCube(path, zero, zero.header);
  NullProgress progress;
  CancelToken cancel;
  const FrameCube loaded = io::loadFrames({path}, {}, progress, cancel);
  const auto hl = recognisePreparedHeader(loaded.header, path);
  ASSERT_TRUE(hl && hl->backgroundWindows);
  const stats::PixelBackgroundWindows wl = preparedBackgroundWindows(*hl, loaded, notes);
  EXPECT_TRUE(notes.empty());
  EXPECT_EQ(wl.frames, oracle.frames);
  EXPECT_EQ(wl.windowS, oracle.windowS);
  const std::vector<double> tl = loaded.timeOffsetsS();
  for (std::size_t n = 0; n < loaded.frameCount(); ++n)
    EXPECT_EQ(wl.leftOut(n, tl), oracle.leftOut(n, t)) << "frame " << n;
  // Neither the filtered cube nor a cube without windows (aligned frames) carries them.
  EXPECT_FALSE(preparedCubeCards(p, PreparedState::Filtered).has("BGWINS"));
  p.backgroundWindows = {};
  EXPECT_FALSE(preparedCubeCards(p, PreparedState::ZeroBiased).has("BGWINS"));
}

// What cannot be used is said, and the fit keeps the paper's model: a header from before the windows, a
// frame set larger than the cube, frames out of time order; a partial or unreadable record is refused,
// naming the keyword.
TEST(PreparedCube, BackgroundWindowsThatDoNotFitTheCubeAreNotUsed) {
  FrameCube zero = test::noiseCube(16, 12, test::unevenTimes(20, 2.0, 9), 1.0, 5);
  Prepared p;
  p.psf = psf::Moffat::fromFwhm(3.0, 4.0);
  p.backgroundWindows = stats::pixelBackgroundWindows(zero, {});
  const FitsHeader cards0 = preparedCubeCards(p, PreparedState::ZeroBiased);
  std::vector<std::string> notes;
  FitsHeader old = cards0;
  for (const char* k : {"BGWINS", "BGNFRM", "BGMINOUT", "BGCLIP"})
    old.erase(k);
  EXPECT_TRUE(preparedBackgroundWindows(*recognisePreparedHeader(old, "p.fits"), zero, notes).empty());
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("BGWINS"), std::string::npos) << notes[0];
  EXPECT_NE(notes[0].find("paper's model"), std::string::npos) << notes[0];

  FitsHeader more = cards0;
  more.setNumber("BGNFRM", 21, "");
  notes.clear();
  EXPECT_TRUE(preparedBackgroundWindows(*recognisePreparedHeader(more, "p.fits"), zero, notes).empty());
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("BGNFRM = 21"), std::string::npos) << notes[0];

  FrameCube shuffled = zero;
  std::swap(shuffled.info()[3].mjdMid, shuffled.info()[7].mjdMid);
  notes.clear();
  EXPECT_TRUE(preparedBackgroundWindows(*recognisePreparedHeader(cards0, "p.fits"), shuffled, notes).empty());
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("time order"), std::string::npos) << notes[0];

  FitsHeader partial = cards0;
  partial.erase("BGCLIP");
  EXPECT_NE(messageOf(partial).find("no BGCLIP"), std::string::npos) << messageOf(partial);
  FitsHeader fraction = cards0;
  fraction.setNumber("BGMINOUT", 2.5, "");
  EXPECT_NE(messageOf(fraction).find("BGMINOUT = 2.5"), std::string::npos) << messageOf(fraction);
  FitsHeader negative = cards0;
  negative.setNumber("BGWINS", -1.0, "");
  EXPECT_NE(messageOf(negative).find("BGWINS = -1"), std::string::npos) << messageOf(negative);
}

// The sidecar's movers (those left out of the per-pixel background) read back as written; no sidecar is
// no list; a JSON that is not a sidecar is refused naming the path.
TEST(PreparedCube, SidecarMoversReadBack) {
  test::TempDir tmp;
  Prepared p;
  detect::MovingSource m;
  m.x = 12.25;
  m.y = 40.5;
  m.v = {0.75, -0.125};
  m.snr = 33.0;
  m.moving = true;
  p.movers = {m};
  const std::string path = (tmp / "p.json").string();
  writePreparedSidecar(path, p);
  const auto movers = readPreparedMovers(path);
  ASSERT_TRUE(movers);
  ASSERT_EQ(movers->size(), 1u);
  EXPECT_EQ((*movers)[0].x, 12.25);
  EXPECT_EQ((*movers)[0].y, 40.5);
  EXPECT_EQ((*movers)[0].v.vx, 0.75);
  EXPECT_EQ((*movers)[0].v.vy, -0.125);
  EXPECT_TRUE((*movers)[0].moving);
  EXPECT_FALSE(readPreparedMovers((tmp / "none.json").string()));
  std::ofstream((tmp / "other.json").string()) << "{\"objects\": []}\n";
  try {
    readPreparedMovers((tmp / "other.json").string());
    ADD_FAILURE() << "a JSON without moving_sources was read as a sidecar";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("other.json"), std::string::npos) << e.what();
  }
  EXPECT_EQ(preparedSidecarPath("/night/prepared.fits"), "/night/prepared.json");
}

}  // namespace
}  // namespace st::pipeline
