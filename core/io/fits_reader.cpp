// loadFrames: plan from the headers (load_plan.cpp), then read the pixels in parallel with one CFITSIO handle
// per job (a 2-D file, or a run of planes of a cube), straight into the cube's memory.
#include "st/io/fits_reader.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>

#include "fits_file.hpp"
#include "load_plan.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/common/units.hpp"
#include "st/io/sections.hpp"
#include "st/io/wcs.hpp"

namespace st::io {
namespace {

using detail::describeFrame;
using detail::FitsFile;
using detail::LoadPlan;
using detail::PlaneRef;
using detail::ScannedFile;

// Fraction of the progress bar given to reading headers.
constexpr double kScanShare = 0.05;

struct ReadJob {
  std::size_t fileIndex = 0;
  std::vector<std::pair<int, std::size_t>> planes;  // (plane, destination frame index)
};

std::vector<ReadJob> makeJobs(const LoadPlan& plan) {
  std::vector<std::vector<std::pair<int, std::size_t>>> perFile(plan.files.size());
  for (std::size_t n = 0; n < plan.frames.size(); ++n) {
    perFile[plan.frames[n].fileIndex].emplace_back(plan.frames[n].plane, n);
  }
  // Cubes are split into runs of planes so that one big file still loads on every core.
  const std::size_t runLength = std::max<std::size_t>(8, plan.frames.size() / (4 * workerCount()) + 1);
  std::vector<ReadJob> jobs;
  for (std::size_t f = 0; f < perFile.size(); ++f) {
    auto& list = perFile[f];
    std::sort(list.begin(), list.end());
    for (std::size_t b = 0; b < list.size(); b += runLength) {
      ReadJob job;
      job.fileIndex = f;
      job.planes.assign(list.begin() + static_cast<long>(b),
                        list.begin() + static_cast<long>(std::min(list.size(), b + runLength)));
      jobs.push_back(std::move(job));
    }
  }
  return jobs;
}

// Reads one plane (the plan's region of it) as float into `out`; `flags` gets 1 for BLANK/NaN pixels.
bool readPlane(const FitsFile& f, const ScannedFile& s, int plane, const PixelRegion& r, float* out,
               std::vector<char>& flags) {
  int status = 0;
  int anyNull = 0;
  const std::size_t n = static_cast<std::size_t>(r.width) * static_cast<std::size_t>(r.height);
  flags.assign(n, 0);
  const bool whole = r.x0 == 0 && r.y0 == 0 && r.width == s.width && r.height == s.height;
  if (whole) {
    long fpix[9] = {1, 1, plane + 1, 1, 1, 1, 1, 1, 1};
    fits_read_pixnull(f.get(), TFLOAT, fpix, static_cast<LONGLONG>(n), out, flags.data(), &anyNull, &status);
  } else {
    long naxes[3] = {s.width, s.height, s.planes};
    long blc[3] = {r.x0 + 1, r.y0 + 1, plane + 1};
    long trc[3] = {r.x0 + r.width, r.y0 + r.height, plane + 1};
    long inc[3] = {1, 1, 1};
    fits_read_subsetnull_flt(f.get(), 1, 3, naxes, blc, trc, inc, out, flags.data(), &anyNull, &status);
  }
  f.check(status, "reading the pixels of plane " + std::to_string(plane + 1));
  if (anyNull == 0) return false;
  for (std::size_t i = 0; i < n; ++i) {
    if (flags[i] != 0) out[i] = 0.0f;
  }
  return true;
}

// Converts big-endian IEEE floats in place. NaN and Inf become masked zeros and denormals zeros, as CFITSIO
// does for its null checks. Returns true when a pixel was masked (flags then hold the mask).
bool swapFloats(float* out, std::size_t n, std::vector<char>& flags) {
  bool anyNull = false;
  for (std::size_t i = 0; i < n; ++i) {
    std::uint32_t v;
    std::memcpy(&v, out + i, 4);
    v = __builtin_bswap32(v);
    std::memcpy(out + i, &v, 4);
    anyNull |= (v & 0x7f800000u) == 0x7f800000u;
  }
  if (!anyNull) return false;
  flags.assign(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint32_t v;
    std::memcpy(&v, out + i, 4);
    if ((v & 0x7f800000u) == 0x7f800000u) {
      flags[i] = 1;
      out[i] = 0.0f;
    }
  }
  return true;
}

// A plain file opened with POSIX for the direct float32 path.
class RawFile {
 public:
  explicit RawFile(const std::string& path) : m_path(path), m_fd(::open(path.c_str(), O_RDONLY | O_CLOEXEC)) {
    if (m_fd < 0) throw InputError(path + ": cannot open: " + std::strerror(errno));
  }
  ~RawFile() { ::close(m_fd); }
  RawFile(const RawFile&) = delete;
  RawFile& operator=(const RawFile&) = delete;
  void read(void* dst, std::size_t bytes, long long offset, int hdu, int plane) const {
    auto* p = static_cast<char*>(dst);
    while (bytes > 0) {
      const ssize_t got = ::pread(m_fd, p, bytes, offset);
      if (got <= 0) {
        throw FitsError(m_path + " HDU " + std::to_string(hdu) + ": reading the pixels of plane " +
                        std::to_string(plane + 1) + ": " +
                        (got == 0 ? std::string("file ends early (truncated)") : std::strerror(errno)));
      }
      p += got;
      bytes -= static_cast<std::size_t>(got);
      offset += got;
    }
  }

 private:
  std::string m_path;
  int m_fd;
};

void readJob(const LoadPlan& plan, const ReadJob& job, FrameCube& cube,
             std::vector<std::vector<std::uint8_t>>& masks, const std::function<void()>& frameDone,
             CancelToken& cancel) {
  const ScannedFile& s = plan.files[job.fileIndex];
  std::vector<char> flags;
  const PixelRegion& r = plan.region;
  if (s.rawFloatOffset >= 0) {
    // Plain float32: the region's rows straight from the file (one read for full-width rows, else one per
    // row), byte-swapped here. Crops and out-of-core tiles read as fast as whole frames (CFITSIO's subset
    // reader took 3x the CPU time, issue 20).
    RawFile f(s.path);
    const std::size_t n = cube.framePixels();
    const long long planeBytes = 4LL * s.width * s.height;
    const bool fullRows = r.x0 == 0 && r.width == s.width;
    for (const auto& [plane, dest] : job.planes) {
      cancel.throwIfCancelled();
      float* out = cube.frame(dest);
      const long long base = s.rawFloatOffset + static_cast<long long>(plane) * planeBytes;
      if (fullRows) {
        f.read(out, n * 4, base + 4LL * r.y0 * s.width, s.hdu, plane);
      } else {
        for (int y = 0; y < r.height; ++y)
          f.read(out + static_cast<std::size_t>(y) * r.width, static_cast<std::size_t>(r.width) * 4,
                 base + 4LL * ((static_cast<long long>(r.y0) + y) * s.width + r.x0), s.hdu, plane);
      }
      if (swapFloats(out, n, flags)) masks[dest].assign(flags.begin(), flags.end());
      frameDone();
    }
    return;
  }
  FitsFile f = FitsFile::openRead(s.path);
  int status = 0;
  fits_movabs_hdu(f.get(), s.hdu, nullptr, &status);
  f.check(status, "moving to the image HDU");
  for (const auto& [plane, dest] : job.planes) {
    cancel.throwIfCancelled();
    if (readPlane(f, s, plane, r, cube.frame(dest), flags)) masks[dest].assign(flags.begin(), flags.end());
    frameDone();
  }
}

void readPixels(const LoadPlan& plan, FrameCube& cube, ProgressSink& progress, CancelToken& cancel) {
  const std::vector<ReadJob> jobs = makeJobs(plan);
  const std::size_t total = plan.frames.size();
  std::vector<std::vector<std::uint8_t>> masks(total);
  std::atomic<std::size_t> done{0};
  const std::function<void()> frameDone = [&] {
    const std::size_t k = ++done;
    progress.report(kScanShare + (1.0 - kScanShare) * static_cast<double>(k) / static_cast<double>(total),
                    "loading frames");
  };
  parallelFor(jobs.size(), 1, [&](std::size_t b, std::size_t e) {
    for (std::size_t j = b; j < e; ++j)
      readJob(plan, jobs[j], cube, masks, frameDone, cancel);
  });
  if (std::any_of(masks.begin(), masks.end(), [](const auto& m) { return !m.empty(); })) {
    cube.mask().assign(cube.pixels().size(), 0);
    for (std::size_t n = 0; n < total; ++n) {
      if (!masks[n].empty()) {
        std::copy(masks[n].begin(), masks[n].end(),
                  cube.mask().begin() + static_cast<long>(n * cube.framePixels()));
      }
    }
  }
}

// The first frame's header, made to describe the loaded (possibly cropped) 2-D frame: a crop moves the WCS
// reference pixel and the image sections (st/io/sections.hpp, cropSections, which warns into `warnings`).
FitsHeader frameHeader(const LoadPlan& plan, std::vector<std::string>& warnings) {
  const ScannedFile& first = plan.files[plan.frames.front().fileIndex];
  FitsHeader h = first.header;
  if (plan.cropped) {
    cropSections(h, plan.region, first.path, warnings);
    for (int axis = 1; axis <= 2; ++axis) {
      const std::string key = "CRPIX" + std::to_string(axis);
      try {
        if (auto v = h.getDouble(key)) h.setNumber(key, *v - (axis == 1 ? plan.region.x0 : plan.region.y0));
      } catch (const InputError&) {
        // not a number: the WCS parser will reject it and warn
      }
    }
    h.setNumber("NAXIS1", plan.region.width);
    h.setNumber("NAXIS2", plan.region.height);
  }
  return h;
}

void attachWcs(FrameCube& cube, const LoadOptions& options) {
  cube.wcs = cubeWcs(cube.header, &cube.warnings);
  if (options.plateScaleArcsecPerPx && (options.forcePlateScale || !cube.wcs)) {
    cube.plateScaleArcsecPerPx = options.plateScaleArcsecPerPx;
  } else if (cube.wcs) {
    cube.plateScaleArcsecPerPx = cube.wcs->plateScaleArcsecPerPx();
  }
}

// The cube must fit in memory: a header (of a compressed file especially) can claim any size.
void checkMemory(const LoadPlan& plan) {
  const double bytes = static_cast<double>(plan.region.width) * plan.region.height * 4.0 *
                       static_cast<double>(plan.frames.size());
  const long pages = sysconf(_SC_PHYS_PAGES);
  const long pageSize = sysconf(_SC_PAGE_SIZE);
  const double physical =
      pages > 0 && pageSize > 0 ? static_cast<double>(pages) * static_cast<double>(pageSize) : 1e18;
  if (bytes > 0.9 * physical) {
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  "%zu frames of %d x %d px need %.1f GB as float32, more than this machine's %.1f GB",
                  plan.frames.size(), plan.region.width, plan.region.height, bytes / 1e9, physical / 1e9);
    throw InputError(describeFrame(plan, plan.frames.front()) + ": " + buf +
                     "; load fewer frames or --crop [x1:x2,y1:y2] to a smaller region");
  }
}

}  // namespace

std::shared_ptr<const Wcs> cubeWcs(const FitsHeader& header, std::vector<std::string>* warnings) {
  FitsHeader forWcs = header;
  forWcs.set("NAXIS", "2");
  forWcs.erase("NAXIS3");
  return Wcs::fromHeader(forWcs, warnings);
}

FrameCube loadFrames(const std::vector<std::string>& inputs, const LoadOptions& options,
                     ProgressSink& progress, CancelToken& cancel) {
  SubProgress scanProgress(progress, 0.0, kScanShare);
  LoadPlan plan = detail::planLoad(inputs, options, scanProgress, cancel);
  checkMemory(plan);
  // Every pixel of every frame is read below (or the load throws): no zero fill first.
  FrameCube cube = FrameCube::forOverwrite(plan.region.width, plan.region.height, plan.frames.size());
  readPixels(plan, cube, progress, cancel);
  for (std::size_t n = 0; n < plan.frames.size(); ++n) {
    const PlaneRef& p = plan.frames[n];
    const ScannedFile& s = plan.files[p.fileIndex];
    cube.info()[n] = FrameInfo{*p.mjdMid, p.exposureS.value_or(0.0), s.path, s.hdu, p.plane, p.offsetXPx,
                               p.offsetYPx};
  }
  cube.warnings = plan.warnings;
  cube.header = frameHeader(plan, cube.warnings);
  attachWcs(cube, options);
  return cube;
}

FrameCube loadFrames(const std::vector<std::string>& inputs) {
  NullProgress progress;
  CancelToken cancel;
  return loadFrames(inputs, LoadOptions{}, progress, cancel);
}

InputSummary summarizeInputs(const std::vector<std::string>& inputs, const LoadOptions& options) {
  NullProgress progress;
  CancelToken cancel;
  LoadPlan plan = detail::planLoad(inputs, options, progress, cancel);
  InputSummary s;
  const ScannedFile& first = plan.files[plan.frames.front().fileIndex];
  s.frames = plan.frames.size();
  s.width = plan.region.width;
  s.height = plan.region.height;
  s.bitpix = first.bitpix;
  s.hdu = first.hdu;
  s.timeSource = plan.timeSource;
  for (const auto& f : plan.frames)
    s.mjdMid.push_back(*f.mjdMid);
  s.firstMjd = s.mjdMid.front();
  s.lastMjd = s.mjdMid.back();
  if (s.frames > 1) {
    std::vector<double> d;
    for (std::size_t n = 1; n < s.mjdMid.size(); ++n)
      d.push_back((s.mjdMid[n] - s.mjdMid[n - 1]) * kSecondsPerDay);
    std::nth_element(d.begin(), d.begin() + static_cast<long>(d.size() / 2), d.end());
    s.medianCadenceS = d[d.size() / 2];
  }
  s.exposureS = plan.frames.front().exposureS.value_or(0.0);
  for (const auto& f : plan.files)
    s.files.push_back(f.path);
  s.warnings = plan.warnings;
  FitsHeader h = frameHeader(plan, s.warnings);
  h.set("NAXIS", "2");
  h.erase("NAXIS3");
  const auto wcs = Wcs::fromHeader(h, &s.warnings);
  s.hasWcs = wcs != nullptr;
  s.header = h;
  if (options.plateScaleArcsecPerPx && (options.forcePlateScale || !wcs)) {
    s.plateScaleArcsecPerPx = options.plateScaleArcsecPerPx;
  } else if (wcs) {
    s.plateScaleArcsecPerPx = wcs->plateScaleArcsecPerPx();
  }
  if (wcs) {
    char buf[200];
    try {
      const auto c = wcs->pixelToSky((s.width - 1) / 2.0, (s.height - 1) / 2.0);
      std::snprintf(buf, sizeof buf, "%s / %s, centre RA %.6f Dec %+.6f deg%s%s",
                    h.getString("CTYPE1").value_or("").c_str(), h.getString("CTYPE2").value_or("").c_str(),
                    c.raDeg, c.decDeg, wcs->hasSip() ? ", SIP" : "", wcs->hasTpv() ? ", TPV" : "");
      s.wcsDescription = buf;
    } catch (const InputError& e) {
      s.wcsDescription = e.what();
    }
  }
  return s;
}

}  // namespace st::io
