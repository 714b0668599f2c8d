#pragma once
// Writes figures to PNG (raster, at a chosen DPI), SVG (Qt SVG's QSvgGenerator) and PDF (QPdfWriter, vector).
// A figure is anything that paints itself into a logical canvas measured in points (1/72 inch): an
// ImageFigure (figure_render.hpp) or a QCustomPlot captured as a QPicture. The size in inches is fixed by
// the caller; a PNG is round(width_in * dpi) x round(height_in * dpi) pixels and records its DPI.
// exportFigure may run on a worker thread (it touches no widget); capturePlot must run on the GUI thread.
#include <QPicture>
#include <QSizeF>
#include <QString>
#include <functional>

class QPainter;
class QCustomPlot;

namespace st::ui {

enum class FigureFormat { Png, Svg, Pdf };

/// The format of a path from its suffix (.png, .svg, .pdf; case-insensitive). Throws st::InputError naming
/// the path for any other suffix.
[[nodiscard]] FigureFormat figureFormatForPath(const QString& path);

/// Size and resolution of an exported figure.
struct FigureSize {
  double widthIn = 7.0;  ///< a two-column journal figure is ~7 in wide
  double heightIn = 3.5;
  double dpi = 300.0;  ///< PNG pixels per inch (PDF and SVG are vector; images in them keep their pixels)
};

/// Paints a figure into (0, 0, sizePt): logical units are points.
using FigurePainter = std::function<void(QPainter& painter, const QSizeF& sizePt)>;

/// Writes the figure to `path` in `format`. `title` goes into the SVG/PDF metadata. Throws st::InputError
/// naming the path when it cannot be written (missing folder, no permission, full disk).
void exportFigure(const QString& path, FigureFormat format, const FigureSize& size,
                  const FigurePainter& paint, const QString& title = {});

/// A plot as it would be drawn at `sizePt` (logical points), recorded as vector drawing commands, with an
/// optional title above it. GUI thread only (QCustomPlot is a widget); the returned picture can be replayed
/// by paintPicture on any thread.
[[nodiscard]] QPicture capturePlot(QCustomPlot& plot, const QSizeF& sizePt, const QString& title = {});

/// A FigurePainter that replays `picture` scaled to fill the canvas (it was recorded at `recordedPt`).
[[nodiscard]] FigurePainter paintPicture(QPicture picture, QSizeF recordedPt);

}  // namespace st::ui
