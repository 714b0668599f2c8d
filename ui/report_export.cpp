#include "report_export.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "st/common/error.hpp"
#include "st/io/wcs.hpp"
#include "st/report/fits_stack.hpp"
#include "st/report/regions.hpp"
#include "st/report/search_report.hpp"
#include "st/report/session_report.hpp"
#include "st/stack/ipsa.hpp"

namespace st::ui {
namespace {

namespace fs = std::filesystem;

std::optional<double> number(const nlohmann::json& j, const char* key) {
  if (j.is_object() && j.contains(key) && j[key].is_number()) return j[key].get<double>();
  return std::nullopt;
}

Velocity skyRateOf(const session::Session& s) {
  if (!s.search.contains("sky_rate")) return {};
  return {s.search["sky_rate"].value("vx_px_s", 0.0), s.search["sky_rate"].value("vy_px_s", 0.0)};
}

bool fitted(const session::CandidateState& c) {
  return c.fit.is_object() && c.fit.value("status", std::string{}) == "converged";
}

void writeText(const std::string& path, const std::string& text) {
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

std::string numberField(const nlohmann::json& j, const char* key) {
  const auto v = number(j, key);
  if (!v) return {};
  std::ostringstream s;
  s.precision(10);
  s << *v;
  return s.str();
}

/// Time span of the frames relative to t_ref (track lines in the regions), or (0, 0).
std::pair<double, double> spanS(const FrameCube* raw) {
  if (!raw || raw->empty()) return {0.0, 0.0};
  const auto dt = raw->timeOffsetsS();
  return {dt.front(), dt.back()};
}

void writeStacksFor(const ReportRequest& r, std::size_t i, const std::string& stem, ReportOutcome& out) {
  const FrameCube& cube = *r.raw;
  const auto& c = r.session.candidates[i];
  const nlohmann::json& src = fitted(c) ? c.fit : c.candidate;
  const Velocity sky = skyRateOf(r.session);
  const auto dt = cube.timeOffsetsS();
  for (const bool object : {false, true}) {
    report::StackProvenance p;
    p.velocity = object ? Velocity{src.value("vx_px_s", 0.0), src.value("vy_px_s", 0.0)} : sky;
    p.what =
        "candidate " + std::to_string(i + 1) + ", IPSA " +
        (object ? std::string("tracking the object at its ") + (fitted(c) ? "fitted" : "search") + " velocity"
                : std::string("tracking the sky (stars)"));
    p.skyRate = sky;
    p.tRefMjd = cube.tRefMjd();
    p.frames = cube.frameCount();
    p.inputs = r.session.inputs;
    char name[48];
    std::snprintf(name, sizeof name, "_c%03zu_%s.fits", i + 1, object ? "object" : "sky");
    const std::string path = stem + name;
    report::writeStackFits(path, stack::stackIpsa(cube, dt, p.velocity).sum, p, cube.wcs.get(), dt.front());
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

void writeSubmission(const ReportRequest& r, const std::string& stem, ReportOutcome& out) {
  std::vector<std::string> warnings;
  const auto detections = report::realDetections(r.session, warnings);
  if (detections.empty())
    warnings.push_back("no candidate is labelled real with a sky position: nothing to submit");
  auto add = [&](const std::vector<std::string>& more) {
    for (const auto& w : more)
      if (std::find(warnings.begin(), warnings.end(), w) == warnings.end()) warnings.push_back(w);
  };
  if (r.ades) {
    const auto t = report::formatAdesPsv(detections, r.submission);
    writeText(stem + ".psv", t.text);
    out.written.push_back(stem + ".psv");
    add(t.warnings);
  }
  if (r.mpc) {
    const auto t = report::formatMpc80(detections, r.submission);
    writeText(stem + "_mpc.txt", t.text);
    out.written.push_back(stem + "_mpc.txt");
    add(t.warnings);
  }
  out.warnings.insert(out.warnings.end(), warnings.begin(), warnings.end());
}

}  // namespace

nlohmann::json candidatesJson(const session::Session& s) {
  nlohmann::json j = s.search.is_object() ? s.search : nlohmann::json::object();
  j.erase("velocity_map");
  if (!s.inputs.empty()) j["inputs"] = s.inputs;
  nlohmann::json list = nlohmann::json::array();
  for (const auto& c : s.candidates) {
    nlohmann::json o = c.candidate;
    if (!c.fit.is_null()) o["fit"] = c.fit;
    o["label"] = session::toString(c.label);
    o["reason"] = session::toString(c.reason);
    o["note"] = c.note;
    o["artifacts"] = c.artifacts;
    list.push_back(std::move(o));
  }
  j["candidates"] = std::move(list);
  return j;
}

std::string candidatesCsv(const session::Session& s) {
  std::string out =
      "number,label,reason,note,x,y,vx_px_s,vy_px_s,snr,n_frames,fap,rate_deg_day,pa_deg,flags,fit_x,fit_y,"
      "fit_vx_px_s,fit_vy_px_s,fit_snr,ra_deg,dec_deg\n";
  for (std::size_t i = 0; i < s.candidates.size(); ++i) {
    const auto& c = s.candidates[i];
    std::string flags;
    if (c.candidate.contains("flags"))
      for (const auto& f : c.candidate["flags"]) {
        if (!flags.empty()) flags += ' ';
        flags += f.get<std::string>();
      }
    std::vector<std::string> f = {std::to_string(i + 1), session::toString(c.label),
                                  session::toString(c.reason), csvField(c.note)};
    for (const char* k : {"x", "y", "vx_px_s", "vy_px_s", "snr", "n_frames", "fap", "rate_deg_day", "pa_deg"})
      f.push_back(numberField(c.candidate, k));
    f.push_back(csvField(flags));
    for (const char* k : {"x", "y", "vx_px_s", "vy_px_s", "snr", "ra_deg", "dec_deg"})
      f.push_back(numberField(c.fit, k));
    for (std::size_t k = 0; k < f.size(); ++k) {
      if (k) out += ',';
      out += f[k];
    }
    out += '\n';
  }
  return out;
}

std::vector<std::string> submissionWarnings(const session::Session& s, double safeSnr) {
  std::vector<std::string> warnings;
  for (const auto& d : report::realDetections(s, warnings)) {
    if (d.snr >= safeSnr) continue;
    char buf[200];
    std::snprintf(
        buf, sizeof buf,
        "%s: SNR %.2f is below the safe %.1f; the MPC rejects shift-and-stack detections pulled out "
        "of the noise: confirm it before submitting",
        d.trkSub.c_str(), d.snr, safeSnr);
    warnings.emplace_back(buf);
  }
  return warnings;
}

ReportOutcome writeReports(const ReportRequest& r, ProgressSink& progress, CancelToken& cancel) {
  ReportOutcome out;
  if (r.folder.empty()) throw InputError("reports: no output folder given");
  std::error_code ec;
  fs::create_directories(r.folder, ec);
  if (ec) throw InputError("cannot create folder '" + r.folder + "': " + ec.message());
  const std::string stem = (fs::path(r.folder) / r.baseName).string();
  // A submission that would not validate is refused before any file is written.
  for (const auto& [wanted, format] : {std::pair{r.ades, report::SubmissionFormat::Ades},
                                       std::pair{r.mpc, report::SubmissionFormat::Mpc80}}) {
    if (!wanted) continue;
    if (const auto problems = report::submissionProblems(r.submission, format); !problems.empty())
      throw InputError(report::problemsText(problems, format));
  }
  progress.report(0.0, "reports");
  if (r.candidatesJson) {
    report::writeJsonFile(stem + "_candidates.json", candidatesJson(r.session));
    out.written.push_back(stem + "_candidates.json");
  }
  if (r.candidatesCsv) {
    writeText(stem + "_candidates.csv", candidatesCsv(r.session));
    out.written.push_back(stem + "_candidates.csv");
  }
  if (r.ds9) {
    const auto [t0, t1] = spanS(r.raw.get());
    astro::PixelToSky toSky;
    std::string frame = "fk5";
    if (r.raw && r.raw->wcs) {
      toSky = report::skyMappingAtTRef(*r.raw->wcs, skyRateOf(r.session), t0);
      frame = report::ds9SkyFrame(*r.raw->wcs);
    }
    report::writeDs9Regions(stem + ".reg", report::regionMarks(r.session, t0, t1), toSky, frame);
    out.written.push_back(stem + ".reg");
  }
  cancel.throwIfCancelled();
  if (r.ades || r.mpc) writeSubmission(r, stem, out);
  if (r.stacks) {
    if (!r.raw || r.raw->empty()) throw InputError("FITS stacks need the observation's frames (none loaded)");
    const auto which = stackCandidates(r);
    if (which.empty()) out.warnings.push_back("FITS stacks: no candidate matches the choice; none written");
    for (std::size_t k = 0; k < which.size(); ++k) {
      cancel.throwIfCancelled();
      progress.report(static_cast<double>(k) / which.size(), "FITS stacks");
      writeStacksFor(r, which[k], stem, out);
    }
  }
  progress.report(1.0, "reports");
  return out;
}

}  // namespace st::ui
