// Internal machinery shared by the initial-state estimation, NLR and DNLRX (not installed).
//
// Operator trajectories.  With unit stiffness the Maxwell Slip operators' deflections delta_i(t)
// are the regressors of both NLR (F = sum k_i delta_i) and DNLRX (lagged delta_i).  Operator i
// depends only on its own threshold Delta_i and initial deflection delta_i(0).  So one
// MaxwellSlip<ceres::Jet<double, 2>> run would give every partial derivative needed: seed every
// threshold with derivative (1, 0) and every initial deflection with (0, 1); since no operator
// mixes with another, the Jet part of delta_i(t) is exactly
// (d delta_i(t) / d Delta_i, d delta_i(t) / d delta_i(0)).  operator_trajectories computes that
// recursion directly (identical numbers, a test checks it against the Jet run).  The second is the
// indicator "not yet saturated" (1 until the operator first reaches a bound, 0 after), which is
// what the initial-state estimation exploits.
#pragma once

#include <ceres/jet.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/QR>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <span>
#include <vector>

#include "friction/error.hpp"
#include "friction/maxwell_slip.hpp"

namespace friction::detail {

struct OperatorTrajectories {
  Eigen::MatrixXd delta;        ///< N x M: delta_i(t), unit stiffness
  Eigen::MatrixXd d_threshold;  ///< d delta_i(t) / d Delta_i with delta_i(0) held fixed
  Eigen::MatrixXd d_initial;    ///< d delta_i(t) / d delta_i(0)
};

/// Deflections of unit-stiffness operators from the given initial deflections (clamped to the
/// thresholds), sample 0 being the initial state and sample k > 0 the state after x[k]-x[k-1].
///
/// This is the recursion of MaxwellSlip<ceres::Jet<double, 2>> (eq. 4 with the clamp of
/// scalar.hpp, which keeps the derivative of the branch taken) written out per operator: at the
/// upper bound the derivatives are (1, 0), at the lower bound (-1, 0), and in between they are
/// carried over unchanged.  The same numbers, bit for bit (test_nlr compares the two), without
/// the Jet arithmetic: the identification evaluates this thousands of times.
inline void operator_trajectories(std::span<const double> thresholds,
                                  std::span<const double> initial, std::span<const double> x,
                                  bool sensitivities, OperatorTrajectories& out) {
  const std::size_t m = thresholds.size();
  FRICTION_CHECK(initial.size() == m, "Maxwell Slip: ", initial.size(), " initial deflections for ",
                 m, " operators");
  const Eigen::Index n = static_cast<Eigen::Index>(x.size());
  const Eigen::Index mi = static_cast<Eigen::Index>(m);
  out.delta.resize(n, mi);
  if (sensitivities) {
    out.d_threshold.resize(n, mi);
    out.d_initial.resize(n, mi);
  }
  // The recursion of one operator is a chain of dependent additions and clamps (about 12 cycles
  // per sample), so the operators are stepped side by side, time outermost: their chains are
  // independent and overlap in the pipeline (3-4x faster at M = 10 than operator by operator).
  std::vector<double> limit(m), v(m), g_threshold(m, 0.0), g_initial(m, 1.0);
  for (std::size_t i = 0; i < m; ++i) {
    limit[i] = thresholds[i];
    FRICTION_CHECK(std::isfinite(limit[i]) && limit[i] > 0.0, "Maxwell Slip: threshold[", i,
                   "] = ", limit[i], " m must be finite and > 0");
    v[i] = initial[i];
    if (v[i] > limit[i])
      v[i] = limit[i], g_threshold[i] = 1.0, g_initial[i] = 0.0;
    else if (v[i] < -limit[i])
      v[i] = -limit[i], g_threshold[i] = -1.0, g_initial[i] = 0.0;
  }
  double* delta = out.delta.data();
  if (!sensitivities) {
    for (Eigen::Index t = 0; t < n; ++t) {
      const double dx =
          t > 0 ? x[static_cast<std::size_t>(t)] - x[static_cast<std::size_t>(t - 1)] : 0.0;
      double* row = delta + t;
      for (std::size_t i = 0; i < m; ++i) {
        const double u = v[i] + dx;
        v[i] = u > limit[i] ? limit[i] : (u < -limit[i] ? -limit[i] : u);
        row[static_cast<Eigen::Index>(i) * n] = v[i];
      }
    }
    return;
  }
  double* dt = out.d_threshold.data();
  double* di = out.d_initial.data();
  for (Eigen::Index t = 0; t < n; ++t) {
    const double dx =
        t > 0 ? x[static_cast<std::size_t>(t)] - x[static_cast<std::size_t>(t - 1)] : 0.0;
    for (std::size_t i = 0; i < m; ++i) {
      const double u = v[i] + dx;
      const bool above = u > limit[i], below = u < -limit[i];
      v[i] = above ? limit[i] : (below ? -limit[i] : u);
      g_threshold[i] = above ? 1.0 : (below ? -1.0 : g_threshold[i]);
      g_initial[i] = above || below ? 0.0 : g_initial[i];
      const Eigen::Index at = static_cast<Eigen::Index>(i) * n + t;
      delta[at] = v[i];
      dt[at] = g_threshold[i];
      di[at] = g_initial[i];
    }
  }
}

inline OperatorTrajectories operator_trajectories(std::span<const double> thresholds,
                                                  std::span<const double> initial,
                                                  std::span<const double> x, bool sensitivities) {
  OperatorTrajectories out;
  operator_trajectories(thresholds, initial, x, sensitivities, out);
  return out;
}

/// Column `c` delayed by `lag` samples, the record being extended backwards with its first value
/// (the system at rest before the record: delta(t < 0) = delta(0), dx(t <= 0) = 0).
inline Eigen::VectorXd lagged(const Eigen::Ref<const Eigen::VectorXd>& c, Eigen::Index lag) {
  const Eigen::Index n = c.size();
  Eigen::VectorXd out(n);
  for (Eigen::Index t = 0; t < n; ++t) out(t) = c(t >= lag ? t - lag : 0);
  return out;
}

/// The active-set solve of box_least_squares on its compressed form: min ||as z - bs|| with as
/// (P x P, or N x P uncompressed) the column-scaled regressors, `scale` their column norms and
/// `b_norm` = ||b|| (for the optimality tolerance).  Returns the unscaled solution.
inline Eigen::VectorXd box_least_squares_reduced(const Eigen::MatrixXd& as,
                                                 const Eigen::VectorXd& bs,
                                                 const Eigen::VectorXd& scale, double b_norm,
                                                 const Eigen::VectorXd& lo,
                                                 const Eigen::VectorXd& hi,
                                                 std::vector<int>* at_bound) {
  const Eigen::Index p = as.cols();
  const Eigen::VectorXd l = lo.cwiseProduct(scale), h = hi.cwiseProduct(scale);
  // state: 0 free, -1 at lower, +1 at upper
  std::vector<int> state(static_cast<std::size_t>(p));
  Eigen::VectorXd z(p);
  for (Eigen::Index j = 0; j < p; ++j) {
    if (std::isfinite(l(j)) && l(j) >= 0.0) {
      z(j) = l(j), state[static_cast<std::size_t>(j)] = -1;
    } else if (std::isfinite(h(j)) && h(j) <= 0.0) {
      z(j) = h(j), state[static_cast<std::size_t>(j)] = +1;
    } else {
      z(j) = 0.0, state[static_cast<std::size_t>(j)] = 0;
    }
  }
  const double tol = 1e-12 * std::max(1.0, b_norm);
  auto solve_free = [&](Eigen::VectorXd& target) {
    std::vector<Eigen::Index> free;
    for (Eigen::Index j = 0; j < p; ++j)
      if (state[static_cast<std::size_t>(j)] == 0) free.push_back(j);
    target = z;
    if (free.empty()) return;
    Eigen::VectorXd rhs = bs;
    for (Eigen::Index j = 0; j < p; ++j)
      if (state[static_cast<std::size_t>(j)] != 0) rhs -= as.col(j) * z(j);
    Eigen::MatrixXd af(as.rows(), static_cast<Eigen::Index>(free.size()));
    for (std::size_t k = 0; k < free.size(); ++k)
      af.col(static_cast<Eigen::Index>(k)) = as.col(free[k]);
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(af);
    qr.setThreshold(1e-12);
    const Eigen::VectorXd zf = qr.solve(rhs);
    for (std::size_t k = 0; k < free.size(); ++k)
      target(free[k]) = zf(static_cast<Eigen::Index>(k));
  };
  // Fast path: the unconstrained solution is feasible (the usual case for stiffnesses).
  {
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(as);
    qr.setThreshold(1e-12);
    const Eigen::VectorXd zu = qr.solve(bs);
    bool feasible = qr.rank() == p;
    for (Eigen::Index j = 0; j < p && feasible; ++j) feasible = zu(j) > l(j) && zu(j) < h(j);
    if (feasible) {
      if (at_bound) at_bound->assign(static_cast<std::size_t>(p), 0);
      return zu.cwiseQuotient(scale);
    }
  }
  const int max_outer = static_cast<int>(3 * p + 10);
  bool first = true;
  for (int outer = 0; outer < max_outer; ++outer) {
    if (!first) {
      const Eigen::VectorXd w = as.transpose() * (bs - as * z);  // minus the gradient
      Eigen::Index best = -1;
      double best_w = tol;
      for (Eigen::Index j = 0; j < p; ++j) {
        const int s = state[static_cast<std::size_t>(j)];
        const double push = s == -1 ? w(j) : (s == +1 ? -w(j) : 0.0);
        if (push > best_w) best_w = push, best = j;
      }
      if (best < 0) break;
      state[static_cast<std::size_t>(best)] = 0;
    }
    first = false;
    for (int inner = 0; inner < max_outer; ++inner) {
      Eigen::VectorXd target;
      solve_free(target);
      double alpha = 1.0;
      Eigen::Index hit = -1;
      int hit_side = 0;
      for (Eigen::Index j = 0; j < p; ++j) {
        if (state[static_cast<std::size_t>(j)] != 0) continue;
        const double step = target(j) - z(j);
        if (target(j) < l(j) && step < 0.0) {
          const double a_j = (l(j) - z(j)) / step;
          if (a_j < alpha) alpha = a_j, hit = j, hit_side = -1;
        } else if (target(j) > h(j) && step > 0.0) {
          const double a_j = (h(j) - z(j)) / step;
          if (a_j < alpha) alpha = a_j, hit = j, hit_side = +1;
        }
      }
      if (hit < 0) {
        z = target;
        break;
      }
      alpha = std::max(0.0, alpha);
      z += alpha * (target - z);
      z(hit) = hit_side < 0 ? l(hit) : h(hit);
      state[static_cast<std::size_t>(hit)] = hit_side;
      for (Eigen::Index j = 0; j < p; ++j) {  // others that landed on a bound
        if (state[static_cast<std::size_t>(j)] != 0) continue;
        if (z(j) <= l(j))
          z(j) = l(j), state[static_cast<std::size_t>(j)] = -1;
        else if (z(j) >= h(j))
          z(j) = h(j), state[static_cast<std::size_t>(j)] = +1;
      }
    }
  }
  if (at_bound) {
    at_bound->assign(static_cast<std::size_t>(p), 0);
    for (Eigen::Index j = 0; j < p; ++j)
      (*at_bound)[static_cast<std::size_t>(j)] = state[static_cast<std::size_t>(j)] != 0;
  }
  return z.cwiseQuotient(scale);
}

/// The compression of box_least_squares from the normal equations: `gram` holds A^T A in its
/// lower triangle and is scaled in place to unit diagonal; `scale` receives the column norms (1
/// for a zero column).  With L L^T its Cholesky factorisation, R = L^T and Q^T b = L^-1 A^T b are
/// the QR's compression up to the signs of R's rows, as long as the normal equations lose few
/// digits: false (as, bs untouched) unless the reciprocal condition of the scaled Gram matrix
/// exceeds 1e-10, i.e. cond(A) below 1e5, at most 5 of 16 digits lost (a zero column fails).
inline bool compress_by_gram(Eigen::MatrixXd& gram, const Eigen::VectorXd& atb,
                             Eigen::LLT<Eigen::MatrixXd>& llt, Eigen::VectorXd& scale,
                             Eigen::MatrixXd& as, Eigen::VectorXd& bs) {
  const Eigen::Index p = gram.cols();
  scale.resize(p);
  for (Eigen::Index j = 0; j < p; ++j) {
    const double s = std::sqrt(gram(j, j));
    scale(j) = s > 0.0 ? s : 1.0;
  }
  for (Eigen::Index j = 0; j < p; ++j)
    for (Eigen::Index i = j; i < p; ++i) gram(i, j) /= scale(i) * scale(j);
  llt.compute(gram);
  if (llt.info() != Eigen::Success || !(llt.rcond() > 1e-10)) return false;
  as = llt.matrixU();
  bs = llt.matrixL().solve(atb.cwiseQuotient(scale).eval());
  return true;
}

/// min ||A z - b|| subject to lo <= z <= hi (entries may be +-infinity) by an active-set method
/// (Lawson-Hanson generalised to two-sided bounds).  Columns are scaled to unit norm internally;
/// the free subproblems are solved by column-pivoted QR, so a rank-deficient free set gives a
/// basic solution, never a NaN.  Converges in a finite number of steps for this convex problem.
/// `at_bound` (optional) receives 1 for every variable left on a bound.
///
/// Compression: with A = Q R (N > P), ||A z - b||^2 = ||R z - Q^T b||^2 + const, so one O(N P^2)
/// factorisation turns the problem into a P x P one and every active-set step (each a fresh QR of
/// the free columns) costs O(P^3) instead of O(N P^2).  Q is orthogonal, so the column norms, the
/// conditioning and hence the rank decisions are those of A itself.
/// Storage box_least_squares may keep from call to call (N x P; see Workspace in nlr.cpp).
struct BoxLeastSquaresStorage {
  Eigen::MatrixXd scaled;
  Eigen::VectorXd rhs;
  Eigen::MatrixXd gram;
  Eigen::LLT<Eigen::MatrixXd> llt;
};

inline Eigen::VectorXd box_least_squares(const Eigen::MatrixXd& a, const Eigen::VectorXd& b,
                                         const Eigen::VectorXd& lo, const Eigen::VectorXd& hi,
                                         std::vector<int>* at_bound = nullptr,
                                         BoxLeastSquaresStorage* storage = nullptr) {
  const Eigen::Index p = a.cols();
  Eigen::VectorXd scale(p);
  Eigen::MatrixXd as;
  Eigen::VectorXd bs;
  BoxLeastSquaresStorage local;
  BoxLeastSquaresStorage& big = storage ? *storage : local;
  if (a.rows() > p) {
    // Compression: the Gram matrix in one blocked pass (N P^2 / 2 multiply-adds at the speed of
    // a matrix product) and its Cholesky factor when well conditioned; otherwise the Householder
    // QR of A (4-5x slower at N = 10^4, P = 10).
    big.gram.setZero(p, p);
    big.gram.template selfadjointView<Eigen::Lower>().rankUpdate(a.transpose());
    if (!compress_by_gram(big.gram, a.transpose() * b, big.llt, scale, as, bs)) {
      big.scaled.resize(a.rows(), p);
      big.scaled.noalias() = a * scale.cwiseInverse().asDiagonal();
      big.rhs = b;
      Eigen::HouseholderQR<Eigen::Ref<Eigen::MatrixXd>> qr(big.scaled);  // in place
      big.rhs.applyOnTheLeft(qr.householderQ().adjoint());
      as = big.scaled.topRows(p).template triangularView<Eigen::Upper>();
      bs = big.rhs.head(p);
    }
  } else {
    for (Eigen::Index j = 0; j < p; ++j) {
      const double s = a.col(j).norm();
      scale(j) = s > 0.0 ? s : 1.0;
    }
    as = a * scale.cwiseInverse().asDiagonal();
    bs = b;
  }
  return box_least_squares_reduced(as, bs, scale, b.norm(), lo, hi, at_bound);
}

/// box_least_squares from the normal equations alone: `gram` = A^T A (lower triangle read),
/// `atb` = A^T b, `btb` = b^T b.  Moving one operator of a fitted set needs no N x P matrix this
/// way (see threshold_moves in nlr.cpp).  False, with z untouched, when the column-scaled Gram
/// matrix has a reciprocal condition of 1e-10 or less (or a zero column): the normal equations
/// would then lose more than 5 digits.  `rss` receives ||A z - b||^2, from the reduced problem
/// (relative accuracy about 1e-16 / (RSS/SSS), ample for comparing fits).
inline bool box_least_squares_gram(const Eigen::MatrixXd& gram, const Eigen::VectorXd& atb,
                                   double btb, const Eigen::VectorXd& lo, const Eigen::VectorXd& hi,
                                   Eigen::VectorXd& z, double& rss,
                                   std::vector<int>* at_bound = nullptr) {
  Eigen::MatrixXd g = gram;
  Eigen::LLT<Eigen::MatrixXd> llt;
  Eigen::VectorXd scale, bs;
  Eigen::MatrixXd as;
  if (!compress_by_gram(g, atb, llt, scale, as, bs)) return false;
  z = box_least_squares_reduced(as, bs, scale, std::sqrt(std::max(btb, 0.0)), lo, hi, at_bound);
  // ||A z - b||^2 = ||b||^2 - ||Q^T b||^2 + ||R z_s - Q^T b||^2 with z_s the scaled solution.
  const Eigen::VectorXd fit = as * z.cwiseProduct(scale) - bs;
  rss = std::max(0.0, btb - bs.squaredNorm() + fit.squaredNorm());
  return true;
}

/// Projection machinery of variable projection for a regressor matrix Phi (N x P): column-scaled,
/// column-pivoted QR, rank-revealing.  For a parameter p with dPhi/dp, the exact (Golub-Pereyra)
/// derivative of the projected residual r = (I - Phi Phi^+) y is
///     dr/dp = -P_perp (dPhi/dp) c - (Phi^+)^T (dPhi/dp)^T r,
/// and `derivative(a, w)` returns it from a = (dPhi/dp) c and w = (dPhi/dp)^T r.  Columns beyond
/// the numerical rank are left out of the pseudo-inverse (minimum-information, never NaN).
struct Projector {
  Eigen::VectorXd scale;  ///< column norms used for scaling
  Eigen::Index rank = 0;

  Projector() = default;
  explicit Projector(const Eigen::MatrixXd& phi, double threshold = 1e-12) {
    compute(phi, threshold);
  }

  /// (Re)factorise for `phi`, reusing storage when the sizes repeat.
  void compute(const Eigen::MatrixXd& phi, double threshold = 1e-12) {
    use_gram_ = false;
    const Eigen::Index p = phi.cols();
    scale.resize(p);
    for (Eigen::Index j = 0; j < p; ++j) {
      const double s = phi.col(j).norm();
      scale(j) = s > 0.0 ? s : 1.0;
    }
    phis_.resize(phi.rows(), p);
    phis_.noalias() = phi * scale.cwiseInverse().asDiagonal();
    // Fast path: normal equations of the unit-norm columns when they are well conditioned
    // (reciprocal condition of the Gram matrix above 1e-10, i.e. cond(Phi) below 1e5: the
    // normal equations then lose at most 5 of 16 digits).  Otherwise the rank-revealing QR.
    if (p > 0) {
      gram_matrix_.resize(p, p);
      gram_matrix_.noalias() = phis_.transpose() * phis_;
      gram_.compute(gram_matrix_);
      if (gram_.info() == Eigen::Success && gram_.rcond() > 1e-10 &&
          threshold * threshold < gram_.rcond()) {
        use_gram_ = true;
        rank = p;
        position_ = Eigen::VectorXi::LinSpaced(p, 0, static_cast<int>(p - 1));
        return;
      }
    }
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(phis_);
    qr.setThreshold(threshold);
    rank = qr.rank();
    q_ = qr.householderQ() * Eigen::MatrixXd::Identity(phi.rows(), rank);
    r11_ = qr.matrixR().topLeftCorner(rank, rank).template triangularView<Eigen::Upper>();
    position_.resize(p);
    const auto& ind = qr.colsPermutation().indices();
    for (Eigen::Index k = 0; k < p; ++k) position_(ind(k)) = static_cast<int>(k);
  }

  /// Basic least-squares solution: columns beyond the numerical rank get coefficient 0 (dropped).
  Eigen::VectorXd solve(const Eigen::VectorXd& y) const {
    if (use_gram_) return gram_.solve(phis_.transpose() * y).cwiseQuotient(scale);
    const Eigen::VectorXd z =
        r11_.template triangularView<Eigen::Upper>().solve(q_.transpose() * y);
    Eigen::VectorXd c = Eigen::VectorXd::Zero(position_.size());
    for (Eigen::Index j = 0; j < position_.size(); ++j)
      if (position_(j) < rank) c(j) = z(position_(j)) / scale(j);
    return c;
  }

  /// True for a column left out (beyond the numerical rank).
  bool dropped(Eigen::Index j) const { return position_(j) >= rank; }

  /// Column-wise `derivative` for many parameters at once: A is N x k, W is P x k.
  Eigen::MatrixXd derivatives(const Eigen::MatrixXd& a, const Eigen::MatrixXd& w) const {
    const Eigen::MatrixXd ws = scale.cwiseInverse().asDiagonal() * w;
    if (use_gram_) return phis_ * gram_.solve(phis_.transpose() * a - ws) - a;
    Eigen::MatrixXd wp = Eigen::MatrixXd::Zero(rank, w.cols());
    for (Eigen::Index j = 0; j < w.rows(); ++j)
      if (position_(j) < rank) wp.row(position_(j)) = ws.row(j);
    const Eigen::MatrixXd v = r11_.transpose().template triangularView<Eigen::Lower>().solve(wp);
    return q_ * (q_.transpose() * a - v) - a;
  }

  /// The same into `out` (N x k), through storage kept from call to call: the variable-projection
  /// Jacobians call this at every accepted step, and fresh N x k temporaries there cost more in
  /// page faults than the arithmetic.
  void derivatives_into(const Eigen::MatrixXd& a, const Eigen::MatrixXd& w, Eigen::MatrixXd& out) {
    if (!use_gram_) {
      out = derivatives(a, w);
      return;
    }
    small_.resize(phis_.cols(), a.cols());
    small_.noalias() = phis_.transpose() * a;
    small_.noalias() -= scale.cwiseInverse().asDiagonal() * w;
    gram_.solveInPlace(small_);
    out = -a;
    out.noalias() += phis_ * small_;
  }

  Eigen::VectorXd derivative(const Eigen::VectorXd& a, const Eigen::VectorXd& w) const {
    if (use_gram_) {
      return -(a - phis_ * gram_.solve(phis_.transpose() * a)) -
             phis_ * gram_.solve(w.cwiseQuotient(scale));
    }
    Eigen::VectorXd out = -(a - q_ * (q_.transpose() * a));
    Eigen::VectorXd wp = Eigen::VectorXd::Zero(rank);
    bool any = false;
    for (Eigen::Index j = 0; j < w.size(); ++j)
      if (position_(j) < rank && w(j) != 0.0) wp(position_(j)) = w(j) / scale(j), any = true;
    if (any) {
      const Eigen::VectorXd v = r11_.transpose().template triangularView<Eigen::Lower>().solve(wp);
      out -= q_ * v;
    }
    return out;
  }

 private:
  Eigen::MatrixXd phis_;  // unit-norm columns
  Eigen::MatrixXd gram_matrix_;
  Eigen::MatrixXd small_;  // P x k scratch of derivatives_into
  Eigen::LLT<Eigen::MatrixXd> gram_;
  bool use_gram_ = false;
  Eigen::MatrixXd q_;         // N x rank, orthonormal basis of the range (QR path)
  Eigen::MatrixXd r11_;       // rank x rank upper triangular (QR path)
  Eigen::VectorXi position_;  // position_[j]: where column j sits after pivoting
};

/// Ordered thresholds in [lo, hi] from a point of the unit box by stick-breaking in log space:
/// beta_i = 1 - prod_{l <= i} (1 - s_l), log Delta_i = log lo + (log hi - log lo) beta_i.  Every
/// s in [0, 1]^M gives lo <= Delta_1 <= ... <= Delta_M <= hi, so box bounds on s (which Ceres and
/// NLopt both handle) keep the thresholds ordered and inside their physical range.
struct StickBreaking {
  double lo, hi;

  std::vector<double> thresholds(std::span<const double> s) const {
    std::vector<double> d(s.size());
    const double a = std::log(lo), w = std::log(hi) - std::log(lo);
    double rest = 1.0;
    for (std::size_t i = 0; i < s.size(); ++i) {
      rest *= 1.0 - s[i];
      d[i] = std::exp(a + w * (1.0 - rest));
    }
    return d;
  }

  /// J(i, l) = d Delta_i / d s_l (lower triangular).
  Eigen::MatrixXd jacobian(std::span<const double> s) const {
    const Eigen::Index m = static_cast<Eigen::Index>(s.size());
    const std::vector<double> d = thresholds(s);
    const double w = std::log(hi) - std::log(lo);
    Eigen::MatrixXd j = Eigen::MatrixXd::Zero(m, m);
    for (Eigen::Index i = 0; i < m; ++i)
      for (Eigen::Index l = 0; l <= i; ++l) {
        double prod = 1.0;
        for (Eigen::Index q = 0; q <= i; ++q)
          if (q != l) prod *= 1.0 - s[static_cast<std::size_t>(q)];
        j(i, l) = d[static_cast<std::size_t>(i)] * w * prod;
      }
    return j;
  }

  /// Inverse map for thresholds (sorted and clamped into [lo, hi] first).
  std::vector<double> coordinates(std::vector<double> d) const {
    std::sort(d.begin(), d.end());
    const double a = std::log(lo), w = std::log(hi) - std::log(lo);
    std::vector<double> s(d.size());
    double prev = 0.0;
    for (std::size_t i = 0; i < d.size(); ++i) {
      const double beta = std::clamp((std::log(std::clamp(d[i], lo, hi)) - a) / w, 0.0, 1.0);
      s[i] = prev < 1.0 ? std::clamp((beta - prev) / (1.0 - prev), 0.0, 1.0) : 0.0;
      prev = std::max(prev, beta);
    }
    return s;
  }
};

/// Marginal (unscaled) covariance of the first `interest` parameters, (J^T J)^-1 restricted to
/// them, where the remaining columns of J are nuisance parameters (initial states) estimated with
/// them.  Columns are scaled to unit norm before the SVD; nuisance columns that are identically
/// zero (an operator saturated from the first sample: its initial state has no effect) are left
/// out.  When J is rank-deficient (reciprocal condition below `rcond`) the nuisance columns are
/// held fixed instead (the conditional covariance); false when even that is rank-deficient.
inline bool marginal_covariance(const Eigen::MatrixXd& jac, Eigen::Index interest,
                                Eigen::MatrixXd& out, double rcond = 1e-10) {
  auto attempt = [&](bool with_nuisance) {
    std::vector<Eigen::Index> cols;
    for (Eigen::Index c = 0; c < jac.cols(); ++c)
      if (c < interest || (with_nuisance && jac.col(c).norm() > 0.0)) cols.push_back(c);
    const Eigen::Index p = static_cast<Eigen::Index>(cols.size());
    Eigen::MatrixXd j(jac.rows(), p);
    Eigen::VectorXd sc(p);
    for (Eigen::Index k = 0; k < p; ++k) {
      j.col(k) = jac.col(cols[static_cast<std::size_t>(k)]);
      sc(k) = j.col(k).norm();
      if (sc(k) == 0.0) sc(k) = 1.0;
      j.col(k) /= sc(k);
    }
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(j, Eigen::ComputeThinV);
    const Eigen::VectorXd sv = svd.singularValues();
    if (sv.size() == 0 || !(sv(sv.size() - 1) > rcond * sv(0))) return false;
    const Eigen::MatrixXd v = svd.matrixV().topRows(interest);
    out = sc.head(interest).cwiseInverse().asDiagonal() *
          (v * sv.cwiseAbs2().cwiseInverse().asDiagonal() * v.transpose()) *
          sc.head(interest).cwiseInverse().asDiagonal();
    return out.allFinite();
  };
  return attempt(true) || attempt(false);
}

}  // namespace friction::detail
