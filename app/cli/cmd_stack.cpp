// synthtrack-cli stack INPUT... --vx-px-s VX --vy-px-s VY [--csa] [--filtered] [--fwhm F] -o stack.fits:
// the synthetic-tracking stack of the frames at one velocity (IPSA, or CSA with --csa), optionally of the
// matched-filtered frames, written as a 2-D FITS image with provenance cards.
#include <algorithm>
#include <cstdio>
#include <string>

#include "cli_args.hpp"
#include "commands.hpp"
#include "load_args.hpp"
#include "st/common/error.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/fits_writer.hpp"
#include "st/io/wcs.hpp"
#include "st/pipeline/prepared_cube.hpp"
#include "st/psf/psf_star.hpp"
#include "st/stack/csa.hpp"
#include "st/stack/ipsa.hpp"
#include "st/stack/matched_filter.hpp"
#include "terminal_progress.hpp"

namespace st::app {
namespace {

constexpr const char* kHelp =
    "usage: synthtrack-cli stack INPUT... --vx-px-s VX --vy-px-s VY -o STACK.fits [options]\n\n"
    "Shift-and-add of the frames at one velocity (px/s), positions at the reference epoch t_ref (mean of\n"
    "the frame mid-times). INPUT should be zero-biased frames (e.g. from `preprocess`).\n\n"
    "  -o STACK.fits        output: the sum S(x, y) (overwritten)\n"
    "  --vx-px-s VX         velocity along x (columns), px/s\n"
    "  --vy-px-s VY         velocity along y (rows), px/s\n"
    "  --csa                continuous (sub-pixel, Fourier) shifts instead of whole-pixel IPSA shifts\n"
    "  --filtered           stack the matched-filtered frames (PSF from --fwhm, else from the header of a\n"
    "                       cube written by `preprocess` (PSFFWHM, PSFBETA), else fitted on a star of the\n"
    "                       zero-velocity stack); a cube that is already filtered (STFILT = T) is not\n"
    "                       filtered again\n"
    "  --fwhm F             PSF FWHM in px for the matched filter (Moffat, beta from --beta)\n"
    "  --beta B             Moffat beta with --fwhm (default: the header's PSFBETA, else 4, the paper's)\n"
    "  --nin NIN.fits       also write N_in(x, y), the frames that contributed to each pixel\n"
    "%s";

/// The PSF for the matched filter: the user's FWHM; else the PSF in the header of a cube written by
/// `preprocess` (PSFFWHM, PSFBETA); else a Moffat fit on the best star of the sum of the frames (which finds
/// none in a pre-processed cube: its stars are zeroed).
psf::Moffat choosePsf(const CliArgs& cli, const FrameCube& cube,
                      const std::optional<pipeline::PreparedHeader>& prepared) {
  if (const auto fwhm = cli.number("fwhm")) {
    const double beta = cli.number("beta", prepared && prepared->psf ? prepared->psf->beta : 4.0);
    if (!(*fwhm > 0.0) || !(beta > 1.0))
      throw UsageError("--fwhm must be > 0 and --beta > 1 (got " + std::to_string(*fwhm) + ", " +
                       std::to_string(beta) + ")");
    return psf::Moffat::fromFwhm(*fwhm, beta);
  }
  if (prepared && prepared->psf) {
    std::fprintf(stderr, "PSF: Moffat R = %.3f px, beta = %.3f, FWHM = %.3f px (header of %s)\n",
                 prepared->psf->radius, prepared->psf->beta, prepared->psf->fwhm(),
                 pipeline::cubeSource(cube).c_str());
    return *prepared->psf;
  }
  const stack::StackResult still = stack::stackIpsa(cube, Velocity{0.0, 0.0});
  const psf::PsfMeasurement m = psf::measurePsf(still.sum, {});
  std::fprintf(stderr,
               "PSF: Moffat R = %.3f px, beta = %.3f, FWHM = %.3f +- %.3f px (star at %.1f, %.1f; %s)\n",
               m.fit.model.radius, m.fit.model.beta, m.fit.fwhm(), m.fit.sigmaFwhm, m.fit.x0, m.fit.y0,
               psf::toString(m.fit.convergence).c_str());
  return m.fit.model;
}

}  // namespace

int cmdStack(const Args& args) {
  if (!args.empty() && args[0] == "--help") {
    std::printf(kHelp, loadOptionsHelp());
    return 0;
  }
  auto names = loadOptionNames();
  names.insert({"o", "vx-px-s", "vy-px-s", "fwhm", "beta", "nin"});
  const CliArgs cli(args, names, {"csa", "filtered"});
  if (cli.positionals().empty()) throw UsageError("give at least one INPUT (a FITS file or a folder)");
  const auto out = cli.value("o");
  if (!out) throw UsageError("give the output file with -o STACK.fits");
  const auto vx = cli.number("vx-px-s"), vy = cli.number("vy-px-s");
  if (!vx || !vy) throw UsageError("give the velocity with --vx-px-s VX --vy-px-s VY (pixels per second)");
  if (cli.has("fwhm") && !cli.flag("filtered")) throw UsageError("--fwhm is used only with --filtered");
  const Velocity v{*vx, *vy};

  TerminalProgress progress;
  CancelToken& cancel = processCancelToken();
  FrameCube cube = io::loadFrames(cli.positionals(), loadOptionsFromArgs(cli), progress, cancel);
  FitsHeader params;
  params.setNumber("VX_PXS", v.vx, "stack velocity x, px/s");
  params.setNumber("VY_PXS", v.vy, "stack velocity y, px/s");
  params.setNumber("REFEPOCH", cube.tRefMjd(), "t_ref, MJD (UTC): mean of the frame mid-times");
  params.setNumber("MJD-AVG", cube.tRefMjd(), "epoch of the stack's positions (t_ref), MJD (UTC)");
  params.setString("STKMODE", cli.flag("csa") ? "CSA" : "IPSA", "shift-and-add method");
  params.setNumber("NFRAMES", double(cube.frameCount()), "frames in the input");
  const auto prepared = pipeline::recognisePreparedHeader(cube.header, pipeline::cubeSource(cube));
  const bool alreadyFiltered = prepared && prepared->state == pipeline::PreparedState::Filtered;
  params.set("FILTERED", cli.flag("filtered") || alreadyFiltered ? "T" : "F",
             "frames matched-filtered before stacking");
  if (cli.flag("filtered") && alreadyFiltered) {
    if (cli.has("fwhm")) {
      throw UsageError("--fwhm: " + pipeline::cubeSource(cube) + " is already matched-filtered (" +
                       prepared->evidence + "); it is not filtered again");
    }
    std::fprintf(stderr, "note: %s is already matched-filtered (%s): stacked as is\n",
                 pipeline::cubeSource(cube).c_str(), prepared->evidence.c_str());
    if (prepared->psf) {
      params.setNumber("PSFFWHM", prepared->psf->fwhm(), "matched-filter PSF FWHM, px");
      params.setNumber("PSFBETA", prepared->psf->beta, "matched-filter Moffat beta");
    }
    if (prepared->sigmaF) params.setNumber("SIGMAF", *prepared->sigmaF, "noise of one filtered frame");
  } else if (cli.flag("filtered")) {
    const psf::Moffat psfModel = choosePsf(cli, cube, prepared);
    const stack::FilterKernel kernel = stack::makeFilterKernel(psfModel);
    const stack::MatchedFilterResult f = stack::filterCube(cube, kernel, progress, cancel);
    params.setNumber("PSFFWHM", psfModel.fwhm(), "matched-filter PSF FWHM, px");
    params.setNumber("PSFBETA", psfModel.beta, "matched-filter Moffat beta");
    params.setNumber("SIGMAF", f.sigmaF, "robust noise of one filtered frame");
  }
  const stack::StackResult s =
      cli.flag("csa") ? stack::stackCsa(cube, v, progress, cancel) : stack::stackIpsa(cube, v);
  FitsHeader header = io::provenanceCards("stack", params);
  if (cube.wcs)
    for (const auto& c : cube.wcs->toHeader().cards)
      header.cards.push_back(c);
  io::writeImage(*out, s.sum, header);
  if (const auto nin = cli.value("nin")) {
    Image counts(s.sum.width, s.sum.height);
    std::copy(s.nIn.begin(), s.nIn.end(), counts.pixels.begin());
    io::writeImage(*nin, counts, header);
  }
  progress.finish();
  for (const auto& w : cube.warnings)
    std::fprintf(stderr, "warning: %s\n", w.c_str());
  const auto maxIn = s.nIn.empty() ? 0 : *std::max_element(s.nIn.begin(), s.nIn.end());
  std::printf(
      "wrote %s: %s stack of %zu frames (%d x %d px) at v = (%g, %g) px/s, t_ref = MJD %.8f, max N_in %d\n",
      out->c_str(), cli.flag("csa") ? "CSA" : "IPSA", cube.frameCount(), cube.width(), cube.height(), v.vx,
      v.vy, s.tRefMjd, int(maxIn));
  return 0;
}

}  // namespace st::app
