#pragma once
// Known objects (issue 8): a list the user loads (CSV: name, RA, Dec and rates at an epoch), propagated
// linearly to the candidate's epoch and matched on the sky within a radius. Linear motion is good over the
// hours an observation spans; for days, give an epoch close to the observation (an ephemeris service's).
#include <optional>
#include <string>
#include <vector>

#include "st/vet/artifacts.hpp"

namespace st::vet {

struct KnownObject {
  std::string name;
  double raDeg = 0.0;  ///< ICRS, at epochMjd
  double decDeg = 0.0;
  double raRateArcsecPerMin = 0.0;   ///< dRA/dt * cos(Dec), arcsec/min (the convention of ephemeris services)
  double decRateArcsecPerMin = 0.0;  ///< dDec/dt, arcsec/min
  double epochMjd = 0.0;             ///< UTC
};

/// Reads a CSV with a header line naming the columns (any order, case-insensitive; other columns ignored):
///   name, ra_deg, dec_deg, epoch_mjd, and the rates either as ra_rate_arcsec_min, dec_rate_arcsec_min
///   (RA rate times cos Dec) or as ra_rate_deg_day, dec_rate_deg_day.
/// Blank lines and lines starting with '#' are skipped; a field may be quoted with "". Throws
/// st::InputError naming the file, line and column at fault (missing column, not a number, |Dec| > 90).
[[nodiscard]] std::vector<KnownObject> readKnownObjects(const std::string& path);

/// Position of `object` at `mjd`, moving linearly on the sky from its epoch: Dec += rate dt, RA += RA rate
/// dt / cos(Dec at mid-interval); RA wrapped to [0, 360).
struct SkyPosition {
  double raDeg = 0.0;
  double decDeg = 0.0;
};
[[nodiscard]] SkyPosition propagate(const KnownObject& object, double mjd) noexcept;

/// Great-circle separation (haversine, stable at small angles), arcsec.
[[nodiscard]] double separationArcsec(double ra1Deg, double dec1Deg, double ra2Deg, double dec2Deg) noexcept;

struct KnownObjectMatch {
  const KnownObject* object = nullptr;  ///< into the list given
  SkyPosition predicted;                ///< at the candidate's epoch
  double separationArcsec = 0.0;
};
/// The nearest object to (raDeg, decDeg) at `mjd` within `radiusArcsec`, or nullopt.
[[nodiscard]] std::optional<KnownObjectMatch> matchKnownObject(const std::vector<KnownObject>& objects,
                                                               double raDeg, double decDeg, double mjd,
                                                               double radiusArcsec);

/// The known-object artifact flag: fires when an object lies within `radiusArcsec`; value = separation to
/// the nearest object (arcsec), or -1 when the list is empty.
[[nodiscard]] ArtifactFlag knownObjectFlag(const std::vector<KnownObject>& objects, double raDeg,
                                           double decDeg, double mjd, double radiusArcsec);

}  // namespace st::vet
