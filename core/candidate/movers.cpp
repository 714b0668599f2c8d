#include "st/candidate/movers.hpp"

#include <cmath>
#include <cstdio>

namespace st::candidate {

std::vector<search::Candidate> moverCandidates(const std::vector<detect::MovingSource>& movers,
                                               const std::vector<search::Candidate>& existing, int frames,
                                               double matchPx, double matchVPxS) {
  std::vector<search::Candidate> out;
  for (const detect::MovingSource& m : movers) {
    if (!m.moving) continue;
    bool known = false;
    for (const search::Candidate& c : existing)
      known = known || (std::hypot(c.x - m.x, c.y - m.y) <= matchPx &&
                        std::hypot(c.v.vx - m.v.vx, c.v.vy - m.v.vy) <= matchVPxS);
    if (known) continue;
    search::Candidate c;
    c.x = static_cast<int>(std::lround(m.x));
    c.y = static_cast<int>(std::lround(m.y));
    c.v = m.v;
    c.snr = m.snr;
    c.nIn = frames;
    c.fap = 1.0;
    c.clusterCells = kMoverClusterCells;
    out.push_back(c);
  }
  return out;
}

std::string moverNote(const detect::MovingSource& mover) {
  char text[200];
  std::snprintf(text, sizeof text,
                "pre-processing mover: shift %.1f px (%.1f sigma) between the first and last thirds, SNR %.1f "
                "in the sky-rate stack",
                mover.shiftPx, mover.shiftSigmaPx > 0 ? mover.shiftPx / mover.shiftSigmaPx : 0.0, mover.snr);
  return text;
}

}  // namespace st::candidate
