#include "report_option.hpp"

#include <filesystem>

#include "cli.hpp"
#include "friction/version.hpp"

namespace friction::cli {

namespace {

std::string& stored_command_line() {
  static std::string line;
  return line;
}

// An argument as a POSIX shell reads it back: bare when it has only safe characters, otherwise in
// single quotes (with ' written as '\'').
std::string shell_quote(const std::string& arg) {
  const bool safe = !arg.empty() && arg.find_first_not_of(
                                        "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                        "0123456789-_./=,:+%@") == std::string::npos;
  if (safe) return arg;
  std::string q = "'";
  for (const char c : arg) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

}  // namespace

void set_command_line(int argc, char** argv) {
  std::string line;
  for (int i = 0; i < argc; ++i) {
    std::string arg = argv[i];
    // The program as it is known, not the path it was started from.
    if (i == 0) arg = std::filesystem::path(arg).filename().string();
    line += (i ? " " : "") + shell_quote(arg);
  }
  stored_command_line() = line;
}

report::RunInfo run_info() {
  return {stored_command_line(), version()};
}

void add_report_option(CLI::App& command, std::string& path) {
  command.add_option("--report", path,
                     "Write a self-contained HTML report (plots of the fit, no network needed) to "
                     "FILE, atomically");
}

void check_report_path(const std::string& path) {
  if (path.empty()) return;
  namespace fs = std::filesystem;
  const fs::path p(path);
  std::error_code ec;
  if (fs::is_directory(p, ec)) throw OptionError("--report " + path + ": is a directory");
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  if (!fs::is_directory(dir, ec))
    throw OptionError("--report " + path + ": directory " + dir.string() + " does not exist");
}

void write_report_file(const std::string& path, const report::Document& document) {
  report::write_report(path, document);
}

}  // namespace friction::cli
