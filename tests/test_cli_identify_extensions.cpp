// `identify --extension NAME`, driven as a user would drive it: the pieces land in the document
// and in the saved model, `validate --model-file` reproduces the estimation error, and bad requests
// exit with the contract's status and a one-line message.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <string>

#include "diagnose_support.hpp"
#include "support/cli_runner.hpp"

namespace test_cli_identify_extensions {
namespace {

using friction::testing::run_cli;
using friction::testing::TempDir;
using Json = nlohmann::json;

// 4 s at 1 kHz of the 4-operator system of diagnose_support.hpp with an offset of `offset` N.
std::string write_record(const TempDir& dir, const std::string& name, double offset,
                         bool with_normal = false) {
  using namespace friction::testing;
  Clean c = make_clean(Injected::offset, offset, Excitation{}, 4000, 0.0);
  const friction::Record r = with_noise(c, 2e-3, 5);
  std::string text = with_normal ? "time,displacement,force,normal\n" : "time,displacement,force\n";
  char line[160];
  for (std::size_t k = 0; k < r.size(); ++k) {
    if (with_normal)
      std::snprintf(line, sizeof line, "%.17g,%.17g,%.17g,%.17g\n", r.time[k], r.displacement[k],
                    r.force[k], 10.0 + 0.5 * std::sin(r.time[k]));
    else
      std::snprintf(line, sizeof line, "%.17g,%.17g,%.17g\n", r.time[k], r.displacement[k],
                    r.force[k]);
    text += line;
  }
  const std::string path = dir.file(name);
  write_text(path, text);
  return path;
}

const std::string kFast = " --model maxwell-slip --operators 4 --no-global ";

TEST(CliIdentifyExtensions, SavedModelHoldsThePiecesAndValidatesToTheSameError) {
  TempDir dir;
  const std::string rec = write_record(dir, "r.csv", 0.02), out = dir.file("m.json");
  auto id = run_cli("identify" + kFast + "--data " + rec +
                    " --extension offset --format json --out " + out);
  ASSERT_EQ(id.status, 0) << id.err;
  const Json doc = Json::parse(friction::testing::read_text(out));
  ASSERT_TRUE(doc["model"].contains("extensions")) << doc["model"].dump();
  const double offset = doc["model"]["extensions"]["offset"]["offset"].get<double>();
  EXPECT_NEAR(offset, 0.02, 0.002);
  EXPECT_EQ(doc["extensions"]["base"].get<std::string>(), "refitted jointly");
  EXPECT_GT(doc["extensions"]["pieces"]["offset"]["offset"]["standard_error"].get<double>(), 0.0);
  const double est = doc["estimation"]["rss_sss_percent"].get<double>();
  EXPECT_LT(est, 0.5 * doc["extensions"]["estimation_before_percent"].get<double>());

  auto val = run_cli("validate --model-file " + out + " --data " + rec + " --format json");
  ASSERT_EQ(val.status, 0) << val.err;
  const Json v = Json::parse(val.out);
  EXPECT_EQ(v["validation"]["initial_state"].get<std::string>(), "estimated");
  EXPECT_NEAR(v["validation"]["rss_sss_percent"].get<double>(), est, 1e-9 * est);
  EXPECT_TRUE(v["model"]["extensions"].contains("offset"));
}

TEST(CliIdentifyExtensions, RepeatedAndCommaListsAreTheSameRequest) {
  TempDir dir;
  const std::string rec = write_record(dir, "r.csv", 0.02);
  auto a = run_cli("identify" + kFast + "--data " + rec +
                   " --extension offset --extension viscous --format json");
  auto b =
      run_cli("identify" + kFast + "--data " + rec + " --extension viscous,offset --format json");
  ASSERT_EQ(a.status, 0) << a.err;
  ASSERT_EQ(b.status, 0) << b.err;
  const Json ja = Json::parse(a.out), jb = Json::parse(b.out);
  EXPECT_EQ(ja["model"]["extensions"].size(), 2u);
  EXPECT_EQ(jb["model"]["extensions"].size(), 2u);
  EXPECT_NEAR(ja["model"]["extensions"]["offset"]["offset"].get<double>(),
              jb["model"]["extensions"]["offset"]["offset"].get<double>(), 1e-4);
}

TEST(CliIdentifyExtensions, TableListsThePiecesWithUnits) {
  TempDir dir;
  const std::string rec = write_record(dir, "r.csv", 0.02);
  auto t = run_cli("identify" + kFast + "--data " + rec + " --extension offset");
  ASSERT_EQ(t.status, 0) << t.err;
  EXPECT_NE(t.out.find("offset.offset"), std::string::npos) << t.out;
  EXPECT_NE(t.out.find(" N\n"), std::string::npos) << t.out;
  EXPECT_NE(t.out.find("extensions offset (base refitted jointly)"), std::string::npos) << t.out;
}

TEST(CliIdentifyExtensions, UnknownNameIsAUsageError) {
  TempDir dir;
  const std::string rec = write_record(dir, "r.csv", 0.0);
  auto r = run_cli("identify" + kFast + "--data " + rec + " --extension viscus");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("viscus"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("normal-load"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << "one line: " << r.err;
}

TEST(CliIdentifyExtensions, NormalLoadNeedsANormalColumn) {
  TempDir dir;
  const std::string rec = write_record(dir, "r.csv", 0.0);
  auto r = run_cli("identify" + kFast + "--data " + rec + " --extension normal-load");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("normal"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("r.csv"), std::string::npos) << r.err;
}

TEST(CliIdentifyExtensions, PiecesTheBaseAlreadyHasAreRefused) {
  TempDir dir;
  const std::string rec = write_record(dir, "r.csv", 0.0);
  auto r = run_cli("identify --model dnlrx --data " + rec + " --extension viscous");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("input filter"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace test_cli_identify_extensions
