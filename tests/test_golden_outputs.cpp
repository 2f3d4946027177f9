// The JSON documents of `compare`, `identify --extension` and `diagnose`, on data/ and on the
// tribometer record, against the documents the CLI gave before the extension engine was
// restructured (tests/golden/, our outputs, not data).  A restructuring must not change behaviour:
// every key and value of a golden document must be present and equal in the new one -- numbers to
// a relative 1e-9, strings, booleans and nulls exactly, arrays element by element and of the same
// length -- except the timings (keys `seconds`) and the tool's name and version (`tool`).  Keys the
// new document adds are allowed: an addition is not a change of behaviour.
//
// The tribometer record (../shared/data/tribometer/reciprocating.csv) is not copied here: the
// test splits it into its first half (estimation) and second half (validation) in a temporary
// directory, as the README's commands do, and skips that part, saying so, when it is absent.
//
// FRICTION_UPDATE_GOLDEN=1 rewrites the golden documents from the current CLI instead of comparing
// (for a deliberate, explained change of behaviour only; commit the new documents on their own).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <sys/wait.h>

#include "support/cli_runner.hpp"

namespace test_golden_outputs {
namespace {

using friction::testing::read_text;
using friction::testing::TempDir;
using Json = nlohmann::json;

constexpr double kRelativeTolerance = 1e-9;

const std::filesystem::path kGoldenDir =
    std::filesystem::path(FRICTION_SOURCE_DIR) / "tests/golden";

bool updating() {
  const char* e = std::getenv("FRICTION_UPDATE_GOLDEN");
  return e && std::string(e) == "1";
}

// Runs the CLI with `directory` as the working directory, so that the file names the documents
// carry are the relative ones given here.
Json run_json(const std::filesystem::path& directory, const std::string& args) {
  const char* env = std::getenv("FRICTION_CLI");
  const std::string cli = env ? env : FRICTION_CLI;
  TempDir tmp;
  const std::string out = tmp.file("stdout"), err = tmp.file("stderr");
  const std::string command = "cd '" + directory.string() + "' && '" + cli + "' " + args +
                              " --format json >'" + out + "' 2>'" + err + "' </dev/null";
  const int raw = std::system(command.c_str());
  const int status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  EXPECT_EQ(status, 0) << args << "\n" << read_text(err);
  return Json::parse(read_text(out));
}

bool ignored(const std::string& key) {
  return key == "seconds" || key == "tool";
}

bool numbers_equal(double a, double b) {
  if (a == b) return true;
  if (!std::isfinite(a) || !std::isfinite(b)) return false;
  return std::abs(a - b) <= kRelativeTolerance * std::max(std::abs(a), std::abs(b));
}

// Every key and value of `golden` present and equal in `now`; differences appended to `out`.
void compare(const Json& golden, const Json& now, const std::string& path,
             std::vector<std::string>& out) {
  const auto differ = [&](const std::string& what) {
    out.push_back(path + ": " + what + " (golden " + golden.dump() + ", now " + now.dump() + ")");
  };
  if (golden.is_number() && now.is_number()) {
    if (!numbers_equal(golden.get<double>(), now.get<double>())) differ("number differs");
    return;
  }
  if (golden.type() != now.type()) return differ("type differs");
  if (golden.is_object()) {
    for (auto it = golden.begin(); it != golden.end(); ++it) {
      if (ignored(it.key())) continue;
      if (!now.contains(it.key())) {
        out.push_back(path + "." + it.key() + ": missing");
        continue;
      }
      compare(it.value(), now.at(it.key()), path + "." + it.key(), out);
    }
    return;
  }
  if (golden.is_array()) {
    if (golden.size() != now.size())
      return differ("array length " + std::to_string(golden.size()) + " -> " +
                    std::to_string(now.size()));
    for (std::size_t i = 0; i < golden.size(); ++i)
      compare(golden[i], now[i], path + "[" + std::to_string(i) + "]", out);
    return;
  }
  if (golden != now) differ("value differs");
}

void check_against_golden(const std::string& name, const std::filesystem::path& directory,
                          const std::string& args) {
  const Json now = run_json(directory, args);
  const std::filesystem::path file = kGoldenDir / (name + ".json");
  if (updating()) {
    std::filesystem::create_directories(kGoldenDir);
    std::ofstream(file) << now.dump(2) << "\n";
    std::cout << "golden document rewritten: " << file.string() << "\n";
    return;
  }
  ASSERT_TRUE(std::filesystem::exists(file)) << "no golden document " << file.string();
  const Json golden = Json::parse(read_text(file.string()));
  std::vector<std::string> differences;
  compare(golden, now, name, differences);
  std::ostringstream s;
  for (std::size_t i = 0; i < differences.size() && i < 40; ++i) s << differences[i] << "\n";
  EXPECT_TRUE(differences.empty())
      << differences.size() << " difference(s) from " << file.string() << " (`" << args << "`):\n"
      << s.str();
}

const std::filesystem::path kSource = FRICTION_SOURCE_DIR;
const std::string kData = "--data data/estimation.csv --validate data/validation.csv";

TEST(GoldenOutputs, CompareOnData) {
  check_against_golden("data_compare", kSource, "compare " + kData);
}

TEST(GoldenOutputs, IdentifyMaxwellSlipWithViscousAndOffsetOnData) {
  check_against_golden("data_identify_maxwell_slip", kSource,
                       "identify --model maxwell-slip --extension viscous,offset " + kData);
}

TEST(GoldenOutputs, IdentifyDnlrxWithOffsetOnData) {
  check_against_golden("data_identify_dnlrx", kSource,
                       "identify --model dnlrx --extension offset " + kData);
}

TEST(GoldenOutputs, DiagnoseOnData) {
  check_against_golden("data_diagnose", kSource, "diagnose " + kData);
}

// The tribometer record split into halves (header kept on both), in a temporary directory.
class GoldenOutputsOnTribometer : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::filesystem::path record =
        std::filesystem::path(FRICTION_SHARED_DIR) / "data/tribometer/reciprocating.csv";
    if (!std::filesystem::exists(record))
      GTEST_SKIP() << "tribometer record absent at " << record.string()
                   << ": its golden outputs are not checked";
    std::ifstream in(record);
    std::string header, line;
    std::getline(in, header);
    std::vector<std::string> rows;
    while (std::getline(in, line))
      if (line.find_first_not_of(" \t\r") != std::string::npos) rows.push_back(line);
    const std::size_t half = rows.size() / 2;
    std::ofstream first(dir_.file("tribo_first.csv")), second(dir_.file("tribo_second.csv"));
    first << header << "\n";
    second << header << "\n";
    for (std::size_t k = 0; k < rows.size(); ++k) (k < half ? first : second) << rows[k] << "\n";
  }
  TempDir dir_;
  const std::string data_ = "--data tribo_first.csv --validate tribo_second.csv";
};

TEST_F(GoldenOutputsOnTribometer, Compare) {
  check_against_golden("tribometer_compare", dir_.path(), "compare " + data_);
}

TEST_F(GoldenOutputsOnTribometer, Diagnose) {
  check_against_golden("tribometer_diagnose", dir_.path(), "diagnose " + data_);
}

TEST_F(GoldenOutputsOnTribometer, IdentifyMaxwellSlipWithNormalLoadAsymmetryAndOffset) {
  check_against_golden(
      "tribometer_identify_maxwell_slip", dir_.path(),
      "identify --model maxwell-slip --extension normal-load,asymmetry,offset " + data_);
}

}  // namespace
}  // namespace test_golden_outputs
