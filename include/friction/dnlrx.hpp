// The DNLRX model: Maxwell Slip operators followed by two finite impulse response filters
// (methods.md section 4, reconstructed from Rizos & Fassois 2005).
//
// The M elasto-slide operators of the basic Maxwell Slip model (paper eq. 4, maxwell_slip.hpp) turn
// the displacement into deflections delta_i(t) in [-Delta_i, Delta_i].  Instead of weighting each
// by one stiffness (paper eq. 5), DNLRX passes them through a vector FIR filter, the "spring"
// filter, and adds an FIR filter on the displacement increments, the "input" filter ("direct
// application of the excitation"):
//
//     F(t) = sum_{i=1..M} sum_{j=0..n} theta_{i,j} delta_i(t-j)  +  sum_{j=0..nx} g_j dx(t-j)
//
// with dx(t) = x(t) - x(t-1).  With n = 0, nx = 0, theta_{i,0} = k_i and g_0 = 0 it is the basic
// Maxwell Slip model.  What the filters add:
//   * the spring filter makes the force depend on the recent history of the deflections: in
//     sliding the deflections sit at +-Delta_i, so it only rescales the sliding level
//     (sum_{i,j} theta_{i,j} Delta_i), but in presliding and just after a reversal it shapes the
//     transient (a lagging or anticipating force);
//   * the input filter acts on increments, not on x, so the model stays translation invariant; at a
//     constant sampling period dx = v Ts, so it contributes (sum_j g_j) Ts v at constant speed: a
//     viscous-like, speed-dependent sliding force, and with unequal taps a lagging one.  Being
//     linear in dx it cannot make friction fall with speed (no Stribeck effect).
//
// Identification.  For fixed thresholds the force is linear in theta and g, so the model is
// estimated by linear least squares on the regressor row
//
//     phi(t) = [delta_1(t) .. delta_1(t-n), ..., delta_M(t) .. delta_M(t-n), dx(t) .. dx(t-nx)]
//
// (theta in row-major order theta_{i,j} at column i (n+1) + j, then g_0..g_nx), produced per sample
// by `DnlrxRegressor` or for a whole record by `dnlrx_regressor_matrix`, and
// F(t) = phi(t) . [theta; g].  The thresholds are then found by nonlinear optimisation of the
// concentrated cost, as in NLR.  When an operator never saturates its deflection is x - x(0) up to
// a constant, which duplicates the input filter: the regressor is then rank deficient (methods.md
// section 8) -- a property of the record, not a bug.
//
// Implementation.  The operator recursion is the one of MaxwellSlip (held with unit stiffnesses, so
// its deflections are the delta_i); the last n + 1 deflection vectors and nx + 1 increments sit in
// ring buffers allocated at construction, so `step` does not allocate.  `Motion::level` scales the
// thresholds exactly as in Maxwell Slip (level effects act on slip forces, methods.md section 7).
// The history before the first sample is the initial state held at rest (deflections constant,
// increments 0), which is what `reset` sets.
#pragma once

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <span>
#include <utility>
#include <vector>

#include "friction/error.hpp"
#include "friction/maxwell_slip.hpp"
#include "friction/motion.hpp"
#include "friction/scalar.hpp"

namespace friction {

/// Parameters of the DNLRX model, SI units.  Orders: M = threshold.size(), n = spring_order,
/// nx = input_filter.size() - 1 (an empty input filter means no input filter at all).
template <typename T>
struct DnlrxParameters {
  std::vector<T> threshold;      ///< Delta_i [m], > 0, i = 1..M
  std::size_t spring_order = 0;  ///< n >= 0: the spring filter has n + 1 taps per operator
  std::vector<T> spring_filter;  ///< theta_{i,j} [N/m], row-major M x (n + 1): [i * (n + 1) + j]
  std::vector<T> input_filter;   ///< g_j [N/m], j = 0..nx

  std::size_t size() const noexcept { return threshold.size(); }  ///< M
  std::size_t spring_taps() const noexcept { return spring_order + 1; }
  std::size_t input_taps() const noexcept { return input_filter.size(); }  ///< nx + 1

  /// theta_{i,j}.
  const T& theta(std::size_t i, std::size_t j) const {
    return spring_filter[i * spring_taps() + j];
  }
  T& theta(std::size_t i, std::size_t j) { return spring_filter[i * spring_taps() + j]; }

  /// The basic Maxwell Slip model as a DNLRX model (n = 0, no input filter).
  static DnlrxParameters from_maxwell_slip(const MaxwellSlipParameters<T>& ms) {
    return {ms.threshold, 0, ms.stiffness, {}};
  }

  /// Throws InvalidParameter unless M >= 1, thresholds are finite and > 0, the filter sizes match
  /// the orders and every filter coefficient is finite.  Filter coefficients may have any sign: the
  /// filters are estimated by unconstrained least squares.
  void validate() const {
    FRICTION_CHECK(!threshold.empty(), "DNLRX needs at least one operator");
    FRICTION_CHECK(spring_filter.size() == size() * spring_taps(), "DNLRX: spring filter has ",
                   spring_filter.size(), " coefficients, expected M (n + 1) = ", size(), " * ",
                   spring_taps());
    for (std::size_t i = 0; i < size(); ++i) {
      const double d = value_of(threshold[i]);
      FRICTION_CHECK(std::isfinite(d) && d > 0.0, "DNLRX: threshold[", i, "] = ", d,
                     " m must be finite and > 0");
    }
    for (std::size_t c = 0; c < spring_filter.size(); ++c)
      FRICTION_CHECK(std::isfinite(value_of(spring_filter[c])), "DNLRX: spring filter coefficient ",
                     c, " is not finite");
    for (std::size_t j = 0; j < input_filter.size(); ++j)
      FRICTION_CHECK(std::isfinite(value_of(input_filter[j])), "DNLRX: input filter g[", j,
                     "] is not finite");
  }

  /// Sliding force without the input filter, sum_{i,j} theta_{i,j} Delta_i [N] (what the force
  /// settles at after a long slide in +x at vanishing speed); the reference of level extensions.
  T sliding_force() const {
    T f(0);
    for (std::size_t i = 0; i < size(); ++i)
      for (std::size_t j = 0; j < spring_taps(); ++j) f += theta(i, j) * threshold[i];
    return f;
  }
};

/// The DNLRX state (operators and filter histories) without the filter coefficients: it produces
/// the regressor row phi(t) per sample, for identification (see the header comment).
///
/// Each history is a ring stored twice over (a buffer of twice its length, every entry written at
/// p and p + length, with p moving backwards), so the newest `length` entries are always contiguous
/// and newest first from p: the filter is then one contiguous dot product, without index wrapping.
template <typename T>
class DnlrxRegressor {
 public:
  /// `input_taps` = nx + 1 (0: no input filter).
  DnlrxRegressor(std::vector<T> threshold, std::size_t spring_order, std::size_t input_taps)
      : operators_(unit_operators(std::move(threshold))),
        rows_(spring_order + 1),
        taps_(input_taps),
        deflection_history_(2 * rows_ * operators_.size(), T(0)),
        dx_history_(2 * taps_, T(0)) {}

  std::size_t size() const noexcept { return operators_.size(); }           ///< M
  std::size_t spring_taps() const noexcept { return rows_; }                ///< n + 1
  std::size_t input_taps() const noexcept { return taps_; }                 ///< nx + 1
  std::size_t row_size() const noexcept { return size() * rows_ + taps_; }  ///< M (n+1) + nx + 1

  /// Virgin state: relaxed operators, at rest since ever.
  void reset() {
    operators_.reset();
    fill_history();
  }

  /// Operators at the given deflections (clamped to the thresholds), at rest since ever.
  void reset(std::span<const T> deflections, const T& asymmetry = T(0)) {
    operators_.reset(deflections, asymmetry);
    fill_history();
  }

  /// Advance the operators by one sample (paper eq. 4) and push the new deflections and increment.
  void advance(const Motion<T>& m) noexcept {
    operators_.step(m);
    const std::size_t n = size();
    head_ = head_ == 0 ? rows_ - 1 : head_ - 1;
    const T* delta = operators_.deflections().data();
    T* first = deflection_history_.data() + head_ * n;
    T* second = first + rows_ * n;
    for (std::size_t i = 0; i < n; ++i) first[i] = second[i] = delta[i];
    if (taps_ > 0) {
      dx_head_ = dx_head_ == 0 ? taps_ - 1 : dx_head_ - 1;
      dx_history_[dx_head_] = dx_history_[dx_head_ + taps_] = m.dx;
    }
  }

  /// Current deflections delta_i(t) [m].
  std::span<const T> deflections() const noexcept { return operators_.deflections(); }

  /// delta_i(t - j), j = 0..n.
  const T& deflection(std::size_t i, std::size_t j) const noexcept {
    return deflection_history_[(head_ + j) * size() + i];
  }

  /// dx(t - j), j = 0..nx.
  const T& increment(std::size_t j) const noexcept { return dx_history_[dx_head_ + j]; }

  /// Writes phi(t) (length row_size(), layout of the header comment) to `row`.
  void row(std::span<T> row) const noexcept {
    FRICTION_ASSERT(row.size() == row_size());
    for (std::size_t i = 0; i < size(); ++i)
      for (std::size_t j = 0; j < rows_; ++j) row[i * rows_ + j] = deflection(i, j);
    for (std::size_t j = 0; j < taps_; ++j) row[size() * rows_ + j] = increment(j);
  }

  /// phi(t) . [theta; g] with the spring filter given lag-major (theta_by_lag[j * M + i]).  Four
  /// partial sums break the chain of dependent additions so that the products pipeline.
  T filter(const T* theta_by_lag, const T* g) const noexcept {
    const std::size_t length = rows_ * size();
    const T* delta = deflection_history_.data() + head_ * size();  // lag-major, newest first
    T acc0(0), acc1(0), acc2(0), acc3(0);
    std::size_t c = 0;
    for (; c + 4 <= length; c += 4) {
      acc0 += theta_by_lag[c] * delta[c];
      acc1 += theta_by_lag[c + 1] * delta[c + 1];
      acc2 += theta_by_lag[c + 2] * delta[c + 2];
      acc3 += theta_by_lag[c + 3] * delta[c + 3];
    }
    for (; c < length; ++c) acc0 += theta_by_lag[c] * delta[c];
    const T* dx = dx_history_.data() + dx_head_;
    for (std::size_t j = 0; j < taps_; ++j) acc1 += g[j] * dx[j];
    return (acc0 + acc1) + (acc2 + acc3);
  }

 private:
  static MaxwellSlip<T> unit_operators(std::vector<T> threshold) {
    MaxwellSlipParameters<T> p;
    p.stiffness.assign(threshold.size(), T(1));
    p.threshold = std::move(threshold);
    return MaxwellSlip<T>(std::move(p));
  }

  void fill_history() {
    const std::span<const T> delta = operators_.deflections();
    for (std::size_t r = 0; r < 2 * rows_; ++r)
      std::copy(delta.begin(), delta.end(), deflection_history_.begin() + r * size());
    std::fill(dx_history_.begin(), dx_history_.end(), T(0));
    head_ = 0;
    dx_head_ = 0;
  }

  MaxwellSlip<T> operators_;           // unit stiffnesses: its deflections are the regressors
  std::size_t rows_;                   // n + 1
  std::size_t taps_;                   // nx + 1
  std::vector<T> deflection_history_;  // 2 rows_ x M, newest row at head_ (and head_ + rows_)
  std::vector<T> dx_history_;          // 2 taps_, newest at dx_head_ (and dx_head_ + taps_)
  std::size_t head_ = 0;
  std::size_t dx_head_ = 0;
};

/// DNLRX model: Maxwell Slip operators, spring filter theta and input filter g.
template <typename T>
class Dnlrx {
 public:
  using Scalar = T;
  using Parameters = DnlrxParameters<T>;

  explicit Dnlrx(Parameters parameters)
      : p_((parameters.validate(), std::move(parameters))),
        state_(p_.threshold, p_.spring_order, p_.input_taps()),
        theta_by_lag_(p_.spring_filter.size()) {
    for (std::size_t i = 0; i < p_.size(); ++i)
      for (std::size_t j = 0; j < p_.spring_taps(); ++j)
        theta_by_lag_[j * p_.size() + i] = p_.theta(i, j);
  }

  const Parameters& parameters() const noexcept { return p_; }
  std::size_t size() const noexcept { return p_.size(); }                ///< M
  std::size_t spring_order() const noexcept { return p_.spring_order; }  ///< n
  std::size_t input_taps() const noexcept { return p_.input_taps(); }    ///< nx + 1

  /// Virgin state: relaxed operators, at rest since ever.
  void reset() { state_.reset(); }

  /// Operators at the given deflections (clamped to the thresholds), at rest since ever.
  void reset(std::span<const T> deflections, const T& asymmetry = T(0)) {
    FRICTION_CHECK(deflections.size() == size(), "DNLRX: ", deflections.size(),
                   " initial deflections for ", size(), " operators");
    state_.reset(deflections, asymmetry);
  }

  /// Advance by one sample and return the friction force.
  T step(const Motion<T>& m) noexcept {
    state_.advance(m);
    return state_.filter(theta_by_lag_.data(), p_.input_filter.data());
  }

  /// Force of the current state.
  T force() const noexcept { return state_.filter(theta_by_lag_.data(), p_.input_filter.data()); }

  /// The state, whose `row()` is the regressor phi(t) of the last step.
  const DnlrxRegressor<T>& state() const noexcept { return state_; }
  std::span<const T> deflections() const noexcept { return state_.deflections(); }

 private:
  Parameters p_;
  DnlrxRegressor<T> state_;
  std::vector<T> theta_by_lag_;  // theta transposed to [j * M + i] for contiguous inner loops
};

/// The regressor matrix of a record: row k is phi(t_k) after stepping `state` (from whatever state
/// it is in: reset it first) over sample k, with the motion convention of simulate.hpp.  The
/// simulated DNLRX force is `matrix * [theta; g]` with theta row-major as in DnlrxParameters.
template <typename T>
Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic> dnlrx_regressor_matrix(
    DnlrxRegressor<T>& state, std::span<const double> time, std::span<const T> x,
    std::span<const T> level = {}) {
  FRICTION_CHECK(time.size() == x.size(), "DNLRX regressors: time and displacement lengths differ");
  FRICTION_CHECK(level.empty() || level.size() == x.size(),
                 "DNLRX regressors: level must be empty or as long as the record");
  Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic> phi(x.size(), state.row_size());
  std::vector<T> row(state.row_size());
  for (std::size_t k = 0; k < x.size(); ++k) {
    state.advance(motion_at(time, x, k, level.empty() ? T(1) : level[k]));
    state.row(row);
    for (std::size_t c = 0; c < row.size(); ++c)
      phi(static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(c)) = row[c];
  }
  return phi;
}

}  // namespace friction
