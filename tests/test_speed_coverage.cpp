// When a validation record moves faster than the estimation record ever did, and the model has
// speed-dependent terms, `identify`, `compare`, `validate` and `diagnose` say so
// (speed_coverage.hpp).
//
// The records are sines sampled exactly, x = A sin(2 pi f t), so the share of the validation
// samples above the estimation record's largest speed is known in closed form: for amplitudes A
// and r A, |cos| > 1/r, a share of 1 - (2/pi) asin(1/r) of a whole number of periods.  The force
// is this test's own: one elasto-plastic element and a viscous term on the exact velocity.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>

#include "friction/csv.hpp"
#include "friction/speed_coverage.hpp"
#include "support/cli_runner.hpp"

namespace test_speed_coverage {
namespace {

using friction::testing::run_cli;
using friction::testing::TempDir;
using Json = nlohmann::json;
constexpr double kPi = std::numbers::pi;

// `periods` periods of x = a sin(2 pi f t + phase) at 1 kHz, f = 2 Hz, and its force: an
// elasto-plastic element (stiffness k, threshold d) plus c v, plus a deterministic ripple of
// 1e-3 of the level as noise.
friction::Record sine_record(double a, double phase, int periods) {
  friction::Record r;
  const double fs = 1000, f = 2, k = 2e4, d = 2e-5, fc = k * d, c = 4.0;
  const int n = static_cast<int>(periods * fs / f);
  double z = 0;
  for (int i = 0; i < n; ++i) {
    const double t = i / fs, w = 2 * kPi * f;
    const double x = a * std::sin(w * t + phase), v = a * w * std::cos(w * t + phase);
    if (i > 0) z = std::clamp(z + x - r.displacement.back(), -d, d);
    r.time.push_back(t);
    r.displacement.push_back(x);
    r.force.push_back(k * z + c * v + 1e-3 * fc * std::sin(37.3 * t));
  }
  return r;
}

std::string write_csv(const TempDir& dir, const std::string& name, const friction::Record& r) {
  const std::string path = dir.file(name);
  friction::write_record_csv(std::filesystem::path(path), r);
  return path;
}

bool warns_faster(const Json& warnings) {
  for (const Json& w : warnings)
    if (w.get<std::string>().find("moves faster than the estimation record") != std::string::npos)
      return true;
  return false;
}

TEST(SpeedCoverage, TheShareAboveTheEstimationSpeedsIsTheClosedForm) {
  const friction::Record est = sine_record(1e-3, 0.0, 8);
  const double largest = friction::largest_speed(est);
  // The estimate at the sample instants of an exact sine: within 1e-4 of its peak a w.
  EXPECT_NEAR(largest, 1e-3 * 4 * kPi, 1e-4 * 1e-3 * 4 * kPi);
  for (double ratio : {1.5, 3.0}) {
    const friction::SpeedCoverage c =
        friction::speed_coverage(largest, sine_record(ratio * 1e-3, 0.7, 8));
    const double expected = 1 - 2 / kPi * std::asin(1 / ratio);
    // Each of the 4 crossings of the level per period decides at most one sample.
    EXPECT_NEAR(c.fraction(), expected, 4.0 * 8 / static_cast<double>(c.samples)) << ratio;
    EXPECT_NEAR(c.validation_largest, ratio * largest, 1e-4 * ratio * largest);
    EXPECT_TRUE(friction::speed_extrapolation_warning(c, {"viscous"})) << ratio;
    // Nothing to say about a model without speed-dependent terms.
    EXPECT_FALSE(friction::speed_extrapolation_warning(c, {})) << ratio;
  }
  // Another phase of the same motion: every sample within the estimation record's speeds but
  // for the sampling of the peak.
  const friction::SpeedCoverage same = friction::speed_coverage(largest, sine_record(1e-3, 0.7, 8));
  EXPECT_LE(same.fraction(), 0.01);
  EXPECT_FALSE(friction::speed_extrapolation_warning(same, {"viscous"}));
}

TEST(SpeedCoverage, TheSpeedDependentTermsOfAModel) {
  using Terms = std::vector<std::string>;
  EXPECT_EQ(friction::speed_dependent_terms(Json{{"type", "maxwell-slip"}}), Terms{});
  EXPECT_EQ(friction::speed_dependent_terms(Json{{"type", "dnlrx"}}), Terms{});
  EXPECT_EQ(friction::speed_dependent_terms(Json{{"type", "lugre"}}).size(), 1u);
  EXPECT_EQ(friction::speed_dependent_terms(Json{{"type", "gms"}}).size(), 1u);
  const Json extended = {{"type", "maxwell-slip"},
                         {"extensions", {{"offset", {}}, {"viscous", {}}, {"stribeck", {}}}}};
  EXPECT_EQ(friction::speed_dependent_terms(extended), (Terms{"stribeck", "viscous"}));
}

TEST(SpeedCoverage, IdentifyAndValidateSayWhenTheValidationRecordIsFaster) {
  TempDir dir;
  const std::string slow = write_csv(dir, "slow.csv", sine_record(1e-3, 0.0, 8));
  const std::string slow_again = write_csv(dir, "slow-again.csv", sine_record(1e-3, 0.7, 8));
  const std::string fast = write_csv(dir, "fast.csv", sine_record(3e-3, 0.7, 8));
  const std::string model = dir.file("model.json");
  const std::string fit = " --model maxwell-slip --operators 1 --no-global --format json";

  auto viscous = run_cli("identify" + fit + " --extension viscous --data " + slow +
                         " --validate " + fast + " --out " + model);
  ASSERT_EQ(viscous.status, 0) << viscous.err;
  const Json doc = Json::parse(friction::testing::read_text(model));
  EXPECT_TRUE(warns_faster(doc["warnings"])) << doc["warnings"].dump();
  EXPECT_NE(viscous.err.find("moves faster"), std::string::npos) << viscous.err;
  EXPECT_NEAR(doc["estimation"]["largest_speed"].get<double>(), 1e-3 * 4 * kPi, 1e-6);

  // The same model on another record at the estimation record's speeds: nothing to say.
  auto same = run_cli("identify" + fit + " --extension viscous --data " + slow + " --validate " +
                      slow_again);
  ASSERT_EQ(same.status, 0) << same.err;
  EXPECT_FALSE(warns_faster(Json::parse(same.out)["warnings"])) << same.out;

  // A rate-independent model on the fast record: nothing to say either.
  auto plain = run_cli("identify" + fit + " --data " + slow + " --validate " + fast);
  ASSERT_EQ(plain.status, 0) << plain.err;
  EXPECT_FALSE(warns_faster(Json::parse(plain.out)["warnings"])) << plain.out;

  // `validate` given the identify document knows the estimation record's speeds.
  auto on_fast = run_cli("validate --model-file " + model + " --data " + fast + " --format json");
  ASSERT_EQ(on_fast.status, 0) << on_fast.err;
  EXPECT_TRUE(warns_faster(Json::parse(on_fast.out)["warnings"])) << on_fast.out;
  auto on_slow =
      run_cli("validate --model-file " + model + " --data " + slow_again + " --format json");
  ASSERT_EQ(on_slow.status, 0) << on_slow.err;
  EXPECT_FALSE(warns_faster(Json::parse(on_slow.out)["warnings"])) << on_slow.out;
}

TEST(SpeedCoverage, CompareSaysItForLgOnly) {
  TempDir dir;
  const std::string slow = write_csv(dir, "slow.csv", sine_record(1e-3, 0.0, 8));
  const std::string fast = write_csv(dir, "fast.csv", sine_record(3e-3, 0.7, 8));
  auto r = run_cli("compare --data " + slow + " --validate " + fast +
                   " --methods LG,NLR --no-global --format json");
  ASSERT_EQ(r.status, 0) << r.err;
  const Json doc = Json::parse(r.out);
  ASSERT_EQ(doc["methods"].size(), 2u);
  for (const Json& row : doc["methods"]) {
    const std::string method = row["method"].get<std::string>();
    EXPECT_EQ(warns_faster(row["warnings"]), method == "LG") << method << row["warnings"].dump();
  }
}

// `diagnose` on a LuGre baseline, whose Stribeck curve and viscous term are fitted on the
// estimation record's speeds: the warning on the fast validation record, not on the slow one.
TEST(SpeedCoverage, DiagnoseSaysItForItsFinalModel) {
  TempDir dir;
  const std::string slow = write_csv(dir, "slow.csv", sine_record(1e-3, 0.0, 8));
  const std::string slow_again = write_csv(dir, "slow-again.csv", sine_record(1e-3, 0.7, 8));
  const std::string fast = write_csv(dir, "fast.csv", sine_record(3e-3, 0.7, 8));
  for (const auto& [validation, expected] : {std::pair{fast, true}, std::pair{slow_again, false}}) {
    auto r = run_cli("diagnose --baseline lugre --no-global --data " + slow + " --validate " +
                     validation + " --format json");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(warns_faster(Json::parse(r.out)["warnings"]), expected) << validation << r.out;
  }
}

}  // namespace
}  // namespace test_speed_coverage
