#include "cli.hpp"

#include <cstdio>
#include <iostream>
#include <sstream>

#include "../parallel_for.hpp"
#include "commands.hpp"
#include "friction/atomic_file.hpp"
#include "friction/version.hpp"
#include "report_option.hpp"
#include "../subnormals.hpp"

namespace friction::cli {

ReadOptions read_options(const InputOptions& in, bool require_force) {
  ReadOptions o;
  if (!in.columns.empty()) o.columns = parse_column_mapping(in.columns);
  if (!in.units.empty()) o.units = parse_units(in.units);
  o.force_sign = parse_force_sign(in.force_sign);
  o.require_force = require_force;
  return o;
}

Record load_record(const std::string& path, const InputOptions& in, bool require_force) {
  return read_record(path, read_options(in, require_force));
}

std::pair<Record, Record> load_record_pair(const std::string& estimation,
                                           const std::string& validation,
                                           const InputOptions& in) {
  std::pair<Record, Record> out;
  detail::parallel_for(2, 2, [&](std::size_t i) {
    if (i == 0)
      out.first = load_record(estimation, in, true);
    else
      out.second = load_record(validation, in, true);
  });
  return out;
}

AnyModel load_model(const std::string& path) {
  try {
    return AnyModel::load(path);
  } catch (const InvalidParameter& e) {
    // A value outside its domain in a file is bad data, not bad usage.
    throw DataError(path, 0, 0, e.what());
  }
}

void emit_stream(const OutputOptions& out, const std::function<void(std::ostream&)>& write) {
  if (out.out.empty()) {
    write(std::cout);
    std::cout.flush();
    if (!std::cout) throw FileError("stdout", "the output could not be written");
  } else {
    write_file_atomically(out.out, write);
  }
}

void emit(const OutputOptions& out, const std::string& text) {
  emit_stream(out, [&](std::ostream& s) {
    s.write(text.data(), static_cast<std::streamsize>(text.size()));
  });
}

void emit_table(const OutputOptions& out, const std::string& table, const Json& document) {
  if (out.out.empty()) {
    emit(out, table);
    return;
  }
  std::fwrite(table.data(), 1, table.size(), stdout);
  std::fflush(stdout);
  emit(out, document.dump(2) + "\n");
}

Json new_document(const std::string& command) {
  Json d;
  d["schema_version"] = 1;
  d["command"] = command;
  d["tool"] = {{"name", "friction-identify"}, {"version", version()}};
  d["warnings"] = Json::array();
  return d;
}

void add_warnings(Json& document, const std::vector<std::string>& warnings) {
  for (const auto& w : warnings) {
    std::cerr << "warning: " << w << "\n";
    document["warnings"].push_back(w);
  }
}

void add_input_options(CLI::App& command, InputOptions& in) {
  command.add_option(
      "--columns", in.columns,
      "Columns by header name: time=NAME,displacement=NAME,force=NAME[,normal=NAME]");
  command.add_option(
      "--units", in.units,
      "Units of the file's columns, e.g. displacement=mm,force=uN,time=ms (SI default)");
  command
      .add_option("--force-sign", in.force_sign,
                  "Sign of the recorded force: +1, -1 or auto (detected from F*v while sliding)")
      ->capture_default_str();
}

void add_output_options(CLI::App& command, OutputOptions& out) {
  command.add_option("--format", out.format, "Output: table (for people) or json (one document)")
      ->check(CLI::IsMember({"table", "json"}))
      ->capture_default_str();
  command.add_option("--out", out.out, "Write the output to FILE (atomically) instead of stdout");
}

int run(int argc, char** argv) {
  const detail::SubnormalsFlushed subnormals_flushed;  // subnormals.hpp
  set_command_line(argc, argv);
  CLI::App app{
      "friction-identify: identify friction models (LuGre, Maxwell Slip, DNLRX, GMS) "
      "from displacement-force records"};
  app.set_version_flag("--version", std::string("friction-identify ") + version());
  app.require_subcommand(1);
  const Action generate = register_generate(app);
  const Action simulate = register_simulate(app);
  const Action identify = register_identify(app);
  const Action validate = register_validate(app);
  const Action compare = register_compare(app);
  const Action diagnose = register_diagnose(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);  // prints the message and usage hint
    return kExitUsage;
  }

  try {
    for (const auto* sub : app.get_subcommands()) {
      const std::string name = sub->get_name();
      if (name == "generate") return generate();
      if (name == "simulate") return simulate();
      if (name == "identify") return identify();
      if (name == "validate") return validate();
      if (name == "compare") return compare();
      if (name == "diagnose") return diagnose();
    }
    return kExitUsage;
  } catch (const OptionError& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitUsage;
  } catch (const InvalidParameter& e) {
    // Values given on the command line (model files are converted to DataError in load_model).
    std::cerr << "error: " << e.what() << "\n";
    return kExitUsage;
  } catch (const Error& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitData;
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitData;
  }
}

}  // namespace friction::cli
