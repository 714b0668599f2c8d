#include "st/report/report_bundle.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "st/common/error.hpp"
#include "st/io/wcs.hpp"
#include "st/report/candidate_json.hpp"
#include "st/report/fits_stack.hpp"
#include "st/report/regions.hpp"
#include "st/report/search_report.hpp"
#include "st/report/session_report.hpp"
#include "st/stack/ipsa.hpp"

namespace st::report {
namespace {

namespace fs = std::filesystem;

void makeParent(const std::string& path) {
  const fs::path parent = fs::path(path).parent_path();
  if (parent.empty()) return;
  std::error_code ec;
  fs::create_directories(parent, ec);
  if (ec) throw InputError("cannot create folder '" + parent.string() + "': " + ec.message());
}

void writeText(const std::string& path, const std::string& text) {
  makeParent(path);
  std::ofstream out(path, std::ios::binary);
  if (!out) throw InputError("cannot write '" + path + "'");
  out << text;
  out.flush();
  if (!out) throw InputError("error writing '" + path + "' (disk full?)");
}

std::string csvField(const std::string& text) {
  if (text.find_first_of(",\"\n\r") == std::string::npos) return text;
  std::string out = "\"";
  for (char ch : text)
    out += ch == '"' ? std::string("\"\"") : std::string(1, ch);
  return out + "\"";
}

std::string numberField(std::optional<double> v) {
  if (!v) return {};
  std::ostringstream s;
  s.precision(10);
  s << *v;
  return s.str();
}

void writeStacksFor(const ReportRequest& r, std::size_t i, ReportOutcome& out) {
  const FrameCube& cube = *r.raw;
  const auto& c = r.session.candidates[i];
  const Velocity sky = sessionSkyRate(r.session);
  const auto dt = cube.timeOffsetsS();
  const std::vector<PixelOffset> offsets = r.frameOffsets.empty() ? cube.frameOffsets() : r.frameOffsets;
  const std::vector<bool> which = r.stacksObjectOnly ? std::vector<bool>{true} : std::vector<bool>{false, true};
  for (const bool object : which) {
    StackProvenance p;
    p.velocity = object ? c.track().v : sky;
    p.what = "candidate " + std::to_string(i + 1) + ", IPSA " +
             (object ? std::string("tracking the object at its ") + (c.fitted() ? "fitted" : "search") +
                           " velocity"
                     : std::string("tracking the sky (stars)"));
    p.skyRate = sky;
    p.tRefMjd = cube.tRefMjd();
    p.frames = cube.frameCount();
    p.inputs = r.session.inputs;
    p.bunit = cube.header.getString("BUNIT").value_or("adu");
    p.bunitComment = "mean per frame, background subtracted";
    char name[48];
    if (r.stacksObjectOnly)
      std::snprintf(name, sizeof name, "%03zu.fits", i + 1);
    else
      std::snprintf(name, sizeof name, "_c%03zu_%s.fits", i + 1, object ? "object" : "sky");
    const std::string path = r.stacksStem + name;
    makeParent(path);
    const stack::StackResult st = stack::stackIpsa(cube, dt, p.velocity, offsets);
    writeStackFits(path, backgroundSubtractedMean(st.sum, st.nIn), p, cube.wcs.get(), dt.front(), &st.nIn,
                   offsets.empty() ? PixelOffset{} : offsets.front());
    out.written.push_back(path);
  }
}

std::vector<std::size_t> stackCandidates(const ReportRequest& r) {
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i < r.session.candidates.size(); ++i) {
    const bool take =
        r.stackChoice == StackChoice::All ||
        (r.stackChoice == StackChoice::Real && r.session.candidates[i].label == session::Label::Real) ||
        (r.stackChoice == StackChoice::Selected && r.selected && *r.selected == static_cast<int>(i));
    if (take) out.push_back(i);
  }
  return out;
}

const std::string* pathOf(const ReportRequest& r, ReportFile file) {
  const auto it = r.files.find(file);
  return it == r.files.end() || it->second.empty() ? nullptr : &it->second;
}

void writeSubmission(const ReportRequest& r, ReportOutcome& out) {
  std::vector<std::string> warnings;
  const auto detections = realDetections(r.session, r.submission.positions, warnings);
  out.detections = detections.size();
  std::set<std::string> objects;
  for (const auto& d : detections)
    objects.insert(d.trkSub);
  out.objects = objects.size();
  if (detections.empty()) {
    // An ADES file needs at least one observation (submit.xsd: obsData holds one or more), and an empty
    // 80-column message is no submission either: none is written.
    for (const ReportFile file : {ReportFile::AdesPsv, ReportFile::AdesXml, ReportFile::Mpc80})
      if (const std::string* path = pathOf(r, file)) {
        out.notWritten.push_back(*path);
        std::error_code ec;
        if (fs::exists(*path, ec))  // not this run's: it must not be taken for one
          warnings.push_back("'" + *path + "' is an earlier file, left as it was: not this run's submission");
      }
    warnings.push_back(
        "no candidate is labelled real with a sky position: nothing to submit, no ADES or MPC file written");
    out.warnings.insert(out.warnings.end(), warnings.begin(), warnings.end());
    return;
  }
  auto add = [&](const std::vector<std::string>& more) {
    for (const auto& w : more)
      if (std::find(warnings.begin(), warnings.end(), w) == warnings.end()) warnings.push_back(w);
  };
  const std::pair<ReportFile, SubmissionText (*)(const std::vector<AstrometricDetection>&,
                                                 const SubmissionSettings&)>
      formats[] = {{ReportFile::AdesPsv, &formatAdesPsv},
                   {ReportFile::AdesXml, &formatAdesXml},
                   {ReportFile::Mpc80, &formatMpc80}};
  for (const auto& [file, format] : formats) {
    const std::string* path = pathOf(r, file);
    if (!path) continue;
    const SubmissionText t = format(detections, r.submission);
    writeText(*path, t.text);
    out.written.push_back(*path);
    add(t.warnings);
  }
  out.warnings.insert(out.warnings.end(), warnings.begin(), warnings.end());
}

}  // namespace

std::string defaultFileName(const std::string& folder, const std::string& baseName, ReportFile file) {
  const char* suffix = "";
  switch (file) {
    case ReportFile::CandidatesJson:
      suffix = "_candidates.json";
      break;
    case ReportFile::CandidatesCsv:
      suffix = "_candidates.csv";
      break;
    case ReportFile::Ds9:
      suffix = ".reg";
      break;
    case ReportFile::AdesPsv:
      suffix = ".psv";
      break;
    case ReportFile::AdesXml:
      suffix = ".xml";
      break;
    case ReportFile::Mpc80:
      suffix = "_mpc.txt";
      break;
  }
  return (fs::path(folder) / (baseName + suffix)).string();
}

RegionContext regionContext(const FrameCube* raw, const session::Session& s,
                            const std::vector<PixelOffset>& frameOffsets) {
  RegionContext ctx;
  if (!raw || raw->empty()) return ctx;
  const auto dt = raw->timeOffsetsS();
  ctx.trackStartS = dt.front();
  ctx.trackEndS = dt.back();
  if (raw->wcs) {
    // The first frame's registration offset: given apart, or the frames' own.
    const PixelOffset first = frameOffsets.empty()
                                  ? PixelOffset{raw->info().front().offsetXPx, raw->info().front().offsetYPx}
                                  : frameOffsets.front();
    ctx.toSky = skyMappingAtTRef(*raw->wcs, sessionSkyRate(s), dt.front(), first);
    ctx.frame = ds9SkyFrame(*raw->wcs);
  }
  return ctx;
}

nlohmann::json candidatesJson(const session::Session& s) {
  nlohmann::json j = s.search.is_object() ? s.search : nlohmann::json::object();
  j.erase("velocity_map");
  if (!s.inputs.empty()) j["inputs"] = s.inputs;
  nlohmann::json list = nlohmann::json::array();
  for (const auto& c : s.candidates)
    list.push_back(toCandidatesFileJson(c));
  j["candidates"] = std::move(list);
  return j;
}

std::string candidatesCsv(const session::Session& s) {
  std::string out =
      "number,label,reason,note,x,y,vx_px_s,vy_px_s,snr,n_frames,fap,rate_deg_day,pa_deg,flags,fit_x,fit_y,"
      "fit_vx_px_s,fit_vy_px_s,fit_snr,ra_deg,dec_deg\n";
  for (std::size_t i = 0; i < s.candidates.size(); ++i) {
    const auto& c = s.candidates[i];
    const search::Candidate& cell = c.search.cell;
    std::string flags;
    for (const auto& f : c.search.flags) {
      if (!flags.empty()) flags += ' ';
      flags += f;
    }
    std::vector<std::string> f = {std::to_string(i + 1), session::toString(c.label),
                                  session::toString(c.reason), csvField(c.note)};
    for (const std::optional<double> v :
         {std::optional<double>(cell.x), std::optional<double>(cell.y), std::optional<double>(cell.v.vx),
          std::optional<double>(cell.v.vy), std::optional<double>(cell.snr), std::optional<double>(cell.nIn),
          std::optional<double>(cell.fap), c.search.rateDegPerDay, c.search.paDeg})
      f.push_back(numberField(v));
    f.push_back(csvField(flags));
    const auto* fit = c.fit ? &*c.fit : nullptr;
    const auto* sky = fit && fit->sky ? &*fit->sky : nullptr;
    for (const std::optional<double> v :
         {fit ? std::optional<double>(fit->x) : std::nullopt, fit ? std::optional<double>(fit->y) : std::nullopt,
          fit ? std::optional<double>(fit->v.vx) : std::nullopt,
          fit ? std::optional<double>(fit->v.vy) : std::nullopt,
          fit ? std::optional<double>(fit->snr) : std::nullopt,
          sky ? std::optional<double>(sky->raDeg) : std::nullopt,
          sky ? std::optional<double>(sky->decDeg) : std::nullopt})
      f.push_back(numberField(v));
    for (std::size_t k = 0; k < f.size(); ++k) {
      if (k) out += ',';
      out += f[k];
    }
    out += '\n';
  }
  return out;
}

std::vector<std::string> submissionWarnings(const session::Session& s, const SubmissionSettings& settings) {
  std::vector<std::string> warnings;
  for (auto& w : lowSnrWarnings(realDetections(s, settings.positions, warnings), settings.safeSnr))
    warnings.push_back(std::move(w));
  return warnings;
}

ReportOutcome writeReports(const ReportRequest& r, ProgressSink& progress, CancelToken& cancel) {
  ReportOutcome out;
  // A submission that would not validate is refused before any file is written.
  for (const auto& [file, format] : {std::pair{ReportFile::AdesPsv, SubmissionFormat::Ades},
                                     std::pair{ReportFile::AdesXml, SubmissionFormat::Ades},
                                     std::pair{ReportFile::Mpc80, SubmissionFormat::Mpc80}}) {
    if (!pathOf(r, file)) continue;
    if (const auto problems = submissionProblems(r.submission, format); !problems.empty())
      throw InputError(problemsText(problems, format));
  }
  if (!r.stacksStem.empty() && (!r.raw || r.raw->empty()))
    throw InputError("FITS stacks need the observation's frames (none loaded)");
  progress.report(0.0, "reports");
  if (const auto* path = pathOf(r, ReportFile::CandidatesJson)) {
    makeParent(*path);
    writeJsonFile(*path, candidatesJson(r.session));
    out.written.push_back(*path);
  }
  if (const auto* path = pathOf(r, ReportFile::CandidatesCsv)) {
    writeText(*path, candidatesCsv(r.session));
    out.written.push_back(*path);
  }
  if (const auto* path = pathOf(r, ReportFile::Ds9)) {
    makeParent(*path);
    writeDs9Regions(*path, regionMarks(r.session, r.regions.trackStartS, r.regions.trackEndS), r.regions.toSky,
                    r.regions.frame);
    out.written.push_back(*path);
  }
  cancel.throwIfCancelled();
  if (pathOf(r, ReportFile::AdesPsv) || pathOf(r, ReportFile::AdesXml) || pathOf(r, ReportFile::Mpc80))
    writeSubmission(r, out);
  if (!r.stacksStem.empty()) {
    const auto which = stackCandidates(r);
    if (which.empty()) out.warnings.push_back("FITS stacks: no candidate matches the choice; none written");
    for (std::size_t k = 0; k < which.size(); ++k) {
      cancel.throwIfCancelled();
      progress.report(static_cast<double>(k) / which.size(), "FITS stacks");
      writeStacksFor(r, which[k], out);
    }
  }
  progress.report(1.0, "reports");
  return out;
}

}  // namespace st::report
