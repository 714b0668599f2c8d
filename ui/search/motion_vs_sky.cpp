#include "motion_vs_sky.hpp"

#include <cmath>

#include "st/search/sky_motion.hpp"

namespace st::ui {

VelocityUnit shownUnit(const Observation& obs) {
  return obs.plateScale() ? obs.unit() : VelocityUnit::PxPerS;
}

Velocity toShownVsSky(const Observation& obs, Velocity v) {
  const Velocity sky = obs.skyRate();
  const auto unit = shownUnit(obs);
  const auto scale = obs.plateScale();
  return {fromPxPerS(v.vx - sky.vx, unit, scale), fromPxPerS(v.vy - sky.vy, unit, scale)};
}

Velocity fromShownVsSky(const Observation& obs, Velocity shown) {
  const Velocity sky = obs.skyRate();
  const auto unit = shownUnit(obs);
  const auto scale = obs.plateScale();
  return {toPxPerS(shown.vx, unit, scale) + sky.vx, toPxPerS(shown.vy, unit, scale) + sky.vy};
}

MotionVsSky motionVsSky(const Observation& obs, double x, double y, Velocity v) {
  MotionVsSky m;
  m.unit = shownUnit(obs);
  const Velocity shown = toShownVsSky(obs, v);
  m.vx = shown.vx;
  m.vy = shown.vy;
  m.rate = std::hypot(shown.vx, shown.vy);  // the conversion is a scale factor: |v| converts as v does
  if (const auto& raw = obs.raw()) {
    const Velocity sky = obs.skyRate();
    m.paDeg = search::skyMotion(*raw, x, y, {v.vx - sky.vx, v.vy - sky.vy}).paDeg;
  }
  return m;
}

QString describeMotion(const MotionVsSky& m) {
  QString text = QString("rate %1 %2 vs sky").arg(m.rate, 0, 'g', 4).arg(unitLabel(m.unit));
  if (m.paDeg) text += QString(", PA %1°").arg(*m.paDeg, 0, 'f', 1);
  return text;
}

QString describeMotionWithComponents(const MotionVsSky& m) {
  return describeMotion(m) + QString(" (vx %1, vy %2)").arg(m.vx, 0, 'g', 4).arg(m.vy, 0, 'g', 4);
}

ShownTrack shownTrack(const Observation& obs, int index, const search::Candidate& c) {
  const session::CandidateState* state = obs.candidateState(index);
  if (state && state->fitted()) return {state->fit->x, state->fit->y, state->fit->v, state->fit->snr, true};
  return {static_cast<double>(c.x), static_cast<double>(c.y), c.v, c.snr, false};
}

QString describeShownTrack(const Observation& obs, const ShownTrack& t) {
  return QString("%1 SNR %2, %3")
      .arg(t.fitted ? "fit" : "search")
      .arg(t.snr, 0, 'f', 1)
      .arg(describeMotion(motionVsSky(obs, t.x, t.y, t.v)));
}

}  // namespace st::ui
