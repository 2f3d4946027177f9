// The DNLRX model: Maxwell Slip operators with a spring filter and an input filter (methods.md 4).
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <vector>

#include "friction/dnlrx.hpp"
#include "friction/maxwell_slip.hpp"
#include "friction/simulate.hpp"
#include "support/model_properties.hpp"

namespace test_dnlrx {
namespace {

using friction::Dnlrx;
using friction::DnlrxParameters;
using friction::DnlrxRegressor;
using friction::MaxwellSlip;
using friction::MaxwellSlipParameters;
using friction::Motion;

const MaxwellSlipParameters<double> kFour{{4e4, 3e4, 2e4, 1e4}, {1e-6, 3e-6, 7e-6, 15e-6}};

std::vector<double> run(auto& model, const std::vector<double>& time,
                        const std::vector<double>& x) {
  model.reset();
  return friction::simulate(model, std::span<const double>(time), std::span<const double>(x));
}

TEST(Dnlrx, TrivialFiltersReproduceMaxwellSlip) {
  std::vector<double> time, x;
  friction::testing::test_excitation(3000, 1e-3, 20e-6, time, x);
  MaxwellSlip<double> ms(kFour);
  auto p = DnlrxParameters<double>::from_maxwell_slip(kFour);
  p.input_filter = {0.0};  // nx = 0, g = 0
  Dnlrx<double> dnlrx(p);
  const auto f_ms = run(ms, time, x);
  const auto f_dnlrx = run(dnlrx, time, x);
  const double scale = kFour.sliding_force();
  for (std::size_t k = 0; k < x.size(); ++k) ASSERT_NEAR(f_dnlrx[k], f_ms[k], 1e-13 * scale) << k;
  EXPECT_NEAR(p.sliding_force(), scale, 1e-15);
}

TEST(Dnlrx, LevelScalesTheThresholdsAsInMaxwellSlip) {
  auto p = DnlrxParameters<double>::from_maxwell_slip(kFour);
  Dnlrx<double> dnlrx(p);
  double f = 0;
  for (int k = 0; k < 400; ++k) f = dnlrx.step({1e-7, 1e-4, 1e-3, 1.3});
  EXPECT_NEAR(f, 1.3 * kFour.sliding_force(), 1e-12);
}

TEST(Dnlrx, InputFilterGivesSpeedDependentSlidingForce) {
  // Steady sliding at constant speed v with period Ts: dx = v Ts on every sample, so the input
  // filter adds (sum g_j) v Ts to the spring filter's sum theta_{i,j} Delta_i.
  auto p = DnlrxParameters<double>::from_maxwell_slip(kFour);
  p.spring_order = 1;
  p.spring_filter = {3e4, 1e4, 2e4, 1e4, 1e4, 1e4, 5e3, 5e3};  // rows i, taps j = 0, 1
  p.input_filter = {2e3, 1e3, 5e2};                            // nx = 2, N/m
  const double ts = 1e-3;
  auto sliding_force_at = [&](double v) {
    Dnlrx<double> m(p);
    double f = 0;
    for (int k = 0; k < 2000; ++k) f = m.step({v * ts, v, ts});
    return f;
  };
  const double f0 = p.sliding_force();
  EXPECT_NEAR(f0, (3e4 + 1e4) * 1e-6 + 3e4 * 3e-6 + 2e4 * 7e-6 + 1e4 * 15e-6, 1e-15);
  for (double v : {1e-4, 1e-3, 1e-2}) {
    EXPECT_NEAR(sliding_force_at(v), f0 + 3.5e3 * v * ts, 1e-12) << "v = " << v;
    EXPECT_NEAR(sliding_force_at(-v), -(f0 + 3.5e3 * v * ts), 1e-12) << "v = " << -v;
  }
  EXPECT_GT(sliding_force_at(1e-2), sliding_force_at(1e-3));
}

TEST(Dnlrx, SpringFilterActsOnDelayedDeflections) {
  // theta_{i,1} only: the force is the Maxwell Slip force one sample late.
  auto p = DnlrxParameters<double>::from_maxwell_slip(kFour);
  p.spring_order = 1;
  p.spring_filter.clear();
  for (double k : kFour.stiffness) p.spring_filter.insert(p.spring_filter.end(), {0.0, k});
  Dnlrx<double> dnlrx(p);
  MaxwellSlip<double> ms(kFour);
  std::vector<double> time, x;
  friction::testing::test_excitation(500, 1e-3, 20e-6, time, x);
  const auto f_ms = run(ms, time, x);
  const auto f_d = run(dnlrx, time, x);
  EXPECT_EQ(f_d[0], 0.0);
  for (std::size_t k = 1; k < x.size(); ++k) ASSERT_NEAR(f_d[k], f_ms[k - 1], 1e-15) << k;
}

TEST(Dnlrx, RegressorRowTimesCoefficientsIsTheForce) {
  auto p = DnlrxParameters<double>::from_maxwell_slip(kFour);
  p.spring_order = 2;
  p.spring_filter.clear();
  for (std::size_t i = 0; i < 4; ++i)
    for (double w : {0.6, 0.3, 0.1})
      p.spring_filter.push_back(w * kFour.stiffness[i] * (1 + 0.1 * i));
  p.input_filter = {1e3, -4e2, 2e2};
  std::vector<double> time, x;
  friction::testing::test_excitation(1500, 1e-3, 20e-6, time, x);
  Dnlrx<double> model(p);
  const auto force = run(model, time, x);

  DnlrxRegressor<double> state(p.threshold, p.spring_order, p.input_taps());
  state.reset();
  const auto phi = friction::dnlrx_regressor_matrix(state, std::span<const double>(time),
                                                    std::span<const double>(x));
  ASSERT_EQ(phi.cols(), 4 * 3 + 3);
  Eigen::VectorXd coefficients(phi.cols());
  for (std::size_t c = 0; c < p.spring_filter.size(); ++c) coefficients[c] = p.spring_filter[c];
  for (std::size_t j = 0; j < 3; ++j) coefficients[12 + j] = p.input_filter[j];
  const Eigen::VectorXd predicted = phi * coefficients;
  for (std::size_t k = 0; k < x.size(); ++k) ASSERT_NEAR(predicted[k], force[k], 1e-12) << k;

  // Linear in the filters: least squares on the regressors recovers them from the force.
  const Eigen::VectorXd f = Eigen::Map<const Eigen::VectorXd>(force.data(), force.size());
  const Eigen::VectorXd estimated = phi.colPivHouseholderQr().solve(f);
  EXPECT_LT((estimated - coefficients).norm(), 1e-6 * coefficients.norm());

  // The per-sample row of the model's own state is the matrix's last row.
  std::vector<double> row(state.row_size());
  model.state().row(row);
  for (std::size_t c = 0; c < row.size(); ++c) EXPECT_EQ(row[c], phi(phi.rows() - 1, c));
}

TEST(Dnlrx, ResetToDeflectionsHoldsThemAtRest) {
  auto p = DnlrxParameters<double>::from_maxwell_slip(kFour);
  p.spring_order = 1;
  p.spring_filter = {2e4, 2e4, 1e4, 2e4, 1e4, 1e4, 5e3, 5e3};
  p.input_filter = {1e3};
  Dnlrx<double> m(p);
  const std::vector<double> d0{1e-6, -2e-6, 5e-6, -20e-6};  // the last one is clamped to -15 um
  m.reset(d0);
  const double expected = 4e4 * 1e-6 - 3e4 * 2e-6 + 2e4 * 5e-6 - 1e4 * 15e-6;
  EXPECT_NEAR(m.step({0, 0, 0}), expected, 1e-15);
  EXPECT_NEAR(m.force(), expected, 1e-15);
}

TEST(Dnlrx, RejectsInvalidParameters) {
  using P = DnlrxParameters<double>;
  EXPECT_THROW(Dnlrx<double>(P{{}, 0, {}, {}}), friction::InvalidParameter);
  EXPECT_THROW(Dnlrx<double>(P{{1e-6}, 0, {1.0, 2.0}, {}}), friction::InvalidParameter);
  EXPECT_THROW(Dnlrx<double>(P{{-1e-6}, 0, {1.0}, {}}), friction::InvalidParameter);
  EXPECT_THROW(Dnlrx<double>(P{{1e-6}, 1, {1.0, NAN}, {}}), friction::InvalidParameter);
  EXPECT_THROW(Dnlrx<double>(P{{1e-6}, 0, {1.0}, {INFINITY}}), friction::InvalidParameter);
  EXPECT_NO_THROW(Dnlrx<double>(P{{1e-6}, 1, {1.0, -2.0}, {-3.0}}));  // any sign
}

TEST(Dnlrx, JetDerivativesMatchFiniteDifferencesAndStepDoesNotAllocate) {
  // M = 3, n = 1, nx = 1: theta (6), g (2), thresholds (3).
  auto factory = [](const auto& theta) {
    using T = typename std::decay_t<decltype(theta)>::value_type;
    DnlrxParameters<T> p;
    p.threshold = {theta[0], theta[1], theta[2]};
    p.spring_order = 1;
    p.spring_filter.assign(theta.begin() + 3, theta.begin() + 9);
    p.input_filter = {theta[9], theta[10]};
    return Dnlrx<T>(p);
  };
  std::vector<double> time, x;
  friction::testing::test_excitation(3000, 1e-3, 20e-6, time, x);
  const std::vector<double> theta{2e-6, 6e-6, 14e-6, 3e4, 1e4, 2e4, 5e3, 1e4, 2e3, 5e3, 2e3};
  friction::testing::expect_derivatives_match_finite_differences(factory, theta, time, x, 1e-4);
  auto model = factory(theta);
  friction::testing::expect_step_does_not_allocate(model, time, x);
}

}  // namespace
}  // namespace test_dnlrx
