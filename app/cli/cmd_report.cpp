// synthtrack-cli report CANDIDATES.json: vetting labels into a session file, and the reports of issue 8 —
// DS9 regions of every candidate, ADES (PSV, XML) and MPC 80-column astrometry of the candidates labelled
// real. A submission that would not validate is refused before any file is written (exit 2, usage).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <nlohmann/json.hpp>

#include "cli_args.hpp"
#include "commands.hpp"
#include "st/common/error.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/wcs.hpp"
#include "st/report/regions.hpp"
#include "st/report/report_bundle.hpp"
#include "st/report/session_report.hpp"
#include "st/report/star_catalogues.hpp"
#include "st/session/session.hpp"
#include "st/vet/artifacts.hpp"
#include "st/vet/known_objects.hpp"
#include "terminal_progress.hpp"

namespace st::app {
namespace {

constexpr const char* kHelp =
    "usage: synthtrack-cli report CANDIDATES.json [--session S.json] [--label N=LABEL]... [--note "
    "N=TEXT]...\n"
    "                             [--candidates-json C.json] [--csv C.csv]\n"
    "                             [--ds9 out.reg] [--ades out.psv] [--ades-xml out.xml] [--mpc out.txt]\n"
    "                             [--station CODE] [--observer NAME] [--measurer NAME] [--submitter NAME]\n"
    "                             [--contact-email ADDRESS]\n"
    "                             [--telescope-aperture M] [--telescope-design D]\n"
    "                             [--telescope-detector CCD|CMO]\n"
    "                             [--ast-cat CAT] [--mpc-cat C] [--safe-snr S] [--positions segments|fit]\n"
    "                             [--wcs FITS] [--stacks DIR] [--prepared P.json] [--known K.csv "
    "[--known-radius ARCSEC]]\n"
    "  CANDIDATES.json   written by 'synthtrack-cli search --json' or the demo (candidates.json)\n"
    "  --session S.json  the vetting session: created from CANDIDATES.json when absent, else opened; every\n"
    "                    change is saved at once (atomically)\n"
    "  --label N=LABEL   label candidate N (1-based): real, unsure, unvetted, artifact or\n"
    "                    artifact:REASON (charge_leakage, diffraction, cosmic_ray, ghost, other)\n"
    "  --note N=TEXT     a note on candidate N\n"
    "  --candidates-json FILE  the candidates with fits, labels, notes and artifact flags (as the GUI's\n"
    "                    export; 'report' reads it back)   --csv FILE  the same as CSV\n"
    "  --ds9 FILE        DS9 regions of every candidate (fk5 with --wcs, else image coordinates)\n"
    "  --wcs FITS        a FITS file whose WCS maps the frames (the observation cube, or a stack written by\n"
    "                    synthtrack: WCSEPOCH names the epoch its WCS belongs to); also gives real "
    "candidates\n"
    "                    whose fit has no RA/Dec one, at the fitted position, and --ast-cat when its header\n"
    "                    names the catalogue (astrometry.net index comments)\n"
    "  --ades FILE       ADES 2022 PSV astrometry of the candidates labelled real\n"
    "  --ades-xml FILE   the same as ADES 2022 XML (what the MPC's submit.xsd validates)\n"
    "  --mpc FILE        MPC 80-column astrometry of the candidates labelled real\n"
    "                    ADES needs --station, --observer (or --measurer), --telescope-aperture\n"
    "                    and --ast-cat (design and detector have defaults); MPC 80-column needs --station\n"
    "                    and --ast-cat (or --mpc-cat).\n"
    "                    A missing value is refused (exit 2) and no file is written.\n"
    "  The values below are kept in the session's settings (--session):\n"
    "  --station CODE    MPC observatory code (3 characters)\n"
    "  --observer NAME   observer name(s), comma-separated\n"
    "  --measurer NAME   measurer (default: the first observer)   --submitter NAME  (default: the measurer)\n"
    "  --contact-email ADDRESS  where the MPC sends its acknowledgment (80-column AC2 line)\n"
    "  --telescope-aperture M     aperture in metres (ADES telescope aperture)\n"
    "  --telescope-design D       reflector (default), refractor, Schmidt, ...\n"
    "  --telescope-detector CCD   CCD (default) or CMO (CMOS); also the ADES mode and 80-column note 2\n"
    "  --ast-cat CAT     reference catalogue of the WCS solution as the MPC spells it (ADES astCat: Gaia3,\n"
    "                    Gaia2, UCAC4, PS1_DR2, ATLAS2, ...); named on the 80-column NET line (column 72\n"
    "                    is left blank: the MPC fills it)\n"
    "  --mpc-cat C       the catalogue by its MPC code (W = Gaia DR3, ...), instead of --ast-cat's\n"
    "  --safe-snr S      warn for detections below this SNR (default 7)\n"
    "  --positions P     positions per real object: 'segments' (default: the tracklet the MPC links a new\n"
    "                    object from, one position per equal-time segment of its fit, floor((SNR/7)^2)\n"
    "                    segments from 2 to 4, each near SNR 7) or 'fit' (the whole fit's one position)\n"
    "  --prepared P.json artifact checks (charge leakage, bright star, diffraction, edge) with the star "
    "catalog\n"
    "                    of the pre-processing sidecar and the input frames' times; kept in the session\n"
    "  --known K.csv     known-object check: CSV of name, ra_deg, dec_deg, epoch_mjd and rates\n"
    "                    (ra_rate_arcsec_min, dec_rate_arcsec_min or *_deg_day)  --known-radius ARCSEC (10)\n"
    "  --stacks DIR      FITS stacks (IPSA at the fitted velocity, else the search's) of the candidates\n"
    "                    labelled real, from the session's input frames, with the WCS moved to t_ref\n";

// clang-format off
const std::set<std::string> kValuedOptions = {
    "session", "label", "note", "ds9", "ades", "ades-xml", "mpc", "station", "observer", "measurer", "submitter",
    "telescope-aperture", "telescope-design", "telescope-detector", "ast-cat", "safe-snr", "wcs", "stacks",
    "mpc-cat", "prepared", "known", "known-radius", "candidates-json", "csv", "positions", "contact-email"};
// clang-format on

nlohmann::json readJson(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError("cannot read '" + path + "'");
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw InputError("'" + path + "' is not valid JSON: " + e.what());
  }
}

std::pair<std::size_t, std::string> indexed(const std::string& text, const char* option) {
  const auto eq = text.find('=');
  std::size_t pos = 0;
  long long n = 0;
  try {
    n = std::stoll(text.substr(0, eq), &pos);
  } catch (const std::exception&) {
    pos = std::string::npos;
  }
  if (eq == std::string::npos || pos != eq || n < 1) {
    throw UsageError(std::string("--") + option + " needs N=VALUE with N >= 1, got '" + text + "'");
  }
  return {static_cast<std::size_t>(n - 1), text.substr(eq + 1)};
}

void applyEdits(const CliArgs& cli, session::SessionEditor& ed) {
  for (const auto& v : cli.values("label")) {
    auto [i, text] = indexed(v, "label");
    const auto colon = text.find(':');
    const session::Label label = session::labelFromString(text.substr(0, colon));
    const session::ArtifactReason reason = colon == std::string::npos
                                               ? session::ArtifactReason::None
                                               : session::reasonFromString(text.substr(colon + 1));
    ed.setLabel(i, label, reason);
  }
  for (const auto& v : cli.values("note")) {
    auto [i, text] = indexed(v, "note");
    ed.setNote(i, text);
  }
  nlohmann::json settings = ed.session().settings;
  if (auto s = cli.value("station")) settings["station"] = *s;
  if (auto s = cli.value("observer")) settings["observers"] = *s;
  if (auto s = cli.value("measurer")) settings["measurer"] = *s;
  if (auto s = cli.value("submitter")) settings["submitter"] = *s;
  if (auto s = cli.value("contact-email")) settings["contact_email"] = *s;
  if (auto s = cli.value("telescope-design")) settings["telescope_design"] = *s;
  if (auto s = cli.value("telescope-detector")) settings["detector"] = *s;
  if (auto m = cli.number("telescope-aperture")) {
    if (!(*m > 0.0)) throw UsageError("--telescope-aperture needs the aperture in metres (> 0)");
    settings["aperture_m"] = *m;
  }
  if (auto s = cli.value("ast-cat")) settings["ast_cat"] = *s;
  if (auto s = cli.value("mpc-cat")) {
    if (s->size() != 1) throw UsageError("--mpc-cat needs one character (the MPC's catalogue code, e.g. W)");
    settings["mpc_catalog_code"] = *s;
  }
  if (auto snr = cli.number("safe-snr")) {
    if (!(*snr > 0.0) || !std::isfinite(*snr))
      throw UsageError("--safe-snr needs a positive SNR, got " + std::to_string(*snr));
    settings["safe_snr"] = *snr;
  }
  if (auto s = cli.value("positions")) {
    try {
      settings["positions"] = report::toString(report::trackletPositionsFromString(*s));
    } catch (const InputError& e) {
      throw UsageError(std::string("--positions: ") + e.what());
    }
  }
  if (settings != ed.session().settings) ed.setSettings(settings);
}

/// The WCS of --wcs FILE, mapping pixels at t_ref (the file's WCSEPOCH, else its first frame's time, is the
/// epoch its WCS belongs to). Holds the loaded cube so the mapping's Wcs stays alive.
struct WcsMapping {
  FrameCube cube;
  astro::PixelToSky toSky;
};

std::optional<WcsMapping> loadWcs(const CliArgs& cli, const session::Session& s) {
  const auto file = cli.value("wcs");
  if (!file) return std::nullopt;
  WcsMapping m;
  m.cube = io::loadFrames({*file});
  if (!m.cube.wcs) throw InputError("'" + *file + "' has no usable celestial WCS");
  const double epoch = m.cube.header.getDouble("WCSEPOCH").value_or(m.cube.info().front().mjdMid);
  const double tRef = s.search.value("t_ref_mjd", epoch);
  m.toSky = report::skyMappingAtTRef(*m.cube.wcs, report::sessionSkyRate(s), (epoch - tRef) * 86400.0);
  return m;
}

/// The option that sets a settings key (report::SettingsProblem::key).
const char* optionFor(const std::string& key) {
  if (key == "station") return "--station CODE";
  if (key == "observers" || key == "measurer") return "--observer NAME or --measurer NAME";
  if (key == "submitter") return "--submitter NAME";
  if (key == "contact_email") return "--contact-email ADDRESS";
  if (key == "telescope_design") return "--telescope-design D";
  if (key == "aperture_m") return "--telescope-aperture M";
  if (key == "detector") return "--telescope-detector CCD|CMO";
  if (key == "ast_cat") return "--ast-cat CAT";
  return "--ast-cat CAT or --mpc-cat C";
}

/// The submission settings of the session (with the catalogue of --wcs's header when none is
/// set); refuses with a usage error naming every missing value and its option, before anything is written.
report::SubmissionSettings submissionSettings(const nlohmann::json& json, const CliArgs& cli,
                                              const std::optional<WcsMapping>& wcs) {
  report::SubmissionSettings out = report::submissionFromJson(json);
  if (out.astCat.empty() && wcs) {
    if (auto cat = report::astCatFromHeader(wcs->cube.header)) {
      out.astCat = *cat;
      std::fprintf(stderr, "note: astCat %s from the header of --wcs (set --ast-cat to override)\n",
                   cat->c_str());
    }
  }
  std::string refused;
  const auto check = [&](const char* option, report::SubmissionFormat format) {
    if (!cli.has(option)) return;
    const auto problems = report::submissionProblems(out, format);
    if (problems.empty()) return;
    refused += std::string(refused.empty() ? "" : "\n") + "--" + option + " needs: ";
    for (std::size_t i = 0; i < problems.size(); ++i)
      refused += (i ? "; " : "") + problems[i].message + " (" + optionFor(problems[i].key) + ")";
  };
  check("ades", report::SubmissionFormat::Ades);
  check("ades-xml", report::SubmissionFormat::Ades);
  check("mpc", report::SubmissionFormat::Mpc80);
  if (!refused.empty()) throw UsageError(refused);
  return out;
}

/// Real candidates whose converged fit has no sky position get one through the --wcs mapping (in memory).
session::Session withSkyPositions(session::Session s, const std::optional<WcsMapping>& wcs) {
  if (!wcs) return s;
  const Velocity sky = report::sessionSkyRate(s);
  for (std::size_t i = 0; i < s.candidates.size(); ++i) {
    auto& c = s.candidates[i];
    if (c.label != session::Label::Real || !c.fitted() || c.fit->sky) continue;
    const auto p = wcs->toSky(c.fit->x, c.fit->y);
    // Its motion on the sky: the fitted velocity relative to the stars through the mapping's local scale.
    const astro::SkyMotion m =
        astro::skyMotionAt(wcs->toSky, c.fit->x, c.fit->y, {c.fit->v.vx - sky.vx, c.fit->v.vy - sky.vy});
    c.fit->sky =
        candidate::SkyPosition{p.raDeg, p.decDeg, m.rateDegPerDay, m.rateArcsecPerMin, m.positionAngleDeg};
    std::fprintf(stderr, "note: candidate %zu: sky position from --wcs at its fitted position\n", i + 1);
    if (!c.fit->segments) continue;
    // Each segment position at its own time: the stars have moved by the sky rate since t_ref.
    for (auto& q : c.fit->segments->positions) {
      if (q.raDeg) continue;
      const auto at = wcs->toSky(q.x - sky.vx * q.tOffsetS, q.y - sky.vy * q.tOffsetS);
      q.raDeg = at.raDeg;
      q.decDeg = at.decDeg;
    }
  }
  return s;
}

/// Where the regions go: the --wcs mapping, and track lines over the observation's span from the frames'
/// times (headers only).
report::RegionContext regionContext(const session::Session& s, const std::optional<WcsMapping>& wcs) {
  report::RegionContext ctx;
  if (!s.inputs.empty() && s.search.contains("t_ref_mjd")) {
    try {
      const io::InputSummary frames = io::summarizeInputs(s.inputs);
      const double tRef = s.search["t_ref_mjd"].get<double>();
      ctx.trackStartS = (frames.firstMjd - tRef) * 86400.0;
      ctx.trackEndS = (frames.lastMjd - tRef) * 86400.0;
    } catch (const Error& e) {
      std::fprintf(stderr, "note: no track lines in the regions (%s)\n", e.what());
    }
  }
  if (wcs) {
    ctx.toSky = wcs->toSky;
    ctx.frame = report::ds9SkyFrame(*wcs->cube.wcs);
  }
  return ctx;
}

/// Artifact flags (and the known-object flag) of every candidate, saved into the session.
void runVetting(const CliArgs& cli, session::SessionEditor& ed, const std::optional<WcsMapping>& wcs) {
  const auto prepared = cli.value("prepared");
  const auto known = cli.value("known");
  if (!prepared && !known) return;
  const session::Session& s = ed.session();
  if (s.inputs.empty())
    throw InputError("the candidates name no input frames (\"inputs\"): vetting needs their times");
  const io::InputSummary frames = io::summarizeInputs(s.inputs);
  std::optional<vet::ArtifactContext> ctx;
  if (prepared) ctx = vet::artifactContextFromPrepared(readJson(*prepared), frames.mjdMid, *prepared);
  const std::vector<vet::KnownObject> objects =
      known ? vet::readKnownObjects(*known) : std::vector<vet::KnownObject>{};
  const double radius = cli.number("known-radius", 10.0);
  const double tRef = s.search.value("t_ref_mjd", frames.mjdMid.empty() ? 0.0 : frames.mjdMid.front());
  ed.setParameters("vetting", {{"prepared", prepared.value_or("")},
                               {"known_objects", known.value_or("")},
                               {"known_radius_arcsec", radius},
                               {"artifacts", vet::toJson(vet::ArtifactParams{})}});
  for (std::size_t i = 0; i < s.candidates.size(); ++i) {
    const auto& c = s.candidates[i];
    const vet::Track track = c.track();
    std::vector<vet::ArtifactFlag> flags;
    if (ctx) flags = vet::checkArtifacts(*ctx, track, vet::ArtifactParams{});
    if (known) {
      if (c.fit && c.fit->sky) {
        flags.push_back(vet::knownObjectFlag(objects, c.fit->sky->raDeg, c.fit->sky->decDeg, tRef, radius));
      } else if (wcs) {
        const auto p = wcs->toSky(track.x, track.y);
        flags.push_back(vet::knownObjectFlag(objects, p.raDeg, p.decDeg, tRef, radius));
      } else {
        flags.push_back(
            {vet::ArtifactKind::KnownObject, false, -1.0, "no sky position (no fitted RA/Dec, no --wcs)"});
      }
    }
    for (const auto& f : flags)
      if (f.triggered)
        std::printf("candidate %zu: %s: %s\n", i + 1, vet::toString(f.kind), f.evidence.c_str());
    ed.setArtifacts(i, std::move(flags));
  }
}

}  // namespace

int cmdReport(const Args& args) {
  const CliArgs cli(args, kValuedOptions, {"help"});
  if (cli.flag("help")) {
    std::printf("%s", kHelp);
    return 0;
  }
  if (cli.positionals().size() != 1) throw UsageError("give one CANDIDATES.json");
  const std::string candidatesPath = cli.positionals()[0];
  session::Session s;
  std::optional<session::SessionStore> store;
  if (auto path = cli.value("session")) {
    store.emplace(*path);
    if (store->exists()) {
      s = store->load();
      // The session is the record; the candidates file only seeds a new one. Say so when they disagree.
      const session::Session fresh = session::fromSearchJson(readJson(candidatesPath));
      if (fresh.candidates.size() != s.candidates.size() ||
          fresh.search.value("t_ref_mjd", 0.0) != s.search.value("t_ref_mjd", 0.0)) {
        std::fprintf(
            stderr,
            "warning: session '%s' holds %zu candidates (t_ref %.8f) and '%s' %zu (t_ref %.8f): using the "
            "session\n",
            path->c_str(), s.candidates.size(), s.search.value("t_ref_mjd", 0.0), candidatesPath.c_str(),
            fresh.candidates.size(), fresh.search.value("t_ref_mjd", 0.0));
      }
    } else {
      s = session::fromSearchJson(readJson(candidatesPath));
      store->save(s);
      std::printf("new session %s (%zu candidates)\n", path->c_str(), s.candidates.size());
    }
  } else {
    s = session::fromSearchJson(readJson(candidatesPath));
    if (cli.has("label") || cli.has("note")) {
      std::fprintf(stderr, "warning: without --session the labels and notes are not kept\n");
    }
  }
  session::SessionEditor editor(store, std::move(s));
  applyEdits(cli, editor);
  const std::optional<WcsMapping> wcs = loadWcs(cli, editor.session());
  const bool submit = cli.has("ades") || cli.has("ades-xml") || cli.has("mpc");
  std::optional<report::SubmissionSettings> settings;
  if (submit) settings = submissionSettings(editor.session().settings, cli, wcs);
  runVetting(cli, editor, wcs);
  report::ReportRequest request;
  request.session = withSkyPositions(editor.session(), wcs);
  for (const auto& [option, file] : {std::pair{"candidates-json", report::ReportFile::CandidatesJson},
                                     std::pair{"csv", report::ReportFile::CandidatesCsv},
                                     std::pair{"ds9", report::ReportFile::Ds9},
                                     std::pair{"ades", report::ReportFile::AdesPsv},
                                     std::pair{"ades-xml", report::ReportFile::AdesXml},
                                     std::pair{"mpc", report::ReportFile::Mpc80}})
    if (auto p = cli.value(option)) request.files[file] = *p;
  if (settings) request.submission = *settings;
  if (cli.has("ds9")) request.regions = regionContext(request.session, wcs);
  if (auto dir = cli.value("stacks")) {
    if (request.session.inputs.empty())
      throw InputError("the candidates name no input frames (\"inputs\"): --stacks needs them");
    TerminalProgress progress;
    request.raw = std::make_shared<const FrameCube>(
        io::loadFrames(request.session.inputs, io::LoadOptions{}, progress, processCancelToken()));
    progress.finish();
    request.stacksStem = (std::filesystem::path(*dir) / "stack_candidate").string();
    request.stacksObjectOnly = true;
    request.stackChoice = report::StackChoice::Real;
  }
  NullProgress quiet;
  const report::ReportOutcome out = report::writeReports(request, quiet, processCancelToken());
  for (const auto& path : out.written) {
    const auto is = [&](const char* option) { return cli.value(option) == path; };
    if (is("ds9"))
      std::printf("DS9 regions of %zu candidates (%s): %s\n", request.session.candidates.size(),
                  request.regions.frame.c_str(), path.c_str());
    else if (is("ades"))
      std::printf("ADES PSV, %zu position(s) of %zu object(s): %s\n", out.detections, out.objects,
                  path.c_str());
    else if (is("ades-xml"))
      std::printf("ADES XML, %zu position(s) of %zu object(s): %s\n", out.detections, out.objects,
                  path.c_str());
    else if (is("candidates-json") || is("csv"))
      std::printf("candidates with their vetting state: %s\n", path.c_str());
    else if (is("mpc"))
      std::printf("MPC 80-column, %zu position(s) of %zu object(s): %s\n", out.detections, out.objects,
                  path.c_str());
    else
      std::printf("FITS stack: %s\n", path.c_str());
  }
  for (const auto& w : out.warnings)
    std::fprintf(stderr, "warning: %s\n", w.c_str());
  if (!out.notWritten.empty()) {
    for (const auto& path : out.notWritten)
      std::fprintf(stderr,
                   "error: %s not written: no detection to submit (label a candidate real, with a fit "
                   "and a WCS)\n",
                   path.c_str());
    return 1;
  }
  return 0;
}

}  // namespace st::app
