// Plate solving (issue 15 item 5) without astrometry.net: the xylist writer against CFITSIO's own reading
// of the table (1-based columns), the header hints, the index-file names, and plateSolve's paths through
// stand-in programs (shell scripts) for solve-field: not installed, no index files, unsuitable index files,
// a failure with its stderr, the time limit, a cancel, and a "solution" read back through st::Wcs. The real
// solve of a Lowell frame is test_plate_solve_real_slow.cpp.
#include <fitsio.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <thread>

#include "st/astro/plate_solve.hpp"
#include "st/common/error.hpp"
#include "st/io/wcs.hpp"
#include "st/io/xylist.hpp"
#include "st/pipeline/plate_solve_stage.hpp"
#include "test_support.hpp"

namespace st {
namespace {

using test::TempDir;

std::string readText(const std::filesystem::path& p) {
  std::ifstream in(p);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

/// An executable shell script at dir/name.
std::string script(const TempDir& dir, const std::string& name, const std::string& body) {
  const auto path = dir / name;
  std::ofstream(path) << "#!/bin/sh\n" << body;
  ::chmod(path.c_str(), 0755);
  return path.string();
}

/// A folder holding an (empty) file with an index file's name: only names are read before solve-field runs.
std::string indexDir(const TempDir& dir, const std::string& name) {
  const auto d = dir / ("idx-" + name);
  std::filesystem::create_directories(d);
  std::ofstream(d / name) << "";
  return d.string();
}

std::vector<io::XyStar> fourStars() {
  return {{10, 20, 5}, {100, 30, 50}, {40, 90, 7}, {70, 60, 1}};
}

TEST(Xylist, WritesOneBasedColumnsSortedByFluxThatCfitsioReads) {
  TempDir dir;
  const std::string path = (dir / "stars.xyls").string();
  io::writeXylist(path, {{0.0, 0.0, 1.0}, {10.25, 3.5, 9.0}, {std::nan(""), 1.0, 100.0}, {4.0, 7.0, 3.0}}, 64,
                  48);
  fitsfile* f = nullptr;
  int status = 0;
  ASSERT_EQ(fits_open_diskfile(&f, path.c_str(), READONLY, &status), 0);
  fits_movabs_hdu(f, 2, nullptr, &status);
  long rows = 0;
  fits_get_num_rows(f, &rows, &status);
  EXPECT_EQ(rows, 3);  // the NaN star is left out
  double x[3] = {}, y[3] = {}, flux[3] = {};
  int cx = 0, cy = 0, cf = 0;
  fits_get_colnum(f, CASEINSEN, const_cast<char*>("X"), &cx, &status);
  fits_get_colnum(f, CASEINSEN, const_cast<char*>("Y"), &cy, &status);
  fits_get_colnum(f, CASEINSEN, const_cast<char*>("FLUX"), &cf, &status);
  fits_read_col(f, TDOUBLE, cx, 1, 1, 3, nullptr, x, nullptr, &status);
  fits_read_col(f, TDOUBLE, cy, 1, 1, 3, nullptr, y, nullptr, &status);
  fits_read_col(f, TDOUBLE, cf, 1, 1, 3, nullptr, flux, nullptr, &status);
  int w = 0, h = 0;
  fits_read_key(f, TINT, "IMAGEW", &w, nullptr, &status);
  fits_read_key(f, TINT, "IMAGEH", &h, nullptr, &status);
  fits_close_file(f, &status);
  ASSERT_EQ(status, 0);
  // Brightest first; 0-based (10.25, 3.5) is FITS (11.25, 4.5): the first pixel's centre is (1, 1).
  EXPECT_DOUBLE_EQ(x[0], 11.25);
  EXPECT_DOUBLE_EQ(y[0], 4.5);
  EXPECT_DOUBLE_EQ(flux[0], 9.0);
  EXPECT_DOUBLE_EQ(x[1], 5.0);
  EXPECT_DOUBLE_EQ(x[2], 1.0);
  EXPECT_DOUBLE_EQ(y[2], 1.0);
  EXPECT_EQ(w, 64);
  EXPECT_EQ(h, 48);
  const auto back = io::readXylist(path);  // and our reader undoes the +1
  ASSERT_EQ(back.size(), 3u);
  EXPECT_DOUBLE_EQ(back[0].x, 10.25);
  EXPECT_DOUBLE_EQ(back[2].y, 0.0);
  EXPECT_THROW(io::writeXylist(path, fourStars(), 0, 10), InputError);
}

TEST(PlateSolveHints, ReadsScaleAndSexagesimalPointingFromAHeaderWithoutWcs) {
  FitsHeader h;  // the Lowell 42" frames' cards
  h.setString("RA", "08:18:29.9");
  h.setString("DEC", "+25:20:01");
  h.setNumber("PIXSCAL", 0.327);
  h.setString("CCDSUM", "3 3");
  astro::PlateSolveHints hints = astro::plateSolveHints(h);
  ASSERT_TRUE(hints.scaleArcsecPerPx && hints.raDeg && hints.decDeg);
  EXPECT_NEAR(*hints.scaleArcsecPerPx, 0.981, 1e-12);
  EXPECT_NEAR(*hints.raDeg, (8 + 18 / 60.0 + 29.9 / 3600.0) * 15.0, 1e-9);
  EXPECT_NEAR(*hints.decDeg, 25 + 20 / 60.0 + 1 / 3600.0, 1e-9);
  h.setString("SECPIXX", "1.1");  // a direct scale wins over PIXSCAL x binning; quoted numbers are read
  h.setString("DEC", "-05 30 00");
  hints = astro::plateSolveHints(h);
  EXPECT_NEAR(*hints.scaleArcsecPerPx, 1.1, 1e-12);
  EXPECT_NEAR(*hints.decDeg, -5.5, 1e-12);
  FitsHeader none;
  none.setString("RA", "not an angle");
  hints = astro::plateSolveHints(none);
  EXPECT_FALSE(hints.raDeg);
  EXPECT_FALSE(hints.scaleArcsecPerPx);
}

TEST(PlateSolveIndex, ScaleFromFileNamesAndPackagesForAFieldSize) {
  TempDir dir;
  for (const char* n : {"index-tycho2-07.littleendian.fits", "index-4208.fits", "index-5206-03.fits",
                        "notes.txt", "index-4119.fits"})
    std::ofstream(dir / n) << "";
  const auto found = astro::findIndexFiles({dir.path().string(), (dir / "missing").string()});
  ASSERT_EQ(found.size(), 4u);
  std::map<std::string, int> scale;
  for (const auto& i : found)
    scale[std::filesystem::path(i.path).filename().string()] = i.scale;
  EXPECT_EQ(scale["index-tycho2-07.littleendian.fits"], 7);
  EXPECT_EQ(scale["index-4208.fits"], 8);
  EXPECT_EQ(scale["index-5206-03.fits"], 6);
  EXPECT_EQ(scale["index-4119.fits"], 19);
  EXPECT_EQ(astro::quadSizeArcmin(7), std::make_pair(22.0, 30.0));
  // A 26.4' field (diagonal 37'): Tycho-2 07 (22'-30') and 08 (30'-44'); a 5' field: none of them.
  const auto pk = astro::indexPackagesFor(26.4);
  ASSERT_EQ(pk.size(), 2u);
  EXPECT_EQ(pk[0], "astrometry-data-tycho2-07-littleendian");
  EXPECT_EQ(pk[1], "astrometry-data-tycho2-08-littleendian");
  EXPECT_TRUE(astro::indexPackagesFor(5.0).empty());
  EXPECT_EQ(astro::indexPackagesFor(600.0).back(), "astrometry-data-tycho2-10-19-littleendian");
  std::ofstream(dir / "astrometry.cfg")
      << "# comment\nadd_path /a/b\nindex /c/d/index-4107.fits\nautoindex\n";
  EXPECT_EQ(astro::configIndexDirs((dir / "astrometry.cfg").string()),
            (std::vector<std::string>{"/a/b", "/c/d"}));
}

std::string messageOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no InputError)";
}

TEST(PlateSolve, MissingSolveFieldNamesThePackage) {
  NullProgress progress;
  CancelToken cancel;
  astro::PlateSolveParams p;
  p.solveField = "/nonexistent/solve-field";
  std::string m = messageOf([&] { (void)astro::plateSolve(fourStars(), 128, 128, p, progress, cancel); });
  EXPECT_NE(m.find("solve-field, which was not found"), std::string::npos) << m;
  EXPECT_NE(m.find("package astrometry.net"), std::string::npos) << m;
  p.solveField = "synthtrack-no-such-program-on-path";
  m = messageOf([&] { (void)astro::plateSolve(fourStars(), 128, 128, p, progress, cancel); });
  EXPECT_NE(m.find("not found"), std::string::npos) << m;
}

TEST(PlateSolve, NoIndexFilesOrNoneForTheFieldSizeNamesThePackage) {
  TempDir dir;
  NullProgress progress;
  CancelToken cancel;
  astro::PlateSolveParams p;
  p.solveField = script(dir, "solve-field", "exit 0\n");
  std::filesystem::create_directories(dir / "empty");
  p.indexDirs = {(dir / "empty").string()};
  std::string m = messageOf([&] { (void)astro::plateSolve(fourStars(), 128, 128, p, progress, cancel); });
  EXPECT_NE(m.find("no astrometry.net index files"), std::string::npos) << m;
  EXPECT_NE(m.find("astrometry-data-tycho2-07-littleendian"), std::string::npos) << m;
  // Only the widest Tycho-2 scale installed, a 26' field (1432 x 1370 px at 1.1 arcsec/px): 07 and 08 named.
  p.indexDirs = {indexDir(dir, "index-tycho2-19.littleendian.fits")};
  p.scaleArcsecPerPx = 1.1;
  p.fieldIndex = false;
  m = messageOf([&] { (void)astro::plateSolve(fourStars(), 1432, 1370, p, progress, cancel); });
  EXPECT_NE(m.find("no index file suits a field of 26."), std::string::npos) << m;
  EXPECT_NE(m.find("install astrometry-data-tycho2-07-littleendian astrometry-data-tycho2-08-littleendian"),
            std::string::npos)
      << m;
  p.scaleArcsecPerPx = 0.2;  // a 4.8' field: smaller than any Tycho-2 quad
  m = messageOf([&] { (void)astro::plateSolve(fourStars(), 1432, 1370, p, progress, cancel); });
  EXPECT_NE(m.find("deeper catalogue"), std::string::npos) << m;
  EXPECT_NE(messageOf([&] {
              (void)astro::plateSolve({{1, 1, 1}}, 128, 128, p, progress, cancel);
            }).find("at least 4"),
            std::string::npos);
}

TEST(PlateSolve, FailureKeepsStderrAndNoSolutionSaysWhatWasTried) {
  TempDir dir;
  NullProgress progress;
  CancelToken cancel;
  astro::PlateSolveParams p;
  p.indexDirs = {indexDir(dir, "index-tycho2-07.littleendian.fits")};
  p.solveField = script(dir, "solve-field", "echo 'index file is corrupt: boom' >&2\nexit 3\n");
  std::string m = messageOf([&] { (void)astro::plateSolve(fourStars(), 128, 128, p, progress, cancel); });
  EXPECT_NE(m.find("solve-field failed (exit 3): index file is corrupt: boom"), std::string::npos) << m;
  p.solveField = script(dir, "solve-field-quiet", "echo 'Did not solve'\nexit 0\n");
  p.raDeg = 124.6;
  p.decDeg = 25.3;
  p.fieldIndex = false;
  m = messageOf([&] { (void)astro::plateSolve(fourStars(), 128, 128, p, progress, cancel); });
  EXPECT_NE(m.find("found no solution (4 stars, scale 0.1-100 arcsec/px (no hint), within 2 deg of RA 124.6"),
            std::string::npos)
      << m;
}

TEST(PlateSolve, TimeLimitAndCancelStopTheProgramPromptly) {
  TempDir dir;
  NullProgress progress;
  astro::PlateSolveParams p;
  p.indexDirs = {indexDir(dir, "index-tycho2-07.littleendian.fits")};
  p.solveField = script(dir, "solve-field", "sleep 30\n");
  p.timeLimitS = 0.5;
  CancelToken cancel;
  auto t0 = std::chrono::steady_clock::now();
  const std::string m =
      messageOf([&] { (void)astro::plateSolve(fourStars(), 128, 128, p, progress, cancel); });
  EXPECT_NE(m.find("no solution within the time limit of 0.5 s"), std::string::npos) << m;
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 5.0);
  p.timeLimitS = 60.0;
  std::thread canceller([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    cancel.cancel();
  });
  t0 = std::chrono::steady_clock::now();
  EXPECT_THROW((void)astro::plateSolve(fourStars(), 128, 128, p, progress, cancel), Cancelled);
  canceller.join();
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 5.0);
}

TEST(PlateSolve, ReadsTheSolutionAndPassesTheStarListAndHintsAsArguments) {
  TempDir dir;
  // The "solution": a TAN WCS, RA 150 Dec 2 at 1-based pixel (64.5, 32.5), 1.5 arcsec/px.
  FitsHeader wcs;
  test::setTanWcs(wcs, 150.0, 2.0, 64.5, 32.5, 1.5);
  const std::string wcsFile = (dir / "truth.wcs").string();
  io::writeHeaderFile(wcsFile, wcs);
  // A stand-in for solve-field: records its arguments, copies the WCS to --dir/--out.wcs, says which index.
  const std::string args = (dir / "args.txt").string();
  const std::string body =
      "for a in \"$@\"; do echo \"$a\" >> '" + args +
      "'; done\n"
      "while [ $# -gt 0 ]; do case \"$1\" in --dir) d=\"$2\"; shift;; --out) o=\"$2\"; shift;; "
      "esac; shift; done\n"
      "cp '" +
      wcsFile +
      "' \"$d/$o.wcs\" && touch \"$d/$o.solved\"\n"
      "echo 'Field 1: solved with index index-tycho2-07.littleendian.fits.'\n";
  astro::PlateSolveParams p;
  p.solveField = script(dir, "solve-field", body);
  p.indexDirs = {indexDir(dir, "index-4200.fits")};  // quads of 2'-2.8' for this 3.2' field
  p.scaleArcsecPerPx = 1.5;
  p.raDeg = 150.01;
  p.decDeg = 2.0;
  p.fieldIndex = false;
  NullProgress progress;
  CancelToken cancel;
  const astro::PlateSolution s = astro::plateSolve(fourStars(), 128, 64, p, progress, cancel);
  ASSERT_TRUE(s.wcs);
  EXPECT_NEAR(s.scaleArcsecPerPx, 1.5, 1e-9);
  // 0-based (63.5, 31.5) is the 1-based reference pixel.
  EXPECT_NEAR(s.centreRaDeg, 150.0, 1e-9);
  EXPECT_NEAR(s.centreDecDeg, 2.0, 1e-9);
  EXPECT_EQ(s.index, "index-tycho2-07.littleendian.fits");
  EXPECT_EQ(s.starsGiven, 4u);
  const std::string a = readText(args);
  for (const char* expected :
       {"--x-column\nX\n", "--y-column\nY\n", "--sort-column\nFLUX\n", "--width\n128\n", "--height\n64\n",
        "--scale-units\narcsecperpix\n", "--scale-low\n1.153846", "--scale-high\n1.95\n", "--ra\n150.01\n",
        "--dec\n2\n", "--radius\n2\n", "--config\n"})
    EXPECT_NE(a.find(expected), std::string::npos) << expected << " not in\n" << a;
}

TEST(PlateSolveStage, CatalogueStarsMoveToTheFirstFrame) {
  FrameCube cube(100, 80, 3);
  for (std::size_t n = 0; n < 3; ++n)
    cube.info()[n].mjdMid = 60000.0 + static_cast<double>(n) * 10.0 / 86400.0;  // t - t_ref = -10, 0, 10 s
  cube.info()[0].offsetXPx = 1.5;
  cube.info()[0].offsetYPx = -2.0;
  detect::Star a, b;
  a.x = 50.0, a.y = 40.0, a.flux = 10.0;
  b.x = 99.0, b.y = 40.0, b.flux = 5.0;
  const auto stars = pipeline::firstFrameStars({a, b}, cube, Velocity{-0.5, 0.25});
  // x + v (t_0 - t_ref) + o_0 = 50 + 5 + 1.5, 40 - 2.5 - 2
  ASSERT_EQ(stars.size(), 1u);          // b: 99 + 5 + 1.5 = 105.5 is outside 100 columns
  EXPECT_NEAR(stars[0].x, 56.5, 1e-6);  // MJD times: ~1e-6 s resolution
  EXPECT_NEAR(stars[0].y, 35.5, 1e-6);
  EXPECT_DOUBLE_EQ(stars[0].flux, 10.0);
}

}  // namespace
}  // namespace st
