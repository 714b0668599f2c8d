// Display mapping: pixel values -> expected RGB for each stretch and colormap, and the limits.
#include <gtest/gtest.h>

#include <QApplication>
#include <cmath>

#include "image_render.hpp"
#include "image_view.hpp"
#include "ui_test_support.hpp"

using namespace st;
using namespace st::ui;

namespace {
QRgb renderOne(float v, double lo, double hi, Stretch s, Colormap c) {
  Image img(1, 1, v);
  DisplaySettings d;
  d.stretch = s;
  d.colormap = c;
  return renderImage(img, lo, hi, d).pixel(0, 0);
}
}  // namespace

TEST(ImageRender, LinearGrayMapsLimitsToBlackAndWhiteAndMidToMidGray) {
  EXPECT_EQ(renderOne(10.0f, 10, 20, Stretch::Linear, Colormap::Gray), qRgb(0, 0, 0));
  EXPECT_EQ(renderOne(20.0f, 10, 20, Stretch::Linear, Colormap::Gray), qRgb(255, 255, 255));
  EXPECT_EQ(renderOne(-5.0f, 10, 20, Stretch::Linear, Colormap::Gray), qRgb(0, 0, 0));        // clamped below
  EXPECT_EQ(renderOne(99.0f, 10, 20, Stretch::Linear, Colormap::Gray), qRgb(255, 255, 255));  // clamped above
  const int mid = qRed(renderOne(15.0f, 10, 20, Stretch::Linear, Colormap::Gray));
  EXPECT_NEAR(mid, 128, 1);
  const int quarter = qRed(renderOne(12.5f, 10, 20, Stretch::Linear, Colormap::Gray));
  EXPECT_NEAR(quarter, 64, 1);
}

TEST(ImageRender, LogAndAsinhFollowTheirFormulas) {
  for (double t : {0.01, 0.1, 0.3, 0.7}) {
    const double v = 100.0 + 50.0 * t;
    const int logGray = qRed(renderOne(static_cast<float>(v), 100, 150, Stretch::Log, Colormap::Gray));
    EXPECT_NEAR(logGray, 255.0 * std::log10(1.0 + 1000.0 * t) / 3.0, 1.5) << t;
    const int asinhGray = qRed(renderOne(static_cast<float>(v), 100, 150, Stretch::Asinh, Colormap::Gray));
    EXPECT_NEAR(asinhGray, 255.0 * std::asinh(10.0 * t) / std::asinh(10.0), 1.5) << t;
  }
  // Both brighten faint levels compared with linear.
  EXPECT_GT(qRed(renderOne(110.f, 100, 150, Stretch::Log, Colormap::Gray)),
            qRed(renderOne(110.f, 100, 150, Stretch::Linear, Colormap::Gray)));
}

TEST(ImageRender, ColormapEndpointsAreMatplotlibs) {
  // viridis: #440154 at 0, #fde725 at 1; inferno: #000004 at 0, #fcffa4 at 1 (matplotlib, +-1 per channel).
  auto near = [](QRgb a, QRgb b) {
    return std::abs(qRed(a) - qRed(b)) <= 1 && std::abs(qGreen(a) - qGreen(b)) <= 1 &&
           std::abs(qBlue(a) - qBlue(b)) <= 1;
  };
  EXPECT_TRUE(near(renderOne(0.f, 0, 1, Stretch::Linear, Colormap::Viridis), qRgb(0x44, 0x01, 0x54)));
  EXPECT_TRUE(near(renderOne(1.f, 0, 1, Stretch::Linear, Colormap::Viridis), qRgb(0xfd, 0xe7, 0x25)));
  EXPECT_TRUE(near(renderOne(0.f, 0, 1, Stretch::Linear, Colormap::Inferno), qRgb(0x00, 0x00, 0x04)));
  EXPECT_TRUE(near(renderOne(1.f, 0, 1, Stretch::Linear, Colormap::Inferno), qRgb(0xfc, 0xff, 0xa4)));
  // viridis at 0.5 is matplotlib's #21918c.
  const QRgb mid = renderOne(0.5f, 0, 1, Stretch::Linear, Colormap::Viridis);
  EXPECT_NEAR(qRed(mid), 0x21, 2);
  EXPECT_NEAR(qGreen(mid), 0x91, 2);
  EXPECT_NEAR(qBlue(mid), 0x8c, 2);
}

TEST(ImageRender, RowZeroIsDrawnAtTheBottomAndNanIsMarked) {
  Image img(2, 2, 0.0f);
  img.at(1, 0) = 1.0f;           // x = 1, y = 0: bottom-right on screen
  img.at(0, 1) = std::nanf("");  // top-left on screen
  DisplaySettings d;
  const QImage q = renderImage(img, 0, 1, d);
  EXPECT_EQ(q.pixel(1, 1), qRgb(255, 255, 255));
  EXPECT_EQ(q.pixel(0, 0), qRgb(120, 0, 0));
}

TEST(ImageRender, PercentileAndZScaleLimits) {
  // A ramp 0..9999: the 99 % limits are the 1st and 99th percentiles.
  std::vector<float> ramp(10000);
  for (int i = 0; i < 10000; ++i)
    ramp[static_cast<std::size_t>(i)] = static_cast<float>(i);
  DisplaySettings d;
  d.limits = LimitsMode::Percentile;
  d.percentile = 99.0;
  auto [lo, hi] = computeLimits(ramp.data(), ramp.size(), d);
  EXPECT_NEAR(lo, 100, 2);
  EXPECT_NEAR(hi, 9899, 2);
  // Gaussian-like noise around 100 with one very bright star: zscale ignores the star.
  std::vector<float> sky(40000);
  for (std::size_t i = 0; i < sky.size(); ++i)
    sky[i] = 100.0f + static_cast<float>(std::sin(i * 12.9898) * 5.0);
  sky[20000] = 1e6f;
  d.limits = LimitsMode::ZScale;
  std::tie(lo, hi) = computeLimits(sky.data(), sky.size(), d);
  // zscale's contrast 0.25 widens the +-5 spread of the sky four times, and the star does not count.
  EXPECT_GT(lo, 75.0);
  EXPECT_LT(hi, 125.0);
  EXPECT_LT(lo, hi);
  // A constant image still gets lo < hi.
  std::vector<float> flat(100, 3.0f);
  std::tie(lo, hi) = computeLimits(flat.data(), flat.size(), d);
  EXPECT_LT(lo, hi);
}

TEST(ImageView, PixelMappingRoundTripsAndZoomKeepsTheCursorPixel) {
  ImageView view;
  view.resize(400, 300);
  auto img = std::make_shared<const Image>(64, 32, 1.0f);
  view.setImage(img);
  view.zoomToFit();
  const QPointF w = view.imageToWidget(QPointF(10, 20));
  const QPointF back = view.widgetToImage(w);
  EXPECT_NEAR(back.x(), 10, 1e-9);
  EXPECT_NEAR(back.y(), 20, 1e-9);
  // Image y grows upwards on screen.
  EXPECT_LT(view.imageToWidget(QPointF(10, 30)).y(), view.imageToWidget(QPointF(10, 0)).y());
  view.zoomOneToOne();
  EXPECT_DOUBLE_EQ(view.zoom(), 1.0);
  view.centreOn(5, 5);
  const QPointF c = view.widgetToImage(QPointF(200, 150));
  EXPECT_NEAR(c.x(), 5, 1e-9);
  EXPECT_NEAR(c.y(), 5, 1e-9);
}

ST_UI_TEST_MAIN()
