// Initial-state estimation of the Maxwell Slip operators from the record itself.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "friction/initial_state.hpp"
#include "identification_fixtures.hpp"

namespace {

using namespace friction;
using friction::testing::four_operator_system;
using friction::testing::synthetic_record;

// Cost of a free run from the given state.
double cost(const MaxwellSlipParameters<double>& p, const Record& rec,
            const std::vector<double>& d) {
  MaxwellSlip<double> m(p);
  m.reset(std::span<const double>(d));
  const auto f =
      simulate(m, std::span<const double>(rec.time), std::span<const double>(rec.displacement));
  return compute_errors(rec.force, f).rss;
}

TEST(InitialState, RecoversAKnownInitialDeflectionExactlyWithoutNoise) {
  // A record that starts slowly (400-sample fade-in): every operator moves freely over many
  // samples before it first saturates, so each delta_i(0) is determined by the data.
  const auto sys = four_operator_system();
  const std::vector<double> d0{0.5e-6, -2e-6, 3e-6, -10e-6};
  const Record rec = synthetic_record(sys, 2000, 30e-6, 0, 0.0, 1, d0, nullptr, 400);
  const auto d = estimate_initial_deflections(sys, rec.displacement, rec.force);
  ASSERT_EQ(d.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i) EXPECT_NEAR(d[i], d0[i], 1e-9 * sys.threshold[i]) << i;
}

TEST(InitialState, AFastStartIsFittedAsWellAsTheTrueState) {
  // Starting at full speed, operators saturate within a few samples and different states give the
  // same force: the estimate must then fit at least as well as the true state does.
  const auto sys = four_operator_system();
  const std::vector<double> d0{0.5e-6, -2e-6, 3e-6, -10e-6};
  const Record rec = synthetic_record(sys, 2000, 30e-6, 0, 0.0, 1, d0, nullptr);
  const auto d = estimate_initial_deflections(sys, rec.displacement, rec.force);
  EXPECT_LE(cost(sys, rec, d), 1e-24);
}

TEST(InitialState, RecoversItWithinNoiseAndBeatsTheVirginState) {
  const auto sys = four_operator_system();
  const std::vector<double> d0{-1e-6, 3e-6, -6e-6, 12e-6};  // operators 1 and 2 start saturated
  const Record rec = synthetic_record(sys, 2000, 25e-6, 1, 2e-3, 2, d0, nullptr, 400);
  const auto run = free_run_maxwell_slip(sys, rec.time, rec.displacement, rec.force);
  EXPECT_NEAR(run.initial_deflections[3], d0[3], 0.02 * sys.threshold[3]);
  EXPECT_NEAR(run.initial_deflections[2], d0[2], 0.05 * sys.threshold[2]);
  for (std::size_t i = 0; i < 4; ++i)
    EXPECT_LE(std::abs(run.initial_deflections[i]), sys.threshold[i]);
  // At least as good as the true state (it is the minimiser), and much better than virgin.
  EXPECT_LE(run.errors.rss, cost(sys, rec, d0) * (1 + 1e-9));
  EXPECT_LT(run.errors.rss, 0.5 * cost(sys, rec, {0, 0, 0, 0}));
}

TEST(InitialState, SpringFilterFormWithLags) {
  // A two-tap spring filter: Fhat = sum_i (a_i delta_i(t) + b_i delta_i(t-1)), record at rest
  // before.
  const std::vector<double> thr{2e-6, 9e-6};
  Eigen::MatrixXd filter(2, 2);
  filter << 3e4, 1e4, 2e4, -5e3;
  const std::vector<double> d0{-1.5e-6, 4e-6};
  const auto x = friction::testing::excitation(1500, 20e-6, 0, 400);
  MaxwellSlip<double> ops({{1.0, 1.0}, thr});
  ops.reset(std::span<const double>(d0));
  std::vector<double> f(x.size());
  std::vector<double> prev = d0;
  for (std::size_t k = 0; k < x.size(); ++k) {
    ops.step(Motion<double>{k > 0 ? x[k] - x[k - 1] : 0.0, 0.0, 0.0});
    const auto d = ops.deflections();
    f[k] = 0;
    for (std::size_t i = 0; i < 2; ++i)
      f[k] += filter(static_cast<Eigen::Index>(i), 0) * d[i] +
              filter(static_cast<Eigen::Index>(i), 1) * prev[i];
    prev.assign(d.begin(), d.end());
  }
  const auto d = estimate_initial_deflections(x, f, thr, filter);
  for (std::size_t i = 0; i < 2; ++i) EXPECT_NEAR(d[i], d0[i], 1e-9 * thr[i]) << i;
}

TEST(InitialState, RejectsMismatchedInput) {
  const std::vector<double> x(10, 0.0), f(9, 0.0), thr{1e-6};
  EXPECT_THROW(estimate_initial_deflections(x, f, thr, Eigen::MatrixXd::Ones(1, 1)),
               InvalidParameter);
  EXPECT_THROW(estimate_initial_deflections(x, std::vector<double>(10, 0.0), thr,
                                            Eigen::MatrixXd::Ones(2, 1)),
               InvalidParameter);
}

}  // namespace
