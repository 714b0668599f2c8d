// libFuzzer target for the FITS reader: the input bytes are written to a temporary file and loaded with
// loadFrames and summarizeInputs (headers, times, WCS, pixels). Anything but an st::Error is a bug, and so is
// any sanitizer report. Build: CC=clang CXX=clang++ cmake -DST_FUZZ=ON ...; ninja fuzz_fits_reader;
// run: ./fuzz_fits_reader -max_total_time=300 -max_len=65536 corpus-copy/ ../tests/fuzz/corpus
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "st/common/error.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/sections.hpp"
#include "st/io/wcs.hpp"

namespace {

std::string tempPath() {
  const char* dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
  return std::string(dir) + "/st-fuzz-" + std::to_string(getpid()) + ".fits";
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  setenv("ST_THREADS", "1", 1);  // deterministic, and faster for tiny inputs
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::string path = tempPath();
  if (std::FILE* f = std::fopen(path.c_str(), "wb")) {
    std::fwrite(data, 1, size, f);
    std::fclose(f);
  } else {
    return 0;
  }
  st::io::LoadOptions options;
  options.startMjd = 60000.0;  // so that frames without times still reach the pixel reader
  options.frameRateHz = 10.0;
  st::NullProgress progress;
  st::CancelToken cancel;
  try {
    (void)st::io::summarizeInputs({path}, options);
  } catch (const st::Error&) {
  }
  try {
    const st::FrameCube cube = st::io::loadFrames({path}, options, progress, cancel);
    if (cube.wcs) {
      (void)cube.wcs->toHeader();
      try {
        (void)cube.wcs->pixelToSky(0.0, 0.0);
      } catch (const st::Error&) {
      }
    }
    for (const char* key : {"TRIMSEC", "BIASSEC", "DATASEC"}) {
      try {
        (void)st::io::sectionFromHeader(cube.header, key);
      } catch (const st::Error&) {
      }
    }
  } catch (const st::Error&) {
  }
  return 0;
}
