#pragma once
// Injection tests: a simulated raw cube ("small" preset: 128 x 128 x 64, conventional CCD with gain 2, stars,
// a saturated star, cosmic rays, hot pixels) with its exact masters, calibrated, and its field measured.
#include <cstdint>

#include "st/calib/calibration.hpp"
#include "st/inject/field.hpp"
#include "st/inject/injection.hpp"
#include "st/sim/simulator.hpp"

namespace st::inject::fixture {

struct SimField {
  sim::SimResult sim;
  calib::MasterCalibration masters;
  FrameCube calibrated;
  Field field;
};

inline FrameCube calibratedCopy(const FrameCube& raw, const calib::MasterCalibration& masters) {
  FrameCube c = raw;
  NullProgress p;
  CancelToken t;
  calib::applyCalibration(c, masters, {}, p, t);
  return c;
}

inline SimField makeSimField(std::uint64_t seed, bool measurePsf = false) {
  NullProgress p;
  CancelToken c;
  SimField s{sim::simulate(sim::preset("small"), seed, p, c), {}, {}, {}};
  s.masters = sim::exactMasters(s.sim);
  s.calibrated = calibratedCopy(s.sim.cube, s.masters);
  FieldParams fp;
  if (!measurePsf) fp.psf = psf::Moffat{s.sim.truth.psfRadiusPx, s.sim.truth.psfBeta};
  fp.psfFrames = 5;
  s.field = measureField(s.calibrated, fp, p, c);
  return s;
}

inline InjectParams smallParams(std::uint64_t seed, int count = 4) {
  InjectParams p;
  p.count = count;
  p.snrMin = 8.0;
  p.snrMax = 15.0;
  p.rateMinPxS = 0.5;  // 3-13 px over the 6.4 s span, trails of 0.05-0.2 px in 0.09 s exposures
  p.rateMaxPxS = 2.0;
  p.seed = seed;
  return p;
}

}  // namespace st::inject::fixture
