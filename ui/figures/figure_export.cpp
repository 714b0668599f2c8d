#include "figure_export.hpp"

#include <QDir>
#include <QFileInfo>
#include <QImage>
#include <QPageSize>
#include <QPainter>
#include <QPdfWriter>
#include <QSvgGenerator>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>
#include <qcustomplot.h>

#include "st/common/error.hpp"

namespace st::ui {
namespace {

[[noreturn]] void fail(const QString& path, const QString& why) {
  throw InputError("cannot write figure " + path.toStdString() + ": " + why.toStdString());
}

void checkFolder(const QString& path) {
  const QFileInfo info(path);
  if (!info.absoluteDir().exists()) fail(path, "folder " + info.absolutePath() + " does not exist");
}

void writePng(const QString& path, const FigureSize& size, const FigurePainter& paint, double logicalDpi) {
  const int w = static_cast<int>(std::lround(size.widthIn * size.dpi));
  const int h = static_cast<int>(std::lround(size.heightIn * size.dpi));
  if (w <= 0 || h <= 0 || w > 30000 || h > 30000)
    fail(path, QString("bad pixel size %1 x %2 (size or DPI out of range)").arg(w).arg(h));
  QImage image(w, h, QImage::Format_ARGB32_Premultiplied);
  image.fill(Qt::white);
  // While painting the image resolves point sizes at the logical DPI; the chosen DPI is recorded after.
  const auto setDpi = [&image](double dpi) {
    const int dotsPerMetre = static_cast<int>(std::lround(dpi / 0.0254));
    image.setDotsPerMeterX(dotsPerMetre);
    image.setDotsPerMeterY(dotsPerMetre);
  };
  setDpi(logicalDpi);
  {
    QCPPainter painter(&image);
    painter.setMode(QCPPainter::pmNoCaching);
    painter.scale(size.dpi / logicalDpi, size.dpi / logicalDpi);
    paint(painter, QSizeF(size.widthIn * logicalDpi, size.heightIn * logicalDpi));
  }
  setDpi(size.dpi);
  if (!image.convertToFormat(QImage::Format_RGB32).save(path, "PNG")) fail(path, "the PNG writer failed");
}

void writeSvg(const QString& path, const FigureSize& size, const FigurePainter& paint, const QString& title,
              double logicalDpi) {
  const QSizeF canvas(size.widthIn * logicalDpi, size.heightIn * logicalDpi);
  QSvgGenerator svg;
  svg.setFileName(path);
  svg.setSize(canvas.toSize());
  svg.setViewBox(QRectF(QPointF(0, 0), canvas));
  svg.setResolution(static_cast<int>(std::lround(logicalDpi)));
  svg.setTitle(title);
  svg.setDescription("synthtrack figure");
  QCPPainter painter;
  if (!painter.begin(&svg)) fail(path, "the SVG writer could not open it");
  painter.setMode(QCPPainter::pmVectorized);
  painter.setMode(QCPPainter::pmNoCaching);
  paint(painter, canvas);
  painter.end();
}

void writePdf(const QString& path, const FigureSize& size, const FigurePainter& paint, const QString& title,
              double logicalDpi) {
  QPdfWriter pdf(path);
  pdf.setTitle(title);
  pdf.setCreator("synthtrack");
  pdf.setPageSize(QPageSize(QSizeF(size.widthIn, size.heightIn), QPageSize::Inch));
  pdf.setPageMargins(QMarginsF(0, 0, 0, 0));
  pdf.setResolution(static_cast<int>(std::lround(logicalDpi)));
  QCPPainter painter;
  if (!painter.begin(&pdf)) fail(path, "the PDF writer could not open it");
  painter.setMode(QCPPainter::pmVectorized);
  painter.setMode(QCPPainter::pmNoCaching);
  paint(painter, QSizeF(size.widthIn * logicalDpi, size.heightIn * logicalDpi));
  painter.end();
}

}  // namespace

FigureFormat figureFormatForPath(const QString& path) {
  const QString suffix = QFileInfo(path).suffix().toLower();
  if (suffix == "png") return FigureFormat::Png;
  if (suffix == "svg") return FigureFormat::Svg;
  if (suffix == "pdf") return FigureFormat::Pdf;
  throw InputError("figure " + path.toStdString() + ": unknown format '" + suffix.toStdString() +
                   "' (use .png, .svg or .pdf)");
}

void exportFigure(const QString& path, FigureFormat format, const FigureSize& size,
                  const FigurePainter& paint, const QString& title, double logicalDpi) {
  if (!(size.widthIn > 0) || !(size.heightIn > 0)) fail(path, "the figure size must be positive");
  if (!(logicalDpi > 0)) fail(path, "the logical DPI must be positive");
  checkFolder(path);
  switch (format) {
    case FigureFormat::Png:
      writePng(path, size, paint, logicalDpi);
      break;
    case FigureFormat::Svg:
      writeSvg(path, size, paint, title, logicalDpi);
      break;
    case FigureFormat::Pdf:
      writePdf(path, size, paint, title, logicalDpi);
      break;
  }
  // QSvgGenerator and QPdfWriter report no errors: check the file is there and not empty.
  const QFileInfo written(path);
  if (!written.exists() || written.size() == 0) fail(path, "nothing was written (permissions or disk full?)");
}

namespace {

struct ColourBin {
  std::int64_t n = 0, r = 0, g = 0, b = 0;
  [[nodiscard]] QRgb mean() const {
    return qRgb(static_cast<int>(r / n), static_cast<int>(g / n), static_cast<int>(b / n));
  }
};

int binOf(QRgb c) {
  return ((qRed(c) >> 2) << 12) | ((qGreen(c) >> 2) << 6) | (qBlue(c) >> 2);
}

int distance2(QRgb a, QRgb b) {
  const int dr = qRed(a) - qRed(b), dg = qGreen(a) - qGreen(b), db = qBlue(a) - qBlue(b);
  return dr * dr + dg * dg + db * db;
}

// The most frequent three quarters of the palette, then the colours farthest from it (greedy), so rare but
// distinct colours (a yellow marker, the top of a colour bar) keep a colour of their own.
QList<QRgb> choosePalette(const std::vector<ColourBin>& bins, std::vector<int> used, int colours) {
  const auto count = [&](int i) { return bins[static_cast<std::size_t>(i)].n; };
  std::sort(used.begin(), used.end(), [&](int a, int b) { return count(a) > count(b); });
  const std::size_t frequent = used.size() <= static_cast<std::size_t>(colours)
                                   ? used.size()
                                   : static_cast<std::size_t>(colours * 3 / 4);
  QList<QRgb> palette;
  for (std::size_t k = 0; k < frequent; ++k)
    palette.push_back(bins[static_cast<std::size_t>(used[k])].mean());
  std::vector<int> rest(used.begin() + static_cast<std::ptrdiff_t>(frequent), used.end());
  std::vector<int> nearest(rest.size(), std::numeric_limits<int>::max());
  for (std::size_t k = 0; k < rest.size(); ++k)
    for (QRgb c : palette)
      nearest[k] = std::min(nearest[k], distance2(c, bins[static_cast<std::size_t>(rest[k])].mean()));
  while (palette.size() < colours && !rest.empty()) {
    const auto far =
        static_cast<std::size_t>(std::max_element(nearest.begin(), nearest.end()) - nearest.begin());
    const QRgb c = bins[static_cast<std::size_t>(rest[far])].mean();
    palette.push_back(c);
    for (std::size_t k = 0; k < rest.size(); ++k)
      nearest[k] = std::min(nearest[k], distance2(c, bins[static_cast<std::size_t>(rest[k])].mean()));
  }
  return palette;
}

}  // namespace

QImage reduceToPalette(const QImage& image, int colours) {
  colours = std::clamp(colours, 2, 256);
  const QImage rgb = image.convertToFormat(QImage::Format_RGB32);
  std::vector<ColourBin> bins(1 << 18);
  for (int y = 0; y < rgb.height(); ++y) {
    const auto* line = reinterpret_cast<const QRgb*>(rgb.constScanLine(y));
    for (int x = 0; x < rgb.width(); ++x) {
      ColourBin& b = bins[static_cast<std::size_t>(binOf(line[x]))];
      ++b.n;
      b.r += qRed(line[x]);
      b.g += qGreen(line[x]);
      b.b += qBlue(line[x]);
    }
  }
  std::vector<int> used;
  for (int i = 0; i < static_cast<int>(bins.size()); ++i)
    if (bins[static_cast<std::size_t>(i)].n > 0) used.push_back(i);
  const QList<QRgb> palette = choosePalette(bins, used, colours);
  std::vector<std::uint8_t> lut(bins.size(), 0);
  for (int i : used) {
    const QRgb c = bins[static_cast<std::size_t>(i)].mean();
    int best = std::numeric_limits<int>::max();
    for (int k = 0; k < palette.size(); ++k)
      if (const int d = distance2(palette[k], c); d < best) {
        best = d;
        lut[static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(k);
      }
  }
  QImage out(rgb.size(), QImage::Format_Indexed8);
  out.setColorTable(palette);
  out.setDotsPerMeterX(image.dotsPerMeterX());
  out.setDotsPerMeterY(image.dotsPerMeterY());
  for (int y = 0; y < rgb.height(); ++y) {
    const auto* line = reinterpret_cast<const QRgb*>(rgb.constScanLine(y));
    std::uint8_t* dst = out.scanLine(y);
    for (int x = 0; x < rgb.width(); ++x)
      dst[x] = lut[static_cast<std::size_t>(binOf(line[x]))];
  }
  return out;
}

void paintPlot(QCPPainter& painter, const QSizeF& size, QCustomPlot& plot, const QString& title) {
  const double titleH = title.isEmpty() ? 0.0 : 18.0;
  painter.save();
  painter.fillRect(QRectF(QPointF(0, 0), size), Qt::white);
  if (!title.isEmpty()) {
    QFont f("DejaVu Sans");
    f.setPixelSize(11);
    f.setBold(true);
    painter.setFont(f);
    painter.setPen(Qt::black);
    painter.drawText(QRectF(0, 0, size.width(), titleH), Qt::AlignCenter, title);
    painter.translate(0, titleH);
  }
  plot.toPainter(&painter, static_cast<int>(size.width()), static_cast<int>(size.height() - titleH));
  painter.restore();
}

}  // namespace st::ui
