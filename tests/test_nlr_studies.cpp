// NLR studies on random systems (ctest label "long": many fits of the same code path, which the
// Release pass runs and the sanitizer passes leave to the short tests of test_nlr.cpp).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <random>
#include <vector>

#include "friction/nlr.hpp"
#include "friction/record.hpp"

namespace test_nlr_studies {
namespace {

using namespace friction;

TEST(NlrStudy, TheDictionaryStartAloneReachesTheFloorOnRandomSystems) {
  // Random operator systems (4-8 operators, thresholds log-uniform over two to three decades of
  // the travel, sliding forces log-uniform over a factor 5, a random initial state), driven by a
  // random multisine under a random envelope, quantised to a 10 nm encoder, with white noise: the
  // test's own recursion, not the library's.  NLR at the true M without its global stage has one
  // start and one local search from it, so each fit must reach the noise floor from the
  // dictionary's clusters alone, with every parameter within four standard errors of the truth.
  // (Without the dictionary, the force-quantile and geometric starts end 3-10x above the floor on
  // such records and only the global stage's threshold moves found the minimum.)
  std::mt19937_64 gen(20261126);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  constexpr std::size_t kSystems = 8, n = 6000;
  constexpr double ts = 1e-3, q = 1e-8;
  int at_floor = 0;
  for (std::size_t sys_index = 0; sys_index < kSystems; ++sys_index) {
    const std::size_t m = 4 + static_cast<std::size_t>(u(gen) * 5.0);
    const double travel = 20e-6 * std::pow(10.0, u(gen));
    const double span = std::pow(10.0, 2.0 + u(gen));  // largest / smallest threshold
    std::vector<double> thr;
    while (thr.size() < m) {
      thr.clear();
      for (std::size_t i = 0; i < m; ++i) thr.push_back(0.5 * travel * std::pow(span, -u(gen)));
      std::sort(thr.begin(), thr.end());
      for (std::size_t i = 1; i < thr.size(); ++i)
        if (thr[i] < 1.7 * thr[i - 1]) thr.clear();
    }
    MaxwellSlipParameters<double> sys;
    for (std::size_t i = 0; i < m; ++i) {
      sys.threshold.push_back(thr[i]);
      sys.stiffness.push_back(std::pow(5.0, u(gen)) / thr[i]);  // sliding force 1-5 N each
    }
    std::vector<double> delta(m);
    for (std::size_t i = 0; i < m; ++i) delta[i] = (2.0 * u(gen) - 1.0) * thr[i];
    const std::vector<double> truth_initial = delta;
    double f[3], phase[3];
    for (int j = 0; j < 3; ++j) f[j] = 0.3 + 4.0 * u(gen), phase[j] = 2.0 * M_PI * u(gen);
    const double envelope_periods = 1.0 + 3.0 * u(gen), envelope_power = 0.5 + 2.0 * u(gen);
    const double sigma = 3e-3 * sys.sliding_force();
    std::normal_distribution<double> noise(0.0, sigma);
    Record rec;
    double x_prev = 0;
    for (std::size_t t = 0; t < n; ++t) {
      const double tt = ts * static_cast<double>(t);
      const double env =
          0.05 +
          0.95 * std::pow(std::abs(std::sin(M_PI * envelope_periods * static_cast<double>(t) /
                                            static_cast<double>(n))),
                          envelope_power);
      double x = 0;
      for (int j = 0; j < 3; ++j) x += std::sin(2.0 * M_PI * f[j] * tt + phase[j]) / 3.0;
      x = q * std::round(travel * env * x / q);
      if (t == 0) x_prev = x;
      double force = 0;
      for (std::size_t i = 0; i < m; ++i) {
        delta[i] = std::clamp(delta[i] + (x - x_prev), -thr[i], thr[i]);
        force += sys.stiffness[i] * delta[i];
      }
      x_prev = x;
      rec.time.push_back(tt);
      rec.displacement.push_back(x);
      rec.force.push_back(force + noise(gen));
    }
    NlrOptions o;
    o.operators = m;
    o.global_stage = false;
    const NlrResult r = identify_maxwell_slip(rec.time, rec.displacement, rec.force, o);
    ASSERT_FALSE(r.report.starts.empty());
    EXPECT_EQ(r.report.starts.front().kind, "dictionary");
    const double floor = static_cast<double>(n) * sigma * sigma;
    const double bound = floor * (1.0 + 4.0 * std::sqrt(2.0 / static_cast<double>(n)));
    std::cout << "system " << sys_index << ": M = " << m
              << ", RSS / (N sigma^2) = " << r.report.estimation.rss / floor << ", "
              << r.report.starts.size() << " local searches\n";
    EXPECT_LT(r.report.estimation.rss, bound) << "system " << sys_index << " (M = " << m << ")";
    at_floor += r.report.estimation.rss < bound;
    ASSERT_EQ(r.parameters.size(), m) << "system " << sys_index;
    for (std::size_t i = 0; i < 2 * m; ++i) {
      const ParameterEstimate& e = r.report.parameters[i];
      const double truth = i < m ? sys.stiffness[i] : sys.threshold[i - m];
      ASSERT_GT(e.standard_error, 0.0) << e.name;
      const double z = std::log(e.value / truth) / (e.standard_error / e.value);
      EXPECT_LE(std::abs(z), 4.0) << "system " << sys_index << " " << e.name << " " << e.value
                                  << " against " << truth;
    }
  }
  EXPECT_EQ(at_floor, static_cast<int>(kSystems));
}

}  // namespace
}  // namespace test_nlr_studies
