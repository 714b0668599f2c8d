// synthtrack-cli fit: the co-moving PSF fit of one candidate (paper §3.2), its segment checks (§5.1),
// photometry and astrometry (§5.1-5.2), on a zero-biased cube (e.g. from `synthtrack-cli preprocess`).
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "cli_args.hpp"
#include "commands.hpp"
#include "st/astro/astrometry.hpp"
#include "st/astro/photometry.hpp"
#include "st/candidate/candidate_fit.hpp"
#include "st/fit/comoving_fit.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/wcs.hpp"
#include "st/pipeline/prepared_json.hpp"
#include "st/vet/segments.hpp"
#include "terminal_progress.hpp"

namespace st::app {
namespace {

constexpr const char* kUsage =
    R"(usage: synthtrack-cli fit INPUT... --x X --y Y --vx-px-s VX --vy-px-s VY [options]

INPUT is a zero-biased, unfiltered cube (or frames), e.g. the output of `synthtrack-cli preprocess`.
X, Y: 0-based pixel at the cube's reference epoch (mean mid-time); VX, VY in px/s (a search candidate).
On a cube from `preprocess` the fit models a slow mover's own flux in its per-pixel background (header
BGWINS, BGNFRM, BGMINOUT, BGCLIP), taking the movers of the sidecar PREPARED.json as left out of it.

  --fwhm F | --psf-r R --psf-beta B   PSF (Moffat; with --fwhm alone beta = 4, the paper's)
  --segments K          segment checks with K equal-time segments (default 4; 0 = none)
  --sigma-n S           per-pixel noise of one frame, data units (default: from the fit residuals)
  --gain G              photons (e-) per data unit (default: GAIN, else EGAIN, over EMGAIN; else 1)
  --stamp H             stamp half-size, px (default ceil(3 FWHM))
  --max-iter N          Levenberg-Marquardt iterations (default 100)
  --sky-vx-px-s V, --sky-vy-px-s V   motion of the stars, px/s (default 0: tracked)
  --star X,Y            a static star for relative astrometry (repeatable)
  --zero-point ZP       magnitude of 1 photon/s; or --cal-mag M --cal-photons-s F from a calibration star
  --plate-scale A       arcsec/px when the frames have no WCS
  --json                print one JSON object instead of text
)";

psf::Moffat psfFromArgs(const CliArgs& a) {
  if (a.has("fwhm")) {
    const double beta = a.number("psf-beta", 4.0);
    return {psf::Moffat::radiusForFwhm(*a.number("fwhm"), beta), beta};
  }
  if (a.has("psf-r") && a.has("psf-beta")) return {*a.number("psf-r"), *a.number("psf-beta")};
  throw UsageError("give the PSF: --fwhm F, or --psf-r R --psf-beta B");
}

nlohmann::json paramsJson(const fit::FitParams& p) {
  return {{"x_px", p.xc},      {"y_px", p.yc},     {"vx_px_s", p.v.vx},
          {"vy_px_s", p.v.vy}, {"alpha", p.alpha}, {"i0", p.i0}};
}

nlohmann::json fitJson(const fit::FitResult& r) {
  nlohmann::json j = {{"status", fit::toString(r.status)},
                      {"message", r.message},
                      {"iterations", r.iterations},
                      {"cost_history", r.costHistory},
                      {"start", paramsJson(r.start)},
                      {"params", paramsJson(r.params)},
                      {"t_ref_mjd", r.tRefMjd},
                      {"frames", r.framesUsed},
                      {"pixels", r.pixels},
                      {"rms_residual", r.rmsResidual},
                      {"sigma_n", r.sigmaN},
                      {"reduced_chi2", r.reducedChi2},
                      {"snr", r.snr},
                      {"photons_per_frame", r.photonsPerFrame},
                      {"t_tot_s", r.tTotS},
                      {"warnings", r.warnings}};
  const char* names[] = {"vx_px_s", "vy_px_s", "x_px", "y_px", "alpha", "i0"};
  for (int i = 0; i < fit::kParamCount; ++i) {
    j["sigma_hessian"][names[i]] = r.sigma[i];
    j["sigma_noise_model"][names[i]] = r.sigmaNoiseModel[i];
  }
  j["sigma_paper"] = {{"pos_eq_sig_px", r.sigmaPosPaper},
                      {"pos_cent_snr_px", r.sigmaPosSnr},
                      {"vel_vel_snr_px_s", r.sigmaVelPaper}};
  return j;
}

nlohmann::json segmentsJson(const vet::SegmentReport& s) {
  nlohmann::json j = {{"flagged", s.flagged()},
                      {"reasons", s.reasons},
                      {"position_chi2", s.positionChi2},
                      {"position_dof", s.positionDof},
                      {"position_p", s.positionProbability},
                      {"flux_chi2", s.fluxChi2},
                      {"flux_dof", s.fluxDof},
                      {"flux_p", s.fluxProbability}};
  for (const auto& m : s.segments) {
    j["segments"].push_back({{"index", m.index},
                             {"frames", m.frames.size()},
                             {"t_mid_offset_s", m.tMidOffsetS},
                             {"forced_snr", m.forcedSnr},
                             {"expected_snr", m.expectedSnr},
                             {"missing", m.missing},
                             {"fit_status", fit::toString(m.fitStatus)},
                             {"x_px", m.x},
                             {"y_px", m.y},
                             {"sigma_x_px", m.sigmaX},
                             {"sigma_y_px", m.sigmaY},
                             {"predicted_x_px", m.predictedX},
                             {"predicted_y_px", m.predictedY},
                             {"snr", m.snr},
                             {"photons_per_frame", m.photonsPerFrame}});
  }
  return j;
}

// Photometry: photons/s from the fit, magnitude when a zero point is known, error from the segments.
nlohmann::json photometryJson(const CliArgs& a, const FrameCube& cube, const fit::FitResult& r,
                              const vet::SegmentReport* seg) {
  const double frameS = cube.info().front().exposureS;
  nlohmann::json j = {{"photons_per_frame", r.photonsPerFrame}};
  if (!(frameS > 0)) return j;
  const double rate = r.photonsPerFrame / frameS;
  j["photons_per_s"] = rate;
  std::optional<double> zp = a.number("zero-point");
  if (!zp && a.has("cal-mag") && a.has("cal-photons-s")) {
    zp = astro::zeroPointFromStar(*a.number("cal-mag"), *a.number("cal-photons-s"));
  }
  if (zp && rate > 0) {
    j["zero_point_mag"] = *zp;
    j["mag"] = astro::magnitude(rate, *zp);
  }
  if (seg != nullptr) {
    std::vector<double> fluxes;
    for (const auto& m : seg->segments) {
      if (!m.frames.empty()) fluxes.push_back(m.photonsPerFrame / frameS);
    }
    const astro::SegmentScatter s = astro::segmentScatter(fluxes);
    j["sigma_photons_per_s"] = s.sigmaMean;
    j["sigma_mag"] = s.sigmaMag;
  }
  return j;
}

nlohmann::json astrometryJson(const CliArgs& a, const FrameCube& cube, const fit::FitResult& r,
                              const fit::FitOptions& opt, Velocity sky) {
  nlohmann::json j;
  std::vector<fit::FitResult> stars;
  for (const std::string& s : a.values("star")) {
    double x = 0, y = 0;
    char comma = 0;
    std::istringstream in(s);
    if (!(in >> x >> comma >> y) || comma != ',') throw UsageError("--star wants X,Y, got '" + s + "'");
    stars.push_back(astro::fitStar(cube, x, y, sky, opt));
    j["stars"].push_back({{"x_px", stars.back().params.xc},
                          {"y_px", stars.back().params.yc},
                          {"status", fit::toString(stars.back().status)}});
  }
  if (!stars.empty() && r.ok()) {
    const astro::RelativeAstrometry rel = astro::relativeToStars(r, stars);
    for (const auto& o : rel.perStar) {
      j["relative"].push_back(
          {{"dx_px", o.dx}, {"dy_px", o.dy}, {"sigma_x_px", o.sigmaX}, {"sigma_y_px", o.sigmaY}});
    }
  }
  if (cube.wcs) {
    const astro::SkyMeasurement m = astro::skyMeasurement(cube, r, sky);  // the first frame's WCS
    j["sky"] = {{"t_ref_mjd", m.tRefMjd},
                {"ra_deg", m.raDeg},
                {"dec_deg", m.decDeg},
                {"sigma_ra_arcsec", m.sigmaRaArcsec},
                {"sigma_dec_arcsec", m.sigmaDecArcsec},
                {"rate_deg_day", m.rateDegPerDay},
                {"rate_arcsec_min", m.rateArcsecPerMin},
                {"sigma_rate_deg_day", m.sigmaRateDegPerDay},
                {"pa_deg", m.positionAngleDeg}};
  } else if (const auto scale =
                 a.number("plate-scale").has_value() ? a.number("plate-scale") : cube.plateScaleArcsecPerPx) {
    const astro::PlateScaleRate p = astro::rateFromPlateScale(r, sky, *scale);
    j["rate"] = {{"plate_scale_arcsec_px", *scale},
                 {"rate_deg_day", p.rateDegPerDay},
                 {"rate_arcsec_min", p.rateArcsecPerMin},
                 {"sigma_rate_deg_day", p.sigmaRateDegPerDay}};
  }
  return j;
}

void printText(const nlohmann::json& j) {
  const auto& f = j["fit"];
  const auto& p = f["params"];
  std::printf("status      %s %s\n", f["status"].get<std::string>().c_str(),
              f["message"].get<std::string>().c_str());
  std::printf("iterations  %d   cost %.6g -> %.6g\n", f["iterations"].get<int>(),
              f["cost_history"].front().get<double>(), f["cost_history"].back().get<double>());
  std::printf("position    x %.4f +- %.4f  y %.4f +- %.4f px at MJD %.8f\n", p["x_px"].get<double>(),
              f["sigma_noise_model"]["x_px"].get<double>(), p["y_px"].get<double>(),
              f["sigma_noise_model"]["y_px"].get<double>(), f["t_ref_mjd"].get<double>());
  std::printf("velocity    vx %.5f +- %.5f  vy %.5f +- %.5f px/s\n", p["vx_px_s"].get<double>(),
              f["sigma_noise_model"]["vx_px_s"].get<double>(), p["vy_px_s"].get<double>(),
              f["sigma_noise_model"]["vy_px_s"].get<double>());
  std::printf("signal      SNR %.2f  photons/frame %.2f  sigma_n %.4g  reduced chi2 %.3f\n",
              f["snr"].get<double>(), f["photons_per_frame"].get<double>(), f["sigma_n"].get<double>(),
              f["reduced_chi2"].get<double>());
  std::printf("paper       eq:sig %.4f px  cent_snr %.4f px  vel_snr %.5f px/s\n",
              f["sigma_paper"]["pos_eq_sig_px"].get<double>(),
              f["sigma_paper"]["pos_cent_snr_px"].get<double>(),
              f["sigma_paper"]["vel_vel_snr_px_s"].get<double>());
  for (const auto& w : f["warnings"])
    std::printf("warning     %s\n", w.get<std::string>().c_str());
  if (j.contains("segments")) {
    for (const auto& s : j["segments"]["segments"]) {
      std::printf("segment %d   frames %3zu  SNR %6.2f (expected %6.2f)%s  x %.3f y %.3f  [%s]\n",
                  s["index"].get<int>() + 1, s["frames"].get<std::size_t>(), s["forced_snr"].get<double>(),
                  s["expected_snr"].get<double>(), s["missing"].get<bool>() ? " MISSING" : "",
                  s["x_px"].get<double>(), s["y_px"].get<double>(),
                  s["fit_status"].get<std::string>().c_str());
    }
    for (const auto& r : j["segments"]["reasons"])
      std::printf("FLAG        %s\n", r.get<std::string>().c_str());
  }
  if (j["photometry"].contains("mag")) {
    std::printf("photometry  %.2f photons/s  mag %.2f +- %.2f\n",
                j["photometry"]["photons_per_s"].get<double>(), j["photometry"]["mag"].get<double>(),
                j["photometry"].value("sigma_mag", 0.0));
  }
  if (j["astrometry"].contains("sky")) {
    const auto& s = j["astrometry"]["sky"];
    std::printf("sky         RA %.7f Dec %.7f deg  rate %.4f deg/day (%.3f\"/min) PA %.2f deg\n",
                s["ra_deg"].get<double>(), s["dec_deg"].get<double>(), s["rate_deg_day"].get<double>(),
                s["rate_arcsec_min"].get<double>(), s["pa_deg"].get<double>());
  }
}

// A zero-biased cube from `preprocess`: the fit models its per-pixel background (header BGWINS...) and
// takes the movers in the sidecar beside it as left out of that background, as `search --fit` does on the
// frames it pre-processed (candidate::fitOptions). Returns what was done, for the user.
std::vector<std::string> modelPreparedBackground(const FrameCube& cube, double x, double y,
                                                 fit::FitOptions& opt) {
  std::vector<std::string> notes;
  const auto h = pipeline::recognisePreparedHeader(cube.header, pipeline::cubeSource(cube));
  if (!h || h->state != pipeline::PreparedState::ZeroBiased) return notes;
  pipeline::PreparedBackgroundModel model = pipeline::readPreparedBackgroundModel(*h, cube, notes);
  if (model.windows.empty()) return notes;
  if (!model.sidecarError.empty()) throw InputError(model.sidecarError);
  opt.selfSubtraction = std::move(model.windows);
  const std::string& sidecar = model.sidecar;
  const auto& movers = model.movers;
  opt.sourceInBackground = !(movers && candidate::amongLeftOutMovers(*movers, opt.psf.fwhm(), x, y));
  notes.push_back(std::string("the fit models the per-pixel background's windows (header BGWINS): ") +
                  (!movers ? "no sidecar " + sidecar + ", so the source is taken as in its background"
                   : opt.sourceInBackground
                       ? "the source is in its background (not one of the sidecar's movers)"
                       : "the source is one of the sidecar's movers, left out of its background"));
  return notes;
}

}  // namespace

int cmdFit(const Args& args) {
  if (!args.empty() && args[0] == "--help") {
    std::printf("%s", kUsage);
    return 0;
  }
  const CliArgs a(args,
                  {"x", "y", "vx-px-s", "vy-px-s", "segments", "fwhm", "psf-r", "psf-beta", "sigma-n", "gain",
                   "stamp", "max-iter", "sky-vx-px-s", "sky-vy-px-s", "star", "zero-point", "cal-mag",
                   "cal-photons-s", "plate-scale"},
                  {"json"});
  if (a.positionals().empty()) throw UsageError("no INPUT given");
  for (const char* req : {"x", "y", "vx-px-s", "vy-px-s"}) {
    if (!a.has(req)) throw UsageError(std::string("missing --") + req);
  }
  fit::FitOptions opt;
  opt.psf = psfFromArgs(a);
  opt.sigmaN = a.number("sigma-n");
  opt.stampHalfSize = static_cast<int>(a.integer("stamp").value_or(0));
  opt.maxIterations = static_cast<int>(a.integer("max-iter").value_or(100));
  const int segments = static_cast<int>(a.integer("segments").value_or(4));
  const Velocity sky{a.number("sky-vx-px-s", 0.0), a.number("sky-vy-px-s", 0.0)};

  TerminalProgress progress;
  CancelToken& cancel = processCancelToken();
  io::LoadOptions load;
  load.plateScaleArcsecPerPx = a.number("plate-scale");
  const FrameCube cube = io::loadFrames(a.positionals(), load, progress, cancel);
  progress.finish();
  for (const auto& w : cube.warnings)
    std::fprintf(stderr, "warning: %s\n", w.c_str());
  // The header's photo-electrons per count (GAIN, or EGAIN, over EMGAIN) unless given: as search --fit.
  opt.gain = a.number("gain").value_or(astro::photoelectronsPerCount(cube.header));
  const std::vector<std::string> notes = modelPreparedBackground(cube, *a.number("x"), *a.number("y"), opt);
  for (const auto& n : notes)
    std::fprintf(stderr, "note: %s\n", n.c_str());

  const fit::FitParams start{
      {*a.number("vx-px-s"), *a.number("vy-px-s")}, *a.number("x"), *a.number("y"), std::nan(""), 0.0};
  const fit::FitResult r = fit::fitComoving(cube, start, opt, {}, cancel);
  nlohmann::json out = {{"inputs", a.positionals()}, {"fit", fitJson(r)}, {"notes", notes}};
  std::optional<vet::SegmentReport> seg;
  if (segments > 0 && r.sigmaN > 0) {
    vet::SegmentOptions so;
    so.segments = segments;
    seg = vet::checkSegments(cube, r, opt, so, cancel);
    out["segments"] = segmentsJson(*seg);
  }
  out["photometry"] = photometryJson(a, cube, r, seg ? &*seg : nullptr);
  out["astrometry"] = astrometryJson(a, cube, r, opt, sky);
  if (a.flag("json")) {
    std::printf("%s\n", out.dump(2).c_str());
  } else {
    printText(out);
  }
  return r.ok() ? 0 : 1;
}

}  // namespace st::app
