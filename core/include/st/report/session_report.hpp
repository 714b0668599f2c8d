#pragma once
// Reports from a session: the candidates a person labelled real become astrometric detections (ADES / MPC),
// every candidate becomes a DS9 mark coloured by its label.
#include <string>
#include <vector>

#include "st/report/mpc_submission.hpp"
#include "st/report/regions.hpp"
#include "st/session/session.hpp"

namespace st::report {

/// The detections of the candidates labelled real, in session order. A candidate contributes when its
/// accepted fit converged and has a sky position (astro::skyMeasurement at t_ref, as the demo and GUI write).
/// With TrackletPositions::Segments, one detection per segment position on the sky (the fit's segment check:
/// each at its segment's mean time, with its own SNR and sigmas) when there are two or more; else, and with
/// TrackletPositions::Fit, the one whole-fit position: epoch the fit's t_ref_mjd, else the search's
/// t_ref_mjd; SNR the fit's; sigmas from sigma_ra_arcsec/sigma_dec_arcsec, else sigma_x_px/sigma_y_px times
/// the plate scale; magnitude and band the fit's. trkSub = `prefix` + the 1-based candidate number,
/// zero-padded to 7 characters, the same for all of one object's positions. A real candidate that is not
/// reported, or is reported with one position where segments were asked for, adds a warning naming why.
[[nodiscard]] std::vector<AstrometricDetection> realDetections(const session::Session& session,
                                                               TrackletPositions positions,
                                                               std::vector<std::string>& warnings,
                                                               const std::string& prefix = "st");

/// The session's sky rate (its search's "sky_rate", px/s; zero when absent).
[[nodiscard]] Velocity sessionSkyRate(const session::Session& session);

/// One DS9 mark per candidate at its fitted position (else its search cell), radius 2 PSF FWHM (5 px when
/// unknown), with its velocity (and the session's sky rate, for a track on the sky) as a track line over the
/// observation's span when it is known, coloured by label (real green, artifact red, unsure yellow, unvetted
/// cyan), text "#N SNR s label".
[[nodiscard]] std::vector<RegionMark> regionMarks(const session::Session& session, double trackStartS = 0.0,
                                                  double trackEndS = 0.0);

}  // namespace st::report
