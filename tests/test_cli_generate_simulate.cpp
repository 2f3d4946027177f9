// The generate and simulate commands, driven as a user would drive them.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <string>

#include "friction/csv.hpp"
#include "support/cli_runner.hpp"

namespace test_cli_generate_simulate {
namespace {

using friction::testing::run_cli;
using friction::testing::TempDir;

double rms_of(const std::vector<double>& v) {
  double s = 0;
  for (double e : v) s += e * e;
  return std::sqrt(s / static_cast<double>(v.size()));
}

// Generated records are in the model's convention: read them without sign detection.
friction::ReadOptions positive_sign() {
  friction::ReadOptions o;
  o.force_sign = friction::ForceSign::positive;
  return o;
}

// Short records keep the suite quick: one slow speed and a few presliding cycles.
const std::string kShort = " --stroke 0.2e-3 --speeds 1e-3,4e-3 --cycles 3 ";

TEST(CliGenerate, WritesARecordAndTheTruthThatSimulateReproduces) {
  TempDir dir;
  for (const std::string model : {"maxwell-slip", "dnlrx", "lugre", "gms", "static"}) {
    SCOPED_TRACE(model);
    const std::string rec = dir.file(model + ".csv"), truth = dir.file(model + ".json");
    auto g = run_cli("generate --model " + model + kShort + "--out " + rec + " --truth " + truth);
    ASSERT_EQ(g.status, 0) << g.err;
    auto s = run_cli("simulate --model-file " + truth + " --data " + rec + " --out " +
                     dir.file("sim.csv"));
    ASSERT_EQ(s.status, 0) << s.err;
    friction::ReadOptions o;
    o.columns.force = "simulated";
    o.force_sign = friction::ForceSign::positive;
    const auto sim = friction::read_record(dir.file("sim.csv"), o);
    const auto original = friction::read_record(rec, positive_sign());
    ASSERT_EQ(sim.size(), original.size());
    // No noise: simulating the generating model on the record reproduces its force.
    for (std::size_t k = 0; k < sim.size(); ++k) ASSERT_NEAR(sim.force[k], original.force[k], 1e-9);
  }
}

TEST(CliGenerate, NoiseHasTheRequestedLevelAndTheSeedReproducesIt) {
  TempDir dir;
  const std::string a = dir.file("a.csv"), b = dir.file("b.csv"), c = dir.file("c.csv"),
                    truth = dir.file("t.json");
  ASSERT_EQ(run_cli("generate" + kShort + "--noise 0.05 --seed 9 --out " + a + " --truth " + truth)
                .status,
            0);
  ASSERT_EQ(run_cli("generate" + kShort + "--noise 0.05 --seed 9 --out " + b).status, 0);
  ASSERT_EQ(run_cli("generate" + kShort + "--noise 0.05 --seed 10 --out " + c).status, 0);
  EXPECT_EQ(friction::testing::read_text(a), friction::testing::read_text(b));
  EXPECT_NE(friction::testing::read_text(a), friction::testing::read_text(c));
  ASSERT_EQ(
      run_cli("simulate --model-file " + truth + " --data " + a + " --out " + dir.file("s.csv"))
          .status,
      0);
  friction::ReadOptions o;
  o.columns.force = "residual";
  o.force_sign = friction::ForceSign::positive;
  const auto residual = friction::read_record(dir.file("s.csv"), o);
  const double n = static_cast<double>(residual.size());
  // The residual is the noise: its RMS is 0.05 N within 4 standard errors (0.05 / sqrt(2 n)).
  EXPECT_NEAR(rms_of(residual.force), 0.05, 4 * 0.05 / std::sqrt(2 * n));
}

TEST(CliGenerate, EncoderResolutionQuantisesTheDisplacement) {
  TempDir dir;
  const std::string rec = dir.file("q.csv");
  ASSERT_EQ(run_cli("generate" + kShort + "--resolution 1e-7 --out " + rec).status, 0);
  const auto r = friction::read_record(rec);
  for (double x : r.measured()) ASSERT_NEAR(x / 1e-7, std::round(x / 1e-7), 1e-6);
  // The models see the staircase's estimate (sample_derivatives.hpp), which differs from it...
  ASSERT_FALSE(r.measured_displacement.empty());
  EXPECT_NE(r.displacement, r.measured_displacement);
  // ...but `simulate` writes back the displacement as it was read.
  const std::string truth = dir.file("t.json"), sim = dir.file("sim.csv");
  ASSERT_EQ(
      run_cli("generate" + kShort + "--resolution 1e-7 --out " + rec + " --truth " + truth).status,
      0);
  ASSERT_EQ(run_cli("simulate --model-file " + truth + " --data " + rec + " --out " + sim).status,
            0);
  friction::ReadOptions o;
  o.columns.force = "simulated";
  o.force_sign = friction::ForceSign::positive;
  const auto written = friction::read_record(sim, o);
  EXPECT_EQ(written.measured(), friction::read_record(rec).measured());
}

TEST(CliGenerate, EffectsChangeTheForceAsTheirFormulaSays) {
  TempDir dir;
  const std::string base = dir.file("base.csv"), off = dir.file("off.csv");
  ASSERT_EQ(run_cli("generate" + kShort + "--out " + base).status, 0);
  ASSERT_EQ(run_cli("generate" + kShort + "--effect offset=0.3 --out " + off).status, 0);
  const auto a = friction::read_record(base, positive_sign());
  const auto b = friction::read_record(off, positive_sign());
  for (std::size_t k = 0; k < a.size(); ++k) ASSERT_NEAR(b.force[k] - a.force[k], 0.3, 1e-12);
  // A normal-load effect makes the record carry a normal force column.
  const std::string normal = dir.file("normal.csv");
  ASSERT_EQ(run_cli("generate" + kShort + "--effect normal-load=0.3 --out " + normal).status, 0);
  EXPECT_TRUE(friction::read_record(normal).has_normal());
}

TEST(CliGenerate, JsonSummaryNamesTheRecord) {
  TempDir dir;
  auto g = run_cli("generate" + kShort + "--format json --seed 4 --out " + dir.file("r.csv"));
  ASSERT_EQ(g.status, 0) << g.err;
  const auto doc = nlohmann::json::parse(g.out);
  EXPECT_EQ(doc["schema_version"], 1);
  EXPECT_TRUE(doc["warnings"].is_array());
  EXPECT_EQ(doc["model"]["type"], "maxwell-slip");
  EXPECT_EQ(doc["record"]["seed"], 4);
}

// compare identifies its methods on concurrent threads; the document (every row, warning and
// parameter, in the order asked) must be the same on one thread and on more threads than methods.
TEST(CliCompare, TheDocumentDoesNotDependOnTheThreadCount) {
  TempDir dir;
  const std::string est = dir.file("est.csv"), val = dir.file("val.csv");
  ASSERT_EQ(
      run_cli("generate --model maxwell-slip" + kShort + "--noise 0.01 --seed 21 --out " + est)
          .status,
      0);
  ASSERT_EQ(
      run_cli("generate --model maxwell-slip" + kShort + "--noise 0.01 --seed 22 --out " + val)
          .status,
      0);
  auto strip_seconds = [](nlohmann::json& j, auto& self) -> void {
    if (j.is_object()) {
      j.erase("seconds");
      for (auto& [k, v] : j.items()) self(v, self);
    } else if (j.is_array()) {
      for (auto& v : j) self(v, self);
    }
  };
  std::vector<nlohmann::json> docs;
  for (const std::string threads : {"1", "4"}) {
    const std::string out = dir.file("compare-" + threads + ".json");
    const auto r = run_cli("compare --data " + est + " --validate " + val + " --threads " +
                           threads + " --out " + out);
    ASSERT_EQ(r.status, 0) << r.err;
    nlohmann::json doc = nlohmann::json::parse(std::ifstream(out));
    ASSERT_EQ(doc["methods"].size(), 3u);
    for (const auto& row : doc["methods"]) EXPECT_FALSE(row.contains("error")) << row["method"];
    strip_seconds(doc, strip_seconds);
    doc.erase("command");
    docs.push_back(std::move(doc));
  }
  EXPECT_EQ(docs[0], docs[1]) << nlohmann::json::diff(docs[0], docs[1]).dump(1);
}

TEST(CliUsage, BadUsageExitsWithTwoAndBadDataWithOne) {
  TempDir dir;
  EXPECT_EQ(run_cli("").status, 2);
  EXPECT_EQ(run_cli("no-such-command").status, 2);
  EXPECT_EQ(run_cli("generate --model coulomb-only").status, 2);
  EXPECT_EQ(run_cli("generate --effect sticky=1").status, 2);
  EXPECT_EQ(run_cli("simulate --data x.csv").status, 2);  // --model-file missing
  EXPECT_EQ(run_cli("--help").status, 0);

  const std::string truth = dir.file("t.json"), rec = dir.file("r.csv");
  ASSERT_EQ(run_cli("generate" + kShort + "--out " + rec + " --truth " + truth).status, 0);
  friction::testing::write_text(dir.file("bad.csv"), "time,x,force\n0,0,1\n0.1,abc,2\n");
  auto r = run_cli("simulate --model-file " + truth + " --data " + dir.file("bad.csv"));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("bad.csv:3:2"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;

  friction::testing::write_text(dir.file("bad.json"),
                                "{\"type\": \"maxwell-slip\",\n \"parameters\": {\"stiffness\": "
                                "[1e4], \"threshold\": [-1e-6]}}");
  r = run_cli("simulate --model-file " + dir.file("bad.json") + " --data " + rec);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("threshold"), std::string::npos) << r.err;

  friction::testing::write_text(dir.file("broken.json"), "{\"type\": \n  \"maxwell-slip\",, }");
  r = run_cli("simulate --model-file " + dir.file("broken.json") + " --data " + rec);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("broken.json:2:"), std::string::npos) << r.err;
}

// The estimation and validation records are read on two threads (load_record_pair): the error a
// user sees must not depend on which finished first.  Both bad: the estimation file's, one line;
// only the validation file bad: its own.
TEST(CliUsage, TwoBadRecordsReportTheEstimationFilesErrorFirst) {
  TempDir dir;
  friction::testing::write_text(dir.file("est.csv"), "time,x,force\n0,0,1\n0.1,abc,2\n");
  friction::testing::write_text(dir.file("val.csv"), "time,x,force\n0,0,1\n0.1,0,x\n");
  const std::string good = dir.file("good.csv");
  ASSERT_EQ(run_cli("generate" + kShort + "--out " + good).status, 0);
  for (const std::string command : {"identify --model maxwell-slip", "compare", "diagnose"}) {
    for (int repeat = 0; repeat < 5; ++repeat) {
      auto r = run_cli(command + " --data " + dir.file("est.csv") + " --validate " +
                       dir.file("val.csv"));
      EXPECT_EQ(r.status, 1) << command;
      EXPECT_NE(r.err.find("est.csv:3:2"), std::string::npos) << command << ": " << r.err;
      EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << command << ": " << r.err;
    }
    auto r = run_cli(command + " --data " + good + " --validate " + dir.file("val.csv"));
    EXPECT_EQ(r.status, 1) << command;
    EXPECT_NE(r.err.find("val.csv:3:3"), std::string::npos) << command << ": " << r.err;
  }
}

TEST(CliSimulate, NeverLeavesAHalfWrittenOutput) {
  TempDir dir;
  const std::string truth = dir.file("t.json"), rec = dir.file("r.csv"), out = dir.file("out.csv");
  ASSERT_EQ(run_cli("generate" + kShort + "--out " + rec + " --truth " + truth).status, 0);
  friction::testing::write_text(out, "precious\n");
  friction::testing::write_text(dir.file("bad.csv"), "time,x,force\n0,0,1\n0,1,2\n");
  EXPECT_EQ(
      run_cli("simulate --model-file " + truth + " --data " + dir.file("bad.csv") + " --out " + out)
          .status,
      1);
  EXPECT_EQ(friction::testing::read_text(out), "precious\n");
}

// A simulation of a long record is streamed to stdout; a stream that cannot take it (a full disk:
// /dev/full) is an error, not a silent success with a truncated CSV.
TEST(CliSimulate, AnOutputThatCannotBeWrittenIsAnError) {
  TempDir dir;
  const std::string truth = dir.file("t.json"), rec = dir.file("r.csv"), err = dir.file("err");
  ASSERT_EQ(run_cli("generate" + kShort + "--out " + rec + " --truth " + truth).status, 0);
  const char* env = std::getenv("FRICTION_CLI");
  const std::string cli = env ? env : FRICTION_CLI;
  const int raw = std::system(("'" + cli + "' simulate --model-file " + truth + " --data " + rec +
                               " >/dev/full 2>'" + err + "'")
                                  .c_str());
  ASSERT_TRUE(WIFEXITED(raw));
  EXPECT_NE(WEXITSTATUS(raw), 0);
  EXPECT_NE(friction::testing::read_text(err).find("could not be written"), std::string::npos)
      << friction::testing::read_text(err);
}

}  // namespace
}  // namespace test_cli_generate_simulate
