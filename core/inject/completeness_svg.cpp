#include "st/inject/completeness_svg.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace st::inject {
namespace {

constexpr double kWidth = 640, kHeight = 440;
constexpr double kLeft = 80, kRight = 30, kTop = 50, kBottom = 70;

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f", v);
  return buf;
}

/// A "nice" tick step for a range: 1, 2 or 5 x 10^k giving about `ticks` ticks.
double niceStep(double range, int ticks) {
  const double raw = range / ticks;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (const double m : {1.0, 2.0, 5.0, 10.0})
    if (m * p >= raw) return m * p;
  return 10 * p;
}

}  // namespace

std::string xmlEscape(const std::string& text) {
  std::string out;
  for (const char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string completenessSvg(const std::vector<CompletenessBin>& bins, const std::string& title) {
  double xMax = 1.0;
  for (const auto& b : bins) {
    if (b.total == 0) continue;
    xMax = std::max({xMax, b.valueMax, std::isfinite(b.hi) ? b.hi : 0.0});
  }
  const double step = niceStep(xMax, 8);
  xMax = std::ceil(xMax * 1.02 / step) * step;
  const double pw = kWidth - kLeft - kRight, ph = kHeight - kTop - kBottom;
  auto sx = [&](double x) { return kLeft + pw * std::clamp(x, 0.0, xMax) / xMax; };
  // 0 and 1 sit 5% inside the frame, so that a bin's bar at 0% or 100% is not drawn over the frame's edge.
  auto sy = [&](double y) { return kTop + ph * (1.05 - std::clamp(y, 0.0, 1.0)) / 1.1; };
  std::string s;
  s += "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
  s += "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + num(kWidth) + "\" height=\"" + num(kHeight) +
       "\" viewBox=\"0 0 " + num(kWidth) + " " + num(kHeight) + "\" font-family=\"sans-serif\" font-size=\"12\">\n";
  s += "<rect x=\"0\" y=\"0\" width=\"" + num(kWidth) + "\" height=\"" + num(kHeight) + "\" fill=\"white\"/>\n";
  s += "<text x=\"" + num(kWidth / 2) + "\" y=\"28\" text-anchor=\"middle\" font-size=\"15\">" + xmlEscape(title) +
       "</text>\n";
  // Grid and ticks.
  s += "<g stroke=\"#dddddd\" stroke-width=\"1\">\n";
  for (double y = 0.0; y <= 1.0001; y += 0.2)
    s += "<line x1=\"" + num(kLeft) + "\" y1=\"" + num(sy(y)) + "\" x2=\"" + num(kLeft + pw) + "\" y2=\"" +
         num(sy(y)) + "\"/>\n";
  for (double x = 0.0; x <= xMax + 1e-9; x += step)
    s += "<line x1=\"" + num(sx(x)) + "\" y1=\"" + num(kTop) + "\" x2=\"" + num(sx(x)) + "\" y2=\"" +
         num(kTop + ph) + "\"/>\n";
  s += "</g>\n<g fill=\"black\">\n";
  for (double y = 0.0; y <= 1.0001; y += 0.2)
    s += "<text x=\"" + num(kLeft - 8) + "\" y=\"" + num(sy(y) + 4) + "\" text-anchor=\"end\">" + num(y).substr(0, 3) +
         "</text>\n";
  for (double x = 0.0; x <= xMax + 1e-9; x += step) {
    char label[32];
    std::snprintf(label, sizeof label, "%g", x);
    s += "<text x=\"" + num(sx(x)) + "\" y=\"" + num(kTop + ph + 18) + "\" text-anchor=\"middle\">" + label +
         "</text>\n";
  }
  s += "</g>\n";
  // Axes and their labels.
  s += "<rect x=\"" + num(kLeft) + "\" y=\"" + num(kTop) + "\" width=\"" + num(pw) + "\" height=\"" + num(ph) +
       "\" fill=\"none\" stroke=\"black\" stroke-width=\"1\"/>\n";
  s += "<text x=\"" + num(kLeft + pw / 2) + "\" y=\"" + num(kHeight - 22) +
       "\" text-anchor=\"middle\">expected SNR (optimal matched filter, whole track)</text>\n";
  s += "<text x=\"22\" y=\"" + num(kTop + ph / 2) + "\" text-anchor=\"middle\" transform=\"rotate(-90 22 " +
       num(kTop + ph / 2) + ")\">completeness (fraction recovered)</text>\n";
  // Points: bin extent (horizontal), Wilson 68% interval (vertical), counts.
  s += "<g stroke=\"#1f4e9c\" stroke-width=\"1.5\" fill=\"#1f4e9c\">\n";
  for (const auto& b : bins) {
    if (b.total == 0) continue;
    const double lo = std::isfinite(b.lo) ? b.lo : b.valueMin;
    const double hi = std::isfinite(b.hi) ? b.hi : b.valueMax;
    const double x = sx(b.valueMean), y = sy(b.fraction);
    s += "<line x1=\"" + num(sx(lo)) + "\" y1=\"" + num(y) + "\" x2=\"" + num(sx(hi)) + "\" y2=\"" + num(y) + "\"/>\n";
    s += "<line x1=\"" + num(x) + "\" y1=\"" + num(sy(b.errLow)) + "\" x2=\"" + num(x) + "\" y2=\"" +
         num(sy(b.errHigh)) + "\"/>\n";
    for (const double e : {b.errLow, b.errHigh})
      s += "<line x1=\"" + num(x - 4) + "\" y1=\"" + num(sy(e)) + "\" x2=\"" + num(x + 4) + "\" y2=\"" + num(sy(e)) +
           "\"/>\n";
    s += "<circle cx=\"" + num(x) + "\" cy=\"" + num(y) + "\" r=\"4\"/>\n";
    s += "<text x=\"" + num(x) + "\" y=\"" + num(sy(b.errHigh) - 6) + "\" text-anchor=\"middle\" stroke=\"none\">" +
         std::to_string(b.recovered) + "/" + std::to_string(b.total) + "</text>\n";
  }
  s += "</g>\n";
  s += "<text x=\"" + num(kLeft + pw) + "\" y=\"" + num(kHeight - 6) +
       "\" text-anchor=\"end\" font-size=\"10\" fill=\"#555555\">k/n: recovered/injected per bin; horizontal bar: "
       "the bin; vertical bar: Wilson 68% interval</text>\n";
  s += "</svg>\n";
  return s;
}

}  // namespace st::inject
