// The LuGre friction model (Canudas de Wit et al. 1995; Rizos & Fassois 2005, eqs. 1-3).
//
// One internal state z [m], the mean deflection of the elastic bristles:
//
//     dz/dt = v - |v| z / s(v)                                                       (eq. 1)
//     F     = sigma0 z + sigma1 dz/dt + sigma2 v                                     (eq. 2)
//
// s(v) [m] is the steady-state bristle deflection: at constant velocity z settles at
// z_ss = sgn(v) s(v), and F_ss = sigma0 s(v) sgn(v) + sigma2 v is the Stribeck/viscous curve.
// Two shapes of it are offered, both with w(v) in (0, 1], w(0) = 1, falling with |v|:
//
//     Rational (the paper's eq. 3, the default):  w(v) = 1 / (1 + (|v|/vs)^mu)
//     Exponential (Canudas de Wit et al. 1995):   w(v) = exp(-(|v|/vs)^mu)
//     sigma0 s(v) = level * (Fc + (Fs - Fc) w(v))
//
// so a1 = Fc/sigma0 and a2 = (Fs - Fc)/sigma0 of eq. 3.  The exponential shape takes the same
// exponent mu: Canudas de Wit's published curve exp(-(v/vs)^2) is mu = 2.  Keeping mu in both
// shapes keeps the seven parameters the same and their derivatives meaningful in either shape.
// `Motion::level` multiplies s(v): level effects scale the slip forces (methods.md section 7),
// which for LuGre is the bristle deflection at which slip is reached, not a term added to F.
//
// Exact step.  Over a sample interval of length dt the velocity is taken constant (the backward
// difference of a piecewise-linear displacement, motion.hpp), so eq. 1 is linear in z with constant
// coefficients and integrates in closed form:
//
//     z+ = z_inf + (z - z_inf) exp(-|v| dt / s(v)),     z_inf = sgn(v) s(v).
//
// This is exact for any dt, hence unconditionally stable however stiff the relaxation rate |v|/s(v)
// is (it reaches 1e4..1e5 1/s when sliding with sigma0 ~ 1e5..1e6 N/m).  The output is eq. 2 at
// the END of the interval, with dz/dt = v - |v| z+/s(v) written as -(|v|/s)(z - z_inf) e, which is
// the same number without the cancellation of v against |v| z+/s in sliding.  A first sample
// (dt = 0, v = 0) leaves z unchanged and gives F = sigma0 z.
//
// Derivatives.  The step is a template on the scalar, so ceres::Jet flows through it.  Two points
// need care: |v| is written sgn(v) v so that its derivative is 0 (not +-1) at v = 0, and
// (|v|/vs)^mu is computed as exp(mu log(|v|/vs)) only when |v| > 0 (value branch), w = 1 exactly at
// v = 0 -- otherwise d/dmu |v|^mu = |v|^mu log|v| evaluates 0 * -inf = NaN at rest, and d/dv |v|^mu
// is infinite there for mu < 1.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <span>
#include <utility>

#include "friction/error.hpp"
#include "friction/motion.hpp"
#include "friction/scalar.hpp"

namespace friction {

/// Shape of the Stribeck curve s(v) (see the header comment).
enum class StribeckShape {
  Rational,     ///< paper eq. 3: w = 1 / (1 + (|v|/vs)^mu)
  Exponential,  ///< Canudas de Wit et al. 1995 (mu = 2): w = exp(-(|v|/vs)^mu)
};

/// Parameters of the LuGre model, SI units.  The order of `to_array()` / `from_array()` is the
/// order of the members: sigma0, sigma1, sigma2, Fc, Fs, vs, mu.
template <typename T>
struct LuGreParameters {
  static constexpr std::size_t kSize = 7;  ///< number of continuous parameters

  T stiffness{};          ///< sigma0 [N/m], > 0
  T micro_damping{};      ///< sigma1 [N s/m], >= 0
  T viscous{};            ///< sigma2 [N s/m], >= 0
  T coulomb{};            ///< Fc [N], > 0
  T static_force{};       ///< Fs [N], > 0 (Fs > Fc for a Stribeck dip; Fs < Fc is allowed)
  T stribeck_velocity{};  ///< vs [m/s], > 0
  T stribeck_exponent{};  ///< mu [-], > 0
  StribeckShape shape = StribeckShape::Rational;

  /// Throws InvalidParameter unless every value is finite, sigma0, Fc, Fs, vs, mu > 0 and
  /// sigma1, sigma2 >= 0.  Fc, Fs > 0 keeps s(v) > 0 at every speed, which eq. 1 divides by.
  void validate() const {
    const double s0 = value_of(stiffness), s1 = value_of(micro_damping), s2 = value_of(viscous);
    const double fc = value_of(coulomb), fs = value_of(static_force);
    const double vs = value_of(stribeck_velocity), mu = value_of(stribeck_exponent);
    FRICTION_CHECK(std::isfinite(s0) && s0 > 0.0, "LuGre: stiffness sigma0 = ", s0,
                   " N/m must be finite and > 0");
    FRICTION_CHECK(std::isfinite(s1) && s1 >= 0.0, "LuGre: micro_damping sigma1 = ", s1,
                   " N s/m must be finite and >= 0");
    FRICTION_CHECK(std::isfinite(s2) && s2 >= 0.0, "LuGre: viscous sigma2 = ", s2,
                   " N s/m must be finite and >= 0");
    FRICTION_CHECK(std::isfinite(fc) && fc > 0.0, "LuGre: coulomb Fc = ", fc,
                   " N must be finite and > 0");
    FRICTION_CHECK(std::isfinite(fs) && fs > 0.0, "LuGre: static_force Fs = ", fs,
                   " N must be finite and > 0");
    FRICTION_CHECK(std::isfinite(vs) && vs > 0.0, "LuGre: stribeck_velocity vs = ", vs,
                   " m/s must be finite and > 0");
    FRICTION_CHECK(std::isfinite(mu) && mu > 0.0, "LuGre: stribeck_exponent mu = ", mu,
                   " must be finite and > 0");
  }

  /// {sigma0, sigma1, sigma2, Fc, Fs, vs, mu}.
  std::array<T, kSize> to_array() const {
    return {stiffness,    micro_damping,     viscous,          coulomb,
            static_force, stribeck_velocity, stribeck_exponent};
  }

  /// Inverse of `to_array()`.
  static LuGreParameters from_array(std::span<const T, kSize> theta,
                                    StribeckShape shape = StribeckShape::Rational) {
    return {theta[0], theta[1], theta[2], theta[3], theta[4], theta[5], theta[6], shape};
  }

  /// The same parameters in another scalar (e.g. double -> Jet with zero derivative).
  template <typename U>
  LuGreParameters<U> cast() const {
    return {U(stiffness),    U(micro_damping),     U(viscous),           U(coulomb),
            U(static_force), U(stribeck_velocity), U(stribeck_exponent), shape};
  }
};

/// Names of the parameters in `to_array()` order (the SI names used in reports).
inline constexpr std::array<const char*, 7> kLuGreParameterNames{
    "stiffness",    "micro_damping",     "viscous",          "coulomb",
    "static_force", "stribeck_velocity", "stribeck_exponent"};

/// Stribeck weight w in (0, 1) of a moving sample from ln(|v| / vs): the shape's formula applied
/// to (|v| / vs)^mu = exp(mu ln(|v| / vs)).  LG's global stage keeps ln|v| per distinct motion and
/// calls this directly.
template <typename T>
T stribeck_weight_of_log_ratio(const LuGreParameters<T>& p, const T& log_ratio) {
  using std::exp;
  const T ratio_pow = exp(p.stribeck_exponent * log_ratio);
  if (p.shape == StribeckShape::Exponential) return exp(-ratio_pow);
  return T(1) / (T(1) + ratio_pow);
}

/// Stribeck weight w(v) in (0, 1], exactly 1 at v = 0 with zero derivatives there.
template <typename T>
T stribeck_weight(const LuGreParameters<T>& p, const T& v) {
  using std::log;
  const T speed = T(sign_of(v)) * v;
  if (value_of(speed) == 0.0) return T(1);
  return stribeck_weight_of_log_ratio(p, T(log(T(speed / p.stribeck_velocity))));
}

/// s(v) [m] of eq. 3 (or its exponential counterpart), times the slip-force level.
template <typename T>
T steady_deflection(const LuGreParameters<T>& p, const T& v, const T& level = T(1)) {
  return level * (p.coulomb + (p.static_force - p.coulomb) * stribeck_weight(p, v)) / p.stiffness;
}

/// Steady-state force at constant velocity: sigma0 s(v) sgn(v) + sigma2 v [N].
template <typename T>
T steady_state_force(const LuGreParameters<T>& p, const T& v, const T& level = T(1)) {
  return p.stiffness * steady_deflection(p, v, level) * T(sign_of(v)) + p.viscous * v;
}

/// dz/dt of eq. 1 [m/s] at state z [m] and velocity v [m/s].  Templated so that CVODES gets its
/// right-hand side, and (through ceres::Jet) its partial derivatives in z and in the parameters,
/// from this one expression.
template <typename T>
T lugre_rhs(const LuGreParameters<T>& p, const T& z, const T& v, const T& level = T(1)) {
  const T speed = T(sign_of(v)) * v;
  return v - speed * z / steady_deflection(p, v, level);
}

/// Force of eq. 2 [N] at state z and velocity v, with dz/dt from eq. 1.
template <typename T>
T lugre_force(const LuGreParameters<T>& p, const T& z, const T& v, const T& level = T(1)) {
  return p.stiffness * z + p.micro_damping * lugre_rhs(p, z, v, level) + p.viscous * v;
}

/// The LuGre model with the exact exponential step for piecewise-constant velocity.
template <typename T>
class LuGre {
 public:
  using Scalar = T;
  using Parameters = LuGreParameters<T>;

  explicit LuGre(Parameters parameters) : p_(std::move(parameters)) { p_.validate(); }

  const Parameters& parameters() const noexcept { return p_; }

  /// Virgin state: bristles relaxed, z = 0.
  void reset() { z_ = T(0); }

  /// Start from a given bristle deflection z0 [m] (e.g. an estimated initial state).
  void reset(const T& z0) { z_ = z0; }

  /// Current bristle deflection z [m].
  const T& state() const noexcept { return z_; }

  /// Advance over one interval with constant velocity `m.velocity` for `m.dt` (exact solution of
  /// eq. 1) and return eq. 2 at the end of the interval.  No allocation, no branch on derivatives.
  T step(const Motion<T>& m) noexcept { return step(transition(m)); }

  /// What one interval does, apart from the state: z+ = z_inf + (z - z_inf) decay, with the rate
  /// |v| / s(v) and the viscous force.  It depends on the motion and the parameters only, so a
  /// record whose motions repeat can compute each distinct one once per parameter set: an encoder
  /// at a fixed rate gives a few hundred distinct velocities in 10,000 samples, and the two
  /// transcendental functions here are most of the cost of a step.  step(m) is
  /// step(transition(m)), the same operations in the same order.
  struct Transition {
    T z_inf, decay, rate, viscous_force;
  };

  Transition transition(const Motion<T>& m) const noexcept {
    using std::exp;
    const T& v = m.velocity;
    const double direction = sign_of(v);
    const T s = steady_deflection(p_, v, T(m.level * (T(1) + T(direction) * m.asymmetry)));
    const T rate = T(direction) * v / s;  // |v| / s(v) [1/s]
    return {T(direction) * s, exp(-rate * m.dt), rate, p_.viscous * v};
  }

  /// Advance over an interval whose transition is known (eq. 1 exactly, eq. 2 at its end).
  T step(const Transition& tr) noexcept {
    const T excess = (z_ - tr.z_inf) * tr.decay;
    z_ = tr.z_inf + excess;
    const T dz_dt = -tr.rate * excess;
    return p_.stiffness * z_ + p_.micro_damping * dz_dt + tr.viscous_force;
  }

 private:
  Parameters p_;
  T z_ = T(0);
};

}  // namespace friction
