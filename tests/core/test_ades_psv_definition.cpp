// ADES PSV (ADES 2022, the MPC's "ADES Description" and its PSV rules) checked field by field against the
// format's definition rather than against our own expectations: every data line of formatAdesPsv() for a
// set of awkward detections (RA near 360, southern Dec, no magnitude, low SNR, sub-second epochs) must
// satisfy each field's syntax and range, carry the required optical fields, and keep the PSV table shape.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <regex>
#include <set>
#include <sstream>

#include "st/io/fits_time.hpp"
#include "st/report/mpc_submission.hpp"

namespace st::report {
namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(' ');
  const auto e = s.find_last_not_of(' ');
  return b == std::string::npos ? "" : s.substr(b, e - b + 1);
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::size_t start = 0;
  for (std::size_t p; (p = line.find('|', start)) != std::string::npos; start = p + 1)
    out.push_back(trim(line.substr(start, p - start)));
  out.push_back(trim(line.substr(start)));
  return out;
}

std::vector<AstrometricDetection> awkwardDetections() {
  std::vector<AstrometricDetection> ds;
  const double base = io::mjdFromCalendar(2024, 12, 31, 86399.9996);  // rounds across the year
  const double ras[] = {359.99999999, 0.0, 123.456789012, 15.0};
  const double decs[] = {-89.9999, 0.0000001, -0.5, 45.25};
  const double snrs[] = {25.0, 7.0, 5.5, 100.0};
  for (int i = 0; i < 4; ++i) {
    AstrometricDetection d;
    d.trkSub = "st0000" + std::to_string(i + 1);
    d.mjdUtc = base + i * 0.37 / 86400.0;
    d.raDeg = ras[i];
    d.decDeg = decs[i];
    d.snr = snrs[i];
    if (i != 1) d.mag = 20.0 + i * 0.333;
    if (i != 2) d.sigmaRaArcsec = 0.05 * (i + 1), d.sigmaDecArcsec = 0.07 * (i + 1);
    ds.push_back(d);
  }
  return ds;
}

}  // namespace

TEST(AdesPsvDefinition, EveryDataLineSatisfiesTheFieldDefinitions) {
  SubmissionSettings s;
  s.stationCode = "I41";
  s.observers = "A. Observer";
  s.astCat = "Gaia3";
  s.apertureM = 1.05;
  const auto ds = awkwardDetections();
  const SubmissionText t = formatAdesPsv(ds, s);
  std::vector<std::string> lines;
  std::stringstream ss(t.text);
  for (std::string l; std::getline(ss, l);)
    lines.push_back(l);
  ASSERT_FALSE(lines.empty());
  EXPECT_EQ(lines[0], "# version=2022");  // ADES: the version line comes first
  std::size_t h = 0;
  while (h < lines.size() && (lines[h][0] == '#' || lines[h][0] == '!'))
    ++h;
  ASSERT_EQ(lines.size(), h + 1 + ds.size());
  const auto names = split(lines[h]);
  std::map<std::string, std::size_t> col;
  for (std::size_t k = 0; k < names.size(); ++k)
    col[names[k]] = k;
  // Optical observations need an identification, mode, stn, obsTime, ra, dec and astCat.
  EXPECT_TRUE(col.count("permID") || col.count("provID") || col.count("trkSub"));
  for (const char* required : {"mode", "stn", "obsTime", "ra", "dec", "astCat"})
    EXPECT_TRUE(col.count(required)) << required;

  const std::regex trkSub(R"(^[A-Za-z0-9]{1,8}$)");
  const std::regex stn(R"(^[A-Z0-9]{3}$)");
  const std::regex obsTime(R"(^(\d{4})-(\d\d)-(\d\d)T(\d\d):(\d\d):(\d\d)(\.\d{1,6})?Z$)");
  const std::regex ra(R"(^\d{1,3}(\.\d+)?$)");
  const std::regex dec(R"(^[+-]?\d{1,2}(\.\d+)?$)");
  const std::regex positive(R"(^\d+(\.\d+)?$)");
  const std::regex decimal(R"(^[+-]?\d+(\.\d+)?$)");
  const std::set<std::string> modes = {"CCD", "CMO", "VID", "PHO", "ENC", "PMT", "MIC", "MEA", "TDI", "UNK"};
  for (std::size_t i = 0; i < ds.size(); ++i) {
    const std::string& line = lines[h + 1 + i];
    SCOPED_TRACE(line);
    EXPECT_EQ(line.find('\t'), std::string::npos);  // PSV: '|' separated, blanks only as padding
    const auto f = split(line);
    ASSERT_EQ(f.size(), names.size());
    EXPECT_TRUE(std::regex_match(f[col["trkSub"]], trkSub));
    EXPECT_TRUE(modes.count(f[col["mode"]]));
    EXPECT_TRUE(std::regex_match(f[col["stn"]], stn));
    std::smatch m;
    ASSERT_TRUE(std::regex_match(f[col["obsTime"]], m, obsTime));
    EXPECT_TRUE(std::stoi(m[2]) >= 1 && std::stoi(m[2]) <= 12);
    EXPECT_TRUE(std::stoi(m[3]) >= 1 && std::stoi(m[3]) <= 31);
    EXPECT_LT(std::stoi(m[4]), 24);
    EXPECT_LT(std::stoi(m[5]), 60);
    EXPECT_LT(std::stoi(m[6]), 60);
    EXPECT_EQ(f[col["obsTime"]], isoUtcFromMjd(ds[i].mjdUtc));
    ASSERT_TRUE(std::regex_match(f[col["ra"]], ra));
    const double raV = std::stod(f[col["ra"]]);
    EXPECT_TRUE(raV >= 0.0 && raV < 360.0) << raV;
    EXPECT_NEAR(std::remainder(raV - ds[i].raDeg, 360.0), 0.0, 1e-6);
    ASSERT_TRUE(std::regex_match(f[col["dec"]], dec));
    EXPECT_NEAR(std::stod(f[col["dec"]]), ds[i].decDeg, 1e-6);
    EXPECT_FALSE(f[col["astCat"]].empty());
    for (const char* rms : {"rmsRA", "rmsDec"})
      if (!f[col[rms]].empty()) {
        EXPECT_TRUE(std::regex_match(f[col[rms]], positive)) << rms;
        EXPECT_GT(std::stod(f[col[rms]]), 0.0) << rms;
      }
    EXPECT_EQ(f[col["rmsRA"]].empty(), !ds[i].sigmaRaArcsec.has_value());
    if (ds[i].mag) {
      ASSERT_TRUE(std::regex_match(f[col["mag"]], decimal));
      EXPECT_NEAR(std::stod(f[col["mag"]]), *ds[i].mag, 0.005);
      EXPECT_FALSE(f[col["band"]].empty());  // a magnitude needs its band
    } else {
      EXPECT_TRUE(f[col["mag"]].empty());
    }
    ASSERT_TRUE(std::regex_match(f[col["logSNR"]], decimal));
    EXPECT_NEAR(std::pow(10.0, std::stod(f[col["logSNR"]])), ds[i].snr, 0.012 * ds[i].snr);
  }
  // The 23:59:59.9996 epoch rounds to the next year's first millisecond, with every carry.
  EXPECT_EQ(split(lines[h + 1])[col["obsTime"]], "2025-01-01T00:00:00.000Z");
  // One warning: the SNR 5.5 detection (the paper's threshold 7 is the default safe SNR; 7.0 itself is safe).
  ASSERT_EQ(t.warnings.size(), 1u);
  EXPECT_NE(t.warnings[0].find("st00003"), std::string::npos);
}

}  // namespace st::report
