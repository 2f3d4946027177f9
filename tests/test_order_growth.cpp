// Told the effect, it fits it, where the base's order selection cannot see through the effect:
// `identify --extension normal-load` and `--extension delay` on records of the independent
// simulator (tests/study, the discovery study's own record design).
//
// The restart of an extended Maxwell Slip fit selects M again by NLR on the force with the pieces
// taken out (extension_identification.hpp, section 1).  Dividing by the level is exact only for
// operators at their slip limits, and a delay shifts the motion the operators see: on a study
// record with a varying normal force BIC stopped at 4 operators and the extended model validated
// at 5.6 times the floor.  The criterion is the study's (issue 7): where the base fits the twin
// without the effect within 1.05 times its floor and the effect contributes at least 3 times the
// noise, the extended fit validates within 1.2 times the reachable floor.
//
// The random records' seeds were not used while the growth was developed.  They found a defect
// of their own: a delay fit started at D = 0 had a zero gradient there (delayed_displacement_into
// dropped the derivative) and stayed at 0, 36 times the floor (delay-7).  On them the growth
// itself changes nothing (with ExtensionFitOptions::grow_operators off they pass too); the study's
// record in the second test fails without it.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "friction/diagnose.hpp"
#include "friction/effect_table.hpp"
#include "friction/methods.hpp"
#include "friction/signals.hpp"
#include "study_design.hpp"
#include "truth_records.hpp"

namespace friction {
namespace test_order_growth {
namespace {

using testing::record_of;

double validation_percent(const truth::StudyRecord& s, const MethodOptions& o) {
  const IdentifiedModel id = identify_model("maxwell-slip", record_of(s.trace_estimation), o);
  return validate_model(id.model, record_of(s.trace_validation)).errors.rss_sss_percent;
}

struct Told {
  bool eligible = false;
  double twin = 0, told = 0;  // validation over the reachable floor
};

// The study's told-the-effect case (tests/study/test_discovery_study.cpp, run_told) on `spec`.
Told told_case(const truth::RecordSpec& spec, Effect effect) {
  const truth::StudyRecord s = truth::make_record(spec);
  const truth::StudyRecord twin = truth::twin_without(s, spec.effects);
  Told t;
  t.twin = validation_percent(twin, MethodOptions{}) / twin.reachable_floor_percent;
  const bool strong = s.contribution.at(spec.effects.front()) >= 3 * s.validation.noise_sigma;
  if (!strong || t.twin > 1.05) return t;
  t.eligible = true;
  MethodOptions o;
  o.extensions = {effect};
  t.told = validation_percent(s, o) / s.reachable_floor_percent;
  std::printf("%-14s %s: the base on the twin %.3f, told %.3f times the floor\n",
              spec.id.c_str(), s.summary().c_str(), t.twin, t.told);
  return t;
}

TEST(OrderGrowth, ToldNormalLoadOrDelayTheExtendedFitReachesTheFloor) {
  int eligible = 0;
  const std::vector<std::pair<std::string, Effect>> effects = {
      {"normal-load", Effect::normal_load}, {"delay", Effect::delay}};
  for (std::uint64_t k = 0; k < 8; ++k) {
    const auto& [name, effect] = effects[k % 2];
    truth::RecordSpec spec;
    spec.id = name + "-" + std::to_string(k);
    spec.effects = {name};
    spec.family = static_cast<truth::Family>((k / 2) % 3);
    spec.seed = 0x6a09e667f3bcc908ULL + 1000003ULL * k;
    const Told t = told_case(spec, effect);
    eligible += t.eligible;
    if (t.eligible) {
      EXPECT_LE(t.told, 1.2) << spec.id << ", seed " << spec.seed;
    }
  }
  // The criterion needs records it applies to: all 8 are eligible on these seeds.
  EXPECT_GE(eligible, 4);
}

// The discovery-study record that led here (seed 0xad334fae2b6c3603), kept as a regression:
// without the growth the extended fit stays at the base's 4 operators and validates at 5.6 times
// the floor.  (The study's delay-2, 2.05 times the floor before the restart ran on the shifted
// displacement, is not eligible here: read from its CSV file by the CLI its twin's base reaches
// 1.03 times the floor, from the unrounded trace 1.33.)
TEST(OrderGrowth, TheStudyRecordThatLedHereReachesTheFloor) {
  truth::RecordSpec spec;
  spec.id = "normal-load-3";
  spec.effects = {"normal-load"};
  spec.family = truth::Family::envelope;
  spec.seed = 2539026706453809786ULL;
  spec.validation = truth::ValidationDesign::independent_design;  // the record as the study drew it
  const Told t = told_case(spec, Effect::normal_load);
  ASSERT_TRUE(t.eligible) << spec.id << ": the base on the twin " << t.twin;
  EXPECT_LE(t.told, 1.2) << spec.id;
}

// Growth past NLR's first range of M = 1..8 (extension_identification.hpp, 1: Order growth).  The
// study's systems have 3 to 12 elements, and the growth stopped at 8.  With it allowed to go on
// while the joint BIC falls, the diagnosis's final model came closer to the reachable floor on 20
// records of six study seeds (8835639881565398229, 101, 202, 303, 404, 505), none further.  Two
// of the three furthest before are kept here: diagnosed, each must be named exactly and the final
// model validate within 1.2 times the reachable floor (the study's told criterion, on the
// diagnosis).  Through the CLI they validated at 2.92 and 1.59 times the floor with the growth
// capped at 8, and at 1.17 and 0.67 without the cap (README, "Growth past NLR's first range");
// here 2.89 and 1.59 against 1.17 and 0.66.  The third, stribeck-2 at seed 101 (1.60 -> 0.91
// through the CLI), is not a test of the growth: from the unrounded trace the diagnosis ends in
// another minimum, 1.76 times the floor with the growth and 1.60 without.
TEST(OrderGrowth, StudyRecordsOfMoreElementsThanNlrsFirstRangeReachTheFloor) {
  const struct {
    std::uint64_t seed;
    const char* id;
    Effect effect;
  } cases[] = {{404, "normal-load-2", Effect::normal_load},
               {404, "position-dependence-1", Effect::position_dependence}};
  for (const auto& c : cases) {
    const std::optional<truth::RecordSpec> spec = truth::plan_record(c.seed, c.id);
    ASSERT_TRUE(spec) << c.id;
    const truth::StudyRecord s = truth::make_record(*spec);
    ASSERT_GT(s.system.elements.size(), 8u) << c.id;
    // Conditioned as read from a file (the encoder's staircase replaced by the displacement the
    // models see, signals.hpp): the diagnosis a user gets.
    Record est = record_of(s.trace_estimation), val = record_of(s.trace_validation);
    condition_record(est);
    condition_record(val);
    DiagnoseOptions capped;
    capped.method.max_operators = 8;
    const Diagnosis grown = diagnose(est, val), at_eight = diagnose(est, val, capped);
    std::vector<std::string> named;
    for (const Finding& f : grown.findings)
      named.emplace_back(f.effect ? effect_name(*f.effect) : "nonlocal-memory");
    const double floor = s.reachable_floor_percent;
    std::printf("%-22s %s: %zu findings, final %.3f times the floor (capped at 8: %.3f)\n", c.id,
                s.summary().c_str(), named.size(), grown.final_validation_percent / floor,
                at_eight.final_validation_percent / floor);
    EXPECT_EQ(named, std::vector<std::string>{std::string(effect_name(c.effect))})
        << c.id << " at seed " << c.seed;
    EXPECT_LE(grown.final_validation_percent, 1.2 * floor) << c.id << " at seed " << c.seed;
  }
}

}  // namespace
}  // namespace test_order_growth
}  // namespace friction
