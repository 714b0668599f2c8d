#include "sim_header.hpp"

#include <cmath>
#include <cstdio>

#include "st/common/units.hpp"

namespace st::sim::detail {

namespace {

// Days since 1970-01-01 -> civil date (H. Hinnant's algorithm).
void civilFromDays(long long z, int& year, int& month, int& day) {
  z += 719468;
  const long long era = (z >= 0 ? z : z - 146096) / 146097;
  const long long doe = z - era * 146097;
  const long long yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const long long doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const long long mp = (5 * doy + 2) / 153;
  day = static_cast<int>(doy - (153 * mp + 2) / 5 + 1);
  month = static_cast<int>(mp < 10 ? mp + 3 : mp - 9);
  year = static_cast<int>(yoe + era * 400 + (month <= 2 ? 1 : 0));
}

}  // namespace

std::string mjdToIsoUtc(double mjd) {
  constexpr double kMjdUnixEpoch = 40587.0;
  const double days = mjd - kMjdUnixEpoch;
  long long wholeDays = static_cast<long long>(std::floor(days));
  long long micro = std::llround((days - static_cast<double>(wholeDays)) * kSecondsPerDay * 1e6);
  if (micro >= static_cast<long long>(kSecondsPerDay) * 1000000LL) {
    micro -= static_cast<long long>(kSecondsPerDay) * 1000000LL;
    ++wholeDays;
  }
  int y = 0, m = 0, d = 0;
  civilFromDays(wholeDays, y, m, d);
  const long long secs = micro / 1000000LL;
  char buf[64];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02lld:%02lld:%02lld.%06lld", y, m, d, secs / 3600,
                (secs / 60) % 60, secs % 60, micro % 1000000LL);
  return buf;
}

FitsHeader simHeader(const SimParams& p, std::uint64_t seed, const Scene& scene) {
  FitsHeader h;
  const bool em = p.emGain > 1.0;
  h.setString("TELESCOP", "Hale 200-inch (simulated)", "synthtrack observation simulator");
  h.setString("INSTRUME", em ? "CHIMERA-like EMCCD (simulated)" : "CCD (simulated)");
  h.setString("OBJECT", "synthtrack " + p.presetName);
  h.setString("DATE-OBS", mjdToIsoUtc(p.startMjd), "UTC start of the first exposure");
  h.setNumber("MJD-OBS", p.startMjd, "MJD (UTC) start of the first exposure");
  h.setNumber("EXPTIME", p.exposureS, "[s] exposure of each frame");
  h.setNumber("FRAMERAT", p.frameRateHz, "[Hz] frame rate");
  h.setNumber("TREFMJD", scene.tRefMjd, "t_ref: mean of the frame mid-times (MJD UTC)");
  h.setNumber("GAIN", p.gainEPerAdu, "[e-/ADU] output electrons per ADU");
  h.setNumber("RDNOISE", p.readNoiseE, "[e-] read noise at the output");
  h.setNumber("EMGAIN", p.emGain, "EM multiplication gain (1 = none)");
  h.setNumber("SATURATE", p.saturationAdu, "[ADU] ADC full scale");
  h.setString("BUNIT", "ADU");
  h.setString("CTYPE1", "RA---TAN");
  h.setString("CTYPE2", "DEC--TAN");
  h.setString("CUNIT1", "deg");
  h.setString("CUNIT2", "deg");
  h.setString("RADESYS", "ICRS");
  h.setNumber("EQUINOX", 2000.0);
  h.setNumber("CRVAL1", p.raDeg, "[deg] RA at CRPIX, first frame");
  h.setNumber("CRVAL2", p.decDeg, "[deg] Dec at CRPIX, first frame");
  h.setNumber("CRPIX1", 0.5 * (p.width - 1) + 1.0, "1-based reference pixel");
  h.setNumber("CRPIX2", 0.5 * (p.height - 1) + 1.0, "1-based reference pixel");
  const double scaleDeg = p.plateScaleArcsecPerPx / kArcsecPerDeg;
  h.setNumber("CD1_1", -scaleDeg, "RA increases to -x (east left)");
  h.setNumber("CD1_2", 0.0);
  h.setNumber("CD2_1", 0.0);
  h.setNumber("CD2_2", scaleDeg);
  h.setNumber("SKYVX", p.skyDriftXPxPerS, "[px/s] drift of the star field along x");
  h.setNumber("SKYVY", p.skyDriftYPxPerS, "[px/s] drift of the star field along y");
  h.setString("SIMPRSET", p.presetName, "synthtrack simulator preset");
  h.setString("SIMSEED", std::to_string(seed), "simulator seed");
  h.cards.push_back(
      {"COMMENT", "", "Simulated by synthtrack; the WCS holds at the first frame's mid-time;", false});
  h.cards.push_back(
      {"COMMENT", "", "the star field drifts by SKYVX, SKYVY px/s. Truth: the .truth.json file.", false});
  return h;
}

}  // namespace st::sim::detail
