// The basic Maxwell Slip model (Rizos & Fassois 2005, eqs. 4-5).
//
// M elasto-slide operators in parallel share the displacement x(t).  Operator i is a spring of
// stiffness k_i in series with a slider that moves once the spring deflection reaches the
// threshold Delta_i:
//
//     delta_i(t+1) = sgn(dx + delta_i(t)) * min(|dx + delta_i(t)|, Delta_i)        (eq. 4)
//                  = clamp(delta_i(t) + dx, -Delta_i, +Delta_i)
//     F(t)         = sum_i k_i delta_i(t)                                            (eq. 5)
//
// with dx = x(t+1) - x(t).  While at least one operator sticks (|delta_i| < Delta_i) the system is
// in presliding; when all slip it slides with the constant force sum_i k_i Delta_i.  Because each
// operator only remembers its own deflection, the model has nonlocal memory: a larger reversal
// wipes out the inner loops, and a closed minor loop returns to the force it started from.
//
// The `level` of a `Motion` scales every threshold (Delta_i -> level * Delta_i).  That is how level
// effects (Stribeck, asymmetry, drift, ...) act on slip forces rather than being added to the
// total force, which would make the force jump at every reversal (methods.md section 7).
//
// `step` does no allocation and no division: it is the one evaluated in identification (with Jets),
// in `simulate`, in the benchmark and in the installed package.
#pragma once

#include <cstddef>
#include <span>
#include <utility>
#include <vector>

#include "friction/error.hpp"
#include "friction/motion.hpp"
#include "friction/scalar.hpp"

namespace friction {

/// Parameters of the basic Maxwell Slip model, SI units.
template <typename T>
struct MaxwellSlipParameters {
  std::vector<T> stiffness;  ///< k_i [N/m], > 0
  std::vector<T> threshold;  ///< Delta_i [m], > 0 (maximum spring deflection of operator i)

  std::size_t size() const noexcept { return threshold.size(); }

  /// Throws InvalidParameter unless sizes match, M >= 1, thresholds > 0 and finite stiffnesses.
  /// Stiffnesses must be positive for a physical model; `allow_negative_stiffness` exists for
  /// unconstrained least-squares intermediates only.
  void validate(bool allow_negative_stiffness = false) const {
    FRICTION_CHECK(!threshold.empty(), "Maxwell Slip needs at least one operator");
    FRICTION_CHECK(stiffness.size() == threshold.size(), "Maxwell Slip: ", stiffness.size(),
                   " stiffnesses for ", threshold.size(), " thresholds");
    for (std::size_t i = 0; i < size(); ++i) {
      const double d = value_of(threshold[i]);
      const double k = value_of(stiffness[i]);
      FRICTION_CHECK(std::isfinite(d) && d > 0.0, "Maxwell Slip: threshold[", i, "] = ", d,
                     " m must be finite and > 0");
      FRICTION_CHECK(std::isfinite(k) && (allow_negative_stiffness || k > 0.0),
                     "Maxwell Slip: stiffness[", i, "] = ", k, " N/m must be finite and > 0");
    }
  }

  /// Sliding (Coulomb) force sum_i k_i Delta_i [N].
  T sliding_force() const {
    T f(0);
    for (std::size_t i = 0; i < size(); ++i) f += stiffness[i] * threshold[i];
    return f;
  }
};

/// Basic Maxwell Slip model with state delta_i, i = 1..M.
template <typename T>
class MaxwellSlip {
 public:
  using Scalar = T;
  using Parameters = MaxwellSlipParameters<T>;

  explicit MaxwellSlip(Parameters parameters, bool allow_negative_stiffness = false)
      : p_(std::move(parameters)) {
    p_.validate(allow_negative_stiffness);
    deflection_.assign(p_.size(), T(0));
  }

  const Parameters& parameters() const noexcept { return p_; }
  std::size_t size() const noexcept { return p_.size(); }

  /// Virgin state: all springs relaxed.
  void reset() {
    for (auto& d : deflection_) d = T(0);
  }

  /// Start from given deflections, clamped to the thresholds: to [-(1 - a) Delta_i,
  /// (1 + a) Delta_i] with the asymmetry a of Motion::asymmetry (a model with an asymmetry piece
  /// passes its a: clamped to the symmetric box, an equivalent state of it would be cut).
  void reset(std::span<const T> deflections, const T& asymmetry = T(0)) {
    FRICTION_CHECK(deflections.size() == size(), "Maxwell Slip: ", deflections.size(),
                   " initial deflections for ", size(), " operators");
    for (std::size_t i = 0; i < size(); ++i)
      deflection_[i] = clamp(deflections[i], T(-(T(1) - asymmetry) * p_.threshold[i]),
                             T((T(1) + asymmetry) * p_.threshold[i]));
  }

  /// Multiplies every deflection by `level`: a state given at level 1 carried to the slip limits
  /// level * Delta_i (Extended does it at its first step; extensions.hpp, Initial state).
  void scale_state(const T& level) noexcept {
    for (auto& d : deflection_) d *= level;
  }

  /// Current deflections delta_i [m].
  std::span<const T> deflections() const noexcept { return deflection_; }

  /// Advance by one sample (eq. 4) and return the friction force (eq. 5).
  T step(const Motion<T>& m) noexcept {
    const T* k = p_.stiffness.data();
    const T* limit = p_.threshold.data();
    T* delta = deflection_.data();
    const std::size_t n = deflection_.size();
    T force(0);
    // The slip limits -down Delta_i and up Delta_i (scalar.hpp: clamp_to_limits).
    const T up = m.level * (T(1) + m.asymmetry), minus_down = -(m.level * (T(1) - m.asymmetry));
    if (value_of(m.turn) != 0.0) {
      // Through the extremum inside the interval, at the level there (motion.hpp, Turns between
      // samples).
      const T back = m.dx - m.turn;
      const T at_turn = value_of(m.turn_level) > 0.0 ? m.turn_level : m.level;
      const T up_turn = at_turn * (T(1) + m.asymmetry);
      const T minus_down_turn = -(at_turn * (T(1) - m.asymmetry));
      for (std::size_t i = 0; i < n; ++i) {
        const T turned =
            clamp_to_limits(T(delta[i] + m.turn), minus_down_turn, up_turn, limit[i]);
        delta[i] = clamp_to_limits(T(turned + back), minus_down, up, limit[i]);
        force += k[i] * delta[i];
      }
      return force;
    }
    for (std::size_t i = 0; i < n; ++i) {
      delta[i] = clamp_to_limits(T(delta[i] + m.dx), minus_down, up, limit[i]);
      force += k[i] * delta[i];
    }
    return force;
  }

  /// Force of the current state, eq. 5.
  T force() const noexcept {
    T f(0);
    for (std::size_t i = 0; i < size(); ++i) f += p_.stiffness[i] * deflection_[i];
    return f;
  }

  /// True when every operator sits at one of its slip limits at the given level and asymmetry
  /// (Motion::asymmetry): the sliding regime.
  bool sliding(double level = 1.0, double asymmetry = 0.0) const noexcept {
    for (std::size_t i = 0; i < size(); ++i) {
      const double d = value_of(deflection_[i]), limit = level * value_of(p_.threshold[i]);
      const double bound = d >= 0 ? limit * (1 + asymmetry) : limit * (1 - asymmetry);
      if (std::abs(d) < bound * (1.0 - 1e-12)) return false;
    }
    return true;
  }

 private:
  Parameters p_;
  std::vector<T> deflection_;
};

}  // namespace friction
