// The autosave worker (session_autosaver.hpp): saves happen off the calling thread, in order, coalesced per
// file, numbered on from an opened session, and a failure names the path. The crash test: this executable
// re-runs itself as a child that labels candidates one after the other through the real Observation ->
// SessionController -> SessionAutosaver path, printing each label before making it; the parent kills it with
// SIGKILL mid-way (three times, at different moments) and the file must then load and hold every label but
// at most the last one printed.
#include <gtest/gtest.h>

#include <QProcess>
#include <QStandardPaths>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>

#include "session_autosaver.hpp"
#include "session_controller.hpp"
#include "st/common/error.hpp"
#include "test_support.hpp"
#include "ui_test_support.hpp"

using namespace st;
using namespace st::ui;

namespace {

constexpr int kChildCandidates = 600;

/// The label the child gives candidate i (cycles through every label and reason).
session::Label childLabel(int i) {
  return i % 3 == 0 ? session::Label::Real : i % 3 == 1 ? session::Label::Artifact : session::Label::Unsure;
}

/// The child: labels candidates 0, 1, 2, ... of a session at `path` until it is killed.
int runChild(const QString& path) {
  Observation obs;
  SessionController controller(&obs, {});
  controller.prepareNew({"/data/obs.fits"}, false, path);
  obs.setRaw(std::make_shared<const FrameCube>(test::movingDotCube(32, 32, 4, {}, 5, 5)), "crash test");
  auto result = std::make_shared<search::SearchResult>();
  for (int i = 0; i < kChildCandidates; ++i) {
    search::Candidate c;
    c.x = i % 32;
    c.y = i / 32 % 32;
    c.snr = 8.0 + 1e-3 * i;
    result->candidates.push_back(c);
  }
  obs.setResult(result);
  controller.autosaver()->flush();
  for (int i = 0; i < kChildCandidates; ++i) {
    std::printf("%d\n", i);  // announced before it is made: the parent knows every change that may exist
    std::fflush(stdout);
    obs.setCandidateLabel(i, childLabel(i), session::ArtifactReason::Ghost);
    // A person's pace: the next change comes after this one reached the disk (a save takes a few ms, a key
    // press hundreds). The GUI itself never waits; this loop stands in for the person.
    controller.autosaver()->flush();
    QCoreApplication::processEvents();
  }
  return 0;
}

session::Session minimalSession(const std::string& note) {
  session::Session s;
  s.inputs = {"a.fits"};
  s.notes = note;
  return s;
}

}  // namespace

TEST(SessionAutosaver, SavesInOrderCoalescesAndCountsOn) {
  test::TempDir dir;
  const QString path = QString::fromStdString((dir / "s.json").string());
  SessionAutosaver saver;
  std::vector<qint64> saved;
  // Context object on this thread: the signal comes from the worker and is queued here.
  QObject::connect(&saver, &SessionAutosaver::saved, &saver,
                   [&](const QString&, qint64 changes, double) { saved.push_back(changes); });
  saver.setChangeCount(path, 41);  // an opened session that had 41 saves
  for (int i = 0; i < 200; ++i)
    saver.request(path, minimalSession("state " + std::to_string(i)));
  ASSERT_TRUE(saver.flush());
  EXPECT_EQ(saver.pending(), 0);
  const session::Session s = session::SessionStore(path.toStdString()).load();
  EXPECT_EQ(s.notes, "state 199");  // the newest state won
  ASSERT_TRUE(test::waitFor([&] { return !saved.empty() && saved.back() == s.changes; }));
  EXPECT_GE(s.changes, 42);
  EXPECT_LE(s.changes, 41 + 200);
  EXPECT_LT(saved.size(), 200u) << "200 requests in a burst were not coalesced";
  for (std::size_t i = 1; i < saved.size(); ++i)
    EXPECT_EQ(saved[i], saved[i - 1] + 1);
  EXPECT_FALSE(std::filesystem::exists(session::SessionStore(path.toStdString()).tempPath()));
}

TEST(SessionAutosaver, RequestReturnsWithoutWaitingForTheDisk) {
  test::TempDir dir;
  SessionAutosaver saver;
  session::Session big = minimalSession("big");
  big.candidates.resize(20000);
  for (auto& c : big.candidates)
    c.note = std::string(200, 'n');  // ~4 MB of JSON to format and fsync
  const QString path = QString::fromStdString((dir / "big.json").string());
  session::Session copy = big;
  const auto start = std::chrono::steady_clock::now();
  saver.request(path, std::move(copy));
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  EXPECT_GT(saver.pending(), 0);  // still being written
  EXPECT_LT(ms, 50.0);            // a move into the queue, nothing else
  ASSERT_TRUE(saver.flush());
  EXPECT_EQ(session::SessionStore(path.toStdString()).load().candidates.size(), 20000u);
}

TEST(SessionAutosaver, FailureNamesThePath) {
  test::TempDir dir;
  SessionAutosaver saver;
  QString failedPath, message;
  QObject::connect(&saver, &SessionAutosaver::failed, &saver, [&](const QString& p, const QString& m) {
    failedPath = p;
    message = m;
  });
  const QString path = QString::fromStdString((dir / "no" / "such" / "dir" / "s.json").string());
  saver.request(path, minimalSession("x"));
  ASSERT_TRUE(saver.flush());
  ASSERT_TRUE(test::waitFor([&] { return !message.isEmpty(); }));
  EXPECT_EQ(failedPath, path);
  EXPECT_TRUE(message.contains(QString::fromStdString((dir / "no" / "such" / "dir").string())))
      << message.toStdString();
}

TEST(SessionAutosaver, KillDashNineWhileLabellingLosesAtMostTheLastChange) {
  test::TempDir dir;
  for (const int killAfter : {15, 60, 140}) {
    const QString path =
        QString::fromStdString((dir / ("crash" + std::to_string(killAfter) + ".json")).string());
    QProcess child;
    child.setProcessChannelMode(QProcess::ForwardedErrorChannel);
    child.start(QCoreApplication::applicationFilePath(), {"--autosave-child", path});
    ASSERT_TRUE(child.waitForStarted(5000));
    QByteArray out;
    while (out.count('\n') < killAfter && child.state() == QProcess::Running) {
      child.waitForReadyRead(2000);
      out += child.readAllStandardOutput();
    }
    // A moment inside the next save (0 to 2 ms after the label was announced), then SIGKILL.
    std::this_thread::sleep_for(std::chrono::microseconds(700 * (killAfter % 3)));
    ASSERT_EQ(::kill(static_cast<pid_t>(child.processId()), SIGKILL), 0);
    ASSERT_TRUE(child.waitForFinished(5000));
    EXPECT_EQ(child.exitStatus(), QProcess::CrashExit);
    out += child.readAllStandardOutput();
    const QList<QByteArray> lines = out.split('\n');
    int last = -1;  // the last change announced: the only one that may be missing
    for (const QByteArray& line : lines)
      if (!line.isEmpty()) last = line.toInt();
    ASSERT_GE(last, killAfter - 1);
    ASSERT_LT(last, kChildCandidates - 1) << "the child finished before it was killed";
    // The file is complete (never a torn write) and holds every label up to the last one announced.
    session::Session s;
    ASSERT_NO_THROW(s = session::SessionStore(path.toStdString()).load()) << path.toStdString();
    ASSERT_EQ(s.candidates.size(), static_cast<std::size_t>(kChildCandidates));
    for (int i = 0; i < last; ++i)
      ASSERT_EQ(s.candidates[i].label, childLabel(i)) << "change " << i << " of " << last << " was lost";
    EXPECT_TRUE(s.candidates[last].label == childLabel(last) ||
                s.candidates[last].label == session::Label::Unvetted);
    for (int i = last + 1; i < kChildCandidates; ++i)
      ASSERT_EQ(s.candidates[i].label, session::Label::Unvetted);
  }
}

int main(int argc, char** argv) {
  qputenv("QT_QPA_PLATFORM", "offscreen");
  QCoreApplication::setOrganizationName("synthtrack-tests");
  QStandardPaths::setTestModeEnabled(true);
  QApplication app(argc, argv);
  if (argc == 3 && std::string(argv[1]) == "--autosave-child")
    return runChild(QString::fromLocal8Bit(argv[2]));
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
