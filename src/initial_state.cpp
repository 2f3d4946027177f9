// Initial-state estimation (see include/friction/initial_state.hpp for the method).
#include "friction/initial_state.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <tuple>

#include "slip_regression.hpp"

namespace friction {
namespace {

// Single-operator trajectory from initial deflection d (unit stiffness), sample 0 included.
Eigen::VectorXd single_trajectory(std::span<const double> x, double threshold, double d) {
  const Eigen::Index n = static_cast<Eigen::Index>(x.size());
  Eigen::VectorXd out(n);
  double s = std::clamp(d, -threshold, threshold);
  out(0) = s;
  for (Eigen::Index t = 1; t < n; ++t) {
    const std::size_t k = static_cast<std::size_t>(t);
    const double dx = x[k] - x[k - 1], turn = turn_increment(x, k);
    if (turn != 0.0)  // motion.hpp, Turns between samples
      s = std::clamp(std::clamp(s + turn, -threshold, threshold) + (dx - turn), -threshold,
                     threshold);
    else
      s = std::clamp(s + dx, -threshold, threshold);
    out(t) = s;
  }
  return out;
}

// The displacement at the extremum inside interval t, or x_t when there is none (motion.hpp,
// Turns between samples): a range that covers a turn's peak has saturated the operators it covers.
double extreme_of_interval(std::span<const double> x, std::size_t t) {
  const double turn = turn_increment(x, t);
  return turn != 0.0 ? x[t - 1] + turn : x[t];
}

// The end of the prefix [0, end) over which an operator of this threshold depends on its initial
// deflection: until the displacement has covered a range of 2 Delta it may not have saturated, and
// a filter of `taps` taps carries that `taps` samples further (estimate_initial_deflections).
std::size_t prefix_end(std::span<const double> x, double threshold, std::size_t taps) {
  double lo = x[0], hi = x[0];
  for (std::size_t t = 0; t < x.size(); ++t) {
    const double e = extreme_of_interval(x, t);
    lo = std::min({lo, x[t], e});
    hi = std::max({hi, x[t], e});
    if (hi - lo >= 2.0 * threshold) return std::min(x.size(), t + taps + 1);
  }
  return x.size();
}

Eigen::VectorXd filtered(const Eigen::VectorXd& delta, const Eigen::RowVectorXd& taps) {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(delta.size());
  for (Eigen::Index j = 0; j < taps.size(); ++j)
    if (taps(j) != 0.0) f += taps(j) * detail::lagged(delta, j);
  return f;
}

// Exact global minimiser over d in [-Delta, Delta] of sum_t (y(t) - sum_j taps_j delta(t-j; d))^2
// for one operator.  Until its first saturation tau(d) the operator is d + xi(t) (xi = x - x(0));
// from tau on it coincides with the trajectory started at +Delta (if it saturated at the top) or
// at -Delta (bottom).  tau(d) is constant between the breakpoints d = Delta - max_{s<=t} xi(s)
// and d = -Delta - min_{s<=t} xi(s), so on each such interval the cost is a quadratic in d whose
// coefficients come from prefix sums (samples before tau), n explicit samples where lags straddle
// tau, and the suffix cost of the matching reference trajectory.  Minimising every piece gives
// the global minimum in O(N n^2).
class OneOperator {
 public:
  OneOperator(std::span<const double> x, double threshold, const Eigen::RowVectorXd& taps)
      : n_(static_cast<Eigen::Index>(x.size())),
        lags_(taps.size() - 1),
        threshold_(threshold),
        big_theta_(taps.sum()),
        taps_(taps) {
    xi_.resize(n_);
    for (Eigen::Index t = 0; t < n_; ++t) xi_(t) = x[static_cast<std::size_t>(t)] - x[0];
    ref_top_ = single_trajectory(x, threshold, threshold);
    ref_bottom_ = single_trajectory(x, threshold, -threshold);
    if (lags_ > 0) {
      eta_ = filtered(xi_, taps);
      f_top_ = filtered(ref_top_, taps);
      f_bottom_ = filtered(ref_bottom_, taps);
    } else {
      gain_ = taps(0);
    }
    run_max_.resize(n_);
    run_min_.resize(n_);
    std::vector<double> breaks{-threshold, threshold};
    for (Eigen::Index t = 0; t < n_; ++t) {
      // A turn inside interval t counts at sample t (the first sample after it).
      const double e = extreme_of_interval(x, static_cast<std::size_t>(t)) - x[0];
      run_max_(t) = t == 0 ? xi_(0) : std::max({run_max_(t - 1), xi_(t), e});
      run_min_(t) = t == 0 ? xi_(0) : std::min({run_min_(t - 1), xi_(t), e});
      if (t == 0 || run_max_(t) > run_max_(t - 1)) breaks.push_back(threshold - run_max_(t));
      if (t == 0 || run_min_(t) < run_min_(t - 1)) breaks.push_back(-threshold - run_min_(t));
    }
    for (double& v : breaks) v = std::clamp(v, -threshold, threshold);
    std::sort(breaks.begin(), breaks.end());
    breaks.erase(std::unique(breaks.begin(), breaks.end()), breaks.end());
    // One piece per interval: its first saturation time and side do not depend on y.
    for (std::size_t k = 0; k + 1 < breaks.size(); ++k) {
      if (!(breaks[k + 1] > breaks[k])) continue;
      Piece p;
      p.lo = breaks[k];
      p.hi = breaks[k + 1];
      // The midpoint is no breakpoint, so the first saturation is the same with or without
      // equality at the bound.
      std::tie(p.tau, p.top) = saturation(0.5 * (p.lo + p.hi));
      pieces_.push_back(p);
    }
    // The samples at which minimise needs its prefix sums (each piece's first saturation) and
    // suffix sums (where its lag window ends): they do not depend on y.
    marks_ = {0, n_};
    for (const Piece& pc : pieces_) {
      marks_.push_back(pc.tau);
      marks_.push_back(std::min(n_, pc.tau + lags_));
    }
    std::sort(marks_.begin(), marks_.end());
    marks_.erase(std::unique(marks_.begin(), marks_.end()), marks_.end());
    const auto mark = [&](Eigen::Index t) {
      return static_cast<std::size_t>(std::lower_bound(marks_.begin(), marks_.end(), t) -
                                      marks_.begin());
    };
    for (Piece& pc : pieces_) {
      pc.tau_mark = mark(pc.tau);
      pc.end_mark = mark(std::min(n_, pc.tau + lags_));
    }
  }

  /// Global minimiser over d of sum_t (y(t) - sum_j taps_j delta(t-j; d))^2.
  double minimise(const Eigen::Ref<const Eigen::VectorXd>& y) const {
    // Prefix sums of r = y - eta and r^2, and suffix sums of the squared residuals of either
    // reference trajectory, at the marks only (segment_sums).
    const std::size_t nm = marks_.size();
    p1_.assign(nm, 0.0), p2_.assign(nm, 0.0), s_top_.assign(nm, 0.0), s_bottom_.assign(nm, 0.0);
    segment_sums(y);
    for (std::size_t k = nm - 1; k-- > 0;) {
      s_top_[k] += s_top_[k + 1];
      s_bottom_[k] += s_bottom_[k + 1];
    }
    const std::vector<double>&p1 = p1_, &p2 = p2_, &s_top = s_top_, &s_bottom = s_bottom_;
    double best_d = 0.0, best_cost = std::numeric_limits<double>::infinity();
    for (const Piece& pc : pieces_) {
      // cost(d) = qa d^2 + qb d + qc on [lo, hi]
      double qa = big_theta_ * big_theta_ * static_cast<double>(pc.tau);
      double qb = -2.0 * big_theta_ * p1[pc.tau_mark];
      double qc = p2[pc.tau_mark];
      const Eigen::VectorXd& ref = pc.top ? ref_top_ : ref_bottom_;
      const Eigen::Index end = std::min(n_, pc.tau + lags_);
      for (Eigen::Index t = pc.tau; t < end; ++t) {
        double alpha = 0.0, beta = 0.0;
        for (Eigen::Index j = 0; j <= lags_; ++j) {
          const Eigen::Index s = std::max<Eigen::Index>(t - j, 0);
          if (s < pc.tau)
            alpha += taps_(j), beta += taps_(j) * xi_(s);
          else
            beta += taps_(j) * ref(s);
        }
        const double r = y(t) - beta;
        qa += alpha * alpha;
        qb += -2.0 * alpha * r;
        qc += r * r;
      }
      qc += (pc.top ? s_top : s_bottom)[pc.end_mark];
      const double d =
          qa > 0.0 ? std::clamp(-qb / (2.0 * qa), pc.lo, pc.hi) : (qb > 0.0 ? pc.lo : pc.hi);
      const double c = (qa * d + qb) * d + qc;
      if (c < best_cost) best_cost = c, best_d = d;
    }
    return best_d;
  }

  /// The first sample at which the operator started from d (clamped to the box) is clamped, and
  /// at which bound (true: the top), n when it never is.  It moves as d + xi(t) until xi exceeds
  /// Delta - d (a new running maximum) or falls below -Delta - d (a new running minimum), and
  /// from that sample on it is the reference trajectory of that bound (the comment above the
  /// class).  Strict inequalities, as the recursion clamps: an operator that only touches its
  /// bound still moves with d.
  std::pair<Eigen::Index, bool> saturation(double d) const {
    const double* mx = run_max_.data();
    const double* mn = run_min_.data();
    const Eigen::Index tt = std::upper_bound(mx, mx + n_, threshold_ - d) - mx;
    const Eigen::Index tb =
        std::upper_bound(mn, mn + n_, -threshold_ - d, [](double u, double v) { return u > v; }) -
        mn;
    return {std::min(tt, tb), tt <= tb};
  }

  /// sum_j taps_j delta(t - j; d) written to (or, with `add`, added to) out, from the pieces of
  /// the trajectory instead of its recursion: Theta d + eta(t) before the first saturation, the
  /// filtered reference trajectory from `lags` samples after it, and the few samples between
  /// explicitly.  No sample depends on the one before, so every pass vectorises; stepping the
  /// recursion (a chain of dependent additions and clamps) was most of the estimate's time.
  void contribution(double d, Eigen::Ref<Eigen::VectorXd> out, bool add) const {
    d = std::clamp(d, -threshold_, threshold_);
    const auto [tau, top] = saturation(d);
    const Eigen::VectorXd& ref = top ? ref_top_ : ref_bottom_;
    const Eigen::VectorXd& f_ref = filtered_ref(top);
    const Eigen::Index end = std::min(n_, tau + lags_);
    const double level = big_theta_ * d;
    if (add) {
      out.head(tau).array() += gain_ * eta().head(tau).array() + level;
      out.tail(n_ - end) += gain_ * f_ref.tail(n_ - end);
    } else {
      out.head(tau).array() = gain_ * eta().head(tau).array() + level;
      out.tail(n_ - end) = gain_ * f_ref.tail(n_ - end);
    }
    for (Eigen::Index t = tau; t < end; ++t) {
      double f = 0.0;
      for (Eigen::Index j = 0; j <= lags_; ++j) {
        const Eigen::Index s = std::max<Eigen::Index>(t - j, 0);
        f += taps_(j) * (s < tau ? d + xi_(s) : ref(s));
      }
      out(t) = add ? out(t) + f : f;
    }
  }

  /// d/dd of the contribution: sum_j taps_j [t - j before the first saturation].
  void sensitivity(double d, Eigen::Ref<Eigen::VectorXd> out) const {
    d = std::clamp(d, -threshold_, threshold_);
    const Eigen::Index tau = saturation(d).first;
    const Eigen::Index end = std::min(n_, tau + lags_);
    out.head(tau).setConstant(big_theta_);
    out.tail(n_ - end).setZero();
    for (Eigen::Index t = tau; t < end; ++t) {
      double g = 0.0;
      for (Eigen::Index j = 0; j <= lags_; ++j)
        if (std::max<Eigen::Index>(t - j, 0) < tau) g += taps_(j);
      out(t) = g;
    }
  }

 private:
  // The four sums of minimise over every segment between marks, in one pass: p1_ and p2_ get
  // the running prefix sums of r = y - gain eta and r^2 at the marks, s_top_ and s_bottom_ each
  // segment's own sum of (y - gain ref)^2 (minimise accumulates them from the end).  Each sum
  // runs in two lanes, even and odd samples, joined at the segment's end: the lanes are
  // independent chains of additions that the compiler keeps in one vector register.  Where the
  // motion rises smoothly from rest every sample is a new running extreme and a mark, and a
  // segment is one sample long: the four reductions per segment that this pass replaces then
  // cost their set-up at every sample (most of an initial-state estimate on such a record).
  void segment_sums(const Eigen::Ref<const Eigen::VectorXd>& y) const {
    const double* yp = y.data();
    const double* ep = eta().data();
    const double* tp = filtered_ref(true).data();
    const double* bp = filtered_ref(false).data();
    const double g = gain_;
    for (std::size_t k = 0; k + 1 < marks_.size(); ++k) {
      const Eigen::Index a = marks_[k], b = marks_[k + 1];
      double r1[2] = {0, 0}, r2[2] = {0, 0}, st[2] = {0, 0}, sb[2] = {0, 0};
      Eigen::Index t = a;
      for (; t + 1 < b; t += 2)
        for (int l = 0; l < 2; ++l) {
          const double yv = yp[t + l], r = yv - g * ep[t + l];
          const double ut = yv - g * tp[t + l], ub = yv - g * bp[t + l];
          r1[l] += r, r2[l] += r * r, st[l] += ut * ut, sb[l] += ub * ub;
        }
      if (t < b) {
        const double yv = yp[t], r = yv - g * ep[t];
        const double ut = yv - g * tp[t], ub = yv - g * bp[t];
        r1[0] += r, r2[0] += r * r, st[0] += ut * ut, sb[0] += ub * ub;
      }
      p1_[k + 1] = p1_[k] + (r1[0] + r1[1]);
      p2_[k + 1] = p2_[k] + (r2[0] + r2[1]);
      s_top_[k] = st[0] + st[1];
      s_bottom_[k] = sb[0] + sb[1];
    }
  }

  struct Piece {
    double lo, hi;
    Eigen::Index tau;
    bool top;
    std::size_t tau_mark = 0, end_mark = 0;  // positions of tau and of its lag end in marks_
  };
  Eigen::Index n_, lags_;
  double threshold_, big_theta_;
  Eigen::RowVectorXd taps_;
  Eigen::VectorXd xi_, eta_, ref_top_, ref_bottom_, f_top_, f_bottom_, run_max_, run_min_;
  // The filtered signals sum_j taps_j s(t - j) of xi and of the two reference trajectories, read
  // as gain_ times eta() and filtered_ref().  A filter of one tap (NLR's) only scales them: they
  // are not stored (eta_, f_top_ and f_bottom_ stay empty) and gain_ is that tap, the same numbers
  // as filtered() gives (it adds the one product to 0); with more taps they are stored and gain_
  // is 1.  An operator at the travel has the whole record for its prefix, and these three were
  // 24 bytes a sample of a diagnosis' peak.
  double gain_ = 1.0;
  const Eigen::VectorXd& eta() const { return lags_ > 0 ? eta_ : xi_; }
  const Eigen::VectorXd& filtered_ref(bool top) const {
    if (lags_ > 0) return top ? f_top_ : f_bottom_;
    return top ? ref_top_ : ref_bottom_;
  }
  std::vector<Piece> pieces_;
  std::vector<Eigen::Index> marks_;  // sorted, from 0 to n
  // minimise's sums at the marks, kept between calls (an estimate calls it thousands of times;
  // each OneOperator belongs to one estimate, on one thread).
  mutable std::vector<double> p1_, p2_, s_top_, s_bottom_;
};

// One column per operator, each as long as that operator's prefix, in one buffer.  The dense
// N x M matrices they replace held M times the longest prefix, and one operator at the travel (a
// linear spring) makes that the whole record: the contributions and sensitivities of the
// refinements were a fifth of a diagnosis' peak memory at 10^5 samples.
class PrefixColumns {
 public:
  explicit PrefixColumns(const std::vector<Eigen::Index>& lengths) : length_(lengths) {
    Eigen::Index at = 0;
    for (const Eigen::Index l : lengths) {
      offset_.push_back(at);
      at += l;
    }
    data_.resize(at);
  }
  Eigen::Map<Eigen::VectorXd> col(Eigen::Index i) {
    const std::size_t iu = static_cast<std::size_t>(i);
    return {data_.data() + offset_[iu], length_[iu]};
  }
  Eigen::Map<const Eigen::VectorXd> col(Eigen::Index i) const {
    const std::size_t iu = static_cast<std::size_t>(i);
    return {data_.data() + offset_[iu], length_[iu]};
  }
  /// The columns as an N x M matrix, zero beyond each prefix.
  Eigen::MatrixXd dense(Eigen::Index rows) const {
    Eigen::MatrixXd out = Eigen::MatrixXd::Zero(rows, static_cast<Eigen::Index>(length_.size()));
    for (Eigen::Index i = 0; i < out.cols(); ++i)
      out.col(i).head(length_[static_cast<std::size_t>(i)]) = col(i);
    return out;
  }

 private:
  std::vector<Eigen::Index> length_, offset_;
  Eigen::VectorXd data_;
};

}  // namespace

std::vector<double> estimate_initial_deflections(std::span<const double> x,
                                                 std::span<const double> target,
                                                 std::span<const double> thresholds,
                                                 const Eigen::MatrixXd& filter,
                                                 std::span<const double> guess,
                                                 const InitialStateOptions& options) {
  const std::size_t m = thresholds.size();
  FRICTION_CHECK(m >= 1 && static_cast<std::size_t>(filter.rows()) == m && filter.cols() >= 1,
                 "estimate_initial_deflections: filter must be M x (n+1) with M = ", m,
                 " thresholds");
  FRICTION_CHECK(x.size() == target.size() && !x.empty(),
                 "estimate_initial_deflections: displacement and force lengths differ");
  FRICTION_CHECK(guess.empty() || guess.size() == m,
                 "estimate_initial_deflections: guess must have one value per operator");
  for (double d : thresholds)
    FRICTION_CHECK(std::isfinite(d) && d > 0.0, "estimate_initial_deflections: threshold ", d,
                   " must be > 0");
  // Only a prefix of the record depends on d: once the displacement has covered a range of
  // 2 max(Delta) every operator has saturated whatever its initial deflection, and from then on
  // (plus n samples of filter lag) the force no longer depends on d.  The rest of the record adds
  // a constant to the cost and is left out.
  const std::size_t n_taps = static_cast<std::size_t>(filter.cols());
  {
    const std::size_t end =
        prefix_end(x, *std::max_element(thresholds.begin(), thresholds.end()), n_taps);
    x = x.first(end);
    target = target.first(end);
  }
  const Eigen::Map<const Eigen::VectorXd> y(target.data(),
                                            static_cast<Eigen::Index>(target.size()));

  // Operator i's filtered trajectory in pieces (OneOperator): no evaluation steps the recursion.
  // Each operator depends on its own d_i only over its own prefix [0, T_i), until the displacement
  // has covered 2 Delta_i (plus the filter's lags); after it its contribution is the same for every
  // d_i (the trajectories from +Delta_i and -Delta_i have met) and is added once to `fixed`.  So an
  // evaluation costs sum_i T_i instead of M times the longest prefix: on records where one
  // operator's threshold is near the travel (a linear spring) the others' prefixes are short.
  const Eigen::Index n_prefix = y.size();
  std::vector<OneOperator> single;
  std::vector<Eigen::Index> own(m);
  Eigen::VectorXd fixed = Eigen::VectorXd::Zero(n_prefix);
  std::vector<char> active(m);
  for (std::size_t i = 0; i < m; ++i) {
    const Eigen::RowVectorXd taps = filter.row(static_cast<Eigen::Index>(i));
    active[i] = !taps.isZero();
    own[i] = static_cast<Eigen::Index>(prefix_end(x, thresholds[i], n_taps));
    single.emplace_back(x.first(static_cast<std::size_t>(own[i])), thresholds[i], taps);
    if (active[i] && own[i] < n_prefix) {
      const Eigen::VectorXd after =
          filtered(single_trajectory(x, thresholds[i], thresholds[i]), taps);
      fixed.tail(n_prefix - own[i]) += after.tail(n_prefix - own[i]);
    }
  }
  Eigen::VectorXd force(y.size());
  const auto predict = [&](const std::vector<double>& d, Eigen::VectorXd& f) {
    f = fixed;
    for (std::size_t i = 0; i < m; ++i)
      if (active[i]) single[i].contribution(d[i], f.head(own[i]), true);
  };
  auto cost_of = [&](const std::vector<double>& d) {
    predict(d, force);
    return (y - force).squaredNorm();
  };

  // 1. Scan of plausible states.
  std::vector<std::vector<double>> candidates;
  candidates.emplace_back(m, 0.0);
  if (!guess.empty()) {
    std::vector<double> g(m);
    for (std::size_t i = 0; i < m; ++i) g[i] = std::clamp(guess[i], -thresholds[i], thresholds[i]);
    candidates.push_back(g);
  }
  const double dmin = *std::min_element(thresholds.begin(), thresholds.end());
  const double dmax = *std::max_element(thresholds.begin(), thresholds.end());
  const int grid = static_cast<int>(3 * m + 6);
  std::vector<double> travels{0.0};
  for (int k = 0; k < grid; ++k)
    travels.push_back(0.5 * dmin * std::pow(4.0 * dmax / (0.5 * dmin), k / double(grid - 1)));
  for (double s : {1.0, -1.0})
    for (double u : travels) {
      std::vector<double> d(m);
      for (std::size_t i = 0; i < m; ++i) d[i] = s * std::max(thresholds[i] - u, -thresholds[i]);
      candidates.push_back(d);
    }
  std::vector<std::pair<double, std::size_t>> ranked;
  for (std::size_t c = 0; c < candidates.size(); ++c)
    ranked.emplace_back(cost_of(candidates[c]), c);
  std::sort(ranked.begin(), ranked.end());

  // Buffers of the refinements, reused by every start.
  const Eigen::Index mi = static_cast<Eigen::Index>(m);
  PrefixColumns contribution(own), jacobian(own);
  Eigen::MatrixXd gram(mi, mi);
  Eigen::VectorXd jtr(mi);
  Eigen::VectorXd total, yi(y.size()), ci(y.size()), r;
  auto refine = [&](std::vector<double> best, int rounds = 4, int sweeps = 4,
                    int gn_iterations = 8) {
    double best_cost = cost_of(best);
    // 2. Coordinate descent with each operator's exact global 1-D minimum, then
    // 3. projected Gauss-Newton on all operators together (it moves along the valleys where only a
    //    weighted sum of deflections is seen, which coordinate steps cannot follow); alternated
    //    while either improves the cost.
    for (int round = 0; round < rounds; ++round) {
      const double round_start = best_cost;
      {
        // Column i holds operator i's contribution over its own prefix (the rest of the column is
        // never read); `total` adds `fixed`.
        total = fixed;
        for (Eigen::Index i = 0; i < mi; ++i) {
          const std::size_t iu = static_cast<std::size_t>(i);
          single[iu].contribution(best[iu], contribution.col(i), false);
          total.head(own[iu]) += contribution.col(i);
        }
        for (int sweep = 0; sweep < sweeps; ++sweep) {
          bool moved = false;
          for (Eigen::Index i = 0; i < mi; ++i) {
            const std::size_t iu = static_cast<std::size_t>(i);
            if (!active[iu]) continue;
            // Beyond its prefix operator i's contribution does not depend on d_i: the step is
            // chosen, and compared, over the prefix.
            const Eigen::Index ti = own[iu];
            yi.head(ti) = y.head(ti) - (total.head(ti) - contribution.col(i));
            const double d = single[iu].minimise(yi.head(ti));
            if (d == best[iu]) continue;
            single[iu].contribution(d, ci.head(ti), false);
            const double before = (yi.head(ti) - contribution.col(i)).squaredNorm();
            const double after = (yi.head(ti) - ci.head(ti)).squaredNorm();
            if (after < before - 1e-9 * best_cost) {
              best[iu] = d;
              total.head(ti) += ci.head(ti) - contribution.col(i);
              contribution.col(i) = ci.head(ti);
              moved = true;
            }
          }
          if (!moved) break;
        }
        best_cost = cost_of(best);
      }

      for (int it = 0; it < gn_iterations; ++it) {
        predict(best, force);
        // Column i beyond operator i's prefix is zero (PrefixColumns keeps the prefix only).
        for (Eigen::Index i = 0; i < mi; ++i) {
          const std::size_t iu = static_cast<std::size_t>(i);
          single[iu].sensitivity(best[iu], jacobian.col(i));
        }
        r = y - force;
        Eigen::VectorXd lo(mi), hi(mi);
        for (Eigen::Index i = 0; i < mi; ++i) {
          lo(i) = -thresholds[static_cast<std::size_t>(i)] - best[static_cast<std::size_t>(i)];
          hi(i) = thresholds[static_cast<std::size_t>(i)] - best[static_cast<std::size_t>(i)];
        }
        // Column i is zero beyond operator i's prefix, so the normal equations need only
        // sum_ij min(T_i, T_j) products: on records where one operator's threshold is the
        // travel (a linear spring, prefix = the record) the dense N x M^2 product cost several
        // times the rest of the estimate.  The columns are (for Maxwell Slip) Theta_i until
        // operator i first saturates: two operators that saturate at the same sample have equal
        // columns and singular normal equations, which the QR below resolves at N M^2 cost.  A
        // damping of 1e-8 of the diagonal (a Levenberg-Marquardt step; the line search below
        // judges it on the cost) keeps them solvable, and a zero column (saturated from the
        // first sample) gets no step.
        for (Eigen::Index i = 0; i < mi; ++i) {
          const Eigen::Index ti = own[static_cast<std::size_t>(i)];
          jtr(i) = jacobian.col(i).dot(r.head(ti));
          for (Eigen::Index j = 0; j <= i; ++j) {
            const Eigen::Index tij = std::min(ti, own[static_cast<std::size_t>(j)]);
            gram(i, j) = jacobian.col(i).head(tij).dot(jacobian.col(j).head(tij));
          }
          gram(i, i) = gram(i, i) > 0.0 ? gram(i, i) * (1.0 + 1e-8) : 1.0;
        }
        Eigen::VectorXd step;
        double step_rss = 0.0;
        if (!detail::box_least_squares_gram(gram, jtr, r.squaredNorm(), lo, hi, step, step_rss)) {
          step = detail::box_least_squares(jacobian.dense(y.size()), r, lo, hi);
        }
        if (step.norm() <= 1e-14 * dmax) break;
        bool accepted = false;
        for (double alpha = 1.0; alpha > 1e-4; alpha *= 0.25) {
          std::vector<double> trial(m);
          for (std::size_t i = 0; i < m; ++i)
            trial[i] = std::clamp(best[i] + alpha * step(static_cast<Eigen::Index>(i)),
                                  -thresholds[i], thresholds[i]);
          const double c = cost_of(trial);
          if (c < best_cost) {
            accepted = best_cost - c > 1e-14 * best_cost;
            best_cost = c;
            best = trial;
            break;
          }
        }
        if (!accepted) break;
      }
      if (!(best_cost < round_start * (1.0 - 1e-8))) break;
    }
    return std::pair<double, std::vector<double>>(best_cost, best);
  };

  // Refine the best few starts (and the caller's guess): the cost is only piecewise quadratic,
  // and operators that are seen only through a weighted sum early in the record make valleys with
  // several local minima.
  std::pair<double, std::vector<double>> result{std::numeric_limits<double>::infinity(), {}};
  for (std::size_t r = 0; r < ranked.size() && r < options.refined_candidates; ++r) {
    auto out = refine(candidates[ranked[r].second]);
    if (out.first < result.first) result = std::move(out);
  }
  if (!guess.empty() && options.refined_candidates > 0) {
    auto out = refine(candidates[1]);
    if (out.first < result.first) result = std::move(out);
  }
  std::mt19937 gen(options.seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (std::size_t r = 0; r < options.random_starts; ++r) {
    std::vector<double> start(m);
    for (std::size_t i = 0; i < m; ++i) start[i] = unit(gen) * thresholds[i];
    auto out = refine(start);
    if (out.first < result.first) result = std::move(out);
  }
  if (result.second.empty()) return candidates[ranked.front().second];
  // Basin hopping: perturb the winner on several scales and keep what improves.  Minima of this
  // piecewise-quadratic cost can be a few percent of a threshold apart.
  for (std::size_t h = 0; h < options.perturbations; ++h) {
    const double scale = std::array<double, 3>{0.03, 0.1, 0.3}[h % 3];
    std::vector<double> start = result.second;
    for (std::size_t i = 0; i < m; ++i)
      start[i] =
          std::clamp(start[i] + scale * thresholds[i] * unit(gen), -thresholds[i], thresholds[i]);
    auto out = refine(start);
    if (out.first < result.first * (1.0 - 1e-12)) result = std::move(out);
  }
  // Valley moves.  Early in the record every operator still moves freely and the force sees only
  // sum_i Theta_i d_i (Theta_i the sum of operator i's taps), so two operators can trade
  // deflection along Theta_i dd_i + Theta_j dd_j = 0 at almost no cost until one of them first
  // saturates.  Along that line the cost has minima that neither the coordinate steps (one
  // operator at a time) nor Gauss-Newton (which stops at a kink) nor small perturbations leave:
  // on random records the estimate ended above the true state's cost, by up to 634x, with two
  // operators traded that way (test_initial_state).  For each pair the line through the winner is
  // scanned across the box and its best point refined.
  if (options.valley_points > 1 && m > 1) {
    const Eigen::VectorXd theta = filter.rowwise().sum();
    const double theta_scale = theta.cwiseAbs().maxCoeff();
    Eigen::VectorXd others, line_r, line_i(y.size()), line_j(y.size());
    for (int pass = 0; pass < 3; ++pass) {
      bool improved = false;
      for (std::size_t i = 0; i < m; ++i)
        for (std::size_t j = i + 1; j < m; ++j) {
          const double ti = theta(static_cast<Eigen::Index>(i));
          const double tj = theta(static_cast<Eigen::Index>(j));
          if (!(std::abs(ti) > 1e-9 * theta_scale && std::abs(tj) > 1e-9 * theta_scale)) continue;
          // d_i = b_i + s / Theta_i, d_j = b_j - s / Theta_j, both inside the box.
          const std::vector<double>& b = result.second;
          const auto range = [](double t, double lo, double hi) {
            return t > 0 ? std::pair(t * lo, t * hi) : std::pair(t * hi, t * lo);
          };
          const auto [ai, bi] = range(ti, -thresholds[i] - b[i], thresholds[i] - b[i]);
          const auto [aj, bj] = range(-tj, -thresholds[j] - b[j], thresholds[j] - b[j]);
          const double lo = std::max(ai, aj), hi = std::min(bi, bj);
          if (!(hi > lo)) continue;
          // Only d_i and d_j move along the line, and each changes the force over its own
          // prefix only: the points are compared over the longer of the two prefixes, with the
          // residual of the other operators kept (not M prefixes and the whole record per point;
          // an operator at the travel made every point cost the record).
          const Eigen::Index pi = own[i], pj = own[j], pij = std::max(pi, pj);
          predict(b, force);
          others = y.head(pij) - force.head(pij);
          single[i].contribution(b[i], line_i.head(pi), false);
          single[j].contribution(b[j], line_j.head(pj), false);
          others.head(pi) += line_i.head(pi);
          others.head(pj) += line_j.head(pj);
          double best_cost = std::numeric_limits<double>::infinity();
          std::vector<double> best_point, trial = b;
          for (std::size_t g = 0; g < options.valley_points; ++g) {
            const double s = lo + (hi - lo) * static_cast<double>(g) /
                                      static_cast<double>(options.valley_points - 1);
            trial[i] = std::clamp(b[i] + s / ti, -thresholds[i], thresholds[i]);
            trial[j] = std::clamp(b[j] - s / tj, -thresholds[j], thresholds[j]);
            single[i].contribution(trial[i], line_i.head(pi), false);
            single[j].contribution(trial[j], line_j.head(pj), false);
            line_r = others;
            line_r.head(pi) -= line_i.head(pi);
            line_r.head(pj) -= line_j.head(pj);
            const double c = line_r.squaredNorm();  // + the same remainder for every point
            if (c < best_cost) best_cost = c, best_point = trial;
          }
          if (best_point == b) continue;
          auto out = refine(best_point);
          if (out.first < result.first * (1.0 - 1e-12)) {
            result = std::move(out);
            improved = true;
          }
        }
      if (!improved) break;
    }
  }
  // Converge the winner fully.
  return refine(result.second, 20, 10, 40).second;
}

std::vector<double> estimate_initial_deflections(const MaxwellSlipParameters<double>& parameters,
                                                 std::span<const double> x,
                                                 std::span<const double> force,
                                                 std::span<const double> guess,
                                                 const InitialStateOptions& options) {
  parameters.validate(true);
  Eigen::MatrixXd filter(static_cast<Eigen::Index>(parameters.size()), 1);
  for (std::size_t i = 0; i < parameters.size(); ++i)
    filter(static_cast<Eigen::Index>(i), 0) = parameters.stiffness[i];
  return estimate_initial_deflections(x, force, parameters.threshold, filter, guess, options);
}

FreeRun free_run_maxwell_slip(const MaxwellSlipParameters<double>& parameters,
                              std::span<const double> time, std::span<const double> x,
                              std::span<const double> force) {
  FRICTION_CHECK(time.size() == x.size() && x.size() == force.size() && !x.empty(),
                 "free_run_maxwell_slip: time, displacement and force lengths differ");
  FreeRun run;
  run.initial_deflections = estimate_initial_deflections(parameters, x, force);
  MaxwellSlip<double> model(parameters, true);
  model.reset(std::span<const double>(run.initial_deflections));
  run.simulated.resize(x.size());
  for (std::size_t k = 0; k < x.size(); ++k) {
    Motion<double> m{0.0, 0.0, 0.0};
    if (k > 0) {
      m.dx = x[k] - x[k - 1];
      m.dt = time[k] - time[k - 1];
      m.velocity = m.dt > 0.0 ? m.dx / m.dt : 0.0;
      m.turn = turn_increment(x, k);
    }
    run.simulated[k] = model.step(m);
  }
  run.errors = compute_errors(force, run.simulated);
  return run;
}

}  // namespace friction
