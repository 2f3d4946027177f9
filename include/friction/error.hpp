// Typed errors and checks that stay on in release builds.
//
// Following Sophus/manif: a violated precondition that depends on user data (a negative
// stiffness, a record with no motion) throws a typed exception in every build type, so a
// controller or a script gets a message instead of a NaN.  `FRICTION_ASSERT` is for internal
// invariants only and vanishes under NDEBUG.
#pragma once

#include <cassert>
#include <filesystem>
#include <sstream>
#include <stdexcept>
#include <string>

namespace friction {

/// Base of every error the library throws.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A model parameter outside its physical domain (e.g. a threshold <= 0).
class InvalidParameter : public Error {
 public:
  using Error::Error;
};

/// Input data that cannot be used; carries where in the file the problem is.
class DataError : public Error {
 public:
  DataError(std::string file, long line, long column, const std::string& what)
      : Error(format(file, line, column, what)),
        file_(std::move(file)),
        line_(line),
        column_(column) {}
  const std::string& file() const noexcept { return file_; }
  long line() const noexcept { return line_; }      ///< 1-based, 0 when not applicable
  long column() const noexcept { return column_; }  ///< 1-based, 0 when not applicable

 private:
  static std::string format(const std::string& file, long line, long column,
                            const std::string& what) {
    std::ostringstream s;
    s << (file.empty() ? "<input>" : file);
    if (line > 0) s << ":" << line;
    if (column > 0) s << ":" << column;
    s << ": " << what;
    return s.str();
  }
  std::string file_;
  long line_;
  long column_;
};

/// The numerics failed: no convergence, a singular problem, an integrator error.
class NumericalError : public Error {
 public:
  using Error::Error;
};

/// A malformed option value (`--columns`, `--units`, `--force-sign`): a usage error (exit 2).
class OptionError : public Error {
 public:
  using Error::Error;
};

/// A file could not be written (or read, outside of the data checks): names the file and the cause.
class FileError : public Error {
 public:
  FileError(const std::filesystem::path& file, const std::string& what)
      : Error(file.string() + ": " + what), file_(file) {}
  const std::filesystem::path& file() const noexcept { return file_; }

 private:
  std::filesystem::path file_;
};

namespace detail {
// The message is for the user of a tool or a controller: it says what is wrong with which value,
// without the source location (which a debugger gives).
template <class E, class... Args>
[[noreturn]] void throw_with_message(const Args&... args) {
  std::ostringstream s;
  (s << ... << args);
  throw E(s.str());
}
}  // namespace detail

}  // namespace friction

/// Always-on check: throws `ErrorType` with the streamed message when `cond` is false.
#define FRICTION_CHECK_AS(ErrorType, cond, ...)                                  \
  do {                                                                           \
    if (!(cond)) ::friction::detail::throw_with_message<ErrorType>(__VA_ARGS__); \
  } while (false)

/// Always-on parameter check (throws friction::InvalidParameter).
#define FRICTION_CHECK(cond, ...) FRICTION_CHECK_AS(::friction::InvalidParameter, cond, __VA_ARGS__)

/// Debug-only internal invariant.
#define FRICTION_ASSERT(cond) assert(cond)
