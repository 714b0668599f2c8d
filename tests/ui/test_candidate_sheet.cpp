// A sheet of several candidates as a figure source (issue 18 item 6): the user selects rows of the
// candidates table with Ctrl+click (or filters the table by label) and exports one figure, a grid of one
// panel per candidate (the IPSA stamp at its velocity in SNR units, with number, SNR, label and the rate
// relative to the sky), as PNG, SVG or PDF through the Export figure dialog. The stamps' numbers are core's
// (st::candidate::candidateSheetStamps) and agree with the candidate inspector's.
#include <gtest/gtest.h>

#include <QComboBox>
#include <QDir>
#include <QDockWidget>
#include <QFile>
#include <QImage>
#include <QSvgRenderer>
#include <QTableView>
#include <QTest>

#include "candidate_sheet.hpp"
#include "candidate_table.hpp"
#include "figure_dialog.hpp"
#include "job_runner.hpp"
#include "main_window.hpp"
#include "search_panel.hpp"
#include "st/candidate/candidate_sheet.hpp"
#include "st/candidate/inspection.hpp"
#include "test_support.hpp"
#include "ui_test_support.hpp"

using namespace st;
using namespace st::ui;

namespace {

QString qpath(const test::TempDir& dir, const std::string& name) {
  return QString::fromStdString((dir / name).string());
}

// Exports the dialog's source `index` to `path` and waits; returns the message, or empty when it worked.
QString exportAndWait(FigureDialog* d, int index, const QString& path, const FigureSize& size) {
  d->setSource(index);
  d->setFigureSize(size);
  bool done = false, ok = false;
  QString message;
  auto c = QObject::connect(d, &FigureDialog::exportFinished, [&](const QString&, bool good, const QString& m) {
    done = true;
    ok = good;
    message = m;
  });
  d->exportTo(path);
  EXPECT_TRUE(test::waitFor([&] { return done; }, 30000));
  QObject::disconnect(c);
  return ok ? QString() : message;
}

QString readAll(const QString& path) {
  QFile f(path);
  EXPECT_TRUE(f.open(QIODevice::ReadOnly)) << path.toStdString();
  return QString::fromUtf8(f.readAll());
}

void ctrlClickRow(QTableView* table, int row) {
  const QRect r = table->visualRect(table->model()->index(row, 0));
  QTest::mouseClick(table->viewport(), Qt::LeftButton, Qt::ControlModifier, r.center());
}

}  // namespace

TEST(CandidateSheet, CoreStampsAgreeWithTheInspector) {
  auto cube = std::make_shared<search::FilteredCube>();
  cube->frames = test::movingDotCube(64, 64, 30, {5.0, -2.0}, 30, 32);
  cube->sigmaF = 0.05;
  std::vector<search::Candidate> cs(2);
  cs[0].x = 30, cs[0].y = 32, cs[0].v = {5.0, -2.0};
  cs[1].x = 30, cs[1].y = 32, cs[1].v = {0.0, 0.0};  // the sky rate: the dot is smeared
  NullProgress progress;
  CancelToken cancel;
  const auto stamps = candidate::candidateSheetStamps(*cube, cs, 6, progress, cancel);
  ASSERT_EQ(stamps.size(), 2u);
  for (std::size_t i = 0; i < cs.size(); ++i) {
    candidate::InspectionInput in;
    in.filtered = cube;
    in.candidate = cs[i];
    in.stampHalf = 6;
    const auto inspected = candidate::inspectCandidate(in, cancel);
    EXPECT_DOUBLE_EQ(stamps[i].centreSnr, inspected.trackSnr);
    EXPECT_EQ(stamps[i].stamp.pixels, inspected.trackStamp.pixels);
  }
  // Tracked: all 30 frames on one pixel, SNR 30 / (0.05 sqrt 30).
  EXPECT_NEAR(stamps[0].centreSnr, 30.0 / (0.05 * std::sqrt(30.0)), 1e-3);
  EXPECT_LT(stamps[1].centreSnr, 0.5 * stamps[0].centreSnr);
  EXPECT_THROW((void)candidate::candidateSheetStamps(*cube, cs, 0, progress, cancel), InputError);
  cancel.cancel();
  EXPECT_THROW((void)candidate::candidateSheetStamps(*cube, cs, 6, progress, cancel), Cancelled);
}

TEST(CandidateSheet, LaysOutAGridOfOnePanelPerCandidate) {
  search::FilteredCube cube;
  cube.frames = test::movingDotCube(64, 64, 30, {5.0, -2.0}, 30, 32);
  cube.sigmaF = 0.05;
  std::vector<SheetEntry> entries;
  for (int i = 0; i < 5; ++i) {
    search::Candidate c;
    c.x = 30;
    c.y = 32;
    c.v = {5.0, -2.0 + i};
    entries.push_back({i + 1, c, QString("rate %1 px/s vs sky").arg(i), i == 0 ? "real" : "unvetted"});
  }
  CancelToken cancel;
  const ImageFigure fig = candidateSheetFigure(cube, entries, {}, cancel);
  ASSERT_EQ(fig.panels.size(), 5u);
  EXPECT_EQ(fig.columns, 3);  // ceil(sqrt 5)
  EXPECT_TRUE(fig.panels[0].title.startsWith("#1  SNR 109.5  real\nrate 0 px/s vs sky"))
      << fig.panels[0].title.toStdString();
  EXPECT_EQ(fig.panels[0].image->width, 25);
  EXPECT_EQ(fig.panels[0].origin, QPointF(18, 20));  // axes in frame pixels
  // Two rows: the natural height is about twice that of one row of three.
  ImageFigure oneRow = fig;
  oneRow.panels.resize(3);
  const double h2 = naturalFigureSize(fig, 504).height(), h1 = naturalFigureSize(oneRow, 504).height();
  EXPECT_GT(h2, 1.7 * (h1 - 60));
  EXPECT_THROW((void)candidateSheetFigure(cube, {}, {}, cancel), InputError);
}

TEST(CandidateSheet, SelectedRowsAndTheLabelFilterExportAsOneFigure) {
  MainWindow w(test::fakeServices(test::movingDotCube(96, 96, 40, {8.0, -4.0}, 40, 50)));
  w.resize(1400, 900);
  w.show();
  w.openDemo();
  ASSERT_TRUE(test::waitFor([&] { return w.observation()->prepared() && !w.jobs()->busy(); }));
  w.searchPanel()->setGridPxS({6.0, -3.0}, 3.0, 0.5);
  w.runSearch();
  ASSERT_TRUE(test::waitFor([&] { return w.observation()->result() && !w.jobs()->busy(); }));
  ASSERT_GE(w.observation()->result()->candidates.size(), 4u);

  // The user Ctrl+clicks three rows of the table: three candidates are selected, the last is current.
  QTableView* table = w.candidates()->table();
  for (QDockWidget* dock : w.findChildren<QDockWidget*>())
    if (dock->isAncestorOf(table)) dock->raise();
  ASSERT_TRUE(test::waitFor([&] { return table->isVisible() && table->visualRect(table->model()->index(3, 0)).isValid(); }));
  QTest::mouseClick(table->viewport(), Qt::LeftButton, {}, table->visualRect(table->model()->index(0, 0)).center());
  ctrlClickRow(table, 1);
  ctrlClickRow(table, 3);
  const std::vector<int> chosen = w.candidates()->selectedCandidates();
  ASSERT_EQ(chosen.size(), 3u);
  EXPECT_EQ(w.observation()->selected(), chosen[2]);

  FigureDialog* d = w.figureDialog();
  d->refreshSources();
  const int selectedSheet = d->sheetIndex(false);
  ASSERT_GE(selectedSheet, 0);
  EXPECT_EQ(d->sourceNames()[selectedSheet], "Sheet: candidates selected in the table (3)");
  EXPECT_EQ(d->presetIndex(), d->sourceNames().size() - 1);  // the preset stays last
  test::TempDir dir;
  const QString png = qpath(dir, "sheet.png");
  EXPECT_EQ(exportAndWait(d, selectedSheet, png, {7.0, 0.0, 100}), "");
  const QImage image(png);
  EXPECT_EQ(image.width(), 700);
  EXPECT_GT(image.height(), 400);  // two rows of panels (2 x 2 grid for three)
  QDir().mkpath("ui_screens");
  image.save("ui_screens/figure_sheet_selected.png");
  const QString svg = qpath(dir, "sheet.svg");
  EXPECT_EQ(exportAndWait(d, selectedSheet, svg, {7.0, 0.0, 100}), "");
  EXPECT_TRUE(QSvgRenderer(svg).isValid());
  const QString text = readAll(svg);
  for (int i : chosen)
    EXPECT_TRUE(text.contains(QString("#%1 ").arg(i + 1))) << i;
  EXPECT_TRUE(text.contains("vs sky"));  // the rate relative to the stars, in the Search dock's unit
  EXPECT_EQ(exportAndWait(d, selectedSheet, qpath(dir, "sheet.pdf"), {7.0, 0.0, 100}), "");
  EXPECT_TRUE(readAll(qpath(dir, "sheet.pdf")).startsWith("%PDF"));

  // Label the current candidate real with the R key, show only real ones: the other sheet holds just it.
  const int real = *w.observation()->selected();
  QTest::keyClick(table, Qt::Key_R);
  EXPECT_EQ(w.observation()->candidateState(real)->label, session::Label::Real);
  auto* labelFilter = w.candidates()->findChild<QComboBox*>();
  ASSERT_NE(labelFilter, nullptr);
  labelFilter->setCurrentText("Real");
  d->refreshSources();
  const int shownSheet = d->sheetIndex(true);
  EXPECT_EQ(d->sourceNames()[shownSheet], "Sheet: all candidates shown by the table's filters (1)");
  const QString realSvg = qpath(dir, "real.svg");
  EXPECT_EQ(exportAndWait(d, shownSheet, realSvg, {3.5, 0.0, 100}), "");
  const QString realText = readAll(realSvg);
  EXPECT_TRUE(realText.contains(QString("#%1 ").arg(real + 1)));
  EXPECT_TRUE(realText.contains("real"));
  EXPECT_FALSE(realText.contains(QString("#%1 ").arg(chosen[0] + 1)));

  // Nothing shown: the dialog says why instead of writing an empty figure.
  labelFilter->setCurrentText("Artifact");
  d->refreshSources();
  const QString why = exportAndWait(d, d->sheetIndex(true), qpath(dir, "none.png"), {7.0, 0.0, 100});
  EXPECT_TRUE(why.contains("show no candidate")) << why.toStdString();
}

ST_UI_TEST_MAIN()
