// The differentiator at the sample instants (sample_derivatives.hpp) judged against the exact
// velocity and acceleration of the independent simulator (tests/study).  The window rule was
// developed on the validation traces of seeds 4100-4129 (x 7919) and checked on 150 traces of
// seeds 777000-777074; the records here (seeds 5000-5029 and 6000-6011) were not looked at while
// developing it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "friction/sample_derivatives.hpp"
#include "study_design.hpp"

namespace friction::testing {
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

Errors errors_with(const truth::Trace& t, std::size_t mv, std::size_t ma) {
  std::vector<double> v(t.time.size()), a(t.time.size());
  local_polynomial_derivatives(t.time, t.position, mv, ma, v, a);
  return {rms_error(v, t.velocity), rms_error(a, t.acceleration)};
}

// The rule against the best fixed window of the same estimator (every half width up to 120).
void expect_near_best(const truth::Trace& t, const std::string& what) {
  const DerivativeWindows w = choose_derivative_windows(t.time, t.position);
  const Errors rule = errors_with(t, w.velocity_half_width, w.acceleration_half_width);
  Errors best{INFINITY, INFINITY};
  for (std::size_t m = 1; m <= 120 && 2 * m + 1 < t.time.size(); ++m) {
    const Errors e = errors_with(t, m, m);
    best.velocity = std::min(best.velocity, e.velocity);
    best.acceleration = std::min(best.acceleration, e.acceleration);
  }
  EXPECT_LE(rule.velocity, 1.5 * best.velocity)
      << what << ": velocity window " << w.velocity_half_width;
  EXPECT_LE(rule.acceleration, 1.5 * best.acceleration)
      << what << ": acceleration window " << w.acceleration_half_width;
  // The backward difference is half a sample late: never better than the rule on these records.
  std::vector<double> backward(t.time.size(), 0.0);
  for (std::size_t k = 1; k < t.time.size(); ++k)
    backward[k] = (t.position[k] - t.position[k - 1]) / (t.time[k] - t.time[k - 1]);
  EXPECT_LE(rule.velocity, rms_error(backward, t.velocity)) << what;
}

truth::StudyRecord study_record(std::uint64_t seed) {
  truth::RecordSpec spec;
  spec.id = "derivatives";
  spec.family = static_cast<truth::Family>(seed % 3);
  spec.seed = seed * 2654435761u;
  return truth::make_record(spec);
}

// Encoders from travel/30 000 to travel/1000, three excitation families, 200 Hz-5 kHz.
TEST(SampleDerivatives, WithinOneAndAHalfOfTheBestFixedWindowOnEncoderRecords) {
  for (std::uint64_t seed = 5000; seed < 5030; ++seed) {
    const truth::StudyRecord r = study_record(seed);
    expect_near_best(r.trace_estimation, "estimation: " + r.summary());
    expect_near_best(r.trace_validation, "validation: " + r.summary());
  }
}

// An analog sensor: white displacement noise of travel/100 000 to travel/3000, no quantum.
TEST(SampleDerivatives, WithinOneAndAHalfOfTheBestFixedWindowOnAnalogRecords) {
  for (std::uint64_t seed = 6000; seed < 6012; ++seed) {
    const truth::StudyRecord r = study_record(seed);
    truth::Measurement m = r.validation;
    m.quantum = 0;
    m.position_noise = r.travel * std::pow(10.0, -5.0 + 1.5 * static_cast<double>(seed % 4) / 3);
    const truth::Trace t = truth::simulate(r.system, *r.motion_validation, nullptr, m);
    char what[64];
    std::snprintf(what, sizeof what, ", sensor noise %.2g m", m.position_noise);
    expect_near_best(t, r.summary() + what);
  }
}

// A drive force with a large m a, a 10 nm encoder at 1 kHz: the least-squares mass on the rule's
// acceleration is right, where the raw second difference's noise (about q / (sqrt(2) Ts^2) per
// sample) dilutes it.
TEST(SampleDerivatives, InertiaSurvivesQuantisation) {
  truth::StrokeProgram p;
  p.start = -1;
  for (int j = 0; j < 12; ++j) {
    const double speed = (j % 2 ? -1 : 1) * (j % 3 + 1) * 2e-4;
    p.velocity.insert(p.velocity.end(), {speed, 0.0});
    p.duration.insert(p.duration.end(), {0.25, 0.1});
  }
  p.velocity.push_back(0);
  p.duration.push_back(2);
  p.width = 20e-3;
  const auto motion = truth::make_strokes(p);
  truth::System s;
  s.coulomb = 1;
  s.elements = {{1e5, 1.0}};
  truth::Measurement m;
  m.sampling_rate = 1000;
  m.samples = 4000;
  m.quantum = 10e-9;
  const truth::Trace t = truth::simulate(s, *motion, nullptr, m);
  const SampleDerivatives d = sample_derivatives(t.time, t.position);
  std::vector<double> raw(t.time.size(), 0.0);
  for (std::size_t k = 1; k + 1 < t.time.size(); ++k)
    raw[k] = (t.position[k + 1] - 2 * t.position[k] + t.position[k - 1]) * 1e6;
  const double mass = 3400;
  auto least_squares_mass = [&](const std::vector<double>& a) {
    double fa = 0, aa = 0;
    for (std::size_t k = 0; k < a.size(); ++k) {
      fa += mass * t.acceleration[k] * a[k];
      aa += a[k] * a[k];
    }
    return fa / aa;
  };
  EXPECT_NEAR(least_squares_mass(d.acceleration), mass, 0.03 * mass);
  EXPECT_LT(least_squares_mass(raw), 0.8 * mass);  // what the second difference gives
}

}  // namespace
}  // namespace friction::testing
