// Reading and writing records as CSV (cli.md, "Inputs").
//
// Format read: UTF-8 text, one header row naming the columns, then one row per sample.  Columns are
// found by header name, case-insensitively (time: time, t, time_s; displacement: displacement,
// position, x, position_m; force: force, friction, f, friction_force_n; optional normal force:
// normal, normal_force, normal_force_n), or named explicitly (`--columns`).  Other columns are
// ignored (their cells are not even parsed).  Values are SI unless `--units` says otherwise.
//
// Read as intended (harmless quirks): a UTF-8 byte-order mark; CRLF (or CR) line ends; quoted
// header names and quoted cells ("" inside quotes is a quote); spaces or tabs around cells;
// extra or reordered columns; blank lines at the end (and before the header); `;` or tab as the
// separator when the header row has no comma; a leading `+` on numbers.
//
// Refused with a DataError whose message is one line "FILE:LINE:COLUMN: what, expected what"
// (COLUMN is the 1-based CSV column): empty file; no header (first row all numbers); a required
// column missing (the accepted names are listed) or two columns claiming one role; a cell that is
// not a number as a whole (std::from_chars, strict), empty, NaN or Inf, or beyond the range of a
// double (1e999); a row with the wrong number of cells; a blank line between data rows; time not
// strictly increasing; fewer than `min_samples` samples; no motion (constant displacement); NUL
// bytes, other control characters or invalid UTF-8 (binary data).
//
// After reading, the record is conditioned (signals.hpp): force sign, sampling, resolution, noise.
//
// Writing: numbers in the shortest form that reads back to the same double (std::to_chars), so
// write -> read is exact; files are replaced atomically (atomic_file.hpp).
#pragma once

#include <cstddef>
#include <filesystem>
#include <iosfwd>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "friction/error.hpp"
#include "friction/record.hpp"
#include "friction/signals.hpp"

namespace friction {

/// Header names chosen explicitly for each signal; an empty name means "find it by its aliases".
struct ColumnMapping {
  std::string time, displacement, force, normal;
};

/// Parses "time=NAME,displacement=NAME,force=NAME[,normal=NAME]" (any subset, any order; keys
/// case-insensitive, names as in the header).  Throws OptionError.
ColumnMapping parse_column_mapping(std::string_view spec);

/// Factors that convert each column to SI (value_SI = value_file * factor).
struct Units {
  double time = 1.0;          ///< s, ms, us (µs), ns, min, h
  double displacement = 1.0;  ///< m, cm, mm, um (µm), nm
  double force = 1.0;         ///< N, kN, mN, uN (µN), nN
  double normal = 1.0;        ///< as force
};

/// Parses "displacement=mm,force=uN,time=ms,normal=N" (any subset; unit symbols case-sensitive,
/// `u`, `µ` and `μ` all mean micro).  Throws OptionError naming the accepted units.
Units parse_units(std::string_view spec);

/// Factor to SI of `unit` for `quantity` ("time", "displacement", "force" or "normal").
/// Throws OptionError.
double unit_factor(std::string_view quantity, std::string_view unit);

/// Parses `--force-sign`: "auto", "+1"/"1"/"positive", "-1"/"negative".  Throws OptionError.
ForceSign parse_force_sign(std::string_view text);

/// Fewest samples a record may have (an identification needs a few intervals at least).
inline constexpr std::size_t kMinSamples = 10;

struct ReadOptions {
  ColumnMapping columns;
  Units units;
  bool require_force = true;   ///< false for `simulate`: the force column may be absent
  bool require_motion = true;  ///< refuse a record whose displacement is constant
  ForceSign force_sign = ForceSign::automatic;
  std::size_t min_samples = kMinSamples;
  double period_tolerance = kDefaultPeriodTolerance;  ///< relative, for the irregular-sampling rule
};

/// Reads and conditions the CSV file at `path`; messages name the file as given.  Conditioning
/// may replace an encoder's staircase by the estimate the models see (Record::displacement), the
/// values as read then being Record::measured().
/// Throws DataError (also when the file cannot be opened).
Record read_record(const std::filesystem::path& path, const ReadOptions& options = {});

/// Reads and conditions CSV text from a stream; `name` stands for the file in messages.
Record read_record(std::istream& in, const std::string& name, const ReadOptions& options = {});

/// Reads and conditions CSV text held in memory; `name` stands for the file in messages.
Record read_record_text(std::string_view text, const std::string& name,
                        const ReadOptions& options = {});

/// Shortest decimal form of `value` that reads back as the same double ("0.1", "1e-07", "-0").
std::string format_double(double value);

/// One output column: a header name and its values (all columns of one table equally long).
struct CsvColumn {
  std::string name;
  std::span<const double> values;
};

/// Writes a header row and one row per sample; throws InvalidParameter on unequal lengths.
void write_csv(std::ostream& out, std::span<const CsvColumn> columns);

/// write_csv to `path`, atomically (throws FileError on I/O failure).
void write_csv_file(const std::filesystem::path& path, std::span<const CsvColumn> columns);

/// The record's signals as columns time,displacement[,force][,normal] (SI, model convention); the
/// displacement as measured (Record::measured), not the estimate the models see.
std::vector<CsvColumn> record_columns(const Record& record);

/// Writes the record as CSV; reading it back gives the same numbers exactly.
void write_record_csv(std::ostream& out, const Record& record);

/// Writes the record as CSV to `path`, atomically.
void write_record_csv(const std::filesystem::path& path, const Record& record);

}  // namespace friction
