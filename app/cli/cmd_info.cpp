// synthtrack-cli info INPUT... [--json]: what the loader would load, from the headers only.
#include <cstdio>
#include <nlohmann/json.hpp>

#include "cli_args.hpp"
#include "commands.hpp"
#include "load_args.hpp"
#include "st/common/units.hpp"
#include "st/io/fits_reader.hpp"

namespace st::app {
namespace {

const char* bitpixText(int bitpix) {
  switch (bitpix) {
    case 8:
      return "unsigned 8-bit integer";
    case 10:
      return "signed 8-bit integer (BZERO -128)";
    case 16:
      return "signed 16-bit integer";
    case 20:
      return "unsigned 16-bit integer (BZERO 32768)";
    case 32:
      return "signed 32-bit integer";
    case 40:
      return "unsigned 32-bit integer (BZERO 2^31)";
    case 64:
      return "signed 64-bit integer";
    case 80:
      return "unsigned 64-bit integer (BZERO 2^63)";
    case -32:
      return "32-bit float";
    case -64:
      return "64-bit float";
    default:
      return "";
  }
}

void printJson(const io::InputSummary& s) {
  nlohmann::json j;
  j["frames"] = s.frames;
  j["width"] = s.width;
  j["height"] = s.height;
  j["bitpix"] = s.bitpix;
  j["hdu"] = s.hdu;
  j["first_mjd"] = s.firstMjd;
  j["last_mjd"] = s.lastMjd;
  j["first_utc"] = isoFromMjd(s.firstMjd);
  j["span_s"] = (s.lastMjd - s.firstMjd) * kSecondsPerDay;
  j["median_cadence_s"] = s.medianCadenceS;
  j["exposure_s"] = s.exposureS;
  j["time_source"] = s.timeSource;
  j["has_wcs"] = s.hasWcs;
  j["wcs"] = s.wcsDescription;
  j["plate_scale_arcsec_px"] =
      s.plateScaleArcsecPerPx ? nlohmann::json(*s.plateScaleArcsecPerPx) : nlohmann::json();
  j["mjd_mid"] = s.mjdMid;
  j["files"] = s.files;
  j["warnings"] = s.warnings;
  std::printf("%s\n", j.dump(2).c_str());
}

void printText(const io::InputSummary& s) {
  std::printf("files:       %zu (%s%s)\n", s.files.size(), s.files.front().c_str(),
              s.files.size() > 1 ? ", ..." : "");
  std::printf("frames:      %zu (image HDU %d)\n", s.frames, s.hdu);
  std::printf("size:        %d x %d px\n", s.width, s.height);
  // CFITSIO's equivalent types 10/20/40/80 are BITPIX 8/16/32/64 with the standard BZERO offset.
  const int stored = s.bitpix == 10   ? 8
                     : s.bitpix == 20 ? 16
                     : s.bitpix == 40 ? 32
                     : s.bitpix == 80 ? 64
                                      : s.bitpix;
  std::printf("BITPIX:      %d (%s)\n", stored, bitpixText(s.bitpix));
  // A start time without an exposure time is no mid-time (io::frameTimeFromHeader's "(start), no exposure").
  const bool startOnly = s.timeSource.find("no exposure") != std::string::npos;
  std::printf("first frame: MJD %.8f (%s UTC, %s)\n", s.firstMjd, isoFromMjd(s.firstMjd).c_str(),
              startOnly ? "start of the exposure: no exposure time, so the mid-time is unknown" : "mid-exposure");
  std::printf("last frame:  MJD %.8f (%s UTC)\n", s.lastMjd, isoFromMjd(s.lastMjd).c_str());
  std::printf("time span:   %.3f s\n", (s.lastMjd - s.firstMjd) * kSecondsPerDay);
  if (s.frames > 1) {
    std::printf("cadence:     %.6g s median (%.6g Hz)\n", s.medianCadenceS,
                s.medianCadenceS > 0 ? 1.0 / s.medianCadenceS : 0.0);
  }
  std::printf("exposure:    %.6g s\n", s.exposureS);
  std::printf("times from:  %s\n", s.timeSource.c_str());
  std::printf("WCS:         %s\n", s.hasWcs ? s.wcsDescription.c_str() : "none");
  if (s.plateScaleArcsecPerPx) {
    std::printf("plate scale: %.4f arcsec/px\n", *s.plateScaleArcsecPerPx);
  } else {
    std::printf("plate scale: unknown (give --plate-scale)\n");
  }
  for (const auto& w : s.warnings)
    std::printf("warning:     %s\n", w.c_str());
}

}  // namespace

int cmdInfo(const Args& args) {
  if (!args.empty() && args[0] == "--help") {
    std::printf(
        "usage: synthtrack-cli info INPUT... [--json] [options]\n\n"
        "Describes frames (a 3-D cube, 2-D files or folders) from their headers: frames, size, BITPIX,\n"
        "time span, cadence, exposure, WCS, plate scale, warnings.\n\n  --json               JSON output\n%s",
        loadOptionsHelp());
    return 0;
  }
  const CliArgs cli(args, loadOptionNames(), {"json"});
  if (cli.positionals().empty()) throw UsageError("give at least one INPUT (a FITS file or a folder)");
  const io::LoadOptions options = loadOptionsFromArgs(cli);
  const io::InputSummary s = io::summarizeInputs(cli.positionals(), options);
  if (cli.flag("json")) {
    printJson(s);
  } else {
    printText(s);
  }
  return 0;
}

}  // namespace st::app
