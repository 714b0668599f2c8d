// Reports (issue 8): MPC 80-column lines column by column against a published example, ADES PSV field by
// field, sexagesimal/date rounding with carries, DS9 regions in image and fk5 coordinates.
#include <gtest/gtest.h>

#include "test_support.hpp"

#include <cmath>
#include <sstream>

#include "st/common/error.hpp"
#include "st/io/fits_time.hpp"
#include "st/io/wcs.hpp"
#include "st/report/mpc_submission.hpp"
#include "st/report/regions.hpp"
#include "st/report/star_catalogues.hpp"

namespace st::report {
namespace {

// The first observation in the MPC's digest2 README (NEO NE00030 from station 291), as published:
constexpr const char* kPublished =
    "     NE00030  C2004 09 16.15206 16 13 11.57 +20 52 23.7          21.1 Vd     291";

AstrometricDetection publishedDetection() {
  AstrometricDetection d;
  d.trkSub = "NE00030";
  d.mjdUtc = io::mjdFromCalendar(2004, 9, 16, 0.15206 * 86400.0);
  d.raDeg = 15.0 * (16.0 + 13.0 / 60.0 + 11.57 / 3600.0);
  d.decDeg = 20.0 + 52.0 / 60.0 + 23.7 / 3600.0;
  d.mag = 21.1;
  d.band[0] = 'V';  // (assigning a literal trips a GCC 12 -Wrestrict false positive)
  d.snr = 12.0;
  return d;
}

SubmissionSettings settings291() {
  SubmissionSettings s;
  s.stationCode = "291";
  s.observers = "A. Observer, B. Second";
  s.astCat = "Gaia3";
  s.contactEmail = "observer@example.org";
  return s;
}

/// settings291() with what ADES needs beyond the 80-column format: the telescope aperture.
SubmissionSettings adesSettings291() {
  SubmissionSettings s = settings291();
  s.apertureM = 0.5;
  return s;
}

/// Columns first..last (1-based, inclusive) of a line.
std::string cols(const std::string& line, int first, int last) {
  return line.substr(first - 1, last - first + 1);
}

TEST(Mpc80, ColumnsMatchThePublishedExample) {
  const std::string ours = mpc80Line(publishedDetection(), settings291());
  const std::string pub = kPublished;
  ASSERT_EQ(ours.size(), 80u);
  ASSERT_EQ(pub.size(), 80u);
  // Identical where both carry the same text: designation, notes, magnitude, band, station. Column 72, the
  // catalogue code the MPC added on publication, is blank in a submission.
  for (int c : {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15})
    EXPECT_EQ(ours[c - 1], pub[c - 1]) << "column " << c;
  for (int c = 57; c <= 80; ++c)
    if (c != 72) {
      EXPECT_EQ(ours[c - 1], pub[c - 1]) << "column " << c;
    }
  EXPECT_EQ(pub[71], 'd');
  EXPECT_EQ(ours[71], ' ');
  // Date, RA and Dec: the same separators in the same columns; ours carries one more decimal.
  EXPECT_EQ(cols(ours, 16, 32), "2004 09 16.152060");
  EXPECT_EQ(cols(ours, 33, 44), "16 13 11.570");
  EXPECT_EQ(cols(ours, 45, 56), "+20 52 23.70");
  for (int c : {20, 23, 26, 35, 38, 41, 48, 51, 54})
    EXPECT_EQ(ours[c - 1], pub[c - 1]) << "separator column " << c;
  // Every field read back as a number equals the published value.
  EXPECT_DOUBLE_EQ(std::stod(cols(ours, 24, 32)), std::stod(cols(pub, 24, 32)));
  EXPECT_DOUBLE_EQ(std::stod(cols(ours, 40, 44)), std::stod(cols(pub, 40, 44)));
  EXPECT_DOUBLE_EQ(std::stod(cols(ours, 52, 56)), std::stod(cols(pub, 52, 56)));
  // Full precision fills the fields edge to edge (no blank between them), as the fixed columns allow.
  EXPECT_EQ(ours, "     NE00030  C2004 09 16.15206016 13 11.570+20 52 23.70         21.1 V      291");
}

TEST(Mpc80, RoundingCarriesAndSigns) {
  EXPECT_EQ(sexagesimalRa(15.0 * (5.0 + 59.0 / 60.0 + 59.9996 / 3600.0)), "06 00 00.000");
  EXPECT_EQ(sexagesimalRa(359.99999999), "00 00 00.000");
  EXPECT_EQ(sexagesimalRa(-15.0), "23 00 00.000");
  EXPECT_EQ(sexagesimalDec(-12.5), "-12 30 00.00");
  EXPECT_EQ(sexagesimalDec(-(29.0 + 59.0 / 60.0 + 59.996 / 3600.0)), "-30 00 00.00");
  EXPECT_EQ(sexagesimalDec(-1e-9), "+00 00 00.00");  // rounds to zero: no negative zero
  EXPECT_EQ(sexagesimalDec(-0.5 / 3600.0), "-00 00 00.50");
  // Date: the last microday of 1999 rounds into 2000.
  AstrometricDetection d = publishedDetection();
  d.mjdUtc = 51544.0 - 0.4e-6;
  EXPECT_EQ(cols(mpc80Line(d, settings291()), 16, 32), "2000 01 01.000000");
  EXPECT_EQ(isoUtcFromMjd(51544.5), "2000-01-01T12:00:00.000Z");
  EXPECT_EQ(isoUtcFromMjd(51544.0 - 0.1 / 86400000.0), "2000-01-01T00:00:00.000Z");
  const CalendarDate c = calendarFromMjd(0.25);
  EXPECT_EQ(c.year, 1858);
  EXPECT_EQ(c.month, 11);
  EXPECT_DOUBLE_EQ(c.day, 17.25);
  EXPECT_EQ(calendarFromMjd(60000.0).month, 2);  // MJD 60000 = 2023-02-25
  EXPECT_DOUBLE_EQ(calendarFromMjd(60000.0).day, 25.0);
}

TEST(Mpc80, MessageHasTheHeaderLinesThenTheObservations) {
  const SubmissionText t = formatMpc80({publishedDetection(), publishedDetection()}, settings291());
  std::vector<std::string> lines;
  std::stringstream ss(t.text);
  for (std::string l; std::getline(ss, l);)
    lines.push_back(l);
  ASSERT_EQ(lines.size(), 9u);
  EXPECT_EQ(lines[0], "COD 291");
  EXPECT_EQ(lines[1], "OBS A. Observer, B. Second");
  EXPECT_EQ(lines[2], "MEA A. Observer");
  EXPECT_EQ(lines[3], "TEL reflector + CCD");
  EXPECT_EQ(lines[4], "NET Gaia-DR3");  // the MPC's name of astCat Gaia3
  EXPECT_EQ(lines[5].substr(0, 4), "ACK ");
  EXPECT_EQ(lines[6], "AC2 observer@example.org");
  EXPECT_EQ(lines[7], mpc80Line(publishedDetection(), settings291()));
  EXPECT_TRUE(t.warnings.empty());  // SNR 12, a listed catalogue, observers and a contact given
  // Without a contact e-mail there is no AC2 line, and a warning says where the acknowledgment would go.
  SubmissionSettings noMail = settings291();
  noMail.contactEmail.clear();
  const SubmissionText u = formatMpc80({publishedDetection()}, noMail);
  EXPECT_EQ(u.text.find("AC2"), std::string::npos);
  ASSERT_EQ(u.warnings.size(), 1u);
  EXPECT_NE(u.warnings[0].find("no contact e-mail for the AC2 line"), std::string::npos) << u.warnings[0];
  // A malformed one is refused, by name.
  noMail.contactEmail = "observer at example.org";
  const auto problems = submissionProblems(noMail, SubmissionFormat::Mpc80);
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_EQ(problems[0].key, "contact_email");
  noMail.contactEmail = "a@b@c";
  EXPECT_EQ(submissionProblems(noMail, SubmissionFormat::Mpc80).size(), 1u);
}

TEST(Mpc80, NoMagnitudeCmosAndBadInput) {
  AstrometricDetection d = publishedDetection();
  d.mag.reset();
  SubmissionSettings s = settings291();
  s.detector = "CMO";
  const std::string line = mpc80Line(d, s);
  EXPECT_EQ(cols(line, 66, 71), "      ");
  EXPECT_EQ(line[14], 'B');
  s.stationCode = "29";
  EXPECT_THROW((void)mpc80Line(d, s), InputError);
  AstrometricDetection nan = publishedDetection();
  nan.raDeg = std::nan("");
  EXPECT_THROW((void)mpc80Line(nan, settings291()), InputError);
  EXPECT_THROW((void)formatAdesPsv({nan}, adesSettings291()), InputError);
  d.trkSub = "TOOLONG8";
  EXPECT_THROW((void)mpc80Line(d, settings291()), InputError);
}

TEST(Mpc80, Column72IsBlankAndTheNetLineNamesTheCatalogue) {
  // The MPC's catalogue codes (its "Catalogue Codes" page, and ADES-Master's packUtil.py).
  EXPECT_EQ(mpcCatalogueCode("Gaia3"), 'W');
  EXPECT_EQ(mpcCatalogueCode("Gaia2"), 'V');
  EXPECT_EQ(mpcCatalogueCode("Gaia3E"), 'X');
  EXPECT_EQ(mpcCatalogueCode("UCAC4"), 'q');
  EXPECT_EQ(mpcCatalogueCode("PS1_DR2"), '2');
  EXPECT_EQ(mpcCatalogueCode("gaia3"), ' ');  // ADES spells it exactly
  // Column 72 is the MPC's to fill ("On new submissions, column 72 must be blank"); the NET line names the
  // catalogue as that page does.
  const auto netLine = [](const SubmissionSettings& s) {
    const SubmissionText t = formatMpc80({publishedDetection()}, s);
    const auto at = t.text.find("\nNET ");
    return at == std::string::npos ? std::string()
                                   : t.text.substr(at + 1, t.text.find('\n', at + 1) - at - 1);
  };
  SubmissionSettings s = settings291();
  s.astCat = "Gaia2";
  EXPECT_EQ(mpc80Line(publishedDetection(), s)[71], ' ');
  EXPECT_EQ(netLine(s), "NET Gaia-DR2");
  s.astCat = "UCAC4";
  EXPECT_EQ(netLine(s), "NET UCAC-4");
  s.mpcCatalogCode = 'W';  // a given code names the catalogue
  EXPECT_EQ(netLine(s), "NET Gaia-DR3");
  EXPECT_EQ(mpc80Line(publishedDetection(), s)[71], ' ');
  // A catalogue the list does not know: named as given, with a warning.
  s.mpcCatalogCode = ' ';
  s.astCat = "MyCat";
  const SubmissionText unlisted = formatMpc80({publishedDetection()}, s);
  EXPECT_NE(unlisted.text.find("\nNET MyCat\n"), std::string::npos);
  ASSERT_FALSE(unlisted.warnings.empty());
  EXPECT_NE(unlisted.warnings.front().find("MyCat"), std::string::npos);
  // No catalogue at all, or a code not in the list: refused, naming what is missing.
  s.astCat.clear();
  try {
    (void)mpc80Line(publishedDetection(), s);
    ADD_FAILURE() << "no error without a catalogue";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("NET line"), std::string::npos) << e.what();
  }
  s.astCat = "Gaia3";
  s.mpcCatalogCode = '!';
  EXPECT_THROW((void)formatMpc80({publishedDetection()}, s), InputError);
}

// Messages that name the real problem: observers split at commas ("Doe, J." is two of them, the second
// initials alone: a warning), a name with the PSV separator, an aperture too large.
TEST(SubmissionSettingsMessages, NameWhatIsWrong) {
  SubmissionSettings s = adesSettings291();
  s.observers = "Doe, J.";
  const SubmissionText t = formatMpc80({publishedDetection()}, s);
  ASSERT_FALSE(t.warnings.empty());
  EXPECT_NE(t.warnings.back().find("'J.' is initials alone"), std::string::npos) << t.warnings.back();
  EXPECT_TRUE(formatMpc80({publishedDetection()}, adesSettings291()).warnings.empty());
  s.observers = "A|B";
  auto problems = submissionProblems(s, SubmissionFormat::Ades);
  ASSERT_FALSE(problems.empty());
  EXPECT_NE(problems.front().message.find("without '|'"), std::string::npos) << problems.front().message;
  s = adesSettings291();
  s.apertureM = 12345.678;
  problems = submissionProblems(s, SubmissionFormat::Ades);
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].message.find("< 1000"), std::string::npos) << problems[0].message;
}

TEST(StarCatalogues, AstCatFromAnAstrometryNetHeader) {
  auto header = [](std::vector<std::string> indexes) {
    FitsHeader h;
    h.cards.push_back({"COMMENT", "", "solved by astrometry.net", false});
    for (std::size_t i = 0; i < indexes.size(); ++i)
      h.cards.push_back(
          {"COMMENT", "", "Index(" + std::to_string(i) + "): /data/index-" + indexes[i] + ".fits", false});
    return h;
  };
  EXPECT_EQ(astCatFromHeader(header({"4219", "4218", "4217"})), "2MASS");  // as PANOPTES' solved frames
  EXPECT_EQ(astCatFromHeader(header({"4110"})), "Tyc2");
  EXPECT_EQ(astCatFromHeader(header({"5203-07", "5204-11"})), "Gaia2");
  EXPECT_EQ(astCatFromHeader(header({"4110", "4208"})), std::nullopt);  // two catalogues: which one solved?
  EXPECT_EQ(astCatFromHeader(header({"6001"})), std::nullopt);          // a series we do not know
  EXPECT_EQ(astCatFromHeader(header({})), std::nullopt);
}

TEST(SubmissionSettingsJson, RoundTripAndMistypedKeys) {
  SubmissionSettings s = adesSettings291();
  s.submitter = "S. Ubmitter";
  s.detector = "CMO";
  s.mpcCatalogCode = 'd';
  const SubmissionSettings back = submissionFromJson(toJson(s));
  EXPECT_EQ(toJson(back), toJson(s));
  EXPECT_DOUBLE_EQ(back.apertureM, 0.5);
  EXPECT_EQ(back.mpcCatalogCode, 'd');
  nlohmann::json j = toJson(s);
  j["aperture_m"] = "wide";  // a hand-edited session: the default, not an exception
  EXPECT_DOUBLE_EQ(submissionFromJson(j).apertureM, 0.0);
  // Positions per object: segments by default, "fit" kept, an unknown value the default.
  EXPECT_EQ(back.positions, TrackletPositions::Segments);
  s.positions = TrackletPositions::Fit;
  EXPECT_EQ(toJson(s)["positions"], "fit");
  EXPECT_EQ(submissionFromJson(toJson(s)).positions, TrackletPositions::Fit);
  j["positions"] = "three";
  EXPECT_EQ(submissionFromJson(j).positions, TrackletPositions::Segments);
  EXPECT_EQ(trackletPositionsFromString("fit"), TrackletPositions::Fit);
  EXPECT_THROW((void)trackletPositionsFromString("three"), InputError);
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  std::string f;
  while (std::getline(ss, f, '|')) {
    const auto b = f.find_first_not_of(' ');
    const auto e = f.find_last_not_of(' ');
    out.push_back(b == std::string::npos ? "" : f.substr(b, e - b + 1));
  }
  if (!line.empty() && line.back() == '|') out.emplace_back();
  return out;
}

TEST(AdesPsv, HeaderBlocksAndFieldsOneByOne) {
  AstrometricDetection a = publishedDetection();
  a.trkSub = "st00001";
  a.sigmaRaArcsec = 0.123;
  a.sigmaDecArcsec = 0.2;
  a.snr = 25.0;
  AstrometricDetection b = a;
  b.trkSub = "st00002";
  b.decDeg = -5.25;
  b.mag.reset();
  b.snr = 5.0;  // below the safe SNR
  const SubmissionText t = formatAdesPsv({a, b}, adesSettings291());
  std::vector<std::string> lines;
  std::stringstream ss(t.text);
  for (std::string l; std::getline(ss, l);)
    lines.push_back(l);
  ASSERT_GE(lines.size(), 5u);
  EXPECT_EQ(lines[0], "# version=2022");
  EXPECT_EQ(lines[1], "# observatory");
  EXPECT_EQ(lines[2], "! mpcCode 291");
  const std::string all = t.text;
  EXPECT_NE(all.find("# observers\n! name A. Observer\n! name B. Second\n"), std::string::npos) << all;
  EXPECT_NE(all.find("# measurers\n! name A. Observer\n"), std::string::npos);
  EXPECT_NE(all.find("# telescope\n! design reflector\n! aperture 0.500\n! detector CCD\n"),
            std::string::npos);
  std::size_t h = 0;
  while (h < lines.size() && (lines[h][0] == '#' || lines[h][0] == '!'))
    ++h;
  ASSERT_EQ(lines.size(), h + 3);
  const auto names = split(lines[h]);
  const std::vector<std::string> expected = {"trkSub", "mode",   "stn",    "obsTime", "ra",
                                             "dec",    "rmsRA",  "rmsDec", "astCat",  "mag",
                                             "band",   "logSNR", "remarks"};
  EXPECT_EQ(names, expected);
  const auto r1 = split(lines[h + 1]), r2 = split(lines[h + 2]);
  ASSERT_EQ(r1.size(), names.size());
  ASSERT_EQ(r2.size(), names.size());
  // Columns are aligned: every '|' at the same position on every line.
  EXPECT_EQ(lines[h].find('|'), lines[h + 1].find('|'));
  EXPECT_EQ(lines[h].rfind('|'), lines[h + 2].rfind('|'));
  EXPECT_EQ(r1[0], "st00001");
  EXPECT_EQ(r1[1], "CCD");
  EXPECT_EQ(r1[2], "291");
  EXPECT_EQ(r1[3], isoUtcFromMjd(a.mjdUtc));
  EXPECT_EQ(r1[3], "2004-09-16T03:38:57.984Z");  // 0.15206 day
  EXPECT_NEAR(std::stod(r1[4]), a.raDeg, 0.5e-7);
  EXPECT_EQ(r1[5][0], '+');
  EXPECT_NEAR(std::stod(r1[5]), a.decDeg, 0.5e-7);
  EXPECT_EQ(r1[6], "0.123");
  EXPECT_EQ(r1[7], "0.200");
  EXPECT_EQ(r1[8], "Gaia3");
  EXPECT_EQ(r1[9], "21.10");
  EXPECT_EQ(r1[10], "V");
  EXPECT_EQ(r1[11], "1.40");  // log10(25)
  EXPECT_EQ(r2[5], "-5.2500000");
  EXPECT_EQ(r2[9], "");
  EXPECT_EQ(r2[10], "");
  EXPECT_EQ(r2[11], "0.70");
  // One warning, for the detection below SNR 7.
  ASSERT_EQ(t.warnings.size(), 1u);
  EXPECT_NE(t.warnings[0].find("st00002"), std::string::npos);
  EXPECT_NE(t.warnings[0].find("SNR 5.00"), std::string::npos);
}

TEST(AdesPsv, MissingRequiredValuesAreRefusedNotInvented) {
  // ADES requires a measurer, the telescope aperture and astCat: without them no file is made, and the
  // error names each one.
  SubmissionSettings s;
  s.stationCode = "X05";
  try {
    (void)formatAdesPsv({publishedDetection()}, s);
    ADD_FAILURE() << "no error for settings without measurer, aperture and astCat";
  } catch (const InputError& e) {
    const std::string what = e.what();
    for (const char* needed : {"measurer", "aperture", "astCat"})
      EXPECT_NE(what.find(needed), std::string::npos) << needed << " in: " << what;
  }
  const auto problems = submissionProblems(s, SubmissionFormat::Ades);
  std::vector<std::string> keys;
  for (const auto& p : problems)
    keys.push_back(p.key);
  EXPECT_EQ(keys, (std::vector<std::string>{"measurer", "aperture_m", "ast_cat"}));
  // Given them, the missing observer is only a warning (ADES observers are optional).
  s.measurer = "M. Easurer";
  s.apertureM = 1.0;
  s.astCat = "Gaia3";
  const SubmissionText t = formatAdesPsv({publishedDetection()}, s);
  ASSERT_EQ(t.warnings.size(), 1u);
  EXPECT_NE(t.warnings[0].find("observer"), std::string::npos);
  s.stationCode.clear();
  EXPECT_THROW((void)formatAdesPsv({}, s), InputError);
}

TEST(Ds9, ImageCoordinatesAreOneBased) {
  RegionMark m;
  m.x = 10.0;
  m.y = 20.5;
  m.radiusPx = 4.0;
  m.text = "#1 {SNR} 9";
  m.color = "red";
  m.velocity = Velocity{1.0, -2.0};
  m.trackStartS = -5.0;
  m.trackEndS = 5.0;
  const std::string r = ds9Regions({m}, {});
  EXPECT_EQ(r.rfind("# Region file format: DS9 version 4.1\n", 0), 0u);
  EXPECT_NE(r.find("\nimage\ncircle(11.000,21.500,4.000) # color=red text={#1 SNR 9}\n"), std::string::npos)
      << r;
  EXPECT_NE(r.find("line(6.000,31.500,16.000,11.500) # line=0 1 color=red\n"), std::string::npos) << r;
}

TEST(Ds9, Fk5ThroughAWcsAtTheMappingEpoch) {
  FitsHeader h;
  test::setTanWcs(h, 150.0, 30.0, 101.0, 101.0, 0.3);
  std::vector<std::string> warnings;
  const auto wcs = Wcs::fromHeader(h, &warnings);
  ASSERT_NE(wcs, nullptr);
  // Stars drift +2 px/s; the WCS is the first frame's, 10 s before t_ref: a point at pixel 100 at t_ref was
  // at pixel 80 then.
  const astro::PixelToSky toSky = skyMappingAtTRef(*wcs, {2.0, 0.0}, -10.0);
  const auto p = toSky(120.0, 100.0);
  EXPECT_NEAR(p.raDeg, 150.0, 1e-9);
  EXPECT_NEAR(p.decDeg, 30.0, 1e-9);
  RegionMark m;
  m.x = 120.0;
  m.y = 100.0;
  m.radiusPx = 10.0;
  const std::string r = ds9Regions({m}, toSky);
  EXPECT_NE(r.find("\nfk5\ncircle(150.0000000,+30.0000000,3.000\")"), std::string::npos) << r;
  const std::string icrs = ds9Regions({m}, toSky, "icrs");
  EXPECT_NE(icrs.find("\nicrs\ncircle(150.0000000,+30.0000000,3.000\")"), std::string::npos) << icrs;
}

TEST(Ds9, SkyFrameFollowsTheWcs) {
  // FITS WCS paper II: RADESYS names the frame; without it FK5 for EQUINOX >= 1984, FK4 before, ICRS
  // without EQUINOX.
  const auto frameOf = [](std::optional<std::string> radesys, std::optional<double> equinox) {
    FitsHeader h;
    h.setString("CTYPE1", "RA---TAN");
    h.setString("CTYPE2", "DEC--TAN");
    h.setNumber("CRVAL1", 150.0);
    h.setNumber("CRVAL2", 30.0);
    h.setNumber("CDELT1", -1e-4);
    h.setNumber("CDELT2", 1e-4);
    if (radesys) h.setString("RADESYS", *radesys);
    if (equinox) h.setNumber("EQUINOX", *equinox);
    std::vector<std::string> warnings;
    const auto wcs = Wcs::fromHeader(h, &warnings);
    return wcs ? ds9SkyFrame(*wcs) : std::string("no wcs");
  };
  EXPECT_EQ(frameOf("ICRS", std::nullopt), "icrs");
  EXPECT_EQ(frameOf("FK5", 2000.0), "fk5");
  EXPECT_EQ(frameOf(std::nullopt, 2000.0), "fk5");
  EXPECT_EQ(frameOf(std::nullopt, 1950.0), "fk4");
  EXPECT_EQ(frameOf(std::nullopt, std::nullopt), "icrs");
}

}  // namespace
}  // namespace st::report
