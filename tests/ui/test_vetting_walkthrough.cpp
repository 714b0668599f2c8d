// The vetting GUI as astronomers use it (issue 18 §6): markers on the image and the velocity map coloured by
// label (as the DS9 export) and hidden by the table's label filter; Esc pressed to close a drop-down does not
// cancel a running search, a long search asks first, and the previous velocity map stays until a new search
// completes; the play/pause button uses the style's icons (the "⏸" glyph showed as an empty box); the table
// labels the expected false-alarm count as such.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include <QAbstractItemView>
#include <QHeaderView>
#include <QAction>
#include <QComboBox>
#include <QDir>
#include <QFile>
#include <QLabel>
#include <QMessageBox>
#include <QMouseEvent>
#include <QTableView>
#include <QTableWidget>
#include <QTest>
#include <qcustomplot.h>
#include <QStatusBar>
#include <QToolButton>

#include "candidate_inspector.hpp"
#include "candidate_table.hpp"
#include "fit_panel.hpp"
#include "image_view.hpp"
#include "job_runner.hpp"
#include "main_window.hpp"
#include "search_panel.hpp"
#include "stamp_strip.hpp"
#include "session_controller.hpp"
#include "figure_dialog.hpp"
#include "motion_vs_sky.hpp"
#include "st/candidate/candidate_measurement.hpp"
#include "st/io/wcs.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/session/session.hpp"
#include "test_support.hpp"
#include "ui_test_support.hpp"
#include "velocity_map_widget.hpp"

using namespace st;
using namespace st::ui;
using session::Label;

namespace {

/// A window with the demo pre-processed and searched (fake backend; `slowdownMs` per velocity).
std::unique_ptr<MainWindow> searchedWindow(int slowdownMs = 0) {
  auto w = std::make_unique<MainWindow>(test::fakeServices(test::movingDotCube(96, 64, 12, {6.0, -3.0}, 30, 40),
                                                           slowdownMs));
  w->resize(1200, 760);
  w->show();
  w->openDemo();
  EXPECT_TRUE(test::waitFor([&] { return w->observation()->prepared() && !w->jobs()->busy(); }));
  w->searchPanel()->setGridPxS({6.0, -3.0}, 3.0, 0.5);
  w->runSearch();
  EXPECT_TRUE(test::waitFor([&] { return w->observation()->result() && !w->jobs()->busy(); }));
  return w;
}

QColor colourOf(Label label) {
  return QColor(candidate::labelColour(label));
}

}  // namespace

TEST(VettingWalkthrough, MarkersAreColouredByLabelAndFollowTheLabelFilter) {
  auto w = searchedWindow();
  Observation* obs = w->observation();
  const int n = static_cast<int>(obs->result()->candidates.size());
  ASSERT_GE(n, 3);
  obs->setCandidateLabel(0, Label::Real);
  obs->setCandidateLabel(1, Label::Artifact, session::ArtifactReason::Ghost);
  obs->setSelected(2);
  QCoreApplication::processEvents();
  const auto& markers = w->imageView()->markers();
  ASSERT_EQ(static_cast<int>(markers.size()), std::min(n, 100));
  EXPECT_EQ(markers[0].colour, colourOf(Label::Real));
  EXPECT_EQ(markers[1].colour, colourOf(Label::Artifact));
  EXPECT_EQ(markers[2].colour, colourOf(Label::Unvetted));
  EXPECT_GT(markers[2].width, markers[0].width);  // the selected candidate is drawn thicker
  VelocityMapWidget* map = w->velocityMap();
  EXPECT_EQ(map->candidatePoints(Label::Real), 1);
  EXPECT_EQ(map->candidatePoints(Label::Artifact), 1);
  EXPECT_EQ(map->candidatePoints(Label::Unvetted), n - 2);

  // "Real" in the label filter: the artifact and the unvetted ones leave the image and the velocity map (the
  // table moves the selection to a row it still shows: candidate 1).
  auto* filter = w->candidates()->findChild<QComboBox*>();
  ASSERT_TRUE(filter);
  filter->setCurrentText("Real");
  QCoreApplication::processEvents();
  ASSERT_EQ(w->imageView()->markers().size(), 1u);
  EXPECT_EQ(w->imageView()->markers()[0].colour, colourOf(Label::Real));
  EXPECT_EQ(w->imageView()->markers()[0].label, "#1");
  EXPECT_EQ(map->candidatePoints(Label::Real), 1);
  EXPECT_EQ(map->candidatePoints(Label::Artifact), 0);
  EXPECT_EQ(map->candidatePoints(Label::Unvetted), 0);
  // Relabelling under the filter updates both at once.
  obs->setCandidateLabel(1, Label::Real);
  QCoreApplication::processEvents();
  EXPECT_EQ(map->candidatePoints(Label::Real), 2);
  filter->setCurrentText("All");
  QCoreApplication::processEvents();
  EXPECT_EQ(static_cast<int>(w->imageView()->markers().size()), std::min(n, 100));
}

TEST(VettingWalkthrough, EscClosingADropDownDoesNotCancelTheSearchAndTheOldMapStays) {
  auto w = searchedWindow(10);  // the fake backend sleeps 10 ms per velocity
  const auto first = w->observation()->result();
  ASSERT_TRUE(first);
  // A slow search (625 velocities, ~6 s) on a different grid.
  w->searchPanel()->setGridPxS({6.0, -3.0}, 6.0, 0.5);
  w->runSearch();
  ASSERT_TRUE(test::waitFor([&] { return w->jobs()->busy(); }, 5000));
  // A drop-down is open (the table's label filter) and Esc is pressed to close it.
  auto* combo = w->candidates()->findChild<QComboBox*>();
  ASSERT_TRUE(combo);
  w->activateWindow();
  combo->showPopup();
  ASSERT_TRUE(test::waitFor([&] { return QApplication::activePopupWidget() != nullptr; }, 3000));
  QTest::keyClick(QApplication::activePopupWidget(), Qt::Key_Escape);
  QCoreApplication::processEvents();
  EXPECT_EQ(QApplication::activePopupWidget(), nullptr);
  EXPECT_TRUE(w->jobs()->busy()) << "Esc for the drop-down cancelled the search";
  // The same through Run > Cancel's slot itself (what the Esc shortcut calls), with the popup open.
  combo->showPopup();
  ASSERT_TRUE(test::waitFor([&] { return QApplication::activePopupWidget() != nullptr; }, 3000));
  w->cancelFromKey();
  QCoreApplication::processEvents();
  EXPECT_EQ(QApplication::activePopupWidget(), nullptr);
  EXPECT_TRUE(w->jobs()->busy()) << "Run > Cancel with a drop-down open cancelled the search";
  // Meanwhile the previous result and its map are still shown.
  EXPECT_EQ(w->observation()->result(), first);
  EXPECT_EQ(w->velocityMap()->candidatePoints(Label::Unvetted), static_cast<int>(first->candidates.size()));
  // Esc on the window now cancels (the search is younger than kAskBeforeCancelS, so without asking).
  w->cancelFromKey();
  ASSERT_TRUE(test::waitFor([&] { return !w->jobs()->busy(); }, 5000));
  EXPECT_EQ(w->observation()->result(), first);
  EXPECT_TRUE(w->searchPanel()->statusText().contains("cancelled")) << w->searchPanel()->statusText().toStdString();
}

TEST(VettingWalkthrough, PlayButtonUsesIconsAndFalseAlarmsAreCounts) {
  auto w = searchedWindow();
  auto* play = w->candidateInspector()->findChild<QToolButton*>("inspector.play");
  ASSERT_TRUE(play);
  EXPECT_TRUE(play->text().isEmpty());
  EXPECT_FALSE(play->icon().isNull());
  QTableView* table = w->candidates()->table();
  const auto* model = table->model();
  bool found = false;
  for (int c = 0; c < model->columnCount(); ++c) {
    const QString h = model->headerData(c, Qt::Horizontal).toString();
    EXPECT_NE(h, "FAP");
    if (h == "false alarms") {
      found = true;
      EXPECT_TRUE(model->headerData(c, Qt::Horizontal, Qt::ToolTipRole).toString().contains("count"));
    }
  }
  EXPECT_TRUE(found);
}

TEST(VettingWalkthrough, TheWindowFitsA1366x768Screen) {
  auto w = searchedWindow();
  const QSize min = w->minimumSizeHint().expandedTo(w->minimumSize());
  EXPECT_LE(min.width(), 1366) << min.width() << " x " << min.height();
  EXPECT_LE(min.height(), 768 - 40) << min.width() << " x " << min.height();  // a taskbar of 40 px
  w->resize(1366, 728);
  QCoreApplication::processEvents();
  EXPECT_LE(w->height(), 728);
  EXPECT_LE(w->statusBar()->geometry().bottom(), w->height());
}

// Issue 18 §6: the first window fits a 1366 x 768 laptop screen (a 40 px taskbar), also with a long session
// path in the status bar (a QLabel's minimum width was its whole text), and the status bar's warnings show.
TEST(VettingWalkthrough, TheFirstWindowFitsA1366x768LaptopWithItsStatusBar) {
  EXPECT_EQ(MainWindow::firstSize({1920, 1040}), QSize(1500, 940));
  const QSize laptop(1366, 768 - 40);
  const QSize first = MainWindow::firstSize(laptop);
  EXPECT_LE(first.width() + 16, laptop.width());
  EXPECT_LE(first.height() + 40, laptop.height());
  auto w = searchedWindow();
  test::TempDir dir;
  const std::filesystem::path deep = dir / "a-rather-long-folder-name-for-the-night-of-2026-11-27" /
                                     "and-another-one-for-the-field-and-the-filter";
  std::filesystem::create_directories(deep);
  const QString longPath = QString::fromStdString((deep / "paper-neo-500-frames.synthtrack-session.json").string());
  w->session()->saveAs(longPath);
  ASSERT_TRUE(test::waitFor([&] { return QFile::exists(longPath); }));
  QCoreApplication::processEvents();
  const QSize min = w->minimumSizeHint().expandedTo(w->minimumSize());
  EXPECT_LE(min.width(), first.width()) << min.width() << " x " << min.height();
  EXPECT_LE(min.height(), first.height()) << min.width() << " x " << min.height();
  w->resize(first);
  w->statusBar()->showMessage("⚠ a warning the status bar must show");
  QTest::qWait(200);
  EXPECT_EQ(w->size(), first);
  const QRect bar = w->statusBar()->geometry();
  EXPECT_LE(bar.bottom(), w->height() - 1);
  EXPECT_GT(bar.height(), 10);
  QLabel* sessionLabel = nullptr;
  for (auto* label : w->statusBar()->findChildren<QLabel*>())
    if (label->text().startsWith("Session")) sessionLabel = label;
  ASSERT_TRUE(sessionLabel);
  EXPECT_TRUE(sessionLabel->text().contains(longPath));  // whole in text() and the tooltip, elided on screen
  EXPECT_TRUE(sessionLabel->toolTip().contains(longPath));
  EXPECT_TRUE(sessionLabel->isVisible());
  EXPECT_LE(sessionLabel->mapTo(w.get(), QPoint(sessionLabel->width(), 0)).x(), w->width());
  QDir().mkpath("ui_screens");
  w->grab().save("ui_screens/first_window_1350x688.png");
}

// Issue 18 §6: the table leads with what vetting needs (SNR, rate, PA, flags, label, the accepted fit's SNR)
// and shows the motion relative to the stars, components and rate, in the unit chosen in the Search dock.
TEST(VettingWalkthrough, TableLeadsWithSnrRateLabelAndFitAndShowsMotionRelativeToTheSky) {
  auto w = searchedWindow();
  Observation* obs = w->observation();
  QHeaderView* header = w->candidates()->table()->horizontalHeader();
  std::vector<int> leading;
  for (int v = 0; v < 8; ++v) leading.push_back(header->logicalIndex(v));
  EXPECT_EQ(leading, (std::vector<int>{CandidateModel::Index, CandidateModel::Snr, CandidateModel::Rate,
                                       CandidateModel::Pa, CandidateModel::Flags, CandidateModel::Label,
                                       CandidateModel::Reason, CandidateModel::FitSnr}));
  // A sky rate that is not zero: the table's components and rate are the search's velocity minus it.
  auto view = std::make_shared<PreparedView>(*obs->prepared());
  auto filtered = std::make_shared<search::FilteredCube>(*view->filtered);
  filtered->skyRate = {0.5, -0.25};
  view->filtered = filtered;
  const auto result = obs->result();
  obs->setPrepared(view);
  obs->setResult(result);
  const QAbstractItemModel* m = w->candidates()->filter()->sourceModel();
  const search::Candidate& c = result->candidates[0];
  ASSERT_FALSE(obs->plateScale().has_value());  // px/s: the values are comparable directly
  EXPECT_NEAR(m->index(0, CandidateModel::Vx).data(Qt::UserRole).toDouble(), c.v.vx - 0.5, 1e-12);
  EXPECT_NEAR(m->index(0, CandidateModel::Vy).data(Qt::UserRole).toDouble(), c.v.vy + 0.25, 1e-12);
  EXPECT_NEAR(m->index(0, CandidateModel::Rate).data(Qt::UserRole).toDouble(),
              std::hypot(c.v.vx - 0.5, c.v.vy + 0.25), 1e-12);
  EXPECT_TRUE(m->headerData(CandidateModel::Vx, Qt::Horizontal).toString().contains("vs sky"));
  EXPECT_TRUE(m->index(0, CandidateModel::Pa).data().toString().isEmpty());  // no WCS: no position angle
  // The accepted fit's SNR beside the search's; empty without one.
  EXPECT_TRUE(m->index(0, CandidateModel::FitSnr).data().toString().isEmpty());
  candidate::FitSummary fit;
  fit.status = fit::FitStatus::Converged;
  fit.snr = 12.25;
  obs->setCandidateFit(0, fit);
  EXPECT_EQ(m->index(0, CandidateModel::FitSnr).data().toString(), "12.25");
  w->resize(1366, 728);
  QTest::qWait(200);
  QDir().mkpath("ui_screens");  // looked at by hand (tests/ui/test_main_window.cpp writes its own there)
  w->grab().save("ui_screens/vetting_table_columns.png");
}

// Issue 18 §6: a candidate's accepted fit (a reopened session's too) shows its table when selected, where
// the fit panel used to stay empty until the candidate was fitted again.
TEST(VettingWalkthrough, SelectingACandidateShowsItsAcceptedFitsTable) {
  auto w = searchedWindow();
  Observation* obs = w->observation();
  candidate::FitSummary fit;
  fit.status = fit::FitStatus::Converged;
  fit.iterations = 7;
  fit.x = 30.25;
  fit.v = {6.0, -3.0};
  fit.snr = 12.25;
  fit.sigma.xPx = 0.125;
  obs->setCandidateFit(1, fit);  // as restoreSnapshot hands a reopened session's fits to the Observation
  obs->setSelected(1);
  auto* table = w->fitPanel()->findChild<QTableWidget*>();
  ASSERT_TRUE(table);
  const auto valueOf = [&](const QString& name, int column) {
    for (int r = 0; r < table->rowCount(); ++r)
      if (table->item(r, 0)->text() == name) return table->item(r, column)->text();
    return QString("(no row)");
  };
  EXPECT_EQ(valueOf("SNR (detection_snr)", 1), "12.25");
  EXPECT_EQ(valueOf("x [px] at t_ref", 1), "30.25");
  EXPECT_EQ(valueOf("x [px] at t_ref", 2), "0.125");
  EXPECT_TRUE(w->fitPanel()->statusText().contains("accepted on candidate 2"))
      << w->fitPanel()->statusText().toStdString();
}

// Issue 18 §6: the velocity map's readout (velocity and max SNR under the pointer) does not outlive the map
// it described when another observation is loaded.
TEST(VettingWalkthrough, TheVelocityMapReadoutDoesNotOutliveItsMap) {
  auto w = searchedWindow();
  auto* readout = w->velocityMap()->findChild<QLabel*>("velocityMap.readout");
  ASSERT_TRUE(readout);
  auto* plot = w->velocityMap()->findChild<QWidget*>();
  for (auto* child : w->velocityMap()->findChildren<QWidget*>())
    if (child->inherits("QCustomPlot")) plot = child;
  const QPointF centre(plot->rect().center());
  QMouseEvent move(QEvent::MouseMove, centre, plot->mapToGlobal(centre), Qt::NoButton, Qt::NoButton,
                   Qt::NoModifier);
  QCoreApplication::sendEvent(plot, &move);
  ASSERT_TRUE(readout->text().contains("max SNR")) << readout->text().toStdString();
  auto other = std::make_shared<const FrameCube>(test::movingDotCube(64, 48, 8, {1.0, 1.0}, 20, 20));
  w->observation()->setRaw(other, "another");
  EXPECT_TRUE(readout->text().isEmpty()) << readout->text().toStdString();
}

// Issue 18 §6, one velocity convention: the motion relative to the stars, in the unit chosen in the Search
// dock, is the same number in the candidates table, on the velocity map's axes and readout, in the candidate
// inspector's header, in the fit table and in the figure preset's caption (all through motion_vs_sky.hpp).
TEST(VettingWalkthrough, OneVelocityConventionInTableMapInspectorFitAndCaption) {
  FrameCube cube = test::movingDotCube(96, 64, 12, {6.0, -3.0}, 30, 40);
  test::setTanWcs(cube.header, 150.0, 30.0, 48.5, 32.5, 1.0);
  cube.wcs = Wcs::fromHeader(cube.header, nullptr);
  cube.plateScaleArcsecPerPx = 1.0;
  auto w = std::make_unique<MainWindow>(test::fakeServices(cube));
  w->resize(1200, 760);
  w->show();
  w->openDemo();
  ASSERT_TRUE(test::waitFor([&] { return w->observation()->prepared() && !w->jobs()->busy(); }));
  Observation* obs = w->observation();
  auto view = std::make_shared<PreparedView>(*obs->prepared());  // stars drifting: a sky rate that is not 0
  auto filtered = std::make_shared<search::FilteredCube>(*view->filtered);
  filtered->skyRate = {0.5, -0.25};
  view->filtered = filtered;
  obs->setPrepared(view);
  w->searchPanel()->setGridPxS({6.0, -3.0}, 3.0, 0.5);
  w->runSearch();
  ASSERT_TRUE(test::waitFor([&] { return obs->result() && !w->jobs()->busy(); }));
  obs->setUnit(VelocityUnit::ArcsecPerMin);
  ASSERT_TRUE(obs->plateScale().has_value());
  const search::Candidate c = obs->result()->candidates[0];

  // The table: (v - sky) in "/min (1"/px: 1 px/s = 60 "/min), and a position angle from the WCS.
  const QAbstractItemModel* m = w->candidates()->filter()->sourceModel();
  const double vx = m->index(0, CandidateModel::Vx).data(Qt::UserRole).toDouble();
  const double vy = m->index(0, CandidateModel::Vy).data(Qt::UserRole).toDouble();
  const double rate = m->index(0, CandidateModel::Rate).data(Qt::UserRole).toDouble();
  EXPECT_NEAR(vx, (c.v.vx - 0.5) * 60.0, 1e-9);
  EXPECT_NEAR(vy, (c.v.vy + 0.25) * 60.0, 1e-9);
  const QString pa = m->index(0, CandidateModel::Pa).data().toString();
  ASSERT_FALSE(pa.isEmpty());
  const QString rateText = QString::number(rate, 'g', 4);

  // The velocity map: axes relative to the sky in the same unit, the sky rate at the origin, the candidate
  // where the table puts it.
  VelocityMapWidget* map = w->velocityMap();
  EXPECT_EQ(map->plot()->xAxis->label(), "vx vs sky [\"/min]");
  EXPECT_EQ(map->plot()->yAxis->label(), "vy vs sky [\"/min]");
  bool found = false;
  for (int g = 0; g < map->plot()->graphCount(); ++g) {
    QCPGraph* graph = map->plot()->graph(g);
    if (graph->name() == "sky rate") {
      ASSERT_EQ(graph->dataCount(), 1);
      EXPECT_NEAR(graph->data()->at(0)->key, 0.0, 1e-12);
      EXPECT_NEAR(graph->data()->at(0)->value, 0.0, 1e-12);
    }
    if (graph->name().startsWith("candidates"))
      for (int i = 0; i < graph->dataCount(); ++i)
        found |= std::abs(graph->data()->at(i)->key - vx) < 1e-9 && std::abs(graph->data()->at(i)->value - vy) < 1e-9;
  }
  EXPECT_TRUE(found) << "candidate 1 not at the table's (vx, vy) on the map";
  // A click on the candidate's point selects its velocity back in px/s.
  const Velocity back = map->velocityAtPlotPixel(map->plotPixelOf(c.v));
  EXPECT_NEAR(back.vx, c.v.vx, 1e-9);
  EXPECT_NEAR(back.vy, c.v.vy, 1e-9);

  // The inspector's header and the fit panel's table say the same rate and PA.
  obs->setSelected(0);
  const QString header = w->candidateInspector()->titleText();
  EXPECT_TRUE(header.contains("rate " + rateText + " \"/min vs sky, PA " + pa + "°")) << header.toStdString();
  candidate::FitSummary fit;
  fit.status = fit::FitStatus::Converged;
  fit.x = c.x;
  fit.y = c.y;
  fit.v = c.v;
  fit.snr = 12.25;
  obs->setCandidateFit(0, fit);
  obs->setSelected(std::nullopt);
  obs->setSelected(0);
  auto* table = w->fitPanel()->findChild<QTableWidget*>();
  ASSERT_TRUE(table);
  const auto valueOf = [&](const QString& name) {
    for (int r = 0; r < table->rowCount(); ++r)
      if (table->item(r, 0)->text() == name) return table->item(r, 1)->text();
    return QString("(no row)");
  };
  EXPECT_EQ(valueOf("rate vs sky [\"/min]"), rateText);
  EXPECT_EQ(valueOf("PA [deg] (east of north)"), pa);
  EXPECT_EQ(valueOf("vx vs sky [\"/min]"), QString::number(vx, 'g', 4));
  // The unit follows the Search dock: deg/day everywhere.
  obs->setUnit(VelocityUnit::DegPerDay);
  const QString rateDegDay = QString::number(m->index(0, CandidateModel::Rate).data(Qt::UserRole).toDouble(), 'g', 4);
  EXPECT_EQ(valueOf("rate vs sky [deg/day]"), rateDegDay);
  EXPECT_TRUE(w->candidateInspector()->titleText().contains("rate " + rateDegDay + " deg/day vs sky"));
  EXPECT_EQ(map->plot()->xAxis->label(), "vx vs sky [deg/day]");

  // The figure preset's caption.
  FigureDialog* d = w->figureDialog();
  d->refreshSources();
  d->setSource(d->presetIndex());
  d->setFigureSize({7.0, 0.0, 72});
  test::TempDir dir;
  const QString svg = QString::fromStdString((dir.path() / "preset.svg").string());
  bool done = false;
  QObject::connect(d, &FigureDialog::exportFinished, [&](const QString&, bool, const QString&) { done = true; });
  ASSERT_TRUE(d->exportTo(svg)) << d->lastMessage().toStdString();
  ASSERT_TRUE(test::waitFor([&] { return done; }));
  QFile file(svg);
  ASSERT_TRUE(file.open(QIODevice::ReadOnly));
  const QString text = QString::fromUtf8(file.readAll());
  EXPECT_TRUE(text.contains(rateDegDay)) << "the caption's rate";
  EXPECT_TRUE(text.contains("deg/day vs sky"));
}

// Issue 18 §6: pre-processing's list of moving sources is offered as candidates (Run menu and the table's
// context menu), beside the search's: the ones the search found already are not added twice, labels stay,
// the session goes on in the same file, and the table flags them.
TEST(VettingWalkthrough, PreprocessingMoversAreAddedAsCandidatesForVetting) {
  auto w = searchedWindow();
  Observation* obs = w->observation();
  const auto result = obs->result();
  const search::Candidate found = result->candidates[0];
  auto view = std::make_shared<PreparedView>(*obs->prepared());
  auto products = std::make_shared<pipeline::Prepared>();
  detect::MovingSource missed;  // a mover the search did not list
  missed.x = 70.2;
  missed.y = 12.8;
  missed.v = {-2.0, 1.0};
  missed.shiftPx = 4.0;
  missed.shiftSigmaPx = 0.5;
  missed.snr = 9.5;
  missed.moving = true;
  detect::MovingSource same = missed;  // the search's own candidate 1
  same.x = found.x + 0.4;
  same.y = found.y - 0.3;
  same.v = {found.v.vx + 0.2, found.v.vy};
  detect::MovingSource still = missed;  // measured, but not moving
  still.x = 20.0;
  still.moving = false;
  products->movers = {missed, same, still};
  view->products = products;
  obs->setPrepared(view);
  obs->setResult(result);
  obs->setCandidateLabel(0, Label::Real);
  ASSERT_TRUE(w->session()->autosaver()->flush());
  const QString path = w->session()->path();
  ASSERT_FALSE(path.isEmpty());
  QAction* action = w->findChild<QAction*>("action.addMovers");
  ASSERT_TRUE(action);
  EXPECT_TRUE(action->isEnabled());
  EXPECT_EQ(action->text(), "Add pre-processing's 1 mover as candidates");

  const std::size_t n = result->candidates.size();
  action->trigger();
  ASSERT_EQ(obs->result()->candidates.size(), n + 1);
  const search::Candidate& added = obs->result()->candidates[n];
  EXPECT_EQ(added.x, 70);
  EXPECT_EQ(added.y, 13);
  EXPECT_EQ(added.v, missed.v);
  EXPECT_DOUBLE_EQ(added.snr, 9.5);
  EXPECT_EQ(obs->candidateState(0)->label, Label::Real);  // the vetting so far is kept
  EXPECT_TRUE(QString::fromStdString(obs->candidateState(static_cast<int>(n))->note).contains("8.0 sigma"));
  const QAbstractItemModel* m = w->candidates()->filter()->sourceModel();
  EXPECT_TRUE(m->index(static_cast<int>(n), CandidateModel::Flags).data().toString().contains("pre-processing mover"));
  EXPECT_FALSE(m->index(0, CandidateModel::Flags).data().toString().contains("mover"));
  EXPECT_EQ(w->imageView()->markers().size(), std::min<std::size_t>(n + 1, 100));
  EXPECT_FALSE(action->isEnabled());  // nothing left to add
  EXPECT_EQ(w->addMoversAsCandidates(), 0);
  // The same session file, now with the mover and the label.
  ASSERT_TRUE(w->session()->autosaver()->flush());
  EXPECT_EQ(w->session()->path(), path);
  const session::Session saved = session::SessionStore(path.toStdString()).load();
  ASSERT_EQ(saved.candidates.size(), n + 1);
  EXPECT_EQ(saved.candidates[0].label, Label::Real);
}

// Issue 18 §6: more figure sources through the figure dialog's export: the candidate's stamps and segment
// strip (the inspector's rows) and the fit's data | model | residual, each tile a panel on the row's shared
// limits, captioned with the candidate's SNR and motion relative to the stars.
TEST(VettingWalkthrough, StampsSegmentsAndTheFitsResidualAreFigureSources) {
  auto w = searchedWindow();
  w->selectCandidate(0);
  CandidateInspector* inspector = w->candidateInspector();
  ASSERT_TRUE(test::waitFor([&] { return !inspector->busy() && inspector->stamps()->tileCount() > 0; }));
  ASSERT_GT(inspector->segmentStrip()->tileCount(), 0);
  // The fit panel's data | model | residual, as a finished fit leaves them.
  auto image = std::make_shared<const Image>(21, 21, 1.0f);
  w->fitPanel()->residualView()->setTiles({{image, "data", false}, {image, "model", false}, {image, "residual", false}});
  FigureDialog* d = w->figureDialog();
  d->refreshSources();
  const QStringList names = d->sourceNames();
  test::TempDir dir;
  QDir().mkpath("ui_screens");
  const auto exportAs = [&](const QString& source, const QString& file) {
    const int index = static_cast<int>(names.indexOf(source));
    EXPECT_GE(index, 0) << source.toStdString() << " not in " << names.join(", ").toStdString();
    if (index < 0) return QString();
    d->setSource(index);
    d->setFigureSize({7.0, 0.0, 100});
    bool done = false, ok = false;
    QString message;
    auto c = QObject::connect(d, &FigureDialog::exportFinished, [&](const QString&, bool good, const QString& m) {
      done = true;
      ok = good;
      message = m;
    });
    const QString path = QString::fromStdString((dir.path() / file.toStdString()).string());
    EXPECT_TRUE(d->exportTo(path)) << d->lastMessage().toStdString();
    EXPECT_TRUE(test::waitFor([&] { return done; }));
    QObject::disconnect(c);
    EXPECT_TRUE(ok) << message.toStdString();
    return path;
  };
  for (const auto& [source, file] : std::vector<std::pair<QString, QString>>{
           {"Candidate: candidate stamps", "stamps.png"},
           {"Candidate: segment strip", "segments.png"},
           {"Co-moving fit: fit data, model, residual", "fit.png"}}) {
    const QImage png(exportAs(source, file));
    EXPECT_EQ(png.width(), 700) << file.toStdString();
    EXPECT_GT(png.height(), 100) << file.toStdString();
    png.save("ui_screens/figure_" + file);
  }
  // The caption: the candidate, its SNR and its motion relative to the stars.
  QFile svg(exportAs("Candidate: candidate stamps", "stamps.svg"));
  ASSERT_TRUE(svg.open(QIODevice::ReadOnly));
  const QString text = QString::fromUtf8(svg.readAll());
  EXPECT_TRUE(text.contains("Candidate #1")) << "caption";
  EXPECT_TRUE(text.contains("vs sky")) << "caption";
}

ST_UI_TEST_MAIN_ISOLATED()
