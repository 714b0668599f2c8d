// Figure export: PNG pixel size and DPI, SVG that parses and carries the scale-bar text, PDF, the compass
// from a known WCS, the paper's sky/object preset on a moving dot, and the Export figure dialog driven on the
// main window (worker thread, errors naming the path).
#include <gtest/gtest.h>

#include <QCheckBox>
#include <QDir>
#include <QFile>
#include <QImage>
#include <QPainter>
#include <QSvgRenderer>
#include <QXmlStreamReader>
#include <cmath>
#include <qcustomplot.h>

#include "figure_dialog.hpp"
#include "figure_export.hpp"
#include "figure_preset.hpp"
#include "figure_render.hpp"
#include "job_runner.hpp"
#include "main_window.hpp"
#include "script_runner.hpp"
#include "search_panel.hpp"
#include "test_support.hpp"
#include "ui_test_support.hpp"

using namespace st;
using namespace st::ui;

namespace {

constexpr double kRa0 = 150.0, kDec0 = 30.0, kScale = 1.0;  // deg, deg, arcsec/px

// North up, east left (RA grows to -x), 1"/px, rotated by `rotDeg` (sky from pixels).
SkyOfPixel linearSky(double rotDeg = 0.0) {
  return [rotDeg](double x, double y) -> std::optional<std::pair<double, double>> {
    const double r = rotDeg * M_PI / 180.0;
    const double u = std::cos(r) * x - std::sin(r) * y, v = std::sin(r) * x + std::cos(r) * y;
    const double dec = kDec0 + v * kScale / 3600.0;
    return std::pair{kRa0 - u * kScale / 3600.0 / std::cos(kDec0 * M_PI / 180.0), dec};
  };
}

QString qpath(const test::TempDir& dir, const std::string& name) {
  return QString::fromStdString((dir / name).string());
}

ImageFigure gradientFigure() {
  auto img = std::make_shared<Image>(100, 80);
  for (int y = 0; y < img->height; ++y)
    for (int x = 0; x < img->width; ++x)
      img->at(x, y) = static_cast<float>(x + y);
  ImagePanel p;
  p.image = img;
  p.lo = 0;
  p.hi = 178;
  p.title = "gradient";
  p.units = "ADU";
  p.plateScaleArcsecPerPx = kScale;  // 100 px -> a quarter is 25": the bar is 20"
  p.compass = compassAt(linearSky(), 50, 40);
  ImageFigure fig;
  fig.title = "test figure";
  fig.panels.push_back(p);
  return fig;
}

void exportGradient(const QString& path, FigureFormat format, double dpi) {
  const ImageFigure fig = gradientFigure();
  exportFigure(path, format, {4.0, 3.0, dpi},
               [&](QCPPainter& p, const QSizeF& s) { paintImageFigure(p, s, fig); });
}

}  // namespace

TEST(FigureExport, PngAtTwoDpisHasTheExpectedPixelSizeAndResolution) {
  test::TempDir dir;
  for (double dpi : {100.0, 250.0}) {
    const QString path = qpath(dir, "fig_" + std::to_string(int(dpi)) + ".png");
    exportGradient(path, FigureFormat::Png, dpi);
    const QImage img(path);
    ASSERT_FALSE(img.isNull()) << path.toStdString();
    EXPECT_EQ(img.width(), std::lround(4.0 * dpi));
    EXPECT_EQ(img.height(), std::lround(3.0 * dpi));
    EXPECT_NEAR(img.dotsPerMeterX() * 0.0254, dpi, 0.05);
    // Something was drawn: a good part of the page is not white (the image and colour bar).
    int ink = 0;
    for (int y = 0; y < img.height(); y += 4)
      for (int x = 0; x < img.width(); x += 4)
        ink += img.pixel(x, y) != qRgb(255, 255, 255);
    EXPECT_GT(ink, img.width() * img.height() / 16 / 5);
  }
}

TEST(FigureExport, SvgParsesAndContainsTheScaleBarAndCompassText) {
  test::TempDir dir;
  const QString path = qpath(dir, "fig.svg");
  exportGradient(path, FigureFormat::Svg, 300);
  QSvgRenderer renderer(path);
  EXPECT_TRUE(renderer.isValid());
  QFile file(path);
  ASSERT_TRUE(file.open(QIODevice::ReadOnly));
  QXmlStreamReader xml(&file);
  QStringList texts;
  while (!xml.atEnd())
    if (xml.readNext() == QXmlStreamReader::Characters) texts << xml.text().toString().trimmed();
  EXPECT_FALSE(xml.hasError()) << xml.errorString().toStdString();
  EXPECT_TRUE(texts.contains("20\"")) << texts.join(" | ").toStdString();
  EXPECT_TRUE(texts.contains("N"));
  EXPECT_TRUE(texts.contains("E"));
  EXPECT_TRUE(texts.contains("ADU"));
}

TEST(FigureExport, PdfStartsWithThePdfMagic) {
  test::TempDir dir;
  const QString path = qpath(dir, "fig.pdf");
  exportGradient(path, FigureFormat::Pdf, 300);
  QFile file(path);
  ASSERT_TRUE(file.open(QIODevice::ReadOnly));
  EXPECT_EQ(file.read(5), QByteArray("%PDF-"));
  EXPECT_GT(file.size(), 1000);
}

TEST(FigureExport, ErrorsNameThePath) {
  const QString path = "/nonexistent-folder-st/fig.png";
  try {
    exportGradient(path, FigureFormat::Png, 100);
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(path.toStdString()), std::string::npos) << e.what();
  }
  EXPECT_THROW((void)figureFormatForPath("fig.bmp"), InputError);
  EXPECT_EQ(figureFormatForPath("a/B.SVG"), FigureFormat::Svg);
}

TEST(FigureExport, PaletteReductionKeepsFewColoursAndBoundsTheError) {
  QImage three(40, 30, QImage::Format_RGB32);
  three.fill(qRgb(200, 10, 10));
  for (int x = 0; x < 40; ++x) {
    three.setPixel(x, 5, qRgb(0, 0, 0));
    three.setPixel(x, 20, qRgb(255, 255, 255));
  }
  const QImage p3 = reduceToPalette(three, 256);
  EXPECT_EQ(p3.format(), QImage::Format_Indexed8);
  EXPECT_EQ(p3.colorCount(), 3);
  for (int y : {0, 5, 20})
    EXPECT_EQ(p3.pixel(7, y), three.pixel(7, y));
  // A 256-level gray ramp: 6 bits per channel make 64 bins of 4 levels, each drawn as their mean (error <=
  // 2).
  QImage ramp(256, 8, QImage::Format_RGB32);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 256; ++x)
      ramp.setPixel(x, y, qRgb(x, x, x));
  const QImage p64 = reduceToPalette(ramp, 256);
  EXPECT_EQ(p64.colorCount(), 64);
  int worst = 0;
  for (int x = 0; x < 256; ++x)
    worst = std::max(worst, std::abs(qGray(p64.pixel(x, 3)) - x));
  EXPECT_LE(worst, 2);
}

TEST(FigureRender, ScaleBarLengthsAndTicksAreRound) {
  EXPECT_DOUBLE_EQ(scaleBarArcsec(1.0, 100), 20.0);    // quarter: 25"
  EXPECT_DOUBLE_EQ(scaleBarArcsec(0.5, 1000), 120.0);  // quarter: 125"
  EXPECT_DOUBLE_EQ(scaleBarArcsec(2.0, 8000), 3600.0);
  EXPECT_EQ(scaleBarText(120.0), "2'");
  EXPECT_EQ(scaleBarText(0.5), "0.5\"");
  EXPECT_EQ(niceTicks(-0.5, 99.5, 5), (std::vector<double>{0, 20, 40, 60, 80}));
  EXPECT_EQ(niceTicks(0.0, 1.0, 5), (std::vector<double>{0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0}));
}

TEST(FigureRender, CompassFollowsTheWcs) {
  const auto c = compassAt(linearSky(), 10, 10);
  ASSERT_TRUE(c);
  EXPECT_NEAR(c->north.x(), 0.0, 1e-6);
  EXPECT_NEAR(c->north.y(), 1.0, 1e-6);
  EXPECT_NEAR(c->east.x(), -1.0, 1e-6);
  EXPECT_NEAR(c->east.y(), 0.0, 1e-6);
  // Rotated 30 degrees: v = sin(r) x + cos(r) y grows to the north, so north = (sin r, cos r).
  const auto r = compassAt(linearSky(30.0), 10, 10);
  ASSERT_TRUE(r);
  EXPECT_NEAR(r->north.x(), 0.5, 1e-5);
  EXPECT_NEAR(r->north.y(), std::sqrt(3.0) / 2, 1e-5);
  EXPECT_NEAR(r->east.x(), -std::sqrt(3.0) / 2, 1e-5);
  EXPECT_NEAR(r->east.y(), 0.5, 1e-5);
  EXPECT_FALSE(compassAt({}, 0, 0));
  EXPECT_FALSE(compassAt([](double, double) { return std::optional<std::pair<double, double>>{}; }, 0, 0));
}

TEST(FigurePreset, ObjectTrackedStampIsSharpAndSkyTrackedStreaks) {
  constexpr Velocity v{8.0, -4.0};
  search::FilteredCube cube;
  cube.frames = test::movingDotCube(96, 96, 40, v, 40, 50);
  cube.psfFwhmPx = 2.0;
  search::Candidate c;
  c.x = 40;
  c.y = 50;
  c.v = v;
  c.snr = 12.0;
  SkyAndObjectOptions o;
  o.halfSizePx = 20;
  const ImageFigure fig = skyAndObjectFigure(cube, c, {0.0, 0.0}, o);
  ASSERT_EQ(fig.panels.size(), 2u);
  const Image& obj = *fig.panels[0].image;
  const Image& sky = *fig.panels[1].image;
  ASSERT_EQ(obj.width, 41);
  // Tracking the object: all 40 frames of the dot land on the candidate's pixel (the stamp's centre).
  EXPECT_FLOAT_EQ(obj.at(20, 20), 40.0f);
  EXPECT_FLOAT_EQ(*std::max_element(obj.pixels.begin(), obj.pixels.end()), 40.0f);
  // Tracking the stars: the dot moves 8.9 px/s x 3.9 s = 35 px, about one frame per pixel of the streak.
  EXPECT_LE(*std::max_element(sky.pixels.begin(), sky.pixels.end()), 2.0f);
  EXPECT_EQ(fig.panels[0].lo, fig.panels[1].lo);
  EXPECT_EQ(fig.panels[0].hi, fig.panels[1].hi);
  // The left arrow points down at the object; the right one runs along the streak ((v) dt, dt = +-1.95 s).
  ASSERT_EQ(fig.panels[0].arrows.size(), 1u);
  EXPECT_DOUBLE_EQ(fig.panels[0].arrows[0].to.x(), 20.0);
  EXPECT_GT(fig.panels[0].arrows[0].from.y(), fig.panels[0].arrows[0].to.y());
  const FigureArrow& m = fig.panels[1].arrows.at(0);
  EXPECT_NEAR(m.to.x() - m.from.x(), 8.0 * 3.9, 1e-4);
  EXPECT_NEAR(m.to.y() - m.from.y(), -4.0 * 3.9, 1e-4);
  c.x = 200;
  EXPECT_THROW((void)skyAndObjectFigure(cube, c, {}, o), InputError);
}

TEST(FigureDialog, ExportsTheCentralViewPlotAndPresetFromTheWindow) {
  MainWindow w(test::fakeServices(test::movingDotCube(96, 96, 40, {8.0, -4.0}, 40, 50)));
  w.resize(1400, 900);
  w.show();
  w.openDemo();
  ASSERT_TRUE(test::waitFor([&] { return w.observation()->prepared() && !w.jobs()->busy(); }));
  w.searchPanel()->setGridPxS({6.0, -3.0}, 3.0, 0.5);
  w.runSearch();
  ASSERT_TRUE(test::waitFor([&] { return w.observation()->result() && !w.jobs()->busy(); }));
  w.selectCandidate(0);
  ASSERT_TRUE(test::waitFor([&] { return w.lastStackLatencyMs() > 0; }));

  FigureDialog* d = w.figureDialog();
  d->refreshSources();
  const QStringList names = d->sourceNames();
  ASSERT_GE(names.size(), 3);
  // The fake observation has no WCS: the dialog says a compass cannot be drawn (issue 18 §6).
  QCheckBox* compass = nullptr;
  for (auto* box : d->findChildren<QCheckBox*>())
    if (box->text().startsWith("N/E compass")) compass = box;
  ASSERT_TRUE(compass && compass->text().startsWith("N/E compass"));
  EXPECT_FALSE(compass->isEnabled());
  EXPECT_TRUE(compass->text().contains("no WCS")) << compass->text().toStdString();
  EXPECT_TRUE(compass->toolTip().contains("no compass")) << compass->toolTip().toStdString();
  EXPECT_EQ(names.front(), "Central view");
  EXPECT_TRUE(names.filter("Velocity space: plot").size() >= 1) << names.join(", ").toStdString();
  test::TempDir dir;
  auto run = [&](int source, const QString& name, FigureSize size) {
    d->setSource(source);
    d->setFigureSize(size);
    bool done = false, ok = false;
    QString message;
    auto c =
        QObject::connect(d, &FigureDialog::exportFinished, [&](const QString&, bool good, const QString& m) {
          done = true;
          ok = good;
          message = m;
        });
    const QString path = qpath(dir, name.toStdString());
    d->exportTo(path);
    EXPECT_TRUE(test::waitFor([&] { return done; })) << name.toStdString();
    QObject::disconnect(c);
    EXPECT_TRUE(ok) << message.toStdString();
    return path;
  };
  EXPECT_EQ(QImage(run(0, "central.png", {5.0, 4.0, 120})).size(), QSize(600, 480));
  const int plot = static_cast<int>(names.indexOf(names.filter("Velocity space: plot").front()));
  EXPECT_TRUE(QSvgRenderer(run(plot, "vmap.svg", {5.0, 4.0, 300})).isValid());
  const QImage vmap(run(plot, "vmap.png", {5.0, 4.0, 100}));
  EXPECT_EQ(vmap.size(), QSize(500, 400));
  const QImage preset(run(d->presetIndex(), "preset.png", {7.0, 0.0, 100}));
  EXPECT_EQ(preset.width(), 700);
  EXPECT_GT(preset.height(), 200);  // height from the two square panels: ~330 pt
  // Kept for a look, as test_main_window keeps its screenshots.
  QDir().mkpath("ui_screens");
  preset.save("ui_screens/figure_preset.png");
  QImage(qpath(dir, "central.png")).save("ui_screens/figure_central.png");
  vmap.save("ui_screens/figure_vmap.png");

  // A folder that does not exist: the message names the path.
  d->setSource(0);
  bool failed = false;
  QString message;
  QObject::connect(d, &FigureDialog::exportFinished, [&](const QString&, bool ok, const QString& m) {
    failed = !ok;
    message = m;
  });
  d->exportTo("/nonexistent-st-folder/x.pdf");
  ASSERT_TRUE(test::waitFor([&] { return failed; }));
  EXPECT_TRUE(message.contains("/nonexistent-st-folder/x.pdf")) << message.toStdString();
}

TEST(FigureDialog, ScriptOptionsExportTheFigureAndReports) {
  MainWindow w(test::fakeServices(test::movingDotCube(96, 96, 40, {8.0, -4.0}, 40, 50)));
  w.resize(1200, 800);
  w.show();
  test::TempDir dir;
  ScriptOptions script;
  script.demo = true;
  script.exportFigure = qpath(dir, "script.svg");
  script.exportReports = qpath(dir, "reports");
  script.dialog = "reports";
  bool finished = false, good = false;
  ScriptRunner runner(&w);
  QObject::connect(&runner, &ScriptRunner::finished, [&](bool ok) {
    finished = true;
    good = ok;
  });
  runner.run(script);
  ASSERT_TRUE(test::waitFor([&] { return finished; }, 30000));
  EXPECT_TRUE(good);
  EXPECT_TRUE(QSvgRenderer(script.exportFigure).isValid());  // no candidate selected: the central view
  // No search ran: the reports hold no candidates, but are written.
  EXPECT_TRUE(QFile::exists(qpath(dir, "reports/synthtrack_candidates.json")));
  EXPECT_TRUE(QFile::exists(qpath(dir, "reports/synthtrack.reg")));
}

ST_UI_TEST_MAIN()
