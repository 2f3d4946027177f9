// A delay is named only when it exceeds the shift that stepping the model once per sample
// imitates (diagnose.hpp, Nested candidates), judged on records of the independent simulator
// (tests/study, the discovery study's record design), whose elements step on a grid 16 times finer
// than the sampling.
//
// At a reversal between two samples a model stepped per sample misses the excursion to the extreme
// and reverses late; a small negative delay partly mends that.  Once a delay fit could leave D = 0
// (ff51200), the discovery study at 8e44206's seed named delays of -0.006 to -0.025 sample periods
// on two records without any effect (none-01, none-15, kept below as regressions) and beside a
// viscous term.  With the check they are turned down; true delays (the study's are 0.2 sample
// periods and more) are still named.  Without the check the first test fails on both regression
// records.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "friction/diagnose.hpp"
#include "study_design.hpp"
#include "truth_records.hpp"

namespace friction {
namespace test_delay_stepping {
namespace {

using testing::record_of;

std::vector<std::string> named(const truth::RecordSpec& spec) {
  const truth::StudyRecord s = truth::make_record(spec);
  const Diagnosis d = diagnose(record_of(s.trace_estimation), record_of(s.trace_validation));
  std::vector<std::string> out;
  for (const Finding& f : d.findings)
    if (f.effect) out.push_back(std::string(effect_name(*f.effect)));
  std::string list;
  for (const auto& e : out) list += (list.empty() ? "" : ", ") + e;
  std::printf("%-10s %s: %s\n", spec.id.c_str(), s.summary().c_str(),
              list.empty() ? "nothing" : list.c_str());
  return out;
}

bool has(const std::vector<std::string>& v, const std::string& e) {
  return std::find(v.begin(), v.end(), e) != v.end();
}

TEST(DelayFindings, NoneOnRecordsWithoutADelay) {
  std::vector<truth::RecordSpec> specs;
  // The discovery study's records at 8e44206's seed (10251354291482620972).
  // Records of that day's study, so their validation design is drawn again as it was then.
  specs.push_back({"none-01", {}, "maxwell-slip", truth::Family::envelope, 15848307424988192698ULL,
                   truth::ValidationDesign::independent_design});
  specs.push_back({"none-15", {}, "maxwell-slip", truth::Family::envelope, 15850877211552078544ULL,
                   truth::ValidationDesign::independent_design});
  // Fresh records, every excitation family (envelope twice: its presliding loops reverse most).
  for (std::uint64_t k = 0; k < 4; ++k)
    specs.push_back({"fresh-" + std::to_string(k), {}, "maxwell-slip",
                     static_cast<truth::Family>(k % 3), 0xbb67ae8584caa73bULL + 7919ULL * k});
  for (const auto& spec : specs)
    EXPECT_FALSE(has(named(spec), "delay")) << spec.id << ", seed " << spec.seed;
}

TEST(DelayFindings, TrueDelaysAreStillNamed) {
  for (std::uint64_t k = 0; k < 3; ++k) {
    const truth::RecordSpec spec{"delay-" + std::to_string(k), {"delay"}, "maxwell-slip",
                                 static_cast<truth::Family>(k % 3),
                                 0x3c6ef372fe94f82bULL + 104723ULL * k};
    EXPECT_TRUE(has(named(spec), "delay")) << spec.id << ", seed " << spec.seed;
  }
}

}  // namespace
}  // namespace test_delay_stepping
}  // namespace friction
