#pragma once
// Writes figures to PNG (raster, at a chosen DPI), SVG (Qt SVG's QSvgGenerator) and PDF (QPdfWriter, vector).
// A figure paints itself into a logical canvas of `logicalDpi` units per inch: points (72) for an ImageFigure
// (figure_render.hpp), the screen's DPI for a QCustomPlot (its fonts are in points and its layout is measured
// on screen, so the device must resolve points as the screen does). The size in inches is fixed by the
// caller; a PNG is round(width_in * dpi) x round(height_in * dpi) pixels and records its DPI.
// exportFigure may run on a worker thread when the painter touches no widget; paintPlot is GUI-thread only.
#include <QImage>
#include <QSizeF>
#include <QString>
#include <functional>

class QCustomPlot;
class QCPPainter;

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

/// Paints a figure into (0, 0, size): logical units (see exportFigure). A QCPPainter (a QPainter) so plots
/// can draw themselves too.
using FigurePainter = std::function<void(QCPPainter& painter, const QSizeF& size)>;

/// Writes the figure to `path` in `format`, painted in a canvas of size_in * logicalDpi units. `title` goes
/// into the SVG/PDF metadata. Throws st::InputError naming the path when it cannot be written (missing
/// folder, no permission, full disk).
void exportFigure(const QString& path, FigureFormat format, const FigureSize& size,
                  const FigurePainter& paint, const QString& title = {}, double logicalDpi = 72.0);

/// `image` with an adaptive palette of at most `colours` (2..256) entries, for small PNG screenshots: the
/// colours are binned at 6 bits per channel (each bin drawn as the mean of its pixels); the most frequent
/// bins fill three quarters of the palette, the bins farthest from it the rest (so a small yellow marker
/// keeps its colour); every pixel takes the nearest entry. An image with no more bins than `colours` keeps
/// its colours to within the binning (4 levels per channel).
[[nodiscard]] QImage reduceToPalette(const QImage& image, int colours = 256);

/// Paints `plot` into (0, 0, size) with an optional title above it (11 px bold). GUI thread only.
void paintPlot(QCPPainter& painter, const QSizeF& size, QCustomPlot& plot, const QString& title = {});

}  // namespace st::ui
