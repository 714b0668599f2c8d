#include "figure_export.hpp"

#include <QDir>
#include <QFileInfo>
#include <QImage>
#include <QPageSize>
#include <QPainter>
#include <QPdfWriter>
#include <QSvgGenerator>
#include <cmath>
#include <qcustomplot.h>

#include "st/common/error.hpp"

namespace st::ui {
namespace {

constexpr double kPointsPerInch = 72.0;

[[noreturn]] void fail(const QString& path, const QString& why) {
  throw InputError("cannot write figure " + path.toStdString() + ": " + why.toStdString());
}

void checkFolder(const QString& path) {
  const QFileInfo info(path);
  if (!info.absoluteDir().exists()) fail(path, "folder " + info.absolutePath() + " does not exist");
}

void writePng(const QString& path, const FigureSize& size, const FigurePainter& paint) {
  const int w = static_cast<int>(std::lround(size.widthIn * size.dpi));
  const int h = static_cast<int>(std::lround(size.heightIn * size.dpi));
  if (w <= 0 || h <= 0 || w > 30000 || h > 30000)
    fail(path, QString("bad pixel size %1 x %2 (size or DPI out of range)").arg(w).arg(h));
  QImage image(w, h, QImage::Format_ARGB32_Premultiplied);
  image.fill(Qt::white);
  const int dotsPerMetre = static_cast<int>(std::lround(size.dpi / 0.0254));
  image.setDotsPerMeterX(dotsPerMetre);
  image.setDotsPerMeterY(dotsPerMetre);
  {
    QPainter painter(&image);
    painter.scale(size.dpi / kPointsPerInch, size.dpi / kPointsPerInch);
    paint(painter, QSizeF(size.widthIn * kPointsPerInch, size.heightIn * kPointsPerInch));
  }
  if (!image.convertToFormat(QImage::Format_RGB32).save(path, "PNG")) fail(path, "the PNG writer failed");
}

void writeSvg(const QString& path, const FigureSize& size, const FigurePainter& paint, const QString& title) {
  const QSizeF pt(size.widthIn * kPointsPerInch, size.heightIn * kPointsPerInch);
  QSvgGenerator svg;
  svg.setFileName(path);
  svg.setSize(pt.toSize());
  svg.setViewBox(QRectF(QPointF(0, 0), pt));
  svg.setResolution(static_cast<int>(kPointsPerInch));
  svg.setTitle(title);
  svg.setDescription("synthtrack figure");
  QPainter painter;
  if (!painter.begin(&svg)) fail(path, "the SVG writer could not open it");
  paint(painter, pt);
  painter.end();
}

void writePdf(const QString& path, const FigureSize& size, const FigurePainter& paint, const QString& title) {
  QPdfWriter pdf(path);
  pdf.setTitle(title);
  pdf.setCreator("synthtrack");
  pdf.setPageSize(QPageSize(QSizeF(size.widthIn, size.heightIn), QPageSize::Inch));
  pdf.setPageMargins(QMarginsF(0, 0, 0, 0));
  pdf.setResolution(static_cast<int>(std::lround(std::max(size.dpi, 72.0))));
  QPainter painter;
  if (!painter.begin(&pdf)) fail(path, "the PDF writer could not open it");
  const double s = pdf.resolution() / kPointsPerInch;
  painter.scale(s, s);
  paint(painter, QSizeF(size.widthIn * kPointsPerInch, size.heightIn * kPointsPerInch));
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
                  const FigurePainter& paint, const QString& title) {
  if (!(size.widthIn > 0) || !(size.heightIn > 0)) fail(path, "the figure size must be positive");
  checkFolder(path);
  switch (format) {
    case FigureFormat::Png:
      writePng(path, size, paint);
      break;
    case FigureFormat::Svg:
      writeSvg(path, size, paint, title);
      break;
    case FigureFormat::Pdf:
      writePdf(path, size, paint, title);
      break;
  }
  // QSvgGenerator and QPdfWriter report no errors: check the file is there and not empty.
  const QFileInfo written(path);
  if (!written.exists() || written.size() == 0) fail(path, "nothing was written (permissions or disk full?)");
}

QPicture capturePlot(QCustomPlot& plot, const QSizeF& sizePt, const QString& title) {
  QPicture picture;
  const double titleH = title.isEmpty() ? 0.0 : 18.0;
  QCPPainter painter(&picture);
  painter.setMode(QCPPainter::pmVectorized);
  painter.setMode(QCPPainter::pmNoCaching);
  painter.fillRect(QRectF(QPointF(0, 0), sizePt), Qt::white);
  if (!title.isEmpty()) {
    QFont f("DejaVu Sans");
    f.setPixelSize(11);
    f.setBold(true);
    painter.setFont(f);
    painter.setPen(Qt::black);
    painter.drawText(QRectF(0, 0, sizePt.width(), titleH), Qt::AlignCenter, title);
    painter.translate(0, titleH);
  }
  plot.toPainter(&painter, static_cast<int>(sizePt.width()), static_cast<int>(sizePt.height() - titleH));
  painter.end();
  return picture;
}

FigurePainter paintPicture(QPicture picture, QSizeF recordedPt) {
  return [picture = std::move(picture), recordedPt](QPainter& painter, const QSizeF& sizePt) {
    painter.save();
    painter.fillRect(QRectF(QPointF(0, 0), sizePt), Qt::white);
    painter.scale(sizePt.width() / recordedPt.width(), sizePt.height() / recordedPt.height());
    painter.drawPicture(0, 0, picture);
    painter.restore();
  };
}

}  // namespace st::ui
