// Diagnosis: the pieces (initial state through extensions, residual evidence) and one short
// end-to-end run with its JSON contract (cli.md).  The effect studies are test_diagnose_effects.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "../src/diagnose_stages.hpp"
#include "diagnose_support.hpp"
#include "friction/diagnose.hpp"
#include "support/cli_runner.hpp"

namespace friction::testing {
namespace test_diagnose {
namespace {

MaxwellSlipParameters<double> truth_parameters() {
  const SlipSystem s;
  return {s.k, s.delta};
}

Record noiseless(Injected e, double magnitude, std::size_t n, double t0,
                 const std::vector<double>& d0) {
  Excitation ex;
  Clean c = make_clean(e, magnitude, ex, n, t0);
  if (std::any_of(d0.begin(), d0.end(), [](double v) { return v != 0; })) {
    c.force = slip_force(SlipSystem{}, c.time, c.x, SlipLevel{}, d0);
  }
  return with_noise(c, 0.0, 1);
}

TEST(DiagnoseValidation, EstimatesTheInitialStateThroughTheExtensions) {
  // The true model with an offset and a viscous piece, started from a non-virgin state: the
  // validation error with the state estimated from the record must vanish.
  const std::vector<double> d0{0.8e-6, -2e-6, 5e-6, -10e-6};
  Record r = noiseless(Injected::none, 0, 3000, 0.0, d0);
  const Excitation ex;  // noiseless's motion: the viscous term with its exact velocity
  for (std::size_t k = 0; k < r.size(); ++k) r.force[k] += 0.01 + 30.0 * ex.v(r.time[k]);
  ExtensionParameters<double> ext;
  ext.enable(Effect::offset);
  ext.offset->offset = 0.01;
  ext.enable(Effect::viscous);
  ext.viscous->viscous = 30.0;
  const double pct = extended_validation_percent(truth_parameters(), ext, r);
  EXPECT_LT(pct, 1e-6);
  // And the wrong model (no pieces) is clearly worse.
  EXPECT_GT(extended_validation_percent(truth_parameters(), {}, r), 1e-3);
}

TEST(DiagnoseEvidence, AnOffsetIsTheTopSignatureWithItsSize) {
  const Record r = noiseless(Injected::offset, 0.02, 3000, 0.0, {});
  const ResidualEvidence ev = analyse_residual(truth_parameters(), {}, r);
  ASSERT_FALSE(ev.effects.empty());
  EXPECT_EQ(ev.effects.front().effect, Effect::offset);
  EXPECT_NEAR(ev.effects.front().coefficient, 0.02, 0.002);
  EXPECT_GT(ev.sliding_samples, 100u);
  EXPECT_GT(ev.presliding_samples, 100u);
  // Every velocity bin sees the offset.
  ASSERT_FALSE(ev.velocity_bins.empty());
  for (const auto& b : ev.velocity_bins) EXPECT_NEAR(b.mean_residual, 0.02, 0.005);
}

TEST(DiagnoseEvidence, ADelayShowsAsTheBestShift) {
  const double delay = 0.004;  // 4 samples
  const Record r = noiseless(Injected::delay, delay, 3000, 0.0, {});
  const ResidualEvidence ev = analyse_residual(truth_parameters(), {}, r);
  EXPECT_NEAR(ev.best_shift, delay, 0.6e-3);
}

TEST(DiagnoseEvidence, ViscousFrictionGrowsWithSpeedInTheBins) {
  const Record r = noiseless(Injected::viscous, 40.0, 3000, 0.0, {});
  const ResidualEvidence ev = analyse_residual(truth_parameters(), {}, r);
  // In each direction the mean residual of the fastest bin exceeds the slowest's in magnitude,
  // with the sign of the direction.
  for (int d : {1, -1}) {
    std::vector<ResidualEvidence::Bin> bins;
    for (const auto& b : ev.velocity_bins)
      if (b.direction == d) bins.push_back(b);
    ASSERT_GE(bins.size(), 2u);
    EXPECT_GT(d * bins.back().mean_residual, d * bins.front().mean_residual);
    EXPECT_GT(d * bins.back().mean_residual, 0.0);
  }
}

// One short end-to-end run: the JSON keys of cli.md, the chain of validation errors, and the
// finding's sentence.
TEST(Diagnose, ShortViscousRecordGivesAChainedFindingAndTheContractKeys) {
  Excitation ex;
  const double sigma = 2e-3;
  const Record est = with_noise(make_clean(Injected::viscous, 40.0, ex, 3000, 0.0), sigma, 3);
  const Record val = with_noise(make_clean(Injected::viscous, 40.0, ex, 3000, 3.0), sigma, 4);
  const Diagnosis d = diagnose(est, val);
  ASSERT_EQ(d.findings.size(), 1u) << d.to_table();
  EXPECT_EQ(d.findings[0].name(), "viscous");
  EXPECT_NEAR(d.findings[0].parameter("viscous"), 40.0, 6.0);
  const Json j = d.to_json();
  for (const char* key : {"baseline", "findings", "final"}) EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["baseline"]["model"]["type"], "maxwell-slip");
  EXPECT_TRUE(j["baseline"]["validation"].contains("rss_sss_percent"));
  const Json& f = j["findings"][0];
  for (const char* key :
       {"effect", "evidence", "extension", "parameters", "validation_before", "validation_after"})
    EXPECT_TRUE(f.contains(key)) << key;
  EXPECT_DOUBLE_EQ(f["validation_before"].get<double>(),
                   j["baseline"]["validation"]["rss_sss_percent"].get<double>());
  EXPECT_DOUBLE_EQ(f["validation_after"].get<double>(),
                   j["final"]["validation"]["rss_sss_percent"].get<double>());
  EXPECT_LT(f["validation_after"].get<double>(), f["validation_before"].get<double>());
  EXPECT_TRUE(j["final"]["model"]["extensions"].contains("viscous"));
  // The final model document loads back and reproduces the final validation error.
  const AnyModel back = AnyModel::from_json(j["final"]["model"]);
  const auto& m = std::get<Extended<MaxwellSlip<double>>>(back.variant());
  EXPECT_NEAR(extended_validation_percent(m.base().parameters(), m.extensions(), val),
              d.final_validation_percent, 1e-6 * d.final_validation_percent + 1e-12);
  EXPECT_NE(d.to_table().find("cause: viscous"), std::string::npos);
  // Standard errors of the fit at the finding's step, and of the final joint fit (the same fit
  // here): Gauss-Newton, symmetric intervals (the piece is fitted linearly), and the injected
  // value within a few of them.
  const double value = f["parameters"]["viscous"].get<double>();
  const double se = f["standard_errors"]["viscous"].get<double>();
  ASSERT_TRUE(std::isfinite(se));
  EXPECT_GT(se, 0.0);
  EXPECT_LT(se, 6.0);
  EXPECT_DOUBLE_EQ(f["intervals"]["viscous"][0].get<double>(), value - 1.96 * se);
  EXPECT_DOUBLE_EQ(f["intervals"]["viscous"][1].get<double>(), value + 1.96 * se);
  EXPECT_LT(std::abs(value - 40.0), 5.0 * se) << value << " +- " << se;
  const Json& piece = j["final"]["pieces"]["viscous"]["viscous"];
  EXPECT_EQ(piece["value"].get<double>(), value);
  EXPECT_EQ(piece["standard_error"].get<double>(), se);
  EXPECT_EQ(piece["unit"], "N s/m");
  EXPECT_FALSE(piece["at_bound"].get<bool>());
}

// The candidates of a round run concurrently; each writes its own slot, so the document is the
// same bit for bit on one thread and on several (timings aside).  Two effects, so that a second
// round and the ambiguity refits run too.
namespace {
void drop_timings(Json& j) {
  if (j.is_object()) {
    j.erase("seconds");
    j.erase("baseline_seconds");
    for (auto& [key, value] : j.items()) drop_timings(value);
  } else if (j.is_array()) {
    for (auto& value : j) drop_timings(value);
  }
}
}  // namespace

// An inertial force many times the slip level: the baseline alone cannot be fitted (it would
// need negative stiffness), so diagnose fits it to the force less a regressed m·a and must then
// name the inertia, and only it.
TEST(Diagnose, ADominantInertiaIsNamedWhenTheBaselineAloneCannotBeFitted) {
  Excitation ex;
  const double sigma = 2e-3, mass = 150.0;
  const Record est = with_noise(make_clean(Injected::inertia, mass, ex, 2000, 0.0), sigma, 21);
  const Record val = with_noise(make_clean(Injected::inertia, mass, ex, 2000, 2.0), sigma, 22);
  DiagnoseOptions o;
  o.method.max_operators = 6;
  o.method.global_stage = false;  // the sanitizer pass runs this test some 30 times slower
  const Diagnosis d = diagnose(est, val, o);
  EXPECT_TRUE(std::any_of(d.warnings.begin(), d.warnings.end(), [](const std::string& w) {
    return w.find("the base was fitted to the force less that term") != std::string::npos;
  })) << "the baseline was fitted without the inertia taken out";
  ASSERT_EQ(d.findings.size(), 1u) << d.to_table();
  EXPECT_EQ(d.findings[0].name(), "inertia");
  ASSERT_TRUE(d.final_model.has_value());
  const auto& ext = std::get<Extended<MaxwellSlip<double>>>(d.final_model->variant());
  ASSERT_TRUE(ext.extensions().inertia.has_value());
  EXPECT_NEAR(ext.extensions().inertia->mass, mass, 0.02 * mass);
  EXPECT_LT(d.final_validation_percent, 0.01);
}

TEST(Diagnose, TheSameDiagnosisOnOneThreadAndOnSeveral) {
  Excitation ex;
  const double sigma = 2e-3;
  const std::vector<Injection> effects{{Injected::viscous, 40.0}, {Injected::offset, 0.05}};
  const Record est = with_noise(make_clean(effects, ex, 1000, 0.0), sigma, 11);
  const Record val = with_noise(make_clean(effects, ex, 1000, 1.0), sigma, 12);
  DiagnoseOptions one;
  one.threads = 1;
  // Few candidates, a short record: the ThreadSanitizer pass runs this test ~100 times slower.
  one.candidates = {Effect::viscous, Effect::offset, Effect::asymmetry, Effect::drift};
  one.method.global_stage = false;
  one.method.max_operators = 4;
  DiagnoseOptions four = one;
  four.threads = 4;
  Json a = diagnose(est, val, one).to_json(), b = diagnose(est, val, four).to_json();
  ASSERT_FALSE(a["findings"].empty()) << a.dump(1);
  drop_timings(a);
  drop_timings(b);
  EXPECT_EQ(a.dump(), b.dump());
}

// The refined grid's windows that diagnose() chooses beside the baseline's fit, ahead of the
// floors, are the ones stepped_finely would choose for itself: the same force, bit for bit, and
// the same floor.  Windows chosen for the record instead would give another force (the test
// would see a mix-up of the two).
TEST(DiagnoseFloors, TheRefinedGridsWindowsMadeAheadGiveTheSameSteppedForce) {
  Excitation ex;
  Record r = with_noise(make_clean(Injected::viscous, 40.0, ex, 1500, 0.0), 2e-3, 31);
  for (double& x : r.displacement) x = 2e-8 * std::round(x / 2e-8);  // an encoder's staircase
  diagnose_detail::State s;
  s.base = truth_parameters();
  s.rho.assign(s.base.size(), 0.1);
  s.ext.reference_force = s.base.sliding_force();
  s.ext.enable(Effect::viscous);
  s.ext.viscous->viscous = 40.0;
  s.ext.enable(Effect::inertia);
  s.ext.inertia->mass = 0.5;
  const std::vector<double> initial = deflections_from_relative(s.base, s.rho, s.ext);
  const std::vector<double> chosen_there = diagnose_detail::stepped_finely(s, initial, r);
  const DerivativeWindows ahead = diagnose_detail::fine_grid_windows(r);
  EXPECT_EQ(diagnose_detail::stepped_finely(s, initial, r, &ahead), chosen_there);
  const DerivativeWindows record_windows = record_derivative_windows(r);
  ASSERT_NE(record_windows, ahead);
  EXPECT_NE(diagnose_detail::stepped_finely(s, initial, r, &record_windows), chosen_there);
  for (std::size_t j = 0; j < diagnose_detail::kSensorReplicas; ++j)
    diagnose_detail::warm_sensor_replica(r, j);
  const double floor_there = diagnose_detail::measurement_floor_rss(s, s.rho, r, record_windows, 2);
  EXPECT_GT(floor_there, 0.0);
  EXPECT_EQ(diagnose_detail::measurement_floor_rss(s, s.rho, r, record_windows, 1, &ahead),
            floor_there);
}

// Rule (b) at the estimation record's floor: with N = 4000 samples of unit noise, a floor of
// 4000 and 200 more from the displacement's sampling, a model within three standard deviations of
// the noise's RSS (sqrt(2 N) = 89.4 each) of that floor leaves nothing for a drop to show; one
// above it, or at the same RSS without the sampling's part, does.
TEST(DiagnoseRules, NoDropIsRealOnAModelAtTheEstimationRecordsFloor) {
  const Record est, val;
  const DiagnoseOptions o;
  const auto context = [&](double sampling_rss) {
    return diagnose_detail::Context{est,  val, o,   4000, 1.0, 4000.0, 1.0,     0.0,    0.0,
                                    sampling_rss, {}, {}, 0.0,  0.0, 0.0,    nullptr, nullptr};
  };
  const double band = 3.0 * std::sqrt(2.0 * 4000.0);  // 268.3
  const auto verdict = [&](const diagnose_detail::Context& c, double rss0) {
    // A one-parameter piece taking the model to the noise floor: BIC falls, the drop passes the
    // noise's and the share's parts; the validation falls too.
    return diagnose_detail::accept(c, rss0, 4000.0, 1, 1.0, 0.5, 0.0);
  };
  const diagnose_detail::Context with_sampling = context(200.0);
  const Verdict at = verdict(with_sampling, 4000.0 + 200.0 + band - 1.0);
  EXPECT_TRUE(at.estimation_at_floor);
  EXPECT_TRUE(at.bic_falls() && at.drop_exceeds());
  EXPECT_FALSE(at.passes_estimation_rules());
  EXPECT_FALSE(at.earns_place());
  EXPECT_NE(at.to_text().find("nothing above it to explain"), std::string::npos) << at.to_text();
  const Verdict above = verdict(with_sampling, 4000.0 + 200.0 + band + 1.0);
  EXPECT_FALSE(above.estimation_at_floor);
  EXPECT_TRUE(above.earns_place()) << above.to_text();
  const Verdict without_sampling = verdict(context(0.0), 4000.0 + 200.0 + band - 1.0);
  EXPECT_FALSE(without_sampling.estimation_at_floor);
  EXPECT_TRUE(without_sampling.earns_place()) << without_sampling.to_text();
}

// The table keeps one line per candidate whatever its verdict's length.
TEST(DiagnoseTable, EveryCandidateHasItsLine) {
  Diagnosis d;
  for (Effect e : {Effect::viscous, Effect::offset, Effect::inertia}) {
    CandidateFit c;
    c.effect = e;
    c.verdict.at_bound = "a_parameter_with_a_long_name";
    c.verdict.delta_bic = 12.0;
    c.verdict.required = 1.0;
    c.verdict.operator_limited = true;
    c.verdict.estimation_at_floor = true;
    d.first_round.push_back(c);
  }
  ASSERT_GT(d.first_round.front().verdict.to_text().size(), 400u);
  const std::string table = d.to_table();
  for (const char* name : {"\n  viscous ", "\n  offset ", "\n  inertia "})
    EXPECT_NE(table.find(name), std::string::npos) << name << " in\n" << table;
}

// A LuGre baseline on a multi-element Maxwell Slip record: the single state misses the nonlocal
// memory, and Maxwell Slip elements are the first finding.
TEST(Diagnose, LuGreBaselineFindsNonlocalMemory) {
  Excitation ex;
  const Record est = with_noise(make_clean(Injected::none, 0, ex, 3000, 0.0), 2e-3, 7);
  const Record val = with_noise(make_clean(Injected::none, 0, ex, 3000, 3.0), 2e-3, 8);
  DiagnoseOptions o;
  o.baseline = "lugre";
  const Diagnosis d = diagnose(est, val, o);
  ASSERT_FALSE(d.findings.empty()) << d.to_table();
  EXPECT_EQ(d.findings[0].name(), "nonlocal-memory");
  EXPECT_GE(d.findings[0].elements, 2u);
  EXPECT_LT(d.findings[0].validation_after, d.findings[0].validation_before);
  EXPECT_EQ(d.final_model->type(), "maxwell-slip");
  EXPECT_DOUBLE_EQ(d.findings.back().validation_after, d.final_validation_percent);
  // The element count is not estimated with a covariance: no standard error, said as null.
  const Json f = d.to_json()["findings"][0];
  EXPECT_TRUE(f["standard_errors"]["elements"].is_null());
  EXPECT_TRUE(f["intervals"]["elements"].is_null());
}

TEST(DiagnoseCli, JsonDocumentFollowsTheContract) {
  TempDir dir;
  Excitation ex;
  const Record r = with_noise(make_clean(Injected::offset, 0.01, ex, 4000, 0.0), 2e-3, 5);
  std::string csv = "time,displacement,force\n";
  char line[128];
  for (std::size_t k = 0; k < r.size(); ++k) {
    std::snprintf(line, sizeof line, "%.6f,%.10e,%.10e\n", r.time[k], r.displacement[k],
                  r.force[k]);
    csv += line;
  }
  write_text(dir.file("r.csv"), csv);
  const auto res =
      run_cli("diagnose --data " + dir.file("r.csv") + " --format json --svg " + dir.file("p.svg"));
  ASSERT_EQ(res.status, 0) << res.err;
  const Json j = Json::parse(res.out);
  EXPECT_TRUE(j.contains("schema_version"));
  EXPECT_TRUE(j["warnings"].is_array());
  EXPECT_FALSE(j["warnings"].empty());  // the hold-out is announced
  ASSERT_FALSE(j["findings"].empty());
  EXPECT_EQ(j["findings"][0]["effect"], "offset");
  EXPECT_NE(read_text(dir.file("p.svg")).find("<svg"), std::string::npos);
  // Bad usage: an unknown baseline.
  EXPECT_EQ(run_cli("diagnose --data " + dir.file("r.csv") + " --baseline nonsense").status, 2);
}

// A round on a model that validates at the floor accepts nothing (rule c), so the lag is not fitted
// again on the round's Stribeck curve there: that fit, the slowest of a round, could only change
// which of two turned-down lags the document shows.  The strokes bench record is such a record:
// its baseline validates at the floor, and so it also is on the estimation record, where its
// Stribeck candidate is turned down by rule (b) (before that rule knew the estimation record's
// floor, the curve passed rules a and b and was turned down at the validation floor).  The lag
// shown must be the one with its viscous companion (lag time, viscous, the lag's initial offset:
// 3 numbers; on the curve it is 5).
TEST(DiagnoseCli, NoLagOnTheStribeckCurveWhereNothingIsLeftToExplain) {
  const std::string bench = std::string(FRICTION_SOURCE_DIR) + "/data/bench/strokes/";
  const auto res = run_cli("diagnose --data " + bench + "est.csv --validate " + bench +
                           "val.csv --format json");
  ASSERT_EQ(res.status, 0) << res.err;
  const Json j = Json::parse(res.out);
  EXPECT_TRUE(j["findings"].empty()) << j["findings"].dump(1);
  const Json* stribeck = nullptr;
  const Json* lag = nullptr;
  for (const Json& c : j["candidates"]) {
    EXPECT_FALSE(c["earns_place"].get<bool>()) << c.dump(1);
    if (c["effect"] == "stribeck") stribeck = &c;
    if (c["effect"] == "frictional-lag") lag = &c;
  }
  ASSERT_TRUE(stribeck && lag) << j["candidates"].dump(1);
  // The precondition: the curve was turned down at the floor, on either record.
  const std::string why = stribeck->at("verdict").get<std::string>();
  ASSERT_TRUE(why.find("already at the floor") != std::string::npos ||
              why.find("nothing above it to explain") != std::string::npos)
      << stribeck->dump(1);
  EXPECT_EQ(lag->at("extra_parameters"), 3) << lag->dump(1);
}

}  // namespace
}  // namespace test_diagnose
}  // namespace friction::testing
