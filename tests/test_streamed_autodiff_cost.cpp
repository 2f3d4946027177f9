// The streamed forward-mode cost (src/streamed_autodiff_cost.hpp): its rows, handed over one
// sample at a time, must be Ceres' own autodiff Jacobian to the bit, for any number of columns
// (one pass of 16, 32 or 64 lanes; passes of 64 beyond that) and any pattern of held blocks.
#include <gtest/gtest.h>

#include <ceres/ceres.h>
#include <ceres/dynamic_autodiff_cost_function.h>

#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "../src/compressed_cost.hpp"
#include "../src/streamed_autodiff_cost.hpp"

namespace test_streamed_autodiff_cost {
namespace {

using friction::detail::CompressedCost;
using friction::detail::StreamedAutoDiffCost;

// A recursive system with a state that depends on every parameter through the past, and a
// branch on the state's value (a clamp, as the slip operators have): not a model of this library.
// Block 0 holds gains, block 1 the state's pole, offset and initial value, and more gains.
struct Recursion {
  std::vector<double> x, y;
  int block0 = 0, block1 = 0;

  template <class T, class Visit>
  bool visit(T const* const* p, Visit&& visit) const {
    using std::exp;
    using std::sin;
    const int total = block0 + block1;
    auto param = [&](int j) -> const T& { return j < block0 ? p[0][j] : p[1][j - block0]; };
    if (!(param(0) > T(-5.0))) return false;  // outside the domain
    T s = param(total - 1);
    for (std::size_t k = 0; k < x.size(); ++k) {
      T drive(0);
      for (int j = 0; j < total; ++j)
        drive += param(j) * sin(double(j + 1) * x[k] + 0.1 * double(j));
      s = T(0.8) * s + T(0.05) * exp(T(0.1) * param(1 % total)) * drive;
      if (s > T(1.5)) s = T(1.5);
      if (s < T(-1.5)) s = T(-1.5);
      visit(k, T(T(y[k]) - s));
    }
    return true;
  }
  template <class T, class Visit>
  bool operator()(T const* const* p, Visit&& v) const {
    return visit(p, v);
  }
};

// The same residuals as an array, for ceres::DynamicAutoDiffCostFunction.
struct ArrayRecursion {
  Recursion r;
  template <class T>
  bool operator()(T const* const* p, T* residual) const {
    return r.visit(p, [&](std::size_t k, const T& e) { residual[k] = e; });
  }
};

Recursion make_recursion(unsigned seed, std::size_t n, int block0, int block1) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  Recursion r;
  r.block0 = block0;
  r.block1 = block1;
  for (std::size_t k = 0; k < n; ++k) {
    r.x.push_back(0.01 * static_cast<double>(k) + 0.1 * g(rng));
    r.y.push_back(0.5 * std::sin(0.03 * static_cast<double>(k)) + 0.05 * g(rng));
  }
  return r;
}

std::vector<double> parameters(unsigned seed, int size) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 0.3);
  std::vector<double> p(static_cast<std::size_t>(size));
  for (double& v : p) v = g(rng);
  return p;
}

// Block sizes around every lane count: one pass of 16, 32 and 64 (each full and one over), and
// passes of 64 (70: the cost no longer streams).
TEST(StreamedAutoDiffCost, RowsAreCeresAutodiffJacobianToTheBit) {
  const std::size_t n = 700;
  for (const auto& [b0, b1] : std::vector<std::pair<int, int>>{
           {2, 1}, {10, 6}, {10, 7}, {20, 12}, {20, 13}, {40, 24}, {40, 30}}) {
    const Recursion rec = make_recursion(17u + static_cast<unsigned>(b0 + b1), n, b0, b1);
    StreamedAutoDiffCost<Recursion> streamed(std::make_unique<Recursion>(rec), {b0, b1},
                                             static_cast<int>(n));
    ceres::DynamicAutoDiffCostFunction<ArrayRecursion, 16> ceres_cost(new ArrayRecursion{rec});
    ceres_cost.AddParameterBlock(b0);
    ceres_cost.AddParameterBlock(b1);
    ceres_cost.SetNumResiduals(static_cast<int>(n));
    EXPECT_EQ(streamed.streams(), b0 + b1 <= 64) << b0 + b1 << " columns";
    const std::vector<double> a = parameters(3u + static_cast<unsigned>(b0), b0),
                              b = parameters(5u + static_cast<unsigned>(b1), b1);
    const double* p[] = {a.data(), b.data()};
    for (int pattern = 0; pattern < 4; ++pattern) {  // which blocks are requested
      const bool requested[2] = {(pattern & 1) != 0, (pattern & 2) != 0};
      std::vector<double> r1(n), r2(n, -1), j1a(n * b0, -1), j1b(n * b1, -1), j2a(n * b0, -2),
          j2b(n * b1, -2);
      double* j1[] = {requested[0] ? j1a.data() : nullptr, requested[1] ? j1b.data() : nullptr};
      double* j2[] = {requested[0] ? j2a.data() : nullptr, requested[1] ? j2b.data() : nullptr};
      ASSERT_TRUE(streamed.Evaluate(p, r1.data(), j1));
      ASSERT_TRUE(ceres_cost.Evaluate(p, r2.data(), j2));
      const std::string where =
          std::to_string(b0 + b1) + " columns, pattern " + std::to_string(pattern);
      EXPECT_EQ(r1, r2) << where;
      if (requested[0]) {
        EXPECT_EQ(j1a, j2a) << where;
      }
      if (requested[1]) {
        EXPECT_EQ(j1b, j2b) << where;
      }
      // The rows handed over one by one are those rows, in order, with the residual written.
      std::vector<double> r3(n, -3);
      std::size_t next = 0;
      bool same = true;
      const bool ok = streamed.EvaluateRows(
          p, r3.data(), requested, [&](std::size_t k, const double* const* rows) {
            same = same && k == next++ && r3[k] == r2[k];
            same = same && (rows[0] != nullptr) == requested[0];
            same = same && (rows[1] != nullptr) == requested[1];
            for (int i = 0; requested[0] && i < b0; ++i)
              same = same && rows[0][i] == j2a[k * static_cast<std::size_t>(b0) + i];
            for (int i = 0; requested[1] && i < b1; ++i)
              same = same && rows[1][i] == j2b[k * static_cast<std::size_t>(b1) + i];
          });
      const int columns = (requested[0] ? b0 : 0) + (requested[1] ? b1 : 0);
      if (columns > 64) {
        EXPECT_FALSE(ok) << where << ": more columns than one pass holds";
      } else {
        ASSERT_TRUE(ok) << where;
        EXPECT_TRUE(same) << where;
        EXPECT_EQ(next, n) << where;
      }
    }
    // The value alone, on doubles.
    std::vector<double> r1(n), r2(n, -1);
    ASSERT_TRUE(streamed.Evaluate(p, r1.data(), nullptr));
    ASSERT_TRUE(ceres_cost.Evaluate(p, r2.data(), nullptr));
    EXPECT_EQ(r1, r2);
  }
}

// Outside the functor's domain every form of evaluation says so.
TEST(StreamedAutoDiffCost, OutsideTheDomainEveryEvaluationFails) {
  const std::size_t n = 50;
  const Recursion rec = make_recursion(9u, n, 3, 2);
  const StreamedAutoDiffCost<Recursion> cost(std::make_unique<Recursion>(rec), {3, 2},
                                             static_cast<int>(n));
  const std::vector<double> a{-6.0, 0.1, 0.2}, b{0.3, 0.4};
  const double* p[] = {a.data(), b.data()};
  std::vector<double> r(n), ja(n * 3), jb(n * 2);
  double* j[] = {ja.data(), jb.data()};
  const bool requested[2] = {true, true};
  EXPECT_FALSE(cost.Evaluate(p, r.data(), nullptr));
  EXPECT_FALSE(cost.Evaluate(p, r.data(), j));
  EXPECT_FALSE(cost.EvaluateRows(p, r.data(), requested, [](std::size_t, const double* const*) {}));
}

// Through CompressedCost the streamed rows give the numbers of Ceres' N x P Jacobian.
TEST(StreamedAutoDiffCost, CompressedLikeTheWholeJacobian) {
  const std::size_t n = 1300;
  const Recursion rec = make_recursion(23u, n, 12, 9);
  const CompressedCost streamed(new StreamedAutoDiffCost<Recursion>(
      std::make_unique<Recursion>(rec), {12, 9}, static_cast<int>(n)));
  auto* ceres_cost = new ceres::DynamicAutoDiffCostFunction<ArrayRecursion, 16>(
      new ArrayRecursion{rec});
  ceres_cost->AddParameterBlock(12);
  ceres_cost->AddParameterBlock(9);
  ceres_cost->SetNumResiduals(static_cast<int>(n));
  const CompressedCost whole(ceres_cost);
  const std::vector<double> a = parameters(41u, 12), b = parameters(43u, 9);
  const double* p[] = {a.data(), b.data()};
  std::vector<double> r1(22), r2(22), j1a(22 * 12), j1b(22 * 9), j2a(22 * 12), j2b(22 * 9);
  double* j1[] = {j1a.data(), j1b.data()};
  double* j2[] = {j2a.data(), j2b.data()};
  ASSERT_TRUE(streamed.Evaluate(p, r1.data(), j1));
  ASSERT_TRUE(whole.Evaluate(p, r2.data(), j2));
  EXPECT_EQ(r1, r2);
  EXPECT_EQ(j1a, j2a);
  EXPECT_EQ(j1b, j2b);
}

}  // namespace
}  // namespace test_streamed_autodiff_cost
