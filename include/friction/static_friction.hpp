// The static friction curve: friction as a function of the current velocity alone.
//
//     F(v) = sgn(v) * level * g(v) + sigma2 * v,
//     g(v) = Fc + (Fs - Fc) exp(-(|v| / vs)^q)                         (stribeck.hpp, methods.md 5)
//
// Coulomb (Fs = Fc, sigma2 = 0), Coulomb + viscous, and the Stribeck curve are special cases.  This
// is the steady-state curve that GMS and LuGre settle on at constant speed, and what is left of
// them when presliding and frictional lag are ignored.  The CLI calls it `static`.
//
// It has no state, hence no presliding: the force jumps from -g(0) to +g(0) when the velocity
// changes sign and is 0 at rest (sgn(0) = 0).  With the piecewise-linear record convention
// (motion.hpp) the velocity is the backward difference over the sample interval, so the force of
// sample k is the curve at the mean velocity of (t_{k-1}, t_k].  `level` scales the
// Coulomb-Stribeck part only (methods.md section 7: level effects act on slip forces; viscous
// friction is added).
#pragma once

#include <cmath>

#include "friction/error.hpp"
#include "friction/motion.hpp"
#include "friction/scalar.hpp"
#include "friction/stribeck.hpp"

namespace friction {

/// Parameters of the static friction curve, SI units.
template <typename T>
struct StaticFrictionParameters {
  StribeckCurve<T> curve;  ///< g(v): coulomb, static_force, stribeck_velocity, stribeck_exponent
  T viscous{0};            ///< sigma2 [N s/m], >= 0

  /// Throws InvalidParameter unless the curve is valid and sigma2 is finite and >= 0.
  void validate() const {
    curve.validate("static friction");
    const double s2 = value_of(viscous);
    FRICTION_CHECK(std::isfinite(s2) && s2 >= 0.0, "static friction: viscous sigma2 = ", s2,
                   " N s/m must be finite and >= 0");
  }

  /// The nominal sliding (Coulomb) level Fc [N], the reference of level extensions.
  T sliding_force() const { return curve.coulomb; }
};

/// F = sgn(v) level g(v) + sigma2 v.  Stateless; `reset()` exists for the model interface.
template <typename T>
class StaticFriction {
 public:
  using Scalar = T;
  using Parameters = StaticFrictionParameters<T>;

  explicit StaticFriction(Parameters parameters) : p_(std::move(parameters)) { p_.validate(); }

  const Parameters& parameters() const noexcept { return p_; }

  void reset() noexcept {}

  /// The curve at the sample's velocity.
  T step(const Motion<T>& m) noexcept {
    return force(m.velocity, T(m.level * (T(1) + T(sign_of(m.velocity)) * m.asymmetry)));
  }

  /// The curve itself, F(v) [N].
  T force(const T& v, const T& level = T(1)) const noexcept {
    const double s = sign_of(v);
    if (s == 0.0) return T(0);
    return T(s * level * p_.curve(v)) + p_.viscous * v;
  }

 private:
  Parameters p_;
};

}  // namespace friction
