// NLR identification of the basic Maxwell Slip model: round trip on synthetic records.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <limits>
#include <random>
#include <vector>

#include "../src/slip_regression.hpp"
#include "friction/initial_state.hpp"
#include "friction/nlr.hpp"
#include "identification_fixtures.hpp"

namespace test_nlr {
namespace {

using namespace friction;
using friction::testing::four_operator_system;
using friction::testing::synthetic_record;

constexpr double kSigma = 2e-3;  // N, about 0.5 % of the sliding force 0.42 N

struct RoundTrip {
  Record estimation, validation;
  std::vector<double> validation_noise;
  NlrResult result;
};

const RoundTrip& round_trip() {
  static const RoundTrip rt = [] {
    RoundTrip r;
    const auto sys = four_operator_system();
    r.estimation =
        synthetic_record(sys, 3000, 30e-6, 0, kSigma, 11, {0.5e-6, -2e-6, 3e-6, -10e-6}, nullptr);
    r.validation = synthetic_record(sys, 3000, 25e-6, 1, kSigma, 12, {-1e-6, 3e-6, 0.0, 12e-6},
                                    &r.validation_noise);
    NlrOptions o;
    o.max_operators = 6;
    r.result =
        identify_maxwell_slip(r.estimation.time, r.estimation.displacement, r.estimation.force, o);
    const auto& rep = r.result.report;
    std::cout << "M table:\n";
    for (const auto& row : rep.selection)
      std::cout << "  M=" << row.operators << " rss%=" << row.rss_sss_percent
                << " BIC=" << row.criterion << (row.selected ? " *" : "") << "\n";
    for (const auto& p : rep.parameters)
      std::cout << "  " << p.name << " = " << p.value << " +- " << p.standard_error << " ["
                << p.lower95 << ", " << p.upper95 << "]\n";
    for (const auto& s : rep.starts)
      std::cout << "  start M=" << s.operators << " " << s.kind << " " << s.start_percent << " -> "
                << s.final_percent << (s.distinct ? " distinct" : "") << "\n";
    for (const auto& w : rep.warnings) std::cout << "  warning: " << w << "\n";
    std::cout << "  seconds " << rep.seconds << " estimation " << rep.estimation.rss_sss_percent
              << "% floor " << rep.noise_floor_percent << "%\n";
    return r;
  }();
  return rt;
}

TEST(Nlr, SelectsTheTrueNumberOfOperators) {
  const auto& rep = round_trip().result.report;
  ASSERT_FALSE(rep.selection.empty());
  std::size_t selected = 0;
  for (const auto& row : rep.selection)
    if (row.selected) selected = row.operators;
  EXPECT_EQ(selected, 4u);
  EXPECT_EQ(round_trip().result.parameters.size(), 4u);
}

TEST(Nlr, RecoversTheParametersWithinTheir95PercentIntervals) {
  const auto& r = round_trip().result;
  const auto sys = four_operator_system();
  ASSERT_EQ(r.parameters.size(), 4u);
  ASSERT_EQ(r.report.parameters.size(), 8u);
  for (std::size_t i = 0; i < 4; ++i) {
    const auto& k = r.report.parameters[i];
    const auto& d = r.report.parameters[4 + i];
    EXPECT_GT(k.standard_error, 0.0);
    EXPECT_GT(d.standard_error, 0.0);
    EXPECT_LE(k.lower95, sys.stiffness[i]) << k.name;
    EXPECT_GE(k.upper95, sys.stiffness[i]) << k.name;
    EXPECT_LE(d.lower95, sys.threshold[i]) << d.name;
    EXPECT_GE(d.upper95, sys.threshold[i]) << d.name;
  }
}

TEST(Nlr, ValidationErrorIsAtTheNoiseFloor) {
  const auto& rt = round_trip();
  const auto run = free_run_maxwell_slip(rt.result.parameters, rt.validation.time,
                                         rt.validation.displacement, rt.validation.force);
  const double floor = 100.0 * friction::testing::sum_of_squares(rt.validation_noise) /
                       friction::testing::sum_of_squares(rt.validation.force);
  std::cout << "validation " << run.errors.rss_sss_percent << "% floor " << floor << "%\n";
  EXPECT_LE(run.errors.rss_sss_percent, 1.2 * floor);
  // and the estimation error is at its own floor too (the fit is not stuck in a local minimum)
  EXPECT_LE(rt.result.report.estimation.rss_sss_percent,
            1.2 * rt.result.report.noise_floor_percent + 1e-3);
}

TEST(Nlr, ConstraintsHold) {
  const auto& r = round_trip().result;
  const auto& rep = r.report;
  for (std::size_t i = 0; i < r.parameters.size(); ++i) {
    EXPECT_GT(r.parameters.stiffness[i], 0.0);
    EXPECT_GE(r.parameters.threshold[i], rep.displacement_resolution);
    EXPECT_LE(r.parameters.threshold[i], rep.largest_travel);
    if (i > 0) {
      EXPECT_GE(r.parameters.threshold[i], r.parameters.threshold[i - 1]);
    }
  }
  for (const auto& s : rep.starts)
    for (std::size_t i = 0; i < s.final_thresholds.size(); ++i) {
      EXPECT_GE(s.final_thresholds[i], rep.displacement_resolution * (1 - 1e-12));
      EXPECT_LE(s.final_thresholds[i], rep.largest_travel * (1 + 1e-12));
    }
  EXPECT_EQ(rep.initial_state, "estimated");
  for (double v : rep.correlation.reshaped()) EXPECT_TRUE(std::isfinite(v));
}

// The record and threshold bounds (q, L) of the projected-residual tests.
struct ProjectionCase {
  Record rec;
  double lo, hi;
};

ProjectionCase projection_case() {
  ProjectionCase c;
  c.rec = synthetic_record(four_operator_system(), 1500, 30e-6, 0, kSigma, 5,
                           {0.5e-6, -2e-6, 3e-6, -10e-6}, nullptr);
  c.lo = displacement_resolution(c.rec.displacement);
  c.hi = largest_travel(c.rec.displacement);
  return c;
}

TEST(Nlr, ProjectedJacobianMatchesFiniteDifferences) {
  const auto [rec, lo, hi] = projection_case();
  // A point away from the optimum (large residual, so both Golub-Pereyra terms matter).
  const std::vector<double> start{1.3e-6, 2.5e-6, 8e-6, 13e-6};
  const std::vector<double> s = nlr_coordinates_from_thresholds(start, lo, hi);
  const std::vector<double> rho{0.3, -0.4, 0.2, -0.5};
  Eigen::VectorXd r0;
  Eigen::MatrixXd jac;
  nlr_projected_residual(rec.displacement, rec.force, lo, hi, s, rho, r0, &jac);
  ASSERT_EQ(jac.cols(), 8);
  ASSERT_TRUE(jac.allFinite());
  for (int p = 0; p < 8; ++p) {
    std::vector<double> sp = s, sm = s, rp = rho, rm = rho;
    const double h = 1e-7;
    if (p < 4)
      sp[p] += h, sm[p] -= h;
    else
      rp[p - 4] += h, rm[p - 4] -= h;
    Eigen::VectorXd fp, fm;
    nlr_projected_residual(rec.displacement, rec.force, lo, hi, sp, rp, fp, nullptr);
    nlr_projected_residual(rec.displacement, rec.force, lo, hi, sm, rm, fm, nullptr);
    const Eigen::VectorXd fd = (fp - fm) / (2 * h);
    EXPECT_GT(fd.norm(), 0.0) << "parameter " << p << " has no effect";
    EXPECT_LE((jac.col(p) - fd).norm(), 1e-4 * fd.norm() + 1e-9) << "parameter " << p;
  }
}

TEST(Nlr, CompressedJacobianHasTheNormalEquationsOfTheFullOne) {
  // The local search hands Ceres F with F^T F = [J r]^T [J r] instead of the N x 2M Jacobian J and
  // the N residuals r; F is built from row blocks without storing J.  Checked against the full J
  // at points that take each path: well-conditioned trajectories (blocked), two operators whose
  // thresholds differ by 1e-9 relative (ill-conditioned: the rank-revealing QR's J, compressed),
  // and one or two operators whose stiffness goes to its bound 0 (their columns are zero).
  const auto [rec, lo, hi] = projection_case();
  const std::vector<std::vector<double>> points{{1.3e-6, 2.5e-6, 8e-6, 13e-6},
                                                {1.3e-6, 4e-6, 4e-6 * (1 + 1e-9), 13e-6},
                                                {1e-6, 3e-6, 3.1e-6, 13e-6},
                                                {0.5e-6, 0.55e-6, 2e-6, 13e-6}};
  int bound = 0;
  for (const auto& thr : points) {
    const std::vector<double> s = nlr_coordinates_from_thresholds(thr, lo, hi);
    const std::vector<double> rho{0.3, -0.4, 0.2, -0.5};
    Eigen::VectorXd r;
    Eigen::MatrixXd jac, factor;
    Eigen::VectorXd k;
    nlr_projected_residual(rec.displacement, rec.force, lo, hi, s, rho, r, &jac, &k, &factor);
    ASSERT_EQ(factor.rows(), 9);
    ASSERT_EQ(factor.cols(), 9);
    Eigen::MatrixXd jr(jac.rows(), 9);
    jr << jac, r;
    const Eigen::MatrixXd want = jr.transpose() * jr, got = factor.transpose() * factor;
    for (Eigen::Index i = 0; i < 9; ++i)
      for (Eigen::Index j = 0; j < 9; ++j)
        EXPECT_LE(std::abs(got(i, j) - want(i, j)),
                  1e-10 * std::sqrt(want(i, i) * want(j, j)) + 1e-300)
            << "entry (" << i << ", " << j << ") at thresholds " << thr[0] << " " << thr[1] << " "
            << thr[2] << " " << thr[3];
    bound += (k.array() == 0.0).count() > 0;
  }
  EXPECT_EQ(bound, 2) << "the points meant to put operators at their bound did not";
}

// Unit-stiffness operators in MaxwellSlip<Jet<double, 2>>, every threshold seeded (1, 0) and every
// initial deflection (0, 1), reset with the asymmetry `a`: autodiff through them gives the two
// sensitivities operator_trajectories writes out by hand.
MaxwellSlip<ceres::Jet<double, 2>> seeded_operators(const std::vector<double>& thr,
                                                    const std::vector<double>& init, double a) {
  using Jet = ceres::Jet<double, 2>;
  MaxwellSlipParameters<Jet> p;
  std::vector<Jet> start;
  for (std::size_t i = 0; i < thr.size(); ++i) {
    p.stiffness.push_back(Jet(1.0));
    p.threshold.push_back(Jet(thr[i], 0));
    start.push_back(Jet(init[i], 1));
  }
  MaxwellSlip<Jet> model(p);
  model.reset(std::span<const Jet>(start), Jet(a));
  return model;
}

// The unit-stiffness operators of seeded_operators (no asymmetry) stepped over `x` on Jets: their
// deflections and the two seeded derivatives, N x M each, as operator_trajectories lays them out.
detail::OperatorTrajectories jet_trajectories(const std::vector<double>& thr,
                                              const std::vector<double>& init,
                                              const std::vector<double>& x) {
  using Jet = ceres::Jet<double, 2>;
  const Eigen::Index n = static_cast<Eigen::Index>(x.size());
  const Eigen::Index m = static_cast<Eigen::Index>(thr.size());
  detail::OperatorTrajectories out;
  out.delta.resize(n, m);
  out.d_threshold.resize(n, m);
  out.d_initial.resize(n, m);
  MaxwellSlip<Jet> model = seeded_operators(thr, init, 0.0);
  for (Eigen::Index t = 0; t < n; ++t) {
    const std::size_t tu = static_cast<std::size_t>(t);
    const double dx = t > 0 ? x[tu] - x[tu - 1] : 0.0;
    const double turn = turn_increment(std::span<const double>(x), tu);
    model.step(Motion<Jet>{Jet(dx), Jet(0.0), Jet(0.0), Jet(1.0), Jet(0.0), Jet(turn)});
    for (Eigen::Index i = 0; i < m; ++i) {
      const Jet& j = model.deflections()[static_cast<std::size_t>(i)];
      out.delta(t, i) = j.a;
      out.d_threshold(t, i) = j.v[0];
      out.d_initial(t, i) = j.v[1];
    }
  }
  return out;
}

TEST(Nlr, OperatorTrajectoriesAreTheJetRunOfTheModel) {
  // The hand-written recursion with sensitivities must give, bit for bit, what autodiff through
  // MaxwellSlip<Jet<double, 2>> gives (thresholds seeded (1, 0), initial deflections (0, 1)),
  // including initial deflections beyond the thresholds (clamped) and exactly at them.
  const auto sys = four_operator_system();
  const auto rec = synthetic_record(sys, 1200, 20e-6, 1, kSigma, 3, {0, 0, 0, 0}, nullptr);
  const std::vector<double> thr{0.7e-6, 2e-6, 6e-6, 3e-5};
  const std::vector<double> init{1e-6, -2e-6, 1e-6, -3e-5};
  detail::OperatorTrajectories tr;
  detail::operator_trajectories(thr, init, rec.displacement, true, tr);
  const detail::OperatorTrajectories jet = jet_trajectories(thr, init, rec.displacement);
  EXPECT_TRUE(tr.delta == jet.delta);
  EXPECT_TRUE(tr.d_threshold == jet.d_threshold);
  EXPECT_TRUE(tr.d_initial == jet.d_initial);
  EXPECT_GT((jet.d_threshold.array() != 0.0).count(), 0);  // the comparison covered both branches
  detail::OperatorTrajectories plain;
  detail::operator_trajectories(thr, init, rec.displacement, false, plain);
  EXPECT_TRUE(plain.delta == tr.delta);
}

TEST(Nlr, CompactSensitivitiesDecodeToTheJetRunInAnyBlockOfRows) {
  // operator_trajectories_compact keeps one byte per operator and sample; decoded a block of rows
  // at a time (as the NLR fit's compressed Jacobian reads them) it must give, bit for bit, the
  // sensitivities of autodiff through MaxwellSlip<Jet<double, 2>>, for blocks of any size and at
  // any offset, with initial deflections beyond, at and inside the thresholds.
  const auto sys = four_operator_system();
  const auto rec = synthetic_record(sys, 1300, 20e-6, 1, kSigma, 7, {0, 0, 0, 0}, nullptr);
  const std::vector<double> thr{0.9e-6, 2.5e-6, 5e-6, 2.5e-5};
  const std::vector<double> init{2e-6, -2.5e-6, 1e-6, -1e-5};
  detail::OperatorTrajectories compact;
  detail::operator_trajectories_compact(thr, init, rec.displacement, compact);
  ASSERT_EQ(compact.codes.size(), rec.size() * thr.size());
  EXPECT_EQ(compact.d_threshold.size(), 0);  // the dense form is not kept
  const Eigen::Index n = static_cast<Eigen::Index>(rec.size()), m = 4;
  const detail::OperatorTrajectories jet = jet_trajectories(thr, init, rec.displacement);
  EXPECT_TRUE(compact.delta == jet.delta);
  int codes_seen[3] = {0, 0, 0};
  for (std::uint8_t c : compact.codes) ++codes_seen[c];
  EXPECT_GT(codes_seen[detail::OperatorTrajectories::kFree], 0);  // every form was decoded
  EXPECT_GT(codes_seen[detail::OperatorTrajectories::kUpper], 0);
  EXPECT_GT(codes_seen[detail::OperatorTrajectories::kLower], 0);
  // Blocks of uneven sizes into buffers taller than the block; the dense form the same way.
  detail::OperatorTrajectories dense;
  detail::operator_trajectories(thr, init, rec.displacement, true, dense);
  Eigen::MatrixXd dt = Eigen::MatrixXd::Constant(300, m, 7.0), di = dt;
  const Eigen::Index sizes[] = {1, 7, 256, 300, 13};
  Eigen::Index t0 = 0;
  for (std::size_t k = 0; t0 < n; ++k) {
    const Eigen::Index rows = std::min(sizes[k % 5], n - t0);
    for (const detail::OperatorTrajectories* tr : {&compact, &dense}) {
      tr->sensitivity_rows(t0, rows, dt, di);
      ASSERT_TRUE(dt.topRows(rows) == jet.d_threshold.middleRows(t0, rows)) << t0 << " " << rows;
      ASSERT_TRUE(di.topRows(rows) == jet.d_initial.middleRows(t0, rows)) << t0 << " " << rows;
    }
    t0 += rows;
  }
  EXPECT_THROW(compact.sensitivity_rows(n - 5, 6, dt, di), InvalidParameter);
}

TEST(Nlr, OperatorTrajectoriesUnderLimitsAreTheJetRunOfTheModel) {
  // Under SlipLimits (a level and an asymmetry per sample) the recursion must still be autodiff
  // through MaxwellSlip<Jet<double, 2>> stepped with that level and asymmetry, its state given at
  // level 1 and scaled by the first level (as Extended hands it over).  To rounding: an initial
  // deflection beyond the box is clamped at level 1 and then scaled by the model, and scaled then
  // clamped at the first level by the recursion (the same number in exact arithmetic).
  const auto sys = four_operator_system();
  const auto rec = synthetic_record(sys, 1500, 20e-6, 0, kSigma, 5, {0, 0, 0, 0}, nullptr);
  const std::vector<double> thr{0.7e-6, 2e-6, 6e-6, 3e-5};
  const std::vector<double> init{1e-6, -2e-6, 0.5e-6, -3e-5};
  const double a = 0.15;
  std::vector<double> level(rec.size()), turn_level(rec.size());
  detail::SlipLimits limits;
  for (std::size_t t = 0; t < rec.size(); ++t) {
    level[t] = 1.0 + 0.6 * std::sin(0.013 * static_cast<double>(t) + 0.4);
    // A level at the turns of its own (motion.hpp, The level at the turn), above and below.
    turn_level[t] = level[t] * (1.0 + 0.5 * std::sin(0.021 * static_cast<double>(t)));
    limits.upper.push_back(level[t] * (1.0 + a));
    limits.lower.push_back(level[t] * (1.0 - a));
    limits.turn_upper.push_back(turn_level[t] * (1.0 + a));
    limits.turn_lower.push_back(turn_level[t] * (1.0 - a));
  }
  limits.first = level[0];
  detail::OperatorTrajectories tr;
  detail::operator_trajectories(thr, init, rec.displacement, true, tr, &limits);
  using Jet = ceres::Jet<double, 2>;
  MaxwellSlip<Jet> model = seeded_operators(thr, init, a);
  model.scale_state(Jet(limits.first));
  int at_upper = 0, at_lower = 0, from_turn = 0;
  for (std::size_t t = 0; t < rec.size(); ++t) {
    const double dx = t > 0 ? rec.displacement[t] - rec.displacement[t - 1] : 0.0;
    const double turn = turn_increment(std::span<const double>(rec.displacement), t);
    model.step(Motion<Jet>{Jet(dx), Jet(0.0), Jet(0.0), Jet(level[t]), Jet(a), Jet(turn),
                           Jet(turn_level[t])});
    for (std::size_t i = 0; i < thr.size(); ++i) {
      const Jet& j = model.deflections()[i];
      const auto ti = static_cast<Eigen::Index>(t), ii = static_cast<Eigen::Index>(i);
      ASSERT_NEAR(tr.delta(ti, ii), j.a, 1e-13 * thr[i]) << t << " " << i;
      ASSERT_NEAR(tr.d_threshold(ti, ii), j.v[0], 1e-13) << t << " " << i;
      ASSERT_NEAR(tr.d_initial(ti, ii), j.v[1], 1e-13) << t << " " << i;
      at_upper += j.v[0] > 0.0;
      at_lower += j.v[0] < 0.0;
      from_turn += turn != 0.0 && j.v[0] != 0.0 &&
                   std::abs(j.v[0]) != limits.upper[t] && std::abs(j.v[0]) != limits.lower[t];
    }
  }
  EXPECT_GT(at_upper, 0);  // both limits were met, each with its own factor
  EXPECT_GT(at_lower, 0);
  EXPECT_GT(from_turn, 0);  // and operators kept the bound they met at a turn
  detail::OperatorTrajectories plain;
  detail::operator_trajectories(thr, init, rec.displacement, false, plain, &limits);
  EXPECT_TRUE(plain.delta == tr.delta);
}

TEST(Nlr, UnderLimitsRecoversAnOperatorSystemWhoseSlipForcesFollowALevel) {
  // A force made by the test's own recursion: four operators whose slip limits follow a level
  // that changes along the record (a Stribeck-like bump at slow sliding, a slow ramp), white
  // noise.  NLR under those limits, M fixed, must recover every stiffness and threshold within
  // four of its standard errors (log-normal intervals: z of the logarithm) and fit to the noise
  // floor; NLR on the force divided by the level (what the restart did before) cannot.
  const auto sys = four_operator_system();
  auto rec = synthetic_record(sys, 4000, 30e-6, 0, 0.0, 7, {0, 0, 0, 0}, nullptr);
  const std::size_t n = rec.size();
  detail::SlipLimits limits;
  std::vector<double> level(n);
  for (std::size_t t = 0; t < n; ++t) {
    const double v = t > 0 ? (rec.displacement[t] - rec.displacement[t - 1]) / 1e-3 : 0.0;
    level[t] = (1.0 + 0.5 * std::exp(-std::pow(std::abs(v) / 2e-4, 2))) *
               (1.0 + 0.3 * static_cast<double>(t) / static_cast<double>(n));
  }
  limits.upper = level;
  limits.lower = level;
  limits.first = level[0];
  std::vector<double> delta(sys.size(), 0.0);
  std::mt19937 gen(2718);
  const double sigma = 2e-3 * sys.sliding_force();
  std::normal_distribution<double> noise(0.0, sigma);
  for (std::size_t t = 0; t < n; ++t) {
    const double dx = t > 0 ? rec.displacement[t] - rec.displacement[t - 1] : 0.0;
    double f = 0;
    for (std::size_t i = 0; i < sys.size(); ++i) {
      const double lim = level[t] * sys.threshold[i];
      delta[i] = std::clamp(delta[i] + dx, -lim, lim);
      f += sys.stiffness[i] * delta[i];
    }
    rec.force[t] = f + noise(gen);
  }
  NlrOptions o;
  o.operators = sys.size();
  o.refine_initial_state = false;
  const NlrResult r =
      detail::identify_maxwell_slip_under_limits(rec.time, rec.displacement, rec.force, o, limits);
  ASSERT_EQ(r.parameters.size(), sys.size());
  const double floor = static_cast<double>(n) * sigma * sigma;
  EXPECT_LT(r.report.estimation.rss, floor * (1.0 + 4.0 * std::sqrt(2.0 / static_cast<double>(n))))
      << "floor " << floor;
  for (std::size_t i = 0; i < 2 * sys.size(); ++i) {
    const ParameterEstimate& e = r.report.parameters[i];
    const double truth = i < sys.size() ? sys.stiffness[i] : sys.threshold[i - sys.size()];
    ASSERT_GT(e.standard_error, 0.0) << e.name;
    // The interval is log-normal: the standard error of log(value) is se / value.
    const double z = std::log(e.value / truth) / (e.standard_error / e.value);
    EXPECT_LE(std::abs(z), 4.0) << e.name << " " << e.value << " against " << truth;
  }
  std::vector<double> divided(n);
  for (std::size_t t = 0; t < n; ++t) divided[t] = rec.force[t] / level[t];
  const NlrResult plain = identify_maxwell_slip(rec.time, rec.displacement, divided, o);
  double rss_plain = 0;
  for (std::size_t t = 0; t < n; ++t) {
    const double e = divided[t] - plain.report.estimation_simulated[t];
    rss_plain += e * e * level[t] * level[t];
  }
  EXPECT_GT(rss_plain, 3.0 * floor) << "the division is not what the limits fix on this record";
}

TEST(Nlr, BoxLeastSquaresMatchesTheActiveSetOnTheFullProblem) {
  // The compressed (R, Q^T b) active set must find the constrained minimum of the full problem:
  // the KKT conditions hold on the original N x P matrix.
  std::mt19937 gen(4);
  std::normal_distribution<double> normal;
  Eigen::MatrixXd a(400, 6);
  for (Eigen::Index j = 0; j < a.cols(); ++j)
    for (Eigen::Index t = 0; t < a.rows(); ++t) a(t, j) = normal(gen) + (j == 5 ? a(t, 4) : 0.0);
  Eigen::VectorXd b(400);
  for (Eigen::Index t = 0; t < b.size(); ++t) b(t) = normal(gen);
  b -= 3.0 * a.col(1) - 2.0 * a.col(2);  // the data want k_1 < 0 and k_2 > 0
  const Eigen::VectorXd lo = Eigen::VectorXd::Zero(6);
  const Eigen::VectorXd hi = Eigen::VectorXd::Constant(6, std::numeric_limits<double>::infinity());
  std::vector<int> at_bound;
  const Eigen::VectorXd z = detail::box_least_squares(a, b, lo, hi, &at_bound);
  const Eigen::VectorXd g = a.transpose() * (a * z - b);  // gradient / 2
  EXPECT_EQ(at_bound[1], 1);
  for (Eigen::Index j = 0; j < 6; ++j) {
    EXPECT_GE(z(j), 0.0);
    if (at_bound[static_cast<std::size_t>(j)])
      EXPECT_GE(g(j), -1e-9 * b.norm()) << j;
    else
      EXPECT_NEAR(g(j), 0.0, 1e-9 * b.norm()) << j;
  }
}

TEST(Nlr, BoxLeastSquaresFromTheNormalEquationsAgreesAndRefusesIllConditionedOnes) {
  // box_least_squares compresses through the Cholesky factor of the Gram matrix when that loses
  // few digits and through a Householder QR otherwise; box_least_squares_gram (the threshold
  // moves of NLR's global stage) has only the Gram matrix.  Both must give the constrained
  // minimum of the full problem, and the Gram form must refuse what it cannot solve accurately.
  std::mt19937 gen(11);
  std::normal_distribution<double> normal;
  for (const double tie : {0.3, 1e-7}) {  // columns 4 and 5 nearly collinear for the second
    Eigen::MatrixXd a(500, 6);
    for (Eigen::Index t = 0; t < a.rows(); ++t) {
      for (Eigen::Index j = 0; j < 5; ++j) a(t, j) = normal(gen);
      a(t, 5) = a(t, 4) + tie * normal(gen);
    }
    Eigen::VectorXd b = 2.0 * a.col(0) - 1.5 * a.col(3) + a.col(4) + a.col(5);
    for (Eigen::Index t = 0; t < b.size(); ++t) b(t) += 0.1 * normal(gen);
    const Eigen::VectorXd lo = Eigen::VectorXd::Zero(6);
    const Eigen::VectorXd hi =
        Eigen::VectorXd::Constant(6, std::numeric_limits<double>::infinity());
    std::vector<int> at_bound;
    const Eigen::VectorXd z = detail::box_least_squares(a, b, lo, hi, &at_bound);
    EXPECT_EQ(at_bound[3], 1) << tie;
    const Eigen::VectorXd g = a.transpose() * (a * z - b);
    for (Eigen::Index j = 0; j < 6; ++j) {
      EXPECT_GE(z(j), 0.0);
      if (at_bound[static_cast<std::size_t>(j)])
        EXPECT_GE(g(j), -1e-8 * b.norm()) << tie << " " << j;
      else
        EXPECT_NEAR(g(j), 0.0, 1e-8 * b.norm()) << tie << " " << j;
    }
    Eigen::MatrixXd gram = a.transpose() * a;
    const Eigen::VectorXd atb = a.transpose() * b;
    Eigen::VectorXd zg;
    double rss = -1;
    const bool solved = detail::box_least_squares_gram(gram, atb, b.squaredNorm(), lo, hi, zg, rss);
    if (tie > 1e-3) {
      ASSERT_TRUE(solved);
      EXPECT_LT((zg - z).norm(), 1e-10 * z.norm());
      EXPECT_NEAR(rss, (a * z - b).squaredNorm(), 1e-10 * b.squaredNorm());
    } else {
      EXPECT_FALSE(solved) << "cond(A) ~ 1e7 must be left to the QR";
    }
  }
}

TEST(Nlr, FixedOrderAndJointSolverAgree) {
  const auto& rt = round_trip();
  NlrOptions o;
  o.operators = 4;
  o.solver = NlrSolver::Joint;
  o.covariance = false;
  const auto joint =
      identify_maxwell_slip(rt.estimation.time, rt.estimation.displacement, rt.estimation.force, o);
  ASSERT_EQ(joint.report.selection.size(), 1u);
  EXPECT_NEAR(joint.report.estimation.rss_sss_percent, rt.result.report.estimation.rss_sss_percent,
              0.05 * rt.result.report.estimation.rss_sss_percent);
}

TEST(Nlr, RejectsUnusableRecords) {
  std::vector<double> t(100), x(100, 1e-6), f(100, 0.1);
  for (std::size_t k = 0; k < 100; ++k) t[k] = 1e-3 * static_cast<double>(k);
  EXPECT_THROW(identify_maxwell_slip(t, x, f), InvalidParameter);  // no motion
  std::vector<double> shorter(50, 0.0);
  EXPECT_THROW(identify_maxwell_slip(t, shorter, f), InvalidParameter);
}

}  // namespace
}  // namespace test_nlr
