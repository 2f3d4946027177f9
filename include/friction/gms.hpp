// The Generalized Maxwell Slip (GMS) model (Al-Bender, Lampaert & Swevers 2005; methods.md
// section 5).
//
// N elements in parallel share the displacement x.  Element i has a stiffness k_i and carries the
// share alpha_i (sum_i alpha_i = 1) of the Stribeck curve g(v) of stribeck.hpp; its force F_i obeys
//
//     stick:  dF_i/dt = k_i v                                 while |F_i| < alpha_i g(v)
//     slip:   dF_i/dt = C (sgn(v) alpha_i - F_i / g(v))       once F_i reaches sgn(v) alpha_i g(v),
//                                                             until the motion reverses
//     F = sum_i F_i + sigma2 v
//
// A slipping element follows the curve with a first-order lag: C [N/s] is the attraction constant,
// the time constant being g(v)/C.  That lag is the frictional lag (friction lags velocity changes
// while sliding: loops in F against v); C -> infinity removes it.  Sticking elements give
// presliding hysteresis with nonlocal memory exactly as the Maxwell Slip operators do: with C ->
// infinity and Fs = Fc the model *is* Maxwell Slip with thresholds Delta_i = alpha_i Fc / k_i (each
// sticking element is a spring k_i deflected by F_i / k_i, each slipping one is held at +-alpha_i
// Fc).
//
// Level effects (methods.md section 7) scale the slip forces: alpha_i g(v) -> level alpha_i g(v),
// i.e. g is replaced by G = level g(v) everywhere, including the slip equation (so the slip
// equation relaxes F_i towards sgn(v) alpha_i G with the time constant G / C).
//
// Discretisation (exact under the record convention of motion.hpp).  Over a sample interval of
// length dt the velocity v = dx/dt is constant, hence so are g(v), G and the slip target
// F_inf,i = s alpha_i G with s = sgn(dx).  Then for element i:
//   * slipping in the direction s and still moving in s: the slip equation is linear in F_i with
//     constant coefficients, and its exact solution over dt is
//         F_i+ = F_inf,i + (F_i - F_inf,i) exp(-C dt / G);
//   * sticking (or slipping but the motion reversed or stopped, s differing from the slip
//     direction, which makes it stick): F_i grows linearly, F_i(tau) = F_i + k_i v tau.  If it
//     stays short of the limit over the interval, s (F_i + k_i dx) < alpha_i G, the element sticks
//     and F_i+ = F_i + k_i dx.  Otherwise it reaches the limit at some tau* in the interval and
//     slips for the rest of it; since it enters the slip phase exactly at F_inf,i, which is the
//     fixed point of the slip equation for this interval, it stays there: F_i+ = F_inf,i, slipping
//     in s.  So the stick->slip transition inside a sample is exact without computing tau*.
// A sample with dx = 0 is rest: every element sticks and keeps its force (the slip equation with
// sgn(0) = 0 would relax the force to zero at rest, which is not what a stopped contact does).  The
// direction is taken from dx (the increment the stick phase integrates) and g from the velocity;
// both agree for a record.  When G changes from one sample to the next (speed or level changes)
// the slipping elements move towards the new curve at the rate C: that is the lag.
//
// Sign convention: F resists the motion as the drive sees it (F v >= 0 in sliding), like the rest
// of the library.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "friction/error.hpp"
#include "friction/maxwell_slip.hpp"
#include "friction/motion.hpp"
#include "friction/scalar.hpp"
#include "friction/stribeck.hpp"

namespace friction {

/// Parameters of the GMS model, SI units.
template <typename T>
struct GmsParameters {
  std::vector<T> stiffness;  ///< k_i [N/m], > 0
  std::vector<T> share;      ///< alpha_i [-], > 0, summing to 1
  StribeckCurve<T> curve;    ///< g(v): coulomb, static_force, stribeck_velocity, stribeck_exponent
  T attraction{1e4};         ///< C [N/s], > 0: rate at which slipping elements follow g(v)
  T viscous{0};              ///< sigma2 [N s/m], >= 0

  std::size_t size() const noexcept { return stiffness.size(); }  ///< N

  /// Relative tolerance on sum_i alpha_i = 1.
  static constexpr double kShareTolerance = 1e-9;

  /// Throws InvalidParameter unless N >= 1, the sizes match, k_i > 0, alpha_i > 0 with
  /// |sum alpha_i - 1| <= kShareTolerance, the curve is valid, C > 0 and sigma2 >= 0 (all finite).
  void validate() const {
    FRICTION_CHECK(!stiffness.empty(), "GMS needs at least one element");
    FRICTION_CHECK(share.size() == stiffness.size(), "GMS: ", share.size(), " shares for ",
                   stiffness.size(), " stiffnesses");
    double total = 0.0;
    for (std::size_t i = 0; i < size(); ++i) {
      const double k = value_of(stiffness[i]), a = value_of(share[i]);
      FRICTION_CHECK(std::isfinite(k) && k > 0.0, "GMS: stiffness[", i, "] = ", k,
                     " N/m must be finite and > 0");
      FRICTION_CHECK(std::isfinite(a) && a > 0.0, "GMS: share[", i, "] = ", a,
                     " must be finite and > 0");
      total += a;
    }
    FRICTION_CHECK(std::abs(total - 1.0) <= kShareTolerance, "GMS: the shares sum to ", total,
                   ", not 1");
    curve.validate("GMS");
    const double c = value_of(attraction), s2 = value_of(viscous);
    FRICTION_CHECK(std::isfinite(c) && c > 0.0, "GMS: attraction C = ", c,
                   " N/s must be finite and > 0");
    FRICTION_CHECK(std::isfinite(s2) && s2 >= 0.0, "GMS: viscous sigma2 = ", s2,
                   " N s/m must be finite and >= 0");
  }

  /// The Coulomb level Fc [N], the reference of level extensions.
  T sliding_force() const { return curve.coulomb; }

  /// Maxwell Slip limit: thresholds alpha_i Fc / k_i (what GMS reduces to for C -> infinity and
  /// Fs = Fc, sigma2 = 0).
  MaxwellSlipParameters<T> maxwell_slip_limit() const {
    MaxwellSlipParameters<T> ms;
    ms.stiffness = stiffness;
    for (std::size_t i = 0; i < size(); ++i)
      ms.threshold.push_back(share[i] * curve.coulomb / stiffness[i]);
    return ms;
  }
};

/// Generalized Maxwell Slip model with element forces F_i and stick/slip states.
template <typename T>
class Gms {
 public:
  using Scalar = T;
  using Parameters = GmsParameters<T>;

  explicit Gms(Parameters parameters) : p_(std::move(parameters)) {
    p_.validate();
    force_.assign(p_.size(), T(0));
    slip_.assign(p_.size(), 0);
  }

  const Parameters& parameters() const noexcept { return p_; }
  std::size_t size() const noexcept { return p_.size(); }

  /// Virgin state: all elements relaxed and sticking.
  void reset() {
    for (auto& f : force_) f = T(0);
    for (auto& s : slip_) s = 0;
  }

  /// Start from given element forces F_i [N], all sticking.  (Magnitudes above alpha_i Fs are
  /// clamped, the largest force an element can hold at rest.)
  void reset(std::span<const T> element_forces) {
    FRICTION_CHECK(element_forces.size() == size(), "GMS: ", element_forces.size(),
                   " initial element forces for ", size(), " elements");
    for (std::size_t i = 0; i < size(); ++i) {
      const T limit = p_.share[i] * p_.curve.static_force;
      force_[i] = clamp(element_forces[i], T(-limit), limit);
      slip_[i] = 0;
    }
  }

  /// Element forces F_i [N].
  std::span<const T> element_forces() const noexcept { return force_; }

  /// Slip state of element i: 0 sticking, +1 / -1 slipping in +x / -x.
  int slip_state(std::size_t i) const noexcept { return slip_[i]; }

  /// Advance by one sample (exact step of the header comment) and return F = sum F_i + sigma2 v.
  T step(const Motion<T>& m) noexcept {
    using std::exp;
    const double s = sign_of(m.dx);
    const std::size_t n = force_.size();
    if (s == 0.0) {  // rest: every element sticks with its force
      for (std::size_t i = 0; i < n; ++i) slip_[i] = 0;
      return sum_forces() + p_.viscous * m.velocity;
    }
    const auto dir = static_cast<std::int8_t>(s);
    // G = level (1 + a s) g(v): the slip level in the direction of motion.
    const T limit_scale = m.level * (T(1) + T(s) * m.asymmetry) * p_.curve(m.velocity);
    // exp(-C dt / G): the fraction of the distance to the curve that remains after dt of slip.
    const T remain = exp(-p_.attraction * m.dt / limit_scale);
    const T* k = p_.stiffness.data();
    const T* alpha = p_.share.data();
    T* f = force_.data();
    for (std::size_t i = 0; i < n; ++i) {
      const T target = T(s * alpha[i]) * limit_scale;  // F_inf,i = s alpha_i G
      if (slip_[i] == dir) {
        f[i] = target + (f[i] - target) * remain;
      } else {
        const T stuck = f[i] + k[i] * m.dx;
        if (s * stuck >= s * target) {  // reaches the limit within the interval
          f[i] = target;
          slip_[i] = dir;
        } else {
          f[i] = stuck;
          slip_[i] = 0;
        }
      }
    }
    return sum_forces() + p_.viscous * m.velocity;
  }

  /// sum_i F_i [N] (the force without the viscous term).
  T sum_forces() const noexcept {
    T total(0);
    for (const auto& f : force_) total += f;
    return total;
  }

 private:
  Parameters p_;
  std::vector<T> force_;
  std::vector<std::int8_t> slip_;
};

}  // namespace friction
