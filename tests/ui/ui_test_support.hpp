#pragma once
// Small fakes for the GUI tests: a synthetic cube with one moving dot, and a brute-force IPSA backend
// (sum of integer-shifted frames, out-of-frame samples skipped) that polls the CancelToken. They exercise
// the GUI's threading and wiring, not the science (the core's own tests check that).
#include <gtest/gtest.h>

#include <QApplication>
#include <QDir>
#include <QFile>
#include <QSettings>
#include <QEventLoop>
#include <QMessageBox>
#include <QPointer>
#include <QStandardPaths>
#include <QTimer>
#include <chrono>
#include <cmath>
#include <functional>
#include <thread>

#include "core_services.hpp"
#include "st/common/error.hpp"

namespace st::test {

/// A cube of `frames` frames w x h, 0.1 s apart, noise-free background 0 with a dot of amplitude 1 moving
/// at `v` px/s through (x0, y0) at t_ref.
inline FrameCube movingDotCube(int w, int h, std::size_t frames, Velocity v, int x0, int y0) {
  FrameCube cube(w, h, frames);
  for (std::size_t n = 0; n < frames; ++n)
    cube.info()[n].mjdMid = 60000.0 + n * 0.1 / 86400.0;
  const auto dt = cube.timeOffsetsS();
  for (std::size_t n = 0; n < frames; ++n) {
    const int x = x0 + static_cast<int>(std::lround(v.vx * dt[n]));
    const int y = y0 + static_cast<int>(std::lround(v.vy * dt[n]));
    if (x >= 0 && y >= 0 && x < w && y < h) cube.frame(n)[static_cast<std::size_t>(y) * w + x] = 1.0f;
  }
  return cube;
}

class FakeBackend : public search::SearchBackend {
 public:
  /// `slowdownMs`: extra sleep per velocity (in 1 ms slices, polling cancel) to make searches long.
  explicit FakeBackend(int slowdownMs = 0) : m_slowdownMs(slowdownMs) {}
  std::string name() const override { return "fake cpu"; }

  Image stackAt(const search::FilteredCube& cube, Velocity v, search::StackMode) override {
    const FrameCube& f = cube.frames;
    Image out(f.width(), f.height(), 0.0f);
    const auto dt = f.timeOffsetsS();
    for (std::size_t n = 0; n < f.frameCount(); ++n) {
      const int sx = static_cast<int>(std::lround(v.vx * dt[n]));
      const int sy = static_cast<int>(std::lround(v.vy * dt[n]));
      for (int y = 0; y < f.height(); ++y) {
        const int yy = y + sy;
        if (yy < 0 || yy >= f.height()) continue;
        for (int x = 0; x < f.width(); ++x) {
          const int xx = x + sx;
          if (xx >= 0 && xx < f.width())
            out.at(x, y) += f.frame(n)[static_cast<std::size_t>(yy) * f.width() + xx];
        }
      }
    }
    return out;
  }

  search::SearchResult search(const search::FilteredCube& cube, const search::VelocityGrid& grid,
                              const search::SearchParams& params, ProgressSink& progress,
                              CancelToken& cancel) override {
    search::SearchResult r;
    r.grid = grid;
    r.map.nvx = grid.nvx;
    r.map.nvy = grid.nvy;
    r.snrThreshold = params.snrThreshold;
    r.backend = name();
    const double noise = cube.sigmaF > 0 ? cube.sigmaF : 1.0;
    const auto nf = static_cast<double>(cube.frames.frameCount());
    for (int iy = 0; iy < grid.nvy; ++iy)
      for (int ix = 0; ix < grid.nvx; ++ix) {
        cancel.throwIfCancelled();
        for (int s = 0; s < m_slowdownMs; ++s) {
          std::this_thread::sleep_for(std::chrono::milliseconds(1));
          cancel.throwIfCancelled();
        }
        const Image st = stackAt(cube, grid.at(ix, iy), search::StackMode::Ipsa);
        std::size_t best = 0;
        for (std::size_t k = 1; k < st.size(); ++k)
          if (st.pixels[k] > st.pixels[best]) best = k;
        const double snr = st.pixels[best] / (noise * std::sqrt(nf));
        r.map.maxSnr.push_back(static_cast<float>(snr));
        r.map.argX.push_back(static_cast<int>(best % st.width));
        r.map.argY.push_back(static_cast<int>(best / st.width));
        if (snr >= params.snrThreshold) {
          search::Candidate c;
          c.x = r.map.argX.back();
          c.y = r.map.argY.back();
          c.v = grid.at(ix, iy);
          c.ivx = ix;
          c.ivy = iy;
          c.snr = snr;
          c.nIn = static_cast<int>(nf);
          c.fap = 1e-9;
          r.candidates.push_back(c);
        }
        progress.report(static_cast<double>(iy * grid.nvx + ix + 1) / grid.count(), "velocity search");
      }
    std::sort(r.candidates.begin(), r.candidates.end(), [](auto& a, auto& b) { return a.snr > b.snr; });
    return r;
  }

 private:
  int m_slowdownMs;
};

/// Services around a synthetic cube: "demo" is the moving dot, pre-processing passes the frames through
/// (sigmaF given), the backend is FakeBackend.
inline ui::CoreServices fakeServices(FrameCube cube, int slowdownMs = 0, double sigmaF = 0.05) {
  ui::CoreServices s;
  auto shared = std::make_shared<const FrameCube>(std::move(cube));
  s.simulateDemo = [shared](ProgressSink& p, CancelToken&) {
    p.report(1.0, "simulating");
    return *shared;
  };
  s.preprocessStages = {ui::StageSpec{
      "Matched filter", true, false, {ui::StageParam{"fwhm", "FWHM", "px", 2.5, 0.5, 20, 2, ""}}}};
  s.preprocess = [sigmaF](std::shared_ptr<const FrameCube> raw, const std::vector<ui::StageSpec>&,
                          ProgressSink&, CancelToken&) {
    ui::PreparedView v;
    auto f = std::make_shared<search::FilteredCube>();
    f->frames = *raw;
    f->sigmaF = sigmaF;
    f->psfFwhmPx = 2.5;
    v.filtered = f;
    v.layers.emplace_back("background", Image(raw->width(), raw->height(), 0.0f));
    v.summary = "fake";
    return v;
  };
  s.makeBackend = [slowdownMs](ui::BackendKind, std::string& message) {
    message = "fake cpu";
    return std::make_unique<FakeBackend>(slowdownMs);
  };
  return s;
}

/// Spins the event loop until `done()` or the timeout; returns done().
inline bool waitFor(const std::function<bool()>& done, int timeoutMs = 20000) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeoutMs);
  while (!done() && std::chrono::steady_clock::now() < end) {
    QApplication::processEvents(QEventLoop::AllEvents, 10);
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return done();
}

/// Seconds a modal dialog may stay open before runUiTests' watchdog fails the test and closes it.
inline int modalWatchdogSeconds = 30;

/// Runs the tests in an offscreen QApplication (tests never need a display). The application's name has the
/// process id appended, so that each test process has its own sessions folder and settings file (removed at
/// the end): ctest runs each test in its own process, two at a time, and processes of one test binary raced
/// over one folder (two demo starts on one fresh session name: CI's VettingWalkthrough failure of
/// 2026-12-02) and one settings file (two plate-solve tests, 2026-11-27). `isolated`: QStandardPaths' test
/// mode as well (AppDataLocation and settings under ~/.qttest, never the user's).
inline int runUiTests(int argc, char** argv, bool isolated) {
  qputenv("QT_QPA_PLATFORM", "offscreen");
  QCoreApplication::setOrganizationName("synthtrack-tests");
  if (isolated) QStandardPaths::setTestModeEnabled(true);
  QApplication app(argc, argv);
  QCoreApplication::setApplicationName(QCoreApplication::applicationName() + "-" +
                                       QString::number(QCoreApplication::applicationPid()));
  ::testing::InitGoogleTest(&argc, argv);
  // A modal dialog no test answers (an error box where none was expected) would block its test until
  // ctest's timeout, saying nothing (PlateSolveGui hung 900 s in a run of 2026-12-02): one left open for
  // modalWatchdogSeconds fails the test with its text and is closed.
  QTimer watchdog;
  QPointer<QWidget> lastModal;
  int seen = 0;
  QObject::connect(&watchdog, &QTimer::timeout, [&] {
    QWidget* modal = QApplication::activeModalWidget();
    seen = modal && modal == lastModal ? seen + 1 : 0;
    lastModal = modal;
    if (seen < modalWatchdogSeconds) return;
    const auto* box = qobject_cast<QMessageBox*>(modal);
    ADD_FAILURE() << "a modal dialog was left open for " << seen << " s: \""
                  << modal->windowTitle().toStdString() << "\" "
                  << (box ? box->text().toStdString() : std::string());
    seen = 0;
    if (auto* dialog = qobject_cast<QDialog*>(modal))
      dialog->reject();
    else
      modal->close();
  });
  watchdog.start(1000);
  const int rc = RUN_ALL_TESTS();
  QDir(QStandardPaths::writableLocation(QStandardPaths::AppDataLocation)).removeRecursively();
  QFile::remove(QSettings().fileName());
  return rc;
}

}  // namespace st::test

#define ST_UI_TEST_MAIN()                               \
  int main(int argc, char** argv) {                     \
    return ::st::test::runUiTests(argc, argv, false); \
  }

/// ST_UI_TEST_MAIN with QStandardPaths' test mode: AppDataLocation and settings under ~/.qttest, so tests
/// that save sessions or settings never touch the user's.
#define ST_UI_TEST_MAIN_ISOLATED()                     \
  int main(int argc, char** argv) {                    \
    return ::st::test::runUiTests(argc, argv, true); \
  }
