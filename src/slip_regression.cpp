// The out-of-line parts of slip_regression.hpp.  They were inline in the header, and every source
// that included it compiled Eigen's QR, SVD and Cholesky again: 14 s of a Release build per source.
#include "slip_regression.hpp"

#include <Eigen/QR>
#include <Eigen/SVD>

#include "friction/motion.hpp"

namespace friction::detail {

std::vector<double> turns_of(std::span<const double> x) {
  std::vector<double> out(x.size(), 0.0);
  for (std::size_t k = 1; k < x.size(); ++k) out[k] = turn_increment(x, k);
  return out;
}

namespace {

// One operator's clamp (threshold a, slip limits [-down a, up a]; on the step to the extremum
// when the interval holds a turn, [-down_turn a, up_turn a]: motion.hpp, The level at the turn)
// with the sensitivity d delta / d a when it ended on a bound (`clamped`; `bound` the factor of a
// in that bound).  Through the turn the bound it last met is the one that counts.
struct OperatorStep {
  double value;
  bool clamped;
  double bound;  // d value / d a when clamped
};
inline OperatorStep step_operator(double v, double dx, double turn, double a, double down,
                                  double up, double down_turn, double up_turn) {
  const double lo = -down * a, hi = up * a;
  if (turn != 0.0) {
    const double lo_turn = -down_turn * a, hi_turn = up_turn * a;
    const double u1 = v + turn;
    const bool a1 = u1 > hi_turn, b1 = u1 < lo_turn;
    const double u2 = (a1 ? hi_turn : (b1 ? lo_turn : u1)) + (dx - turn);
    if (u2 > hi) return {hi, true, up};
    if (u2 < lo) return {lo, true, -down};
    if (a1) return {u2, true, up_turn};
    if (b1) return {u2, true, -down_turn};
    return {u2, false, 0.0};
  }
  const double u = v + dx;
  if (u > hi) return {hi, true, up};
  if (u < lo) return {lo, true, -down};
  return {u, false, 0.0};
}

// operator_trajectories under SlipLimits: the same recursion with a box that moves per sample.
void trajectories_under_limits(std::span<const double> thresholds,
                               std::span<const double> initial, std::span<const double> x,
                               bool sensitivities, OperatorTrajectories& out,
                               const SlipLimits& limits, std::span<const double> turn) {
  const std::size_t m = thresholds.size();
  const Eigen::Index n = static_cast<Eigen::Index>(x.size());
  FRICTION_CHECK(limits.upper.size() == x.size() && limits.lower.size() == x.size(),
                 "Maxwell Slip: slip limits for ", limits.upper.size(), " and ",
                 limits.lower.size(), " samples, the record has ", x.size());
  const bool turned = !limits.turn_upper.empty();
  FRICTION_CHECK(!turned || (limits.turn_upper.size() == x.size() &&
                             limits.turn_lower.size() == x.size()),
                 "Maxwell Slip: turn limits for ", limits.turn_upper.size(), " and ",
                 limits.turn_lower.size(), " samples, the record has ", x.size());
  std::vector<double> v(m), g_threshold(m, 0.0), g_initial(m, limits.first);
  for (std::size_t i = 0; i < m; ++i) v[i] = limits.first * initial[i];
  double* delta = out.delta.data();
  double* dt = sensitivities ? out.d_threshold.data() : nullptr;
  double* di = sensitivities ? out.d_initial.data() : nullptr;
  for (Eigen::Index t = 0; t < n; ++t) {
    const std::size_t ts = static_cast<std::size_t>(t);
    const double dx = t > 0 ? x[ts] - x[ts - 1] : 0.0;
    const double up = limits.upper[ts], down = limits.lower[ts];
    const double up_turn = turned ? limits.turn_upper[ts] : up;
    const double down_turn = turned ? limits.turn_lower[ts] : down;
    for (std::size_t i = 0; i < m; ++i) {
      const OperatorStep s =
          step_operator(v[i], dx, turn[ts], thresholds[i], down, up, down_turn, up_turn);
      v[i] = s.value;
      const Eigen::Index at = static_cast<Eigen::Index>(i) * n + t;
      delta[at] = v[i];
      if (sensitivities) {
        g_threshold[i] = s.clamped ? s.bound : g_threshold[i];
        g_initial[i] = s.clamped ? 0.0 : g_initial[i];
        dt[at] = g_threshold[i];
        di[at] = g_initial[i];
      }
    }
  }
}

}  // namespace

void check_slip_limits(const SlipLimits& limits, std::size_t samples) {
  // The slip-limit factors and those at the turns (empty: the slip limits'), by one rule.
  const auto check_factors = [samples](const std::vector<double>& upper,
                                       const std::vector<double>& lower, const char* what) {
    FRICTION_CHECK(upper.size() == samples && lower.size() == samples, "Maxwell Slip: ", what,
                   "s for ", upper.size(), " and ", lower.size(), " samples, the record has ",
                   samples);
    for (std::size_t t = 0; t < samples; ++t)
      FRICTION_CHECK(upper[t] > 0.0 && lower[t] > 0.0 && std::isfinite(upper[t]) &&
                         std::isfinite(lower[t]),
                     "Maxwell Slip: ", what, " factors at sample ", t, " must be finite and > 0");
  };
  check_factors(limits.upper, limits.lower, "slip limit");
  FRICTION_CHECK(std::isfinite(limits.first) && limits.first > 0.0,
                 "Maxwell Slip: the first level ", limits.first, " must be finite and > 0");
  if (!limits.turn_upper.empty() || !limits.turn_lower.empty())
    check_factors(limits.turn_upper, limits.turn_lower, "turn limit");
}

namespace {

// The checks every form of operator_trajectories makes, and the turns: the caller's, or computed
// into `own`.
std::span<const double> checked_turns(std::span<const double> thresholds,
                                      std::span<const double> initial, std::span<const double> x,
                                      std::span<const double> turns, std::vector<double>& own) {
  const std::size_t m = thresholds.size();
  FRICTION_CHECK(initial.size() == m, "Maxwell Slip: ", initial.size(), " initial deflections for ",
                 m, " operators");
  for (std::size_t i = 0; i < m; ++i)
    FRICTION_CHECK(std::isfinite(thresholds[i]) && thresholds[i] > 0.0, "Maxwell Slip: threshold[",
                   i, "] = ", thresholds[i], " m must be finite and > 0");
  FRICTION_CHECK(turns.empty() || turns.size() == x.size(), "Maxwell Slip: ", turns.size(),
                 " turns for ", x.size(), " samples");
  if (!turns.empty()) return turns;
  own = turns_of(x);
  return own;
}

// The nominal box's state before the first sample: the initial deflections clamped to the
// thresholds, with the sensitivities of the branch taken.
struct NominalStart {
  std::vector<double> limit, v, g_threshold, g_initial;
  NominalStart(std::span<const double> thresholds, std::span<const double> initial)
      : limit(thresholds.begin(), thresholds.end()),
        v(initial.begin(), initial.end()),
        g_threshold(thresholds.size(), 0.0),
        g_initial(thresholds.size(), 1.0) {
    for (std::size_t i = 0; i < limit.size(); ++i) {
      if (v[i] > limit[i])
        v[i] = limit[i], g_threshold[i] = 1.0, g_initial[i] = 0.0;
      else if (v[i] < -limit[i])
        v[i] = -limit[i], g_threshold[i] = -1.0, g_initial[i] = 0.0;
    }
  }
};

// The nominal box's recursion with sensitivities: store(at, delta, d_threshold, d_initial) for
// every operator i and sample t, at = i N + t.  One loop for the dense and the compact form, so
// the two cannot differ.
template <typename Store>
void nominal_with_sensitivities(std::span<const double> thresholds,
                                std::span<const double> initial, std::span<const double> x,
                                std::span<const double> turn, Store&& store) {
  const std::size_t m = thresholds.size();
  const Eigen::Index n = static_cast<Eigen::Index>(x.size());
  NominalStart st(thresholds, initial);
  for (Eigen::Index t = 0; t < n; ++t) {
    const double dx =
        t > 0 ? x[static_cast<std::size_t>(t)] - x[static_cast<std::size_t>(t - 1)] : 0.0;
    for (std::size_t i = 0; i < m; ++i) {
      const OperatorStep s = step_operator(st.v[i], dx, turn[static_cast<std::size_t>(t)],
                                           st.limit[i], 1.0, 1.0, 1.0, 1.0);
      st.v[i] = s.value;
      st.g_threshold[i] = s.clamped ? s.bound : st.g_threshold[i];
      st.g_initial[i] = s.clamped ? 0.0 : st.g_initial[i];
      store(static_cast<Eigen::Index>(i) * n + t, st.v[i], st.g_threshold[i], st.g_initial[i]);
    }
  }
}

}  // namespace

void operator_trajectories(std::span<const double> thresholds,
                           std::span<const double> initial, std::span<const double> x,
                           bool sensitivities, OperatorTrajectories& out,
                           const SlipLimits* limits, std::span<const double> turns) {
  const std::size_t m = thresholds.size();
  std::vector<double> own_turns;
  turns = checked_turns(thresholds, initial, x, turns, own_turns);
  const Eigen::Index n = static_cast<Eigen::Index>(x.size());
  const Eigen::Index mi = static_cast<Eigen::Index>(m);
  out.delta.resize(n, mi);
  out.codes.clear();
  if (sensitivities) {
    out.d_threshold.resize(n, mi);
    out.d_initial.resize(n, mi);
  }
  if (limits) {
    trajectories_under_limits(thresholds, initial, x, sensitivities, out, *limits, turns);
    return;
  }
  double* delta = out.delta.data();
  if (sensitivities) {
    double* dt = out.d_threshold.data();
    double* di = out.d_initial.data();
    nominal_with_sensitivities(thresholds, initial, x, turns,
                               [&](Eigen::Index at, double v, double gt, double gi) {
                                 delta[at] = v;
                                 dt[at] = gt;
                                 di[at] = gi;
                               });
    return;
  }
  // The recursion of one operator is a chain of dependent additions and clamps (about 12 cycles
  // per sample), so the operators are stepped side by side, time outermost: their chains are
  // independent and overlap in the pipeline (3-4x faster at M = 10 than operator by operator).
  NominalStart st(thresholds, initial);
  std::vector<double>& v = st.v;
  const std::vector<double>& limit = st.limit;
  const std::span<const double> turn = turns;
  for (Eigen::Index t = 0; t < n; ++t) {
    const double dx =
        t > 0 ? x[static_cast<std::size_t>(t)] - x[static_cast<std::size_t>(t - 1)] : 0.0;
    double* row = delta + t;
    if (const double o = turn[static_cast<std::size_t>(t)]; o != 0.0) {
      for (std::size_t i = 0; i < m; ++i) {
        const double u = std::clamp(v[i] + o, -limit[i], limit[i]) + (dx - o);
        v[i] = u > limit[i] ? limit[i] : (u < -limit[i] ? -limit[i] : u);
        row[static_cast<Eigen::Index>(i) * n] = v[i];
      }
      continue;
    }
    for (std::size_t i = 0; i < m; ++i) {
      const double u = v[i] + dx;
      v[i] = u > limit[i] ? limit[i] : (u < -limit[i] ? -limit[i] : u);
      row[static_cast<Eigen::Index>(i) * n] = v[i];
    }
  }
}

void operator_trajectories_compact(std::span<const double> thresholds,
                                   std::span<const double> initial, std::span<const double> x,
                                   OperatorTrajectories& out, std::span<const double> turns) {
  std::vector<double> own_turns;
  turns = checked_turns(thresholds, initial, x, turns, own_turns);
  const Eigen::Index n = static_cast<Eigen::Index>(x.size());
  out.delta.resize(n, static_cast<Eigen::Index>(thresholds.size()));
  out.d_threshold.resize(0, 0);
  out.d_initial.resize(0, 0);
  out.codes.resize(x.size() * thresholds.size());
  double* delta = out.delta.data();
  std::uint8_t* codes = out.codes.data();
  nominal_with_sensitivities(thresholds, initial, x, turns,
                             [&](Eigen::Index at, double v, double gt, double gi) {
                               delta[at] = v;
                               // gi != 0: never at a bound (then gt = 0); else gt is +-1.
                               codes[at] = gi != 0.0 ? OperatorTrajectories::kFree
                                           : gt > 0.0 ? OperatorTrajectories::kUpper
                                                      : OperatorTrajectories::kLower;
                             });
}

void OperatorTrajectories::sensitivity_rows(Eigen::Index t0, Eigen::Index rows,
                                            Eigen::Ref<Eigen::MatrixXd> dt,
                                            Eigen::Ref<Eigen::MatrixXd> di) const {
  const Eigen::Index n = delta.rows(), m = delta.cols();
  FRICTION_CHECK(t0 >= 0 && rows >= 0 && t0 + rows <= n && dt.rows() >= rows &&
                     di.rows() >= rows && dt.cols() == m && di.cols() == m,
                 "OperatorTrajectories: rows ", t0, " + ", rows, " of ", n, " into ", dt.rows(),
                 " x ", dt.cols(), " and ", di.rows(), " x ", di.cols());
  if (codes.empty()) {
    FRICTION_CHECK(d_threshold.rows() == n && d_initial.rows() == n,
                   "OperatorTrajectories: no sensitivities were computed");
    dt.topRows(rows) = d_threshold.middleRows(t0, rows);
    di.topRows(rows) = d_initial.middleRows(t0, rows);
    return;
  }
  static constexpr double kThreshold[] = {0.0, 1.0, -1.0}, kInitial[] = {1.0, 0.0, 0.0};
  for (Eigen::Index i = 0; i < m; ++i) {
    const std::uint8_t* c = codes.data() + i * n + t0;
    for (Eigen::Index t = 0; t < rows; ++t) {
      dt(t, i) = kThreshold[c[t]];
      di(t, i) = kInitial[c[t]];
    }
  }
}

OperatorTrajectories operator_trajectories(std::span<const double> thresholds,
                                           std::span<const double> initial,
                                           std::span<const double> x, bool sensitivities,
                                           const SlipLimits* limits) {
  OperatorTrajectories out;
  operator_trajectories(thresholds, initial, x, sensitivities, out, limits);
  return out;
}

Eigen::VectorXd box_least_squares_reduced(const Eigen::MatrixXd& as,
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

bool compress_by_gram(Eigen::MatrixXd& gram, const Eigen::VectorXd& atb,
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

Eigen::VectorXd box_least_squares(const Eigen::MatrixXd& a, const Eigen::VectorXd& b,
                                  const Eigen::VectorXd& lo, const Eigen::VectorXd& hi,
                                  std::vector<int>* at_bound,
                                  BoxLeastSquaresStorage* storage) {
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

bool box_least_squares_gram(const Eigen::MatrixXd& gram, const Eigen::VectorXd& atb,
                            double btb, const Eigen::VectorXd& lo, const Eigen::VectorXd& hi,
                            Eigen::VectorXd& z, double& rss,
                            std::vector<int>* at_bound) {
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

bool marginal_covariance(const Eigen::MatrixXd& jac, Eigen::Index interest,
                         Eigen::MatrixXd& out, double rcond) {
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

void Projector::compute(const Eigen::MatrixXd& phi, double threshold) {
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

Eigen::VectorXd Projector::solve(const Eigen::VectorXd& y) const {
  if (use_gram_) return gram_.solve(phis_.transpose() * y).cwiseQuotient(scale);
  const Eigen::VectorXd z =
      r11_.template triangularView<Eigen::Upper>().solve(q_.transpose() * y);
  Eigen::VectorXd c = Eigen::VectorXd::Zero(position_.size());
  for (Eigen::Index j = 0; j < position_.size(); ++j)
    if (position_(j) < rank) c(j) = z(position_(j)) / scale(j);
  return c;
}

Eigen::MatrixXd Projector::derivatives(const Eigen::MatrixXd& a, const Eigen::MatrixXd& w) const {
  const Eigen::MatrixXd ws = scale.cwiseInverse().asDiagonal() * w;
  if (use_gram_) return phis_ * gram_.solve(phis_.transpose() * a - ws) - a;
  Eigen::MatrixXd wp = Eigen::MatrixXd::Zero(rank, w.cols());
  for (Eigen::Index j = 0; j < w.rows(); ++j)
    if (position_(j) < rank) wp.row(position_(j)) = ws.row(j);
  const Eigen::MatrixXd v = r11_.transpose().template triangularView<Eigen::Lower>().solve(wp);
  return q_ * (q_.transpose() * a - v) - a;
}

void Projector::derivatives_into(const Eigen::MatrixXd& a, const Eigen::MatrixXd& w,
                                 Eigen::MatrixXd& out) {
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

Eigen::VectorXd Projector::derivative(const Eigen::VectorXd& a, const Eigen::VectorXd& w) const {
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

}  // namespace friction::detail
