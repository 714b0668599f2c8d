#pragma once
// Publication figures of images: one or more panels side by side, each an image with its colour bar (in
// the data's units), a scale bar in arcsec when the plate scale is known, a N/E compass when there is a WCS,
// markers, arrows, a title and axis labels; an overall title and caption. Painting only (no widgets), onto
// any QPainter in a logical canvas measured in points (1/72 inch): figure_export.hpp maps it to PNG at a
// chosen DPI, SVG or PDF. Pure and thread-safe: a worker may paint while the GUI runs.
#include <QColor>
#include <QPointF>
#include <QRect>
#include <QSizeF>
#include <QString>
#include <functional>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "image_render.hpp"
#include "image_view.hpp"
#include "st/common/image.hpp"

class QPainter;

namespace st::ui {

/// An arrow over an image, in image pixels (0-based, y up), e.g. pointing at a candidate or along its track.
struct FigureArrow {
  QPointF from;
  QPointF to;
  QColor colour = QColor(255, 200, 0);
  QString label;  ///< drawn at the tail
};

/// Directions of north and east on the image, unit vectors in image pixels (y up).
struct Compass {
  QPointF north;
  QPointF east;
};

/// One image panel of a figure.
struct ImagePanel {
  std::shared_ptr<const Image> image;
  double lo = 0.0;  ///< display limits (data units), lo < hi
  double hi = 1.0;
  DisplaySettings display;
  QString title;
  QString units = "ADU";  ///< label of the colour bar
  QString xLabel = "x [px]";
  QString yLabel = "y [px]";
  QPointF origin;  ///< pixel (0, 0) of `image` in the full frame (crops keep the frame's tick labels)
  std::optional<double> plateScaleArcsecPerPx;  ///< scale bar when set
  std::optional<Compass> compass;               ///< N/E arrows when set
  std::vector<ImageMarker> markers;             ///< in `image` pixels
  std::vector<FigureArrow> arrows;              ///< in `image` pixels
  bool showColourBar = true;
  bool showScaleBar = true;
  bool showCompass = true;
  bool showAxes = true;
};

/// A whole figure: panels in a grid of `columns` columns (0: all in one row), filled row by row, with an
/// optional title above and caption below. A panel title may have several lines ('\n').
struct ImageFigure {
  QString title;
  QString caption;
  std::vector<ImagePanel> panels;
  int columns = 0;
};

/// Paints `figure` into the rectangle (0, 0, size) of `painter` (logical units: points). Fonts are sized in
/// those units, so the figure looks the same at every DPI. White background.
void paintImageFigure(QPainter& painter, const QSizeF& size, const ImageFigure& figure);

/// A good size in points for `figure` at `widthPt`: the height follows the panels' aspect ratio.
[[nodiscard]] QSizeF naturalFigureSize(const ImageFigure& figure, double widthPt);

/// Length in arcsec of a scale bar for an image `widthPx` pixels wide at `arcsecPerPx`: the largest of
/// 1, 2, 5 x 10^k arcsec (and 30", 1', 2', 5', 10', 30', 1 deg) not longer than a quarter of the width.
[[nodiscard]] double scaleBarArcsec(double arcsecPerPx, double widthPx);
/// Text of a scale bar: 20", 1.5', 2°.
[[nodiscard]] QString scaleBarText(double arcsec);

/// Round tick values in [lo, hi], about `target` of them (1, 2, 5 x 10^k steps).
[[nodiscard]] std::vector<double> niceTicks(double lo, double hi, int target = 5);

/// (RA, Dec) in degrees of a 0-based pixel, or nullopt without a WCS (CoreServices::pixelToSky bound to a
/// cube).
using SkyOfPixel = std::function<std::optional<std::pair<double, double>>(double x, double y)>;

/// North and east at pixel (x, y) from the sky positions of (x, y), (x + 1, y) and (x, y + 1): the local
/// Jacobian J = d(RA cos Dec, Dec)/d(x, y) is inverted, north = J^-1 (0, 1), east = J^-1 (1, 0), normalised.
/// Nullopt without a WCS, outside the projection, or for a singular J.
[[nodiscard]] std::optional<Compass> compassAt(const SkyOfPixel& sky, double x, double y);

/// The part of `image` inside `rect` (image pixels, clipped to the image); empty when nothing is left.
[[nodiscard]] Image cropImage(const Image& image, const QRect& rect);

}  // namespace st::ui
