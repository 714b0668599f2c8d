#pragma once
// Display mapping of float images to colour pixels: limits (zscale, percentile, min/max), stretch (linear,
// log, asinh) and colormap (gray, viridis, inferno). Pure functions, no widgets; the GUI thread or a worker
// may call them. This is display only: nothing here changes the data the science sees.
#include <QImage>
#include <QRgb>
#include <QString>
#include <array>
#include <cstddef>
#include <utility>

#include "st/common/image.hpp"

namespace st::ui {

enum class Stretch { Linear, Log, Asinh };
enum class LimitsMode { ZScale, Percentile, MinMax };
enum class Colormap { Gray, Viridis, Inferno };

/// How an image is shown. `percentile` is the upper percentile for LimitsMode::Percentile (the lower one
/// is 100 - percentile), e.g. 99.5 maps the 0.5 % and 99.5 % points to black and white.
struct DisplaySettings {
  Stretch stretch = Stretch::Linear;
  LimitsMode limits = LimitsMode::ZScale;
  double percentile = 99.5;
  Colormap colormap = Colormap::Gray;
};

/// The 256-entry colour table of a colormap (viridis and inferno interpolated from matplotlib's tables).
const std::array<QRgb, 256>& colormapTable(Colormap map);

QString toString(Stretch s);
QString toString(LimitsMode m);
QString toString(Colormap c);

/// Display limits (lo, hi) of `n` floats, ignoring NaN/inf. ZScale follows IRAF's zscale (sample of up to
/// 20000 pixels, line fit to the sorted sample with iterative 2.5-sigma rejection, contrast 0.25). Always
/// returns lo < hi (hi = lo + 1 for a constant image).
std::pair<double, double> computeLimits(const float* data, std::size_t n, const DisplaySettings& settings);

/// Normalised display value in [0, 1] of `value` for limits lo < hi and a stretch: linear t = (v-lo)/(hi-lo);
/// log: log10(1 + 1000 t) / 3; asinh: asinh(10 t) / asinh(10). Clamped to [0, 1].
double stretchValue(double value, double lo, double hi, Stretch stretch);

/// Renders an image with the given limits and settings into a QImage (Format_RGB32). Row y of the data is
/// drawn bottom-up (y = 0 at the bottom, as DS9 and FITS viewers show it). NaN pixels are drawn dark red.
QImage renderImage(const Image& image, double lo, double hi, const DisplaySettings& settings);

}  // namespace st::ui
