// The compressed least-squares machinery (src/compressed_cost.hpp): a problem of N residuals
// handed to Ceres as P + 1 must be solved by the same steps, and the row-block factor must carry
// the singular values a covariance is computed from.
#include <gtest/gtest.h>

#include <ceres/ceres.h>
#include <ceres/dynamic_autodiff_cost_function.h>

#include <Eigen/SVD>

#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "../src/compressed_cost.hpp"

namespace test_compressed_cost {
namespace {

using friction::detail::CompressedCost;
using friction::detail::normal_factor;
using friction::detail::RowCompressor;

// Damped oscillation a exp(-b t) cos(w t + phi) + c plus white noise: five parameters, two
// blocks, not a model of this library.
struct Oscillation {
  std::vector<double> t, y;
  template <class T>
  bool operator()(T const* const* p, T* r) const {
    using std::cos;
    using std::exp;
    const T* amp_decay = p[0];
    const T* freq_phase_offset = p[1];
    for (std::size_t k = 0; k < t.size(); ++k)
      r[k] = T(y[k]) - (amp_decay[0] * exp(-amp_decay[1] * t[k]) *
                            cos(freq_phase_offset[0] * t[k] + freq_phase_offset[1]) +
                        freq_phase_offset[2]);
    return true;
  }
};

Oscillation make_data(unsigned seed, std::size_t n) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.05);
  Oscillation o;
  for (std::size_t k = 0; k < n; ++k) {
    const double t = 10.0 * static_cast<double>(k) / static_cast<double>(n);
    o.t.push_back(t);
    o.y.push_back(2.0 * std::exp(-0.3 * t) * std::cos(3.1 * t + 0.4) + 0.2 + noise(rng));
  }
  return o;
}

ceres::CostFunction* oscillation_cost(const Oscillation& data) {
  auto* c = new ceres::DynamicAutoDiffCostFunction<Oscillation, 5>(new Oscillation(data));
  c->AddParameterBlock(2);
  c->AddParameterBlock(3);
  c->SetNumResiduals(static_cast<int>(data.t.size()));
  return c;
}

struct Solved {
  std::vector<double> a, b;
  ceres::Solver::Summary summary;
};

Solved solve(const Oscillation& data, bool compressed, bool hold_second) {
  Solved s{{1.5, 0.2}, {3.0, 0.0, 0.0}, {}};
  ceres::Problem problem;
  ceres::CostFunction* c = oscillation_cost(data);
  if (compressed) c = new CompressedCost(c);
  problem.AddResidualBlock(c, nullptr, s.a.data(), s.b.data());
  problem.SetParameterLowerBound(s.a.data(), 1, 0.0);  // a bound: the projected line search runs
  problem.SetParameterUpperBound(s.a.data(), 0, 10.0);
  if (hold_second) problem.SetParameterBlockConstant(s.b.data());
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::DENSE_QR;
  o.max_num_iterations = 200;
  o.function_tolerance = 1e-12;
  o.gradient_tolerance = 1e-14;
  o.parameter_tolerance = 1e-12;
  ceres::Solve(o, &problem, &s.summary);
  return s;
}

TEST(CompressedCost, CeresTakesTheSameStepsAsOnTheWholeProblem) {
  for (unsigned seed : {20261125u, 7u}) {
    const Oscillation data = make_data(seed, 3000);
    for (bool hold : {false, true}) {
      const Solved whole = solve(data, false, hold), small = solve(data, true, hold);
      ASSERT_TRUE(whole.summary.IsSolutionUsable());
      ASSERT_TRUE(small.summary.IsSolutionUsable());
      EXPECT_EQ(whole.summary.num_successful_steps, small.summary.num_successful_steps)
          << "seed " << seed << (hold ? ", second block held" : "");
      EXPECT_EQ(whole.summary.num_unsuccessful_steps, small.summary.num_unsuccessful_steps);
      EXPECT_NEAR(whole.summary.initial_cost, small.summary.initial_cost,
                  1e-12 * whole.summary.initial_cost);
      EXPECT_NEAR(whole.summary.final_cost, small.summary.final_cost,
                  1e-10 * whole.summary.final_cost);
      // The minimum itself, to well inside its standard errors (about 1e-3 here).
      for (std::size_t j = 0; j < 2; ++j) EXPECT_NEAR(whole.a[j], small.a[j], 1e-8);
      for (std::size_t j = 0; j < 3; ++j) EXPECT_NEAR(whole.b[j], small.b[j], 1e-8);
      if (hold) {
        EXPECT_EQ(small.b, (std::vector<double>{3.0, 0.0, 0.0}));
      } else {
        EXPECT_NEAR(small.b[0], 3.1, 0.01);
      }
    }
  }
}

// The oscillation cost handing its rows over one by one (RowStreamingCost), from a whole
// evaluation of its own; `streams` false makes CompressedCost take the N x P path instead.
class StreamedOscillation final : public ceres::CostFunction,
                                  public friction::detail::RowStreamingCost {
 public:
  StreamedOscillation(const Oscillation& data, bool streams)
      : inner_(oscillation_cost(data)), streams_(streams) {
    *mutable_parameter_block_sizes() = inner_->parameter_block_sizes();
    set_num_residuals(inner_->num_residuals());
  }
  bool Evaluate(double const* const* p, double* r, double** j) const override {
    return inner_->Evaluate(p, r, j);
  }
  bool streams() const override { return streams_; }
  bool EvaluateRows(double const* const* p, double* r, const bool* requested,
                    const RowVisitor& visit) const override {
    const std::size_t n = static_cast<std::size_t>(num_residuals());
    std::vector<double> j0(n * 2), j1(n * 3);
    double* j[] = {requested[0] ? j0.data() : nullptr, requested[1] ? j1.data() : nullptr};
    if (!inner_->Evaluate(p, r, j)) return false;
    for (std::size_t k = 0; k < n; ++k) {
      const double* rows[] = {j[0] ? j[0] + 2 * k : nullptr, j[1] ? j[1] + 3 * k : nullptr};
      visit(k, rows);
    }
    return true;
  }

 private:
  std::unique_ptr<ceres::CostFunction> inner_;
  bool streams_;
};

// Rows handed over one by one must give the very numbers of the N x P path: the same Gram matrix
// to the last bit, for any pattern of held blocks and for N below, at and off a multiple of the
// 256 rows gathered per update.
TEST(CompressedCost, RowsHandedOverOneByOneGiveTheSameNumbers) {
  for (std::size_t n : {100u, 256u, 512u, 3001u}) {
    const Oscillation data = make_data(31u + static_cast<unsigned>(n), n);
    const CompressedCost streamed(new StreamedOscillation(data, true));
    const CompressedCost whole(new StreamedOscillation(data, false));
    const std::vector<double> a{1.7, 0.25}, b{3.05, 0.3, 0.1};
    const double* p[] = {a.data(), b.data()};
    for (int pattern = 1; pattern < 4; ++pattern) {  // which blocks are free
      std::vector<double> r1(6), r2(6), j1a(6 * 2, -1), j1b(6 * 3, -1), j2a(6 * 2, -2),
          j2b(6 * 3, -2);
      double* j1[] = {pattern & 1 ? j1a.data() : nullptr, pattern & 2 ? j1b.data() : nullptr};
      double* j2[] = {pattern & 1 ? j2a.data() : nullptr, pattern & 2 ? j2b.data() : nullptr};
      ASSERT_TRUE(streamed.Evaluate(p, r1.data(), j1));
      ASSERT_TRUE(whole.Evaluate(p, r2.data(), j2));
      EXPECT_EQ(r1, r2) << "n " << n << ", pattern " << pattern;
      if (pattern & 1) {
        EXPECT_EQ(j1a, j2a) << "n " << n << ", pattern " << pattern;
      }
      if (pattern & 2) {
        EXPECT_EQ(j1b, j2b) << "n " << n << ", pattern " << pattern;
      }
    }
    // And the cost alone (no Jacobian) is the same norm.
    std::vector<double> r1(6), r2(6);
    ASSERT_TRUE(streamed.Evaluate(p, r1.data(), nullptr));
    ASSERT_TRUE(whole.Evaluate(p, r2.data(), nullptr));
    EXPECT_EQ(r1, r2);
  }
}

// The oscillation cost counting its evaluations of values alone.
class CountedOscillation final : public ceres::CostFunction {
 public:
  CountedOscillation(const Oscillation& data, int* values)
      : inner_(oscillation_cost(data)), values_(values) {
    *mutable_parameter_block_sizes() = inner_->parameter_block_sizes();
    set_num_residuals(inner_->num_residuals());
  }
  bool Evaluate(double const* const* p, double* r, double** j) const override {
    if (!j) ++*values_;
    return inner_->Evaluate(p, r, j);
  }

 private:
  std::unique_ptr<ceres::CostFunction> inner_;
  int* values_;
};

// Ceres' bounded trust region evaluates the values at each accepted point twice (its line search
// at step 1, then the candidate); the second is answered from the first.  An answer kept for a
// point that has since changed in any one coordinate, or after a Jacobian, would be a wrong cost.
TEST(CompressedCost, ValuesAtTheSamePointAreEvaluatedOnce) {
  const Oscillation data = make_data(90210u, 700);
  int values = 0;
  const CompressedCost cached(new CountedOscillation(data, &values));
  std::vector<double> a{1.7, 0.25}, b{3.05, 0.3, 0.1};
  const double* p[] = {a.data(), b.data()};
  const auto fresh = [&] {  // a new cost at the current point, nothing kept
    int unused = 0;
    const CompressedCost c(new CountedOscillation(data, &unused));
    std::vector<double> r(6);
    EXPECT_TRUE(c.Evaluate(p, r.data(), nullptr));
    return r;
  };
  const auto value = [&] {
    std::vector<double> r(6, -1.0);
    EXPECT_TRUE(cached.Evaluate(p, r.data(), nullptr));
    return r;
  };
  const std::vector<double> at_start = fresh();
  EXPECT_EQ(value(), at_start);
  EXPECT_EQ(value(), at_start);
  EXPECT_EQ(values, 1);
  for (double* x : {&a[0], &a[1], &b[0], &b[1], &b[2]}) {  // each coordinate moved alone
    const double kept = *x;
    *x = kept * (1.0 + 1e-9);
    const std::vector<double> moved = fresh();
    EXPECT_NE(moved, at_start);
    EXPECT_EQ(value(), moved);
    *x = kept;
    EXPECT_EQ(value(), at_start);
  }
  EXPECT_EQ(values, 11);
  // A Jacobian in between leaves the values at the point as they were.
  std::vector<double> r(6), ja(6 * 2), jb(6 * 3);
  double* j[] = {ja.data(), jb.data()};
  ASSERT_TRUE(cached.Evaluate(p, r.data(), j));
  EXPECT_EQ(value(), at_start);
  // A whole bounded solve takes the same steps to the same point with it as without it.
  for (bool hold : {false, true}) {
    const Solved small = solve(data, true, hold), whole = solve(data, false, hold);
    EXPECT_EQ(small.summary.num_successful_steps, whole.summary.num_successful_steps);
    EXPECT_EQ(small.summary.num_unsuccessful_steps, whole.summary.num_unsuccessful_steps);
  }
}

// The accumulator leaves out of a block's product the columns that are zero on all its rows (an
// operator's initial state is forgotten once it slips): columns zero from some row on, zero until
// some row, zero in the middle, everywhere, and never, across block edges (256 rows), each entry
// of the lower triangle against the sum taken here in long double, and the entries of a column
// that is zero everywhere exactly zero.
TEST(CompressedCost, TheGramMatrixOfRowsWithColumnsThatFallSilent) {
  using friction::detail::GramAccumulator;
  std::mt19937 rng(4242);
  std::normal_distribution<double> g(0.0, 1.0);
  const std::size_t n = 1300;
  const std::vector<int> sizes{4, 3};  // blocks of 4 and 3 columns, then the residual
  std::vector<std::vector<double>> rows(n, std::vector<double>(8));
  for (std::size_t k = 0; k < n; ++k) {
    for (double& v : rows[k]) v = g(rng);
    if (k >= 300) rows[k][1] = 0.0;                // silent from row 300 on
    if (k < 700) rows[k][2] = 0.0;                 // silent until row 700
    if (k >= 256 && k < 1024) rows[k][4] = 0.0;    // silent over three whole blocks
    rows[k][5] = 0.0;                              // silent everywhere
    if (k >= 511) rows[k][6] = 1e6 * rows[k][6];   // another scale
  }
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(8, 8);
  {
    GramAccumulator acc(gram);
    for (std::size_t k = 0; k < n; ++k) {
      const double* blocks[] = {rows[k].data(), rows[k].data() + 4};
      acc.add(blocks, sizes, rows[k][7]);
    }
    acc.flush();
  }
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j <= i; ++j) {
      long double want = 0;
      for (std::size_t k = 0; k < n; ++k)
        want += static_cast<long double>(rows[k][static_cast<std::size_t>(i)]) *
                rows[k][static_cast<std::size_t>(j)];
      if (i == 5 || j == 5) {
        EXPECT_EQ(gram(i, j), 0.0) << i << ", " << j;
        continue;
      }
      long double ii = 0, jj = 0;
      for (std::size_t k = 0; k < n; ++k) {
        ii += static_cast<long double>(rows[k][static_cast<std::size_t>(i)]) *
              rows[k][static_cast<std::size_t>(i)];
        jj += static_cast<long double>(rows[k][static_cast<std::size_t>(j)]) *
              rows[k][static_cast<std::size_t>(j)];
      }
      EXPECT_LE(std::abs(static_cast<long double>(gram(i, j)) - want),
                1e-13L * std::sqrt(ii * jj))
          << i << ", " << j;
    }
}

TEST(CompressedCost, NormalFactorOfASingularGramMatrix) {
  // A zero column and two columns 1e6 apart in scale: F^T F = G to rounding, no NaN.
  std::mt19937 rng(11);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixXd a(500, 6);
  for (Eigen::Index i = 0; i < a.rows(); ++i)
    for (Eigen::Index j = 0; j < a.cols(); ++j) a(i, j) = g(rng);
  a.col(2).setZero();
  a.col(4) *= 1e6;
  a.col(5) = a.col(0) + a.col(1);  // rank 4
  const Eigen::MatrixXd want = a.transpose() * a;
  Eigen::MatrixXd gram = want, f;
  normal_factor(gram, f);
  ASSERT_TRUE(f.allFinite());
  const Eigen::MatrixXd got = f.transpose() * f;
  for (Eigen::Index i = 0; i < 6; ++i)
    for (Eigen::Index j = 0; j < 6; ++j)
      EXPECT_LE(std::abs(got(i, j) - want(i, j)),
                1e-12 * std::sqrt(want(i, i) * want(j, j)) + 1e-300)
          << i << ", " << j;
}

TEST(CompressedCost, RowBlocksKeepTheSingularValues) {
  // Columns 1e-5 to 1e3 in scale and one nearly dependent on another: the factor of uneven row
  // blocks has A's singular values to backward-stable accuracy (a few eps times the largest),
  // before and after the unit-norm column scaling marginal_covariance applies.
  std::mt19937 rng(3);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixXd a(2345, 5);
  for (Eigen::Index i = 0; i < a.rows(); ++i)
    for (Eigen::Index j = 0; j < a.cols(); ++j) a(i, j) = g(rng) * std::pow(10.0, 3 - 2 * j);
  a.col(4) += 1e3 * a.col(0);
  RowCompressor rc(5);
  for (Eigen::Index t0 = 0, b = 1; t0 < a.rows(); t0 += b, b = b * 3 + 1)
    rc.add(a.middleRows(t0, std::min(b, a.rows() - t0)));
  const Eigen::MatrixXd r = rc.factor();
  EXPECT_TRUE((r.triangularView<Eigen::StrictlyLower>().toDenseMatrix().array() == 0.0).all());
  const Eigen::VectorXd norms = a.colwise().norm().transpose();
  for (bool scaled : {false, true}) {
    const Eigen::VectorXd s =
        scaled ? Eigen::VectorXd(norms.cwiseInverse()) : Eigen::VectorXd(Eigen::VectorXd::Ones(5));
    const Eigen::VectorXd want =
        Eigen::JacobiSVD<Eigen::MatrixXd>(a * s.asDiagonal()).singularValues();
    const Eigen::VectorXd got =
        Eigen::JacobiSVD<Eigen::MatrixXd>(r * s.asDiagonal()).singularValues();
    for (Eigen::Index k = 0; k < 5; ++k)
      EXPECT_NEAR(got(k), want(k), 1e-14 * want(0))
          << "singular value " << k << (scaled ? " (columns scaled)" : "");
  }
  // Fewer rows than columns so far: the factor is the rows' own, padded with zeros.
  RowCompressor few(5);
  few.add(a.topRows(3));
  const Eigen::MatrixXd rf = few.factor();
  EXPECT_TRUE(rf.bottomRows(2).isZero(0.0));
  const Eigen::MatrixXd gram = a.topRows(3).transpose() * a.topRows(3);
  EXPECT_LE((rf.transpose() * rf - gram).norm(), 1e-12 * gram.norm());
}

}  // namespace
}  // namespace test_compressed_cost
