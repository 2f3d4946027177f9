// The friction-identify command line (contract: shared/design/cli.md).
#pragma once

#include <functional>
#include <iosfwd>
#include <string>
#include <utility>
#include <vector>

#include "friction/csv.hpp"
#include "friction/model_io.hpp"

namespace friction::cli {

/// Exit statuses of the contract.
inline constexpr int kExitOk = 0;
inline constexpr int kExitData = 1;   ///< bad data, or no result could be produced
inline constexpr int kExitUsage = 2;  ///< bad usage

/// Runs the command line; returns the exit status.  Never throws.
int run(int argc, char** argv);

/// Options every command that reads a record shares.
struct InputOptions {
  std::string columns;              ///< --columns
  std::string units;                ///< --units
  std::string force_sign = "auto";  ///< --force-sign
};

/// Output options (--format, --out).
struct OutputOptions {
  std::string format = "table";  ///< "table" or "json"
  std::string out;               ///< --out FILE ("" = stdout)
};

/// ReadOptions from the command-line strings (OptionError on bad values).
ReadOptions read_options(const InputOptions& in, bool require_force);

/// Reads a record; DataError on bad data.
Record load_record(const std::string& path, const InputOptions& in, bool require_force);

/// Reads an estimation and a validation record (both with force) on two threads: reading and
/// conditioning (the derivative-window rule) take tens of milliseconds per 10,000 samples, a
/// tenth of a fit.  The estimation record's error is the one reported when both are bad, as
/// when they were read one after the other.
std::pair<Record, Record> load_record_pair(const std::string& estimation,
                                           const std::string& validation, const InputOptions& in);

/// Loads a model file; DataError (exit 1) for a malformed file or values outside their domain.
AnyModel load_model(const std::string& path);

/// Writes `text` to `out.out` atomically, or to stdout.
void emit(const OutputOptions& out, const std::string& text);
/// The same for output written piece by piece (a CSV of a million samples is not built in memory
/// first): `write` streams to stdout or, with --out, to the atomically replaced file.
void emit_stream(const OutputOptions& out, const std::function<void(std::ostream&)>& write);

/// Table output: with --out the table goes to stdout and the file gets the JSON document (what a
/// script or `simulate --model-file` loads); without it the table goes to stdout.
void emit_table(const OutputOptions& out, const std::string& table, const Json& document);

/// A JSON document with the keys every document carries (schema_version, warnings).
Json new_document(const std::string& command);

/// Prints each warning to stderr ("warning: ...") and appends it to the document's list.
void add_warnings(Json& document, const std::vector<std::string>& warnings);

}  // namespace friction::cli
