// Sessions (issue 8 §6): exact round trip, atomic autosave (an interrupted save or a kill -9 loses at most
// the change being written), clear errors with a backup copy for newer and corrupted files.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <sstream>
#include <thread>

#include "st/common/error.hpp"
#include "st/session/session.hpp"
#include "test_support.hpp"

namespace st::session {
namespace {

namespace fs = std::filesystem;

nlohmann::json searchJson() {
  nlohmann::json j;
  j["inputs"] = {"/data/obs.fits"};
  j["t_ref_mjd"] = 60000.123456789012;
  j["sky_rate"] = {{"vx_px_s", 0.1}, {"vy_px_s", -1e-17}};
  j["candidates"] = nlohmann::json::array();
  for (int i = 0; i < 3; ++i) {
    nlohmann::json c{
        {"x", 100 + i}, {"y", 50}, {"vx_px_s", 1.0 / 3.0 + i}, {"vy_px_s", -2.5e-3}, {"snr", 7.123456789}};
    if (i == 0) c["fit"] = {{"status", "converged"}, {"x", 100.123456789012345}, {"ra_deg", 150.00000001}};
    j["candidates"].push_back(c);
  }
  return j;
}

std::string readAll(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string errorOf(const SessionStore& store) {
  try {
    (void)store.load();
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

/// The backup file named in a message ("... copied to 'PATH'").
fs::path backupNamed(const std::string& message) {
  const auto a = message.find("copied to '");
  if (a == std::string::npos) return {};
  const auto b = message.find('\'', a + 11);
  return message.substr(a + 11, b - a - 11);
}

TEST(Session, FromSearchJsonMovesFitsOut) {
  const Session s = fromSearchJson(searchJson());
  ASSERT_EQ(s.candidates.size(), 3u);
  EXPECT_EQ(s.inputs, std::vector<std::string>{"/data/obs.fits"});
  EXPECT_FALSE(s.search.contains("candidates"));
  ASSERT_TRUE(s.candidates[0].fit.has_value());
  EXPECT_TRUE(s.candidates[0].fit->converged());
  EXPECT_EQ(s.candidates[0].fit->x, 100.123456789012345);
  ASSERT_TRUE(s.candidates[0].fit->sky.has_value());
  EXPECT_EQ(s.candidates[0].fit->sky->raDeg, 150.00000001);
  EXPECT_EQ(s.candidates[0].search.cell.x, 100);
  EXPECT_FALSE(s.candidates[1].fit.has_value());
  EXPECT_THROW((void)fromSearchJson(nlohmann::json::object()), InputError);
}

TEST(Session, RoundTripIsExact) {
  test::TempDir dir;
  SessionStore store((dir / "s.json").string());
  Session s = fromSearchJson(searchJson());
  s.parameters["search"] = {{"snr_threshold", 7.0}, {"grid_step_px", 1.5}, {"tiny", 4.9e-324}};
  s.settings = {{"station", "X05"}, {"observers", "A. \"Quote\" O'Brien, Zoë"}};
  s.notes = "line 1\nline 2 \t tab, unicode: αβγ";
  s.candidates[1].label = Label::Artifact;
  s.candidates[1].reason = ArtifactReason::Diffraction;
  s.candidates[1].note = "spike of the star at (20, 30)";
  s.candidates[2].label = Label::Unsure;
  s.candidates[0].label = Label::Real;
  s.candidates[0].artifacts = {{vet::ArtifactKind::Edge, false, 12.5, ""}};
  candidate::SegmentSummary seg{true, {"segment 2: SNR 1 where 5 was expected"}, {5.1, 1.0}, {}};
  seg.positions.push_back(
      {1, 60000.1234, -7.123456789, 99.9876543210987, 50.5, 0.21, 0.19, 5.05, {}, {}, {}, {}});
  seg.positions.push_back(
      {2, 60000.1235, 7.5, 101.25, 50.5, 0.3, 0.25, 4.5, 150.0000001, -20.1, 0.061, 0.057});
  s.candidates[0].fit->segments = seg;
  store.save(s);
  EXPECT_EQ(s.changes, 1);
  const Session back = store.load();
  EXPECT_EQ(back, s);
  EXPECT_EQ(toJson(back).dump(), toJson(s).dump());
  EXPECT_EQ(back.search["t_ref_mjd"].get<double>(), 60000.123456789012);
  EXPECT_EQ(back.parameters["search"]["tiny"].get<double>(), 4.9e-324);
  // No temporary file is left behind by a completed save.
  EXPECT_FALSE(fs::exists(store.tempPath()));
}

TEST(Session, EveryChangeIsSavedAndAnInterruptedSaveLosesOnlyThatChange) {
  test::TempDir dir;
  SessionStore store((dir / "s.json").string());
  SessionEditor ed(store, fromSearchJson(searchJson()));
  ed.save();
  ed.setLabel(0, Label::Real);
  ed.setLabel(1, Label::Artifact, ArtifactReason::ChargeLeakage);
  ed.setNote(1, "bleed column of the saturated star");
  ed.setParameters("fit", {{"stamp_half_size", 9}});
  ed.setLabel(2, Label::Artifact);  // no reason given: "other"
  EXPECT_EQ(store.load(), ed.session());
  EXPECT_EQ(ed.session().candidates[2].reason, ArtifactReason::Other);
  // The next change was being written when the process died: a partial temporary file remains.
  const Session before = ed.session();
  std::string partial = toJson(before).dump(1);
  partial.resize(partial.size() / 2);
  std::ofstream(store.tempPath()) << partial;
  const Session after = store.load();
  EXPECT_EQ(after, before);
  EXPECT_EQ(after.changes, 6);
  // Bad edits are refused and change nothing.
  EXPECT_THROW(ed.setLabel(7, Label::Real), InputError);
  EXPECT_THROW(ed.setLabel(0, Label::Real, ArtifactReason::Ghost), InputError);
  EXPECT_EQ(store.load().changes, 6);
}

TEST(Session, KillMinus9WhileLabellingLosesAtMostTheLastChange) {
  test::TempDir dir;
  const std::string path = (dir / "s.json").string();
  {
    SessionEditor ed{SessionStore{path}, fromSearchJson(searchJson())};
    ed.save();  // changes = 1
  }
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    // Label and note as fast as possible until killed; note k is written by change k + 1.
    const SessionStore store{path};
    SessionEditor ed{store, store.load()};
    for (long k = 1;; ++k)
      ed.setNote(static_cast<std::size_t>(k % 3), "note " + std::to_string(k));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ASSERT_EQ(kill(child, SIGKILL), 0);
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status));
  // The file parses, and it is exactly the state after its last completed change.
  const Session s = SessionStore(path).load();
  const long last = static_cast<long>(s.changes) - 1;
  ASSERT_GE(last, 1) << "the child saved nothing in 300 ms";
  EXPECT_EQ(s.candidates[static_cast<std::size_t>(last % 3)].note, "note " + std::to_string(last));
  if (last >= 3) {
    EXPECT_EQ(s.candidates[static_cast<std::size_t>((last - 1) % 3)].note,
              "note " + std::to_string(last - 1));
  }
}

TEST(Session, NewerVersionIsRefusedWithABackupAndLeftUntouched) {
  test::TempDir dir;
  SessionStore store((dir / "s.json").string());
  Session s = fromSearchJson(searchJson());
  store.save(s);
  nlohmann::json j = toJson(s);
  j["version"] = 99;
  j["something_new"] = true;
  std::ofstream(store.path()) << j.dump();
  const std::string original = readAll(store.path());
  const std::string msg = errorOf(store);
  EXPECT_NE(msg.find("newer synthtrack"), std::string::npos) << msg;
  EXPECT_NE(msg.find("version 99"), std::string::npos) << msg;
  const fs::path copy = backupNamed(msg);
  ASSERT_TRUE(fs::exists(copy)) << msg;
  EXPECT_NE(copy.filename().string().find("s.newer-"), std::string::npos);
  EXPECT_EQ(readAll(copy), original);
  EXPECT_EQ(readAll(store.path()), original);
}

TEST(Session, CorruptedFilesAreRefusedWithABackup) {
  test::TempDir dir;
  SessionStore store((dir / "s.json").string());
  Session s = fromSearchJson(searchJson());
  store.save(s);
  std::string text = readAll(store.path());
  text.resize(text.size() / 3);  // truncated: not JSON
  std::ofstream(store.path(), std::ios::trunc) << text;
  std::string msg = errorOf(store);
  EXPECT_NE(msg.find("corrupted"), std::string::npos) << msg;
  fs::path copy = backupNamed(msg);
  ASSERT_TRUE(fs::exists(copy)) << msg;
  EXPECT_NE(copy.filename().string().find("s.corrupt-"), std::string::npos) << copy;
  EXPECT_EQ(copy.extension(), ".json");
  EXPECT_EQ(readAll(copy), text);
  EXPECT_EQ(readAll(store.path()), text);
  // Valid JSON of the wrong shape: a bad label.
  nlohmann::json j = toJson(s);
  j["candidates"][1]["label"] = "maybe";
  std::ofstream(store.path(), std::ios::trunc) << j.dump();
  msg = errorOf(store);
  EXPECT_NE(msg.find("maybe"), std::string::npos) << msg;
  EXPECT_NE(msg.find("corrupted"), std::string::npos) << msg;
  EXPECT_TRUE(fs::exists(backupNamed(msg))) << msg;
  EXPECT_NE(backupNamed(msg), copy);  // a second backup does not overwrite the first
  // Not a session at all.
  std::ofstream(store.path(), std::ios::trunc) << "[1, 2, 3]";
  EXPECT_NE(errorOf(store).find("not a synthtrack session"), std::string::npos);
  EXPECT_NE(errorOf(SessionStore((dir / "absent.json").string())).find("cannot read"), std::string::npos);
}

}  // namespace
}  // namespace st::session
