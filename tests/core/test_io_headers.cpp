// Header interpretation: time keyword variants, image sections, WCS (quoted numbers, SIP, TPV), typed cards.
#include <gtest/gtest.h>

#include <cmath>

#include "st/common/error.hpp"
#include "st/common/units.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/fits_time.hpp"
#include "st/io/fits_writer.hpp"
#include "st/io/sections.hpp"
#include "st/io/wcs.hpp"
#include "test_io_fixtures.hpp"
#include "test_support.hpp"

namespace st::io {
namespace {

FitsHeader header(std::initializer_list<FitsCard> cards) {
  FitsHeader h;
  h.cards = cards;
  return h;
}
FitsCard num(std::string k, std::string v, std::string c = {}) {
  return FitsCard{std::move(k), std::move(v), std::move(c), false};
}
FitsCard str(std::string k, std::string v, std::string c = {}) {
  return FitsCard{std::move(k), std::move(v), std::move(c), true};
}

constexpr double kMicrosecond = 1e-6 / kSecondsPerDay;

TEST(IoTime, CalendarOracle) {
  EXPECT_DOUBLE_EQ(mjdFromCalendar(1858, 11, 17, 0.0), 0.0);        // MJD epoch
  EXPECT_DOUBLE_EQ(mjdFromCalendar(2000, 1, 1, 43200.0), 51544.5);  // J2000.0
  EXPECT_DOUBLE_EQ(mjdFromCalendar(2019, 3, 26, 0.0), 58568.0);
  EXPECT_NEAR(mjdFromMjdOrJd(2458568.622064236), 58568.122064236, 1e-9);
}

TEST(IoTime, KeywordVariants) {
  const double d = mjdFromCalendar(2019, 3, 26, 0.0);
  const double start = d + (2 * 3600 + 53 * 60 + 16.35) / kSecondsPerDay;  // 02:53:16.35
  const double half = 150.0 / kSecondsPerDay;
  struct Case {
    const char* name;
    FitsHeader h;
    double expected;
  };
  const std::vector<Case> cases = {
      {"DATE-OBS with time", header({str("DATE-OBS", "2019-03-26T02:53:16.35"), num("EXPTIME", "300.")}),
       start + half},
      {"date + UTCSTART (Lowell)",
       header({str("DATE-OBS", "2019-03-26"), num("EXPTIME", "300."), str("UTCSTART", "02:53:16.35")}),
       start + half},
      {"date + TIME-OBS",
       header({str("DATE-OBS", "2019-03-26"), str("TIME-OBS", "02:53:16.35"), num("EXPOSURE", "300")}),
       start + half},
      {"date + UT", header({str("DATE-OBS", "2019-03-26"), str("UT", "02:53:16.35"), num("EXPTIME", "300")}),
       start + half},
      {"MJD-OBS", header({num("MJD-OBS", "58568.120328125"), num("EXPTIME", "300")}), 58568.120328125 + half},
      {"JD in MJD-OBS", header({num("MJD-OBS", "2458568.620328125"), num("EXPTIME", "300")}),
       58568.120328125 + half},
      {"MJD-OBS said to be mid",
       header({num("MJD-OBS", "58568.2", "MJD at mid-exposure"), num("EXPTIME", "300")}), 58568.2},
      {"DATE-AVG is mid",
       header({str("DATE-AVG", "2019-03-26T02:53:16.35"), str("DATE-OBS", "2000-01-01T00:00:00"),
               num("EXPTIME", "300")}),
       start},
      {"MJD-AVG is mid", header({num("MJD-AVG", "58568.3"), num("EXPTIME", "300")}), 58568.3},
      {"old DD/MM/YY with year 102",
       header({str("DATE-OBS", "26/07/102"), str("TIME-OBS", "19:36:37"), num("EXPTIME", "60")}),
       mjdFromCalendar(2002, 7, 26, 19 * 3600 + 36 * 60 + 37 + 30)},
      {"TIME-OBS holding a full date (NEOSSat)",
       header({str("DATE-OBS", "2023-11-07"), str("TIME-OBS", "2023-11-07T00:58:08.043"),
               num("EXPOSURE", "1.34043E2")}),
       mjdFromCalendar(2023, 11, 7, 58 * 60 + 8.043 + 67.0215)},
      {"no exposure: start taken as mid", header({str("DATE-OBS", "2019-03-26T02:53:16.35")}), start},
  };
  for (const auto& c : cases) {
    const FrameTime t = frameTimeFromHeader(c.h, "x.fits HDU 1");
    ASSERT_TRUE(t.mjdMid.has_value()) << c.name;
    // A JD held in a double resolves only ~40 microseconds.
    const double tol = std::string(c.name).find("JD") != std::string::npos ? 1e-9 : 2 * kMicrosecond;
    EXPECT_NEAR(*t.mjdMid, c.expected, tol) << c.name << " (" << t.source << ")";
  }
  EXPECT_FALSE(frameTimeFromHeader(header({str("DATE-OBS", "2019-03-26"), num("EXPTIME", "1")}), "x").mjdMid);
  EXPECT_THROW((void)frameTimeFromHeader(header({str("DATE-OBS", "yesterday")}), "x"), InputError);
  EXPECT_THROW(
      (void)frameTimeFromHeader(header({str("DATE-OBS", "2019-03-26T02:53"), num("EXPTIME", "-3")}), "x"),
      InputError);
}

TEST(IoSections, ParsesBlanksAndConvertsToZeroBased) {
  EXPECT_EQ(parseSection("[18:1382,1:1370]"), (PixelRegion{17, 0, 1365, 1370}));
  EXPECT_EQ(parseSection("[  17: 528,   1: 520]"), (PixelRegion{16, 0, 512, 520}));
  EXPECT_EQ(parseSection("[1388:1432,1:1370]"), (PixelRegion{1387, 0, 45, 1370}));
  EXPECT_EQ(parseSection("[100:1, 5:5]"), (PixelRegion{0, 4, 100, 1}));
  for (const char* bad :
       {"18:1382,1:1370", "[18:1382]", "[0:10,1:5]", "[a:b,c:d]", "[1:2,3:4]x", "", "[1:2,3:4,5:6]"}) {
    try {
      (void)parseSection(bad, "TRIMSEC");
      ADD_FAILURE() << bad;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("TRIMSEC"), std::string::npos) << e.what();
    }
  }
  FitsHeader h = header({str("TRIMSEC", "[  17: 528,   1: 520]"), str("BIASSEC", "")});
  EXPECT_EQ(sectionFromHeader(h, "TRIMSEC"), (PixelRegion{16, 0, 512, 520}));
  EXPECT_FALSE(sectionFromHeader(h, "BIASSEC")) << "blank section (NEOSSat) means none";
  EXPECT_FALSE(sectionFromHeader(h, "DATASEC"));
}

FitsHeader tanHeader(bool quoted) {
  auto v = [&](std::string k, std::string val) { return FitsCard{std::move(k), std::move(val), {}, quoted}; };
  return header({num("NAXIS", "2"), num("NAXIS1", "1432"), num("NAXIS2", "1370"), str("CTYPE1", "RA---TAN"),
                 str("CTYPE2", "DEC--TAN"), v("CRVAL1", "124.6186165755"), v("CRVAL2", "25.32886785958"),
                 v("CRPIX1", "716.0"), v("CRPIX2", "685.0"), v("CD1_1", "-0.0003073739923533"),
                 v("CD1_2", "1.222848019531e-05"), v("CD2_1", "1.222848019531e-05"),
                 v("CD2_2", "0.0003073739923533"), str("RADESYS", "ICRS")});
}

TEST(IoWcs, QuotedNumbersParseLikeNumbers) {
  std::vector<std::string> w;
  const auto quoted = Wcs::fromHeader(tanHeader(true), &w);
  const auto plain = Wcs::fromHeader(tanHeader(false), &w);
  ASSERT_TRUE(quoted);
  ASSERT_TRUE(plain);
  for (double x : {0.0, 715.0, 1431.0}) {
    const auto a = quoted->pixelToSky(x, 100.0);
    const auto b = plain->pixelToSky(x, 100.0);
    EXPECT_EQ(a.raDeg, b.raDeg);
    EXPECT_EQ(a.decDeg, b.decDeg);
  }
  // 0-based pixel (715, 684) is CRPIX (716, 685): the reference point.
  const auto ref = quoted->pixelToSky(715.0, 684.0);
  EXPECT_NEAR(ref.raDeg, 124.6186165755, 1e-10);
  EXPECT_NEAR(ref.decDeg, 25.32886785958, 1e-10);
  const double det = -0.0003073739923533 * 0.0003073739923533 - 1.222848019531e-05 * 1.222848019531e-05;
  EXPECT_NEAR(quoted->plateScaleArcsecPerPx(), std::sqrt(std::abs(det)) * 3600.0, 1e-12);
  const auto [x, y] = quoted->skyToPixel(124.5, 25.4);
  const auto back = quoted->pixelToSky(x, y);
  EXPECT_NEAR(back.raDeg, 124.5, 1e-10);
  EXPECT_NEAR(back.decDeg, 25.4, 1e-10);
  EXPECT_FALSE(quoted->hasSip());
}

TEST(IoWcs, CdeltWithoutPcGivesPlateScale) {
  // NEOSSat-style CDELT only (unity PC): 8.325e-4 deg/px = 2.997"/px.
  const auto w =
      Wcs::fromHeader(header({str("CTYPE1", "RA---TAN"), str("CTYPE2", "DEC--TAN"), num("CRVAL1", "121.4"),
                              num("CRVAL2", "-40.9"), num("CRPIX1", "262"), num("CRPIX2", "249"),
                              num("CDELT1", "-8.325E-4"), num("CDELT2", "8.325E-4")}),
                      nullptr);
  ASSERT_TRUE(w);
  EXPECT_NEAR(w->plateScaleArcsecPerPx(), 2.997, 1e-12);
}

TEST(IoWcs, ToHeaderRoundTrips) {
  const auto a = Wcs::fromHeader(tanHeader(true), nullptr);
  ASSERT_TRUE(a);
  const FitsHeader h = a->toHeader();
  EXPECT_FALSE(h.find("CRVAL1")->isString) << "written as a number";
  EXPECT_NEAR(*h.getDouble("CRPIX1"), 716.0, 1e-12) << "1-based in the header";
  const auto b = Wcs::fromHeader(h, nullptr);
  ASSERT_TRUE(b);
  for (double x : {0.0, 500.0, 1431.0}) {
    const auto p = a->pixelToSky(x, 1000.0);
    const auto q = b->pixelToSky(x, 1000.0);
    EXPECT_NEAR(p.raDeg, q.raDeg, 1e-12);
    EXPECT_NEAR(p.decDeg, q.decDeg, 1e-12);
  }
}

TEST(IoWcs, SipIsApplied) {
  FitsHeader h = tanHeader(false);
  FitsHeader sip = h;
  sip.setString("CTYPE1", "RA---TAN-SIP");
  sip.setString("CTYPE2", "DEC--TAN-SIP");
  sip.setNumber("A_ORDER", 2);
  sip.setNumber("B_ORDER", 2);
  sip.setNumber("A_2_0", 1e-5);  // dx = 1e-5 * u^2
  sip.setNumber("B_0_2", 0.0);
  const auto plain = Wcs::fromHeader(h, nullptr);
  const auto withSip = Wcs::fromHeader(sip, nullptr);
  ASSERT_TRUE(withSip);
  EXPECT_TRUE(withSip->hasSip());
  // At u = x - crpix = 500 px the SIP term moves the pixel by 1e-5 * 500^2 = 2.5 px along x.
  const auto s = withSip->pixelToSky(715.0 + 500.0, 684.0);
  const auto p = plain->pixelToSky(715.0 + 502.5, 684.0);
  EXPECT_NEAR(s.raDeg, p.raDeg, 1e-9);
  EXPECT_NEAR(s.decDeg, p.decDeg, 1e-9);
}

TEST(IoWcs, ScampTanWithPvIsReadAsTpv) {
  FitsHeader h = tanHeader(true);
  h.cards.push_back(str("PV1_1", "1.0"));
  h.cards.push_back(str("PV2_1", "1.0"));
  h.cards.push_back(str("PV1_6", "0.01"));  // TPV: xi += 0.01 * eta^2 (degrees)
  std::vector<std::string> warnings;
  const auto tpv = Wcs::fromHeader(h, &warnings);
  ASSERT_TRUE(tpv);
  EXPECT_TRUE(tpv->hasTpv());
  ASSERT_FALSE(warnings.empty());
  EXPECT_NE(warnings.front().find("TPV"), std::string::npos);
  const auto tan = Wcs::fromHeader(tanHeader(false), nullptr);
  const auto a = tpv->pixelToSky(715.0, 684.0);  // at the reference point the distortion vanishes
  const auto b = tan->pixelToSky(715.0, 684.0);
  EXPECT_NEAR(a.raDeg, b.raDeg, 1e-10);
  const auto far = tpv->pixelToSky(715.0, 1369.0);
  const auto farTan = tan->pixelToSky(715.0, 1369.0);
  // eta ~ 685 px * 0.000308 deg = 0.211 deg, so xi moves by 0.01 * 0.211^2 = 4.4e-4 deg (RA by that / cos
  // dec).
  EXPECT_NEAR(std::abs(far.raDeg - farTan.raDeg) * std::cos(25.5 * M_PI / 180), 4.4e-4, 0.3e-4);
}

TEST(IoWcs, MalformedWcsWarnsAndNeverThrows) {
  std::vector<std::string> warnings;
  FitsHeader h = tanHeader(false);
  h.setString("CTYPE1", "RA---XYZ");
  EXPECT_EQ(Wcs::fromHeader(h, &warnings), nullptr);
  EXPECT_FALSE(warnings.empty());
  FitsHeader junk = tanHeader(true);
  junk.setString("CRVAL1", "not a number");
  EXPECT_NO_THROW((void)Wcs::fromHeader(junk, &warnings));
  FitsHeader singular = tanHeader(false);
  singular.setNumber("CD1_1", 0.0);
  singular.setNumber("CD1_2", 0.0);
  EXPECT_EQ(Wcs::fromHeader(singular, &warnings), nullptr);
  EXPECT_EQ(Wcs::fromHeader(header({num("NAXIS", "2")}), &warnings), nullptr) << "no WCS at all";
}

TEST(IoWriter, CardsKeepTheirTypesAndQuotedWcsNumbersBecomeNumbers) {
  st::test::TempDir dir;
  FitsHeader h = tanHeader(true);
  h.cards.push_back(num("EXPTIME", "300."));
  h.cards.push_back(num("GAIN", "4"));
  h.cards.push_back(num("INTERLCE", "F"));
  h.cards.push_back(str("OBJECT", "5945 Roachapproach"));
  h.cards.push_back(str("EQUINOX", "2000.0"));
  h.cards.push_back(str("QUOTE", "it's"));
  h.cards.push_back(FitsCard{"HISTORY", "", "a history line", false});
  const std::string path = (dir / "img.fits").string();
  Image img(4, 3, 1.5f);
  writeImage(path, img, h);
  fitsfile* f = nullptr;
  int status = 0;
  fits_open_file(&f, path.c_str(), READONLY, &status);
  ASSERT_EQ(status, 0);
  auto typeOf = [&](const char* key) {
    char value[FLEN_VALUE] = {};
    char comment[FLEN_COMMENT] = {};
    char type = '?';
    int s = 0;
    fits_read_keyword(f, key, value, comment, &s);
    fits_get_keytype(value, &type, &s);
    return s == 0 ? type : '!';
  };
  EXPECT_EQ(typeOf("CRVAL1"), 'F');
  EXPECT_EQ(typeOf("CD1_2"), 'F');
  EXPECT_EQ(typeOf("EQUINOX"), 'F');
  EXPECT_EQ(typeOf("EXPTIME"), 'F');
  EXPECT_EQ(typeOf("GAIN"), 'I');
  EXPECT_EQ(typeOf("INTERLCE"), 'L');
  EXPECT_EQ(typeOf("OBJECT"), 'C');
  EXPECT_EQ(typeOf("CTYPE1"), 'C');
  double crval = 0;
  fits_read_key(f, TDOUBLE, "CRVAL1", &crval, nullptr, &status);
  EXPECT_EQ(crval, 124.6186165755);
  fits_close_file(f, &status);
  const FrameCube back = loadFrames({path}, LoadOptions{.startMjd = 60000.0, .frameRateHz = 1.0},
                                    *std::make_unique<NullProgress>(), *std::make_unique<CancelToken>());
  EXPECT_EQ(back.header.getString("QUOTE").value_or(""), "it's");
  EXPECT_TRUE(back.wcs);
  EXPECT_EQ(back.frame(0)[11], 1.5f);
}

TEST(IoWriter, ProvenanceCards) {
  FitsHeader params;
  params.setNumber("VX_PXS", 1.25, "velocity x, px/s");
  const FitsHeader h = provenanceCards("stack", params);
  EXPECT_EQ(h.getString("SOFTWARE")->rfind("synthtrack ", 0), 0u);
  EXPECT_EQ(*h.getString("STEP"), "stack");
  EXPECT_EQ(*h.getDouble("VX_PXS"), 1.25);
  EXPECT_EQ(h.getString("DATE")->size(), 19u);
}

}  // namespace
}  // namespace st::io
