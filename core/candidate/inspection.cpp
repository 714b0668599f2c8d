#include "st/candidate/inspection.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <string>

#include "st/common/error.hpp"
#include "st/stack/ipsa.hpp"

namespace st::candidate {
namespace {

/// Frames of `frames` whose IPSA sample of the cell (x, y) at velocity v is inside the frame and unmasked:
/// the N_in of the search statistic at that cell.
std::size_t framesInside(const FrameCube& cube, const std::vector<std::size_t>& frames,
                         const std::vector<double>& timesS, int x, int y, Velocity v) {
  std::vector<double> t;
  std::vector<PixelOffset> o;  // registration offsets: the search's round(o_n + v dt_n)
  t.reserve(frames.size());
  for (std::size_t n : frames) {
    t.push_back(timesS[n]);
    o.push_back({cube.info()[n].offsetXPx, cube.info()[n].offsetYPx});
  }
  const auto shifts = stack::ipsaShifts(t, v, o);
  std::size_t count = 0;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const int xx = x + shifts[k].dx;
    const int yy = y + shifts[k].dy;
    if (xx >= 0 && yy >= 0 && xx < cube.width() && yy < cube.height() && !cube.isMasked(frames[k], xx, yy))
      ++count;
  }
  return count;
}

std::string format(const char* fmt, double a, double b, double c) {
  char buf[256];
  std::snprintf(buf, sizeof buf, fmt, a, b, c);
  return buf;
}

vet::SegmentReport segmentStrip(const InspectionInput& in, const std::vector<double>& timesS, double snr,
                                std::size_t nInAll, CancelToken& cancel) {
  const search::FilteredCube& cube = *in.filtered;
  vet::SegmentReport report;
  const int k = std::clamp(in.segments, 1, static_cast<int>(timesS.size()));
  const auto parts = vet::splitEqualTime(timesS, k);
  for (int s = 0; s < k; ++s) {
    cancel.throwIfCancelled();
    vet::SegmentMeasurement m;
    m.index = s;
    m.frames = parts[static_cast<std::size_t>(s)];
    for (std::size_t n : m.frames)
      m.tMidOffsetS += timesS[n] / static_cast<double>(m.frames.size());
    m.predictedX = in.candidate.x + in.candidate.v.vx * m.tMidOffsetS;
    m.predictedY = in.candidate.y + in.candidate.v.vy * m.tMidOffsetS;
    SnrStamp stamp = snrStampAt(cube, m.frames, in.candidate, in.candidate.v, in.stampHalf);
    m.forcedSnr = stamp.centreSnr;
    m.framesInside = stamp.nIn;
    m.stack = std::move(stamp.image);
    m.expectedSnr =
        nInAll > 0 ? snr * std::sqrt(static_cast<double>(m.framesInside) / static_cast<double>(nInAll)) : 0.0;
    m.missing = m.framesInside > 0 && m.forcedSnr < m.expectedSnr - in.segmentOptions.missingSigma &&
                m.forcedSnr < in.segmentOptions.missingFraction * m.expectedSnr;
    if (m.missing) {
      report.missingSignal = true;
      report.reasons.push_back(format("segment %.0f has SNR %.1f where a steady source gives %.1f",
                                      static_cast<double>(s + 1), m.forcedSnr, m.expectedSnr));
    }
    report.fluxChi2 += (m.forcedSnr - m.expectedSnr) * (m.forcedSnr - m.expectedSnr);
    if (m.framesInside > 0) ++report.fluxDof;
    report.segments.push_back(std::move(m));
  }
  report.fluxDof = std::max(0, report.fluxDof - 1);
  report.fluxProbability = vet::chiSquareSurvival(report.fluxChi2, report.fluxDof);
  if (report.fluxDof > 0 && report.fluxProbability < in.segmentOptions.minProbability) {
    report.fluxInconsistent = true;
    report.reasons.push_back(
        format("segment SNRs inconsistent with a steady source: chi2 %.1f for %.0f "
               "dof, p = %.2g",
               report.fluxChi2, report.fluxDof, report.fluxProbability));
  }
  return report;
}

void cutMovie(const InspectionInput& in, const std::vector<double>& timesS, Inspection& out,
              CancelToken& cancel) {
  const FrameCube& frames = in.movieFrames ? *in.movieFrames : in.filtered->frames;
  const std::size_t n = std::min(frames.frameCount(), timesS.size());
  const std::size_t take = std::min(n, std::max<std::size_t>(1, in.maxMovieFrames));
  const int side = 2 * in.stampHalf + 1;
  for (std::size_t k = 0; k < take; ++k) {
    if (k % 64 == 0) cancel.throwIfCancelled();
    const std::size_t f = take == n ? k : k * (n - 1) / std::max<std::size_t>(1, take - 1);
    const FrameInfo& fi = frames.info()[f];
    const int cx = in.candidate.x + static_cast<int>(std::lround(fi.offsetXPx + in.candidate.v.vx * timesS[f]));
    const int cy = in.candidate.y + static_cast<int>(std::lround(fi.offsetYPx + in.candidate.v.vy * timesS[f]));
    Image cut(side, side, 0.0f);
    const float* img = frames.frame(f);
    for (int y = 0; y < side; ++y)
      for (int x = 0; x < side; ++x) {
        const int sx = cx - in.stampHalf + x;
        const int sy = cy - in.stampHalf + y;
        if (sx < 0 || sy < 0 || sx >= frames.width() || sy >= frames.height() || frames.isMasked(f, sx, sy))
          continue;
        cut.at(x, y) = img[static_cast<std::size_t>(sy) * frames.width() + sx];
      }
    out.movie.push_back(std::move(cut));
    out.movieFrameIndex.push_back(f);
    out.movieTimeS.push_back(timesS[f]);
  }
}

}  // namespace

SnrStamp snrStampAt(const search::FilteredCube& cube, const std::vector<std::size_t>& frames,
                    const search::Candidate& c, Velocity v, int half) {
  const std::vector<double> timesS = cube.frames.timeOffsetsS();
  SnrStamp out;
  out.image = vet::stackStamp(cube.frames, frames, c.x, c.y, v, 0.0, half);
  out.nIn = framesInside(cube.frames, frames, timesS, c.x, c.y, v);
  const double scale = out.nIn > 0 ? 1.0 / (cube.sigmaF * std::sqrt(static_cast<double>(out.nIn))) : 0.0;
  for (float& p : out.image.pixels)
    p = static_cast<float>(p * scale);
  out.centreSnr = out.image.at(half, half);
  return out;
}

Inspection inspectCandidate(const InspectionInput& in, CancelToken& cancel) {
  if (!in.filtered || in.filtered->frames.empty())
    throw InputError("candidate inspector: no filtered cube (run pre-processing first)");
  if (!(in.filtered->sigmaF > 0.0))
    throw InputError("candidate inspector: the filtered cube has no noise estimate (sigma_F = " +
                     std::to_string(in.filtered->sigmaF) + ")");
  const search::FilteredCube& cube = *in.filtered;
  const std::vector<double> timesS = cube.frames.timeOffsetsS();
  std::vector<std::size_t> all(cube.frames.frameCount());
  std::iota(all.begin(), all.end(), std::size_t{0});

  Inspection out;
  SnrStamp tracked = snrStampAt(cube, all, in.candidate, in.candidate.v, in.stampHalf);
  const std::size_t nInTrack = tracked.nIn;
  out.trackSnr = tracked.centreSnr;
  out.trackStamp = std::move(tracked.image);
  cancel.throwIfCancelled();
  SnrStamp sky = snrStampAt(cube, all, in.candidate, cube.skyRate, in.stampHalf);
  out.skySnr = sky.centreSnr;
  out.skyStamp = std::move(sky.image);
  out.segments = segmentStrip(in, timesS, out.trackSnr, nInTrack, cancel);
  cutMovie(in, timesS, out, cancel);

  cancel.throwIfCancelled();
  const double fwhm = cube.psfFwhmPx > 0.0 ? cube.psfFwhmPx : 3.0;
  const vet::ArtifactContext ctx = vet::makeArtifactContext(cube.frames, in.stars, cube.skyRate, fwhm);
  const vet::Track track{static_cast<double>(in.candidate.x), static_cast<double>(in.candidate.y),
                         in.candidate.v};
  out.flags = vet::checkArtifacts(ctx, track, in.artifactParams, &out.segments);
  out.flags.push_back(vet::staticSourceFlag(out.trackSnr, out.skySnr));
  static const std::vector<vet::KnownObject> kNone;
  const auto& objects = in.knownObjects ? *in.knownObjects : kNone;
  if (in.skyPosition) {
    out.flags.push_back(vet::knownObjectFlag(objects, in.skyPosition->first, in.skyPosition->second,
                                             cube.frames.tRefMjd(), in.knownObjectRadiusArcsec));
  } else {
    out.flags.push_back(vet::ArtifactFlag{vet::ArtifactKind::KnownObject, false, -1.0,
                                          objects.empty() ? "no known-object list loaded"
                                                          : "the frames have no WCS: the candidate "
                                                            "cannot be placed on the sky"});
  }
  return out;
}

}  // namespace st::candidate
