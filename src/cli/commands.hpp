// Registration and implementation of each friction-identify command.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>

#include "cli.hpp"

namespace friction::cli {

/// Each command adds its subcommand to `root` and returns the function that runs it once the
/// command line has been parsed.
using Action = std::function<int()>;

Action register_generate(CLI::App& root);
Action register_simulate(CLI::App& root);
Action register_identify(CLI::App& root);
Action register_validate(CLI::App& root);
Action register_compare(CLI::App& root);
Action register_diagnose(CLI::App& root);

/// Adds --columns, --units and --force-sign to a subcommand.
void add_input_options(CLI::App& command, InputOptions& in);
/// Adds --format and --out to a subcommand.
void add_output_options(CLI::App& command, OutputOptions& out);

}  // namespace friction::cli
