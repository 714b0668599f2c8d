#pragma once
// Typed exceptions thrown by the core (ARCHITECTURE.md, "Threads, errors, memory"). Every message names the
// file, HDU, keyword or value at fault, so the GUI can show it and the CLI can print it unchanged.
#include <stdexcept>
#include <string>

namespace st {

/// Base of every error the core throws on purpose.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Bad input from the user: a missing file, a wrong parameter, inconsistent frames. CLI exit code 1.
class InputError : public Error {
 public:
  using Error::Error;
};

/// A FITS file could not be read or written; the message carries CFITSIO's own text.
class FitsError : public InputError {
 public:
  using InputError::InputError;
};

/// A CUDA call failed; callers fall back to the CPU backend and say so.
class GpuError : public Error {
 public:
  using Error::Error;
};

/// Thrown by long work when its CancelToken was cancelled. Not an error to report, just a stop.
class Cancelled : public Error {
 public:
  Cancelled() : Error("cancelled") {}
};

}  // namespace st
