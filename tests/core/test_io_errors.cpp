// Every bad input gives one clear st::InputError that names the file, HDU and keyword or value at fault.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "st/common/error.hpp"
#include "st/io/fits_reader.hpp"
#include "test_io_fixtures.hpp"
#include "test_support.hpp"

namespace st::io {
namespace {

using st::test::FixtureImage;
using st::test::TempDir;
using st::test::timedFrame;
using st::test::writeFixture;

// Loads and returns the InputError's message; fails the test when no InputError is thrown.
std::string loadError(const std::vector<std::string>& inputs, const LoadOptions& options = {}) {
  NullProgress progress;
  CancelToken cancel;
  try {
    (void)loadFrames(inputs, options, progress, cancel);
  } catch (const InputError& e) {
    // summarizeInputs runs the same checks and must fail the same way.
    EXPECT_THROW((void)summarizeInputs(inputs, options), InputError);
    return e.what();
  }
  ADD_FAILURE() << "no InputError";
  return {};
}

void expectMentions(const std::string& message, const std::vector<std::string>& parts) {
  for (const auto& p : parts)
    EXPECT_NE(message.find(p), std::string::npos) << "'" << p << "' not in: " << message;
}

TEST(IoErrors, MissingFile) {
  TempDir dir;
  expectMentions(loadError({(dir / "nope.fits").string()}), {"nope.fits", "not found"});
}

TEST(IoErrors, NotFits) {
  TempDir dir;
  std::ofstream(dir / "text.fits")
      << "this is not a FITS file, just some text that is long enough to matter\n";
  expectMentions(loadError({(dir / "text.fits").string()}), {"text.fits", "not a readable FITS file"});
}

TEST(IoErrors, Truncated) {
  TempDir dir;
  const auto path = dir / "cut.fits";
  writeFixture(path, timedFrame("2020-01-01T00:00:00", 1, 0, 100, 100));
  std::filesystem::resize_file(path, 2880 + 5000);  // header + part of the 40000 data bytes
  expectMentions(loadError({path.string()}), {"cut.fits", "HDU 1", "truncated"});
  std::filesystem::resize_file(path, 1000);  // not even a whole header
  expectMentions(loadError({path.string()}), {"cut.fits"});
}

TEST(IoErrors, ZeroFrames) {
  TempDir dir;
  std::filesystem::create_directory(dir / "empty");
  expectMentions(loadError({(dir / "empty").string()}), {"empty", "no FITS files"});
  FixtureImage headerOnly;
  headerOnly.width = 0;
  headerOnly.height = 0;
  {  // a primary HDU without data and nothing else
    fitsfile* f = nullptr;
    int status = 0;
    fits_create_file(&f, (dir / "nodata.fits").string().c_str(), &status);
    fits_create_img(f, 16, 0, nullptr, &status);
    fits_close_file(f, &status);
    ASSERT_EQ(status, 0);
  }
  expectMentions(loadError({(dir / "nodata.fits").string()}), {"nodata.fits", "no image HDU with data"});
  expectMentions(loadError({}), {"zero frames"});
}

TEST(IoErrors, WrongNaxis) {
  TempDir dir;
  FixtureImage four;
  four.width = 2;
  four.height = 2;
  four.planes = 2;
  four.raw.assign(8, 1.0);
  writeFixture(dir / "ok3d.fits", four);
  // A 1-D "image".
  fitsfile* f = nullptr;
  int status = 0;
  long n[4] = {5, 2, 2, 3};
  fits_create_file(&f, (dir / "oned.fits").string().c_str(), &status);
  fits_create_img(f, -32, 1, n, &status);
  fits_close_file(f, &status);
  fits_create_file(&f, (dir / "fourd.fits").string().c_str(), &status);
  fits_create_img(f, -32, 4, n, &status);
  fits_close_file(f, &status);
  ASSERT_EQ(status, 0);
  expectMentions(loadError({(dir / "oned.fits").string()}), {"oned.fits", "HDU 1", "NAXIS = 1"});
  expectMentions(loadError({(dir / "fourd.fits").string()}),
                 {"fourd.fits", "HDU 1", "NAXIS = 4", "NAXIS4 = 3"});
}

TEST(IoErrors, DifferentSizesNameTheOddFileBothSizesAndTheCrop) {
  TempDir dir;
  writeFixture(dir / "a.fits", timedFrame("2020-01-01T00:00:00", 1, 0, 6, 4));
  writeFixture(dir / "b.fits", timedFrame("2020-01-01T00:00:01", 1, 0, 6, 4));
  writeFixture(dir / "odd.fits", timedFrame("2020-01-01T00:00:02", 1, 0, 7, 4));
  const auto msg =
      loadError({(dir / "a.fits").string(), (dir / "odd.fits").string(), (dir / "b.fits").string()});
  expectMentions(msg, {"odd.fits", "7x4", "6x4", "a.fits", "--crop"});
}

TEST(IoErrors, NoTimestampsSaysHowToSupplyThem) {
  TempDir dir;
  FixtureImage img = timedFrame("2020-01-01", 1, 0);  // date only, no time keyword
  writeFixture(dir / "t.fits", img);
  expectMentions(loadError({(dir / "t.fits").string()}),
                 {"t.fits", "HDU 1", "no timestamps", "--start-mjd", "--frame-rate"});
  LoadOptions user;
  user.startMjd = 60000.0;
  user.frameRateHz = 10.0;
  NullProgress progress;
  CancelToken cancel;
  EXPECT_DOUBLE_EQ(loadFrames({(dir / "t.fits").string()}, user, progress, cancel).info()[0].mjdMid, 60000.0);
}

TEST(IoErrors, MalformedTimeKeywordNamesKeywordAndValue) {
  TempDir dir;
  writeFixture(dir / "bad.fits", timedFrame("2020-13-45T99:00:00", 1, 0));
  expectMentions(loadError({(dir / "bad.fits").string()}),
                 {"bad.fits", "HDU 1", "DATE-OBS", "2020-13-45T99:00:00"});
  FixtureImage img = timedFrame("2020-01-01", 1, 0);
  img.cards.push_back({"UTCSTART", "'25:61'", ""});
  writeFixture(dir / "badut.fits", img);
  expectMentions(loadError({(dir / "badut.fits").string()}), {"badut.fits", "UTCSTART", "25:61"});
  FixtureImage exp = timedFrame("2020-01-01T00:00:00", 1, 0);
  exp.cards[1] = {"EXPTIME", "'fast'", ""};
  writeFixture(dir / "badexp.fits", exp);
  expectMentions(loadError({(dir / "badexp.fits").string()}), {"badexp.fits", "EXPTIME", "fast"});
}

TEST(IoErrors, DuplicateTimesNameBothFrames) {
  TempDir dir;
  writeFixture(dir / "first.fits", timedFrame("2020-01-01T00:00:00", 1, 0));
  writeFixture(dir / "again.fits", timedFrame("2020-01-01T00:00:00", 1, 5));
  expectMentions(loadError({(dir / "first.fits").string(), (dir / "again.fits").string()}),
                 {"duplicate frame time", "first.fits", "again.fits"});
  expectMentions(loadError({(dir / "first.fits").string(), (dir / "first.fits").string()}),
                 {"duplicate frame time"});
}

TEST(IoErrors, SomeFramesWithoutTimes) {
  TempDir dir;
  writeFixture(dir / "timed.fits", timedFrame("2020-01-01T00:00:00", 1, 0));
  writeFixture(dir / "untimed.fits", timedFrame("2020-01-01", 1, 0));
  expectMentions(loadError({(dir / "timed.fits").string(), (dir / "untimed.fits").string()}),
                 {"untimed.fits", "no timestamp"});
}

TEST(IoErrors, CorruptRiceTilesAreRefusedNotDecoded) {
  // CFITSIO 4.2 reads past the end of a corrupt RICE tile (and can crash); the loader checks tiles first.
  TempDir dir;
  FixtureImage img = timedFrame("2020-01-01T00:00:00", 1, 0, 64, 8);
  img.bitpix = 16;
  img.compress = RICE_1;
  for (auto& v : img.raw)
    v = 100.0;  // constant rows compress to a few bytes each
  const auto path = dir / "corrupt.fits.fz";
  writeFixture(path, img);
  ASSERT_EQ(loadFrames({path.string()}).frame(0)[70], 100.0f);
  LONGLONG dataStart = 0;
  LONGLONG heapStart = 0;
  LONGLONG heapBytes = 0;
  {
    fitsfile* f = nullptr;
    int status = 0;
    fits_open_file(&f, path.string().c_str(), READONLY, &status);
    fits_movabs_hdu(f, 2, nullptr, &status);
    LONGLONG head = 0;
    LONGLONG end = 0;
    fits_get_hduaddrll(f, &head, &dataStart, &end, &status);
    LONGLONG rowBytes = 0;
    LONGLONG rows = 0;
    fits_read_key(f, TLONGLONG, "NAXIS1", &rowBytes, nullptr, &status);
    fits_read_key(f, TLONGLONG, "NAXIS2", &rows, nullptr, &status);
    fits_read_key(f, TLONGLONG, "PCOUNT", &heapBytes, nullptr, &status);
    fits_close_file(f, &status);
    ASSERT_EQ(status, 0);
    heapStart = dataStart + rowBytes * rows;
  }
  ASSERT_GT(heapBytes, 0);
  {
    std::fstream io(path, std::ios::in | std::ios::out | std::ios::binary);
    io.seekp(heapStart);
    const std::string ff(static_cast<std::size_t>(heapBytes),
                         '\xff');  // every block claims raw 16-bit pixels
    io.write(ff.data(), static_cast<std::streamsize>(ff.size()));
  }
  expectMentions(loadError({path.string()}), {"corrupt.fits.fz", "HDU 2", "tile", "corrupt"});
}

TEST(IoErrors, CropOutsideTheFrame) {
  TempDir dir;
  writeFixture(dir / "a.fits", timedFrame("2020-01-01T00:00:00", 1, 0, 6, 4));
  LoadOptions o;
  o.crop = parseSection("[1:7,1:4]");
  expectMentions(loadError({(dir / "a.fits").string()}, o), {"a.fits", "crop", "6x4"});
}

}  // namespace
}  // namespace st::io
