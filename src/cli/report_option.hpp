// --report FILE.html on identify, validate, compare and diagnose: the option, the early check of
// its path, and the run information the report ends with (report_pages.hpp builds the pages).
#pragma once

#include <CLI/CLI.hpp>

#include <string>

#include "friction/report_pages.hpp"

namespace friction::cli {

/// Remembers the command line (called once by run()).
void set_command_line(int argc, char** argv);

/// The command line and the version, for a report.
report::RunInfo run_info();

/// Adds --report FILE to a subcommand.
void add_report_option(CLI::App& command, std::string& path);

/// Refuses (OptionError, exit 2) a --report path whose directory does not exist or that names a
/// directory, before any work is done: a run of minutes should not end in "cannot write".
void check_report_path(const std::string& path);

/// Writes the report atomically (nothing is left half-written when it fails).
void write_report_file(const std::string& path, const report::Document& document);

}  // namespace friction::cli
