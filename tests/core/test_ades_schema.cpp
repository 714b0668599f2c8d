// ADES files checked against the standard itself: the XML we write, and the XML equivalent of the PSV we
// write (parsed back from its text), validated by xmllint against the IAU's submit.xsd (ADES 2022, in
// ../shared/standards/ades; skipped when that or xmllint is absent). The validation path is shown to fail for
// files missing what the MPC rejected before: the 2017 version, the telescope aperture, astCat.
#include <gtest/gtest.h>

#include "test_support.hpp"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "st/common/error.hpp"
#include "st/io/fits_time.hpp"
#include "st/report/mpc_submission.hpp"

namespace st::report {
namespace {

namespace fs = std::filesystem;

fs::path submitXsd() {
  return fs::path(ST_SOURCE_DIR).parent_path() / "shared" / "standards" / "ades" / "submit.xsd";
}

bool haveXmllint() {
  return std::system("xmllint --version > /dev/null 2>&1") == 0;
}

struct Validation {
  bool valid = false;
  std::string log;  ///< xmllint's own messages
};

/// xmllint --noout --schema submit.xsd on `xml`, written to a file in `dir`.
Validation validate(const test::TempDir& dir, const std::string& xml, const std::string& name) {
  const fs::path file = dir / (name + ".xml");
  const fs::path log = dir / (name + ".log");
  std::ofstream(file) << xml;
  const std::string cmd = "xmllint --noout --schema '" + submitXsd().string() + "' '" + file.string() +
                          "' > '" + log.string() + "' 2>&1";
  Validation v;
  v.valid = std::system(cmd.c_str()) == 0;
  std::ifstream in(log);
  std::stringstream ss;
  ss << in.rdbuf();
  v.log = ss.str();
  return v;
}

class AdesSchema : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::is_regular_file(submitXsd())) GTEST_SKIP() << "no ADES schema at " << submitXsd();
    if (!haveXmllint()) GTEST_SKIP() << "xmllint not installed (Debian: libxml2-utils)";
  }
  test::TempDir tmp;
};

SubmissionSettings observatory() {
  SubmissionSettings s;
  s.stationCode = "695";
  s.observers = "A. Observer, B. Second";
  s.measurer = "C. Measurer";
  s.telescopeDesign = "reflector";
  s.apertureM = 1.05;
  s.detector = "CCD";
  s.astCat = "Gaia3";
  return s;
}

/// Two detections as the pipeline makes them (a magnitude on one, none on the other), and two awkward ones:
/// RA rounding to 360, the south pole, a sub-milliarcsecond sigma, SNR below 1 (negative logSNR), a
/// magnitude out of ADES's range.
std::vector<AstrometricDetection> detections(bool awkward) {
  std::vector<AstrometricDetection> ds(2);
  ds[0].trkSub = "st00001";
  ds[0].mjdUtc = io::mjdFromCalendar(2019, 3, 26, 4.0 * 3600.0 + 12.345);
  ds[0].raDeg = 187.4386521;
  ds[0].decDeg = 9.1133447;
  ds[0].sigmaRaArcsec = 0.081;
  ds[0].sigmaDecArcsec = 0.094;
  ds[0].mag = 21.37;
  ds[0].snr = 11.6;
  ds[1] = ds[0];
  ds[1].trkSub = "st00004";
  ds[1].raDeg = 187.4390117;
  ds[1].decDeg = -0.0123456;
  ds[1].mag.reset();
  ds[1].snr = 7.3;
  if (awkward) {
    ds[0].raDeg = 359.99999999;
    ds[0].decDeg = -89.99999;
    ds[0].sigmaRaArcsec = 0.0002;
    ds[0].snr = 0.5;
    ds[1].mag = 40.0;
  }
  return ds;
}

TEST_F(AdesSchema, XmlOfRealisticDetectionsValidates) {
  std::string xml = formatAdesXml(detections(false), observatory()).text;
  const Validation v = validate(tmp, xml, "ades");
  EXPECT_TRUE(v.valid) << v.log << "\n" << xml;
  EXPECT_NE(xml.find("<ades version=\"2022\">"), std::string::npos);
  // Awkward values and a CMOS camera validate as well.
  SubmissionSettings cmos = observatory();
  cmos.detector = "CMO";
  cmos.astCat = "PS1_DR2";
  const SubmissionText awkward = formatAdesXml(detections(true), cmos);
  const Validation w = validate(tmp, awkward.text, "awkward");
  EXPECT_TRUE(w.valid) << w.log << "\n" << awkward.text;
  EXPECT_EQ(awkward.text.find("<mag>40"), std::string::npos);  // out of range: left out, with a warning
}

TEST_F(AdesSchema, PsvValidatesThroughItsXmlEquivalent) {
  for (bool awkward : {false, true}) {
    SCOPED_TRACE(awkward ? "awkward" : "realistic");
    const std::string psv = formatAdesPsv(detections(awkward), observatory()).text;
    const std::string xml = adesXmlFromPsv(psv);
    const Validation v = validate(tmp, xml, "psv");
    EXPECT_TRUE(v.valid) << v.log << "\nPSV:\n" << psv << "\nXML:\n" << xml;
    // The two spellings say the same: the PSV read back is the XML we write directly.
    EXPECT_EQ(xml, formatAdesXml(detections(awkward), observatory()).text);
  }
}

TEST_F(AdesSchema, FilesMissingWhatTheMpcRequiresAreRejected) {
  const std::string good = formatAdesXml(detections(false), observatory()).text;
  ASSERT_TRUE(validate(tmp, good, "good").valid);
  // What issue 18 found in the old output, one at a time: the 2017 version, no telescope aperture, no astCat.
  const std::string v2017 = std::regex_replace(good, std::regex("version=\"2022\""), "version=\"2017\"");
  const std::string noAperture = std::regex_replace(good, std::regex(" *<aperture>[^<]*</aperture>\n"), "");
  const std::string noAstCat = std::regex_replace(good, std::regex(" *<astCat>[^<]*</astCat>\n"), "");
  for (const auto& [name, xml] :
       {std::pair{"v2017", v2017}, std::pair{"noAperture", noAperture}, std::pair{"noAstCat", noAstCat}}) {
    SCOPED_TRACE(name);
    ASSERT_NE(xml, good);  // the edit happened
    const Validation v = validate(tmp, xml, name);
    EXPECT_FALSE(v.valid) << xml;
    EXPECT_NE(v.log.find("fails to validate"), std::string::npos) << v.log;
  }
  // The PSV path too: a PSV whose astCat column is empty has an XML equivalent that is rejected.
  std::vector<std::string> warnings;
  AdesDocument doc = adesDocument(detections(false), observatory(), warnings);
  for (auto& row : doc.rows)
    row[8].clear();
  ASSERT_EQ(doc.fields[8], "astCat");
  const Validation v = validate(tmp, adesXmlFromPsv(adesPsvText(doc)), "psvNoAstCat");
  EXPECT_FALSE(v.valid);
  EXPECT_NE(v.log.find("Expected is one of ( rmsCorr, astCat )"), std::string::npos) << v.log;
}

TEST(AdesPsvParse, ReadsWhatPsvToXmlReadsAndRefusesTheRest) {
  const std::string psv =
      "# version=2022\n"
      "# observatory\n"
      "! mpcCode 695\n"
      "# observers\n"
      "! name A. O'Brien & Sons\n"
      "! name B. Second\n"
      "\n"
      "trkSub |mode|stn|obsTime                 |ra       |dec      |astCat\n"
      " st1   |CCD |695|2019-03-26T04:00:12.345Z|187.43865|+9.11334 |Gaia3\n"
      " st2   |CCD |695|2019-03-26T04:00:12.345Z|187.43865|+9.11334\n";
  const AdesDocument d = parseAdesPsv(psv);
  EXPECT_EQ(d.version, "2022");
  ASSERT_EQ(d.context.size(), 2u);
  EXPECT_EQ(d.context[1].items[0], (std::pair<std::string, std::string>{"name", "A. O'Brien & Sons"}));
  ASSERT_EQ(d.rows.size(), 2u);
  EXPECT_EQ(d.rows[0][0], "st1");
  EXPECT_EQ(d.rows[1][6], "");  // fewer values than names: absent
  const std::string xml = adesXmlText(d);
  EXPECT_NE(xml.find("<name>A. O&apos;Brien &amp; Sons</name>"), std::string::npos) << xml;
  EXPECT_EQ(xml.find("<astCat></astCat>"), std::string::npos);
  EXPECT_THROW((void)parseAdesPsv("# observatory\n! mpcCode 695\n"), InputError);  // no version line
  EXPECT_THROW((void)parseAdesPsv("# version=2022\n! mpcCode 695\n"), InputError);
  EXPECT_THROW((void)parseAdesPsv("# version=2022\n# observatory\n! mpcCode 695\na|b\n1|2|3\n"), InputError);
  EXPECT_THROW((void)parseAdesPsv("# version=2022\n# observatory\n"), InputError);  // no field names
  AdesDocument bad = d;
  bad.rows[0][0] = "st|1";
  EXPECT_THROW((void)adesPsvText(bad), InputError);
}

}  // namespace
}  // namespace st::report
