#pragma once
// Running the built GUI (synthtrack) in its script mode from the ui tests, offscreen, with its settings,
// caches and autosaved sessions in a temporary folder; the tests skip when it was not built.
#include <QCoreApplication>
#include <QDir>
#include <QElapsedTimer>
#include <QFile>
#include <QFileInfo>
#include <QProcess>
#include <QProcessEnvironment>
#include <QString>
#include <QStringList>

namespace st::test {

/// build/app/synthtrack beside build/tests (where the test executables are), or "" when not built.
inline QString guiPath() {
  const QString dir = QCoreApplication::applicationDirPath();
  for (const QString& rel : {QString("/../app/synthtrack"), QString("/app/synthtrack")}) {
    const QFileInfo f(dir + rel);
    if (f.isExecutable()) return f.absoluteFilePath();
  }
  return {};
}

struct GuiRun {
  int exitCode = -1;
  bool finished = false;
  QString out;  ///< stdout
  QString err;  ///< stderr
  double seconds = 0.0;
};

/// Runs `gui` with `args` offscreen (QT_QPA_PLATFORM=offscreen), HOME and XDG folders under `home`.
inline GuiRun runGui(const QString& gui, const QStringList& args, const QString& home, int timeoutS) {
  QProcess p;
  QProcessEnvironment env = QProcessEnvironment::systemEnvironment();
  env.insert("QT_QPA_PLATFORM", "offscreen");
  env.insert("HOME", home);
  env.insert("XDG_CONFIG_HOME", home + "/config");
  env.insert("XDG_CACHE_HOME", home + "/cache");
  env.insert("XDG_DATA_HOME", home + "/data");
  env.insert("XDG_RUNTIME_DIR", home + "/run");
  QDir().mkpath(home + "/run");
  QFile::setPermissions(home + "/run", QFileDevice::ReadOwner | QFileDevice::WriteOwner | QFileDevice::ExeOwner);
  p.setProcessEnvironment(env);
  GuiRun r;
  QElapsedTimer clock;
  clock.start();
  p.start(gui, args);
  r.finished = p.waitForStarted(30000) && p.waitForFinished(timeoutS * 1000);
  if (!r.finished) p.kill(), p.waitForFinished(5000);
  r.seconds = clock.elapsed() / 1000.0;
  r.exitCode = p.exitCode();
  r.out = QString::fromLocal8Bit(p.readAllStandardOutput());
  r.err = QString::fromLocal8Bit(p.readAllStandardError());
  return r;
}

}  // namespace st::test
