// The differentiator's window rule (sample_derivatives.hpp) judged against the best fixed window on
// the exact velocity and acceleration of the independent simulator (tests/study): studies of 42
// records, labelled long (the sanitizer pass leaves them to the Release pass; the differentiator's
// code runs under the sanitizers in test_sample_derivatives and in every diagnosis).  The window
// rule was developed on the validation traces of seeds 4100-4129 (x 7919) and checked on 150
// traces of seeds 777000-777074; the records here (seeds 5000-5029 and 6000-6011) were not looked
// at while developing it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "derivative_records.hpp"
#include "friction/record.hpp"
#include "friction/sample_derivatives.hpp"
#include "friction/signals.hpp"

namespace friction::testing {
namespace test_sample_derivative_studies {
namespace {

double rms_error(const std::vector<double>& estimate, const std::vector<double>& exact) {
  double s = 0;
  for (std::size_t k = 0; k < exact.size(); ++k)
    s += (estimate[k] - exact[k]) * (estimate[k] - exact[k]);
  return std::sqrt(s / static_cast<double>(exact.size()));
}

struct Errors {
  double velocity, acceleration;
};

Errors errors_with(const truth::Trace& t, const DerivativeWindows& w) {
  std::vector<double> v(t.time.size()), a(t.time.size());
  local_polynomial_derivatives(t.time, t.position, w, v, a);
  return {rms_error(v, t.velocity), rms_error(a, t.acceleration)};
}

// The half widths the rule is judged against: every one up to 20, then steps of about 5 % up to
// 120.  Every half width up to 120 cost three times as much (a window's cost grows with its
// width); near its best a window's error is flat in the logarithm of its width.  Leaving widths
// out can only make the best worse, so the reference is looser than the full grid: on the 72
// traces below its best was within 0.7 % of the full grid's in velocity and within 5.3 % in
// acceleration (2.5 % on the trace whose rule came closest to the bound, 1.48 times the full
// grid's best; measured 2026-12-07).
std::vector<std::size_t> reference_half_widths() {
  std::vector<std::size_t> widths;
  for (std::size_t m = 1; m <= 20; ++m) widths.push_back(m);
  while (widths.back() < 120)
    widths.push_back(std::min<std::size_t>(
        120, std::max(widths.back() + 1,
                      static_cast<std::size_t>(std::lround(1.05 * static_cast<double>(
                                                               widths.back()))))));
  return widths;
}

// The rule against the best fixed window of the same estimator (the half widths above, both
// degrees).
void expect_near_best(const truth::Trace& t, const std::string& what) {
  const DerivativeWindows w = choose_derivative_windows(t.time, t.position);
  const Errors rule = errors_with(t, w);
  Errors best{INFINITY, INFINITY};
  static const std::vector<std::size_t> half_widths = reference_half_widths();
  for (std::size_t degree : {2u, 4u})
    for (std::size_t m : half_widths) {
      if (m < degree / 2 || 2 * m + 1 >= t.time.size()) continue;
      DerivativeWindows fixed;
      fixed.velocity_half_width = fixed.acceleration_half_width = m;
      fixed.velocity_degree = fixed.acceleration_degree = degree;
      const Errors e = errors_with(t, fixed);
      best.velocity = std::min(best.velocity, e.velocity);
      best.acceleration = std::min(best.acceleration, e.acceleration);
    }
  EXPECT_LE(rule.velocity, 1.5 * best.velocity)
      << what << ": velocity window " << w.velocity_half_width << ", degree " << w.velocity_degree;
  EXPECT_LE(rule.acceleration, 1.5 * best.acceleration)
      << what << ": acceleration window " << w.acceleration_half_width << ", degree "
      << w.acceleration_degree;
  // The backward difference is half a sample late: never better than the rule on these records.
  std::vector<double> backward(t.time.size(), 0.0);
  for (std::size_t k = 1; k < t.time.size(); ++k)
    backward[k] = (t.position[k] - t.position[k - 1]) / (t.time[k] - t.time[k - 1]);
  EXPECT_LE(rule.velocity, rms_error(backward, t.velocity)) << what;
}

// Encoders from travel/30 000 to travel/1000, three excitation families, 200 Hz-5 kHz.
TEST(SampleDerivatives, WithinOneAndAHalfOfTheBestFixedWindowOnEncoderRecords) {
  for (std::uint64_t seed = 5000; seed < 5030; ++seed) {
    const truth::StudyRecord r = derivative_record(seed);
    expect_near_best(r.trace_estimation, "estimation: " + r.summary());
    expect_near_best(r.trace_validation, "validation: " + r.summary());
  }
}

// An analog sensor: white displacement noise of travel/100 000 to travel/3000, no quantum.
TEST(SampleDerivatives, WithinOneAndAHalfOfTheBestFixedWindowOnAnalogRecords) {
  for (std::uint64_t seed = 6000; seed < 6012; ++seed) {
    const truth::StudyRecord r = derivative_record(seed);
    truth::Measurement m = r.validation;
    m.quantum = 0;
    m.position_noise = r.travel * std::pow(10.0, -5.0 + 1.5 * static_cast<double>(seed % 4) / 3);
    const truth::Trace t = truth::simulate(r.system, *r.motion_validation, nullptr, m);
    char what[64];
    std::snprintf(what, sizeof what, ", sensor noise %.2g m", m.position_noise);
    expect_near_best(t, r.summary() + what);
  }
}

// The displacement the models see (sample_derivatives.hpp): on encoder records of the independent
// simulator (seeds 5100-5129, not looked at while developing the rule), condition_record's estimate
// against the exact displacement (the same record simulated without the quantiser).  It must never
// be further from it than the staircase; the record keeps the staircase as measured.  (The
// derivatives are taken of the measured displacement, with the windows above: applied to the
// estimate instead, they were worse than 1.5 times the best fixed window on 2 of these 30.)  On an
// unquantised record the models see the samples as measured.
TEST(SampleDerivatives, TheDisplacementTheModelsSeeIsCloserToTheTruthThanTheStaircase) {
  std::vector<double> ratios;
  for (std::uint64_t seed = 5100; seed < 5130; ++seed) {
    const truth::StudyRecord r = derivative_record(seed);
    const truth::Trace& t = r.trace_validation;
    for (const bool quantised : {true, false}) {
      truth::Measurement exact_m = r.validation;
      exact_m.quantum = 0;
      const truth::Trace exact = truth::simulate(r.system, *r.motion_validation, nullptr, exact_m);
      Record rec;
      rec.time = t.time;
      rec.displacement = quantised ? t.position : exact.position;
      rec.force = t.force;
      condition_record(rec);
      if (!quantised) {
        EXPECT_TRUE(rec.measured_displacement.empty()) << r.summary();
        EXPECT_EQ(rec.displacement, exact.position) << r.summary();
        continue;
      }
      ASSERT_EQ(rec.measured(), t.position);
      const double staircase = rms_error(t.position, exact.position);
      const double estimate = rms_error(rec.displacement, exact.position);
      ratios.push_back(estimate / staircase);
      EXPECT_LE(estimate, staircase)
          << r.summary() << ": window " << rec.conditioning.displacement_half_width << ", degree "
          << rec.conditioning.displacement_degree;
    }
  }
  std::sort(ratios.begin(), ratios.end());
  std::printf(
      "RMS error of the estimate / of the staircase over %zu records: median %.3f, range "
      "%.3f-%.3f\n",
      ratios.size(), ratios[ratios.size() / 2], ratios.front(), ratios.back());
  // And it removes a good part of the staircase on a typical record (0.37 of its RMS error was
  // measured): an estimate that did nothing would pass the test above with a ratio of one.
  EXPECT_LT(ratios[ratios.size() / 2], 0.75);
}

}  // namespace
}  // namespace test_sample_derivative_studies
}  // namespace friction::testing
