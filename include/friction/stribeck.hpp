// The Stribeck curve g(v) of the Generalized Maxwell Slip model (methods.md section 5).
//
//     g(v) = Fc + (Fs - Fc) * w(v),     w(v) = exp(-(|v| / vs)^q)                      [N]
//
// g is the magnitude of the steady sliding friction at speed |v| without the viscous part: it
// starts at the static (breakaway) level Fs at rest and falls (Fs > Fc) or rises (Fs < Fc) to the
// Coulomb level Fc over a speed range set by the Stribeck velocity vs; the exponent q shapes the
// transition (q = 2 is the Gaussian curve of Armstrong-Helouvry and Canudas de Wit; q = 1 an
// exponential).  It is shared by the GMS model (gms.hpp), the static curve
// F = sgn(v) g(v) + sigma2 v (static_friction.hpp) and, normalised by Fc, by the `stribeck` level
// extension (extensions.hpp).
//
// Derivatives at rest.  Every model is a template on its scalar so that ceres::Jet flows through
// it.  Two terms misbehave at v = 0 if written naively: d|v|/dv is +-1 there (we want 0, the
// derivative of an even function at its centre), and (|v|/vs)^q = exp(q log(|v|/vs)) has the
// derivative log(0) * 0 = NaN with respect to q (and an infinite derivative in v for q < 1).  So
// |v| is written sgn(v) * v, whose derivative is 0 at v = 0, and the power is evaluated only when
// |v| > 0 (a branch on the value), w = 1 exactly at rest.  Both are the limits of the smooth curve
// for q > 1, and at rest the force is not differentiated with respect to q or vs anyway.
//
// For large |v|/vs the power is large and w underflows to 0 (derivative 0): harmless.
#pragma once

#include <cmath>
#include <type_traits>

#include "friction/error.hpp"
#include "friction/scalar.hpp"

namespace friction {

/// exp(-(|v| / vs)^q) in (0, 1], with value 1 and zero derivatives at v = 0 (see the header).
template <typename T>
T stribeck_weight(const T& v, const T& stribeck_velocity, const T& stribeck_exponent) {
  using std::exp;
  using std::log;
  const double s = sign_of(v);
  if (s == 0.0) return T(1);
  const T ratio = T(s * v) / stribeck_velocity;  // |v| / vs > 0
  const T power_log = stribeck_exponent * log(ratio);
  if constexpr (std::is_same_v<T, double>) {
    // (|v|/vs)^q > e^6.62 > 749: exp(-749) is below half the smallest subnormal, so w is +0
    // exactly, as the two exponentials would give.  Sliding far above vs is most of a record's
    // samples, and the exponentials were a tenth of a diagnosis.
    if (power_log > 6.62) return 0.0;
  } else if constexpr (std::is_same_v<decltype(power_log.a), double>) {
    // The same for a Jet of doubles (a fit's derivatives).  There exp(-exp(p)) is
    // (0, 0 * -(e p.v)) with e = exp(p.a) finite and > 749 while p.a < 709, and e p.v has the
    // sign of p.v and is finite while |p.v| < 1e300: so the lanes are 0 * -p.v, signs of zero
    // included, without the two exponentials.
    if (power_log.a > 6.62 && power_log.a < 709.0 &&
        power_log.v.cwiseAbs().maxCoeff() < 1e300) {
      T w(0.0);
      w.v = 0.0 * (-power_log.v);
      return w;
    }
  }
  return exp(-exp(power_log));
}

/// Parameters of the Stribeck curve g(v), SI units.  The member names are the ones of methods.md
/// section 7 and of the LuGre parameters (`static` is a C++ keyword, hence `static_force`).
template <typename T>
struct StribeckCurve {
  T coulomb{};                ///< Fc [N], > 0: the level at high speed
  T static_force{};           ///< Fs [N], > 0: the level at rest (Fs > Fc: Stribeck dip)
  T stribeck_velocity{1e-3};  ///< vs [m/s], > 0
  T stribeck_exponent{2.0};   ///< q [-], > 0

  /// A flat curve g = Fc (no Stribeck effect): Fs = Fc.
  static StribeckCurve coulomb_only(const T& fc) { return {fc, fc, T(1e-3), T(2.0)}; }

  /// Throws InvalidParameter unless all values are finite and Fc, Fs, vs, q > 0.  Fc, Fs > 0 keep
  /// g(v) > 0 at every speed, which the GMS slip equation divides by.
  void validate(const char* model = "Stribeck curve") const {
    const double fc = value_of(coulomb), fs = value_of(static_force);
    const double vs = value_of(stribeck_velocity), q = value_of(stribeck_exponent);
    FRICTION_CHECK(std::isfinite(fc) && fc > 0.0, model, ": coulomb Fc = ", fc,
                   " N must be finite and > 0");
    FRICTION_CHECK(std::isfinite(fs) && fs > 0.0, model, ": static_force Fs = ", fs,
                   " N must be finite and > 0");
    FRICTION_CHECK(std::isfinite(vs) && vs > 0.0, model, ": stribeck_velocity vs = ", vs,
                   " m/s must be finite and > 0");
    FRICTION_CHECK(std::isfinite(q) && q > 0.0, model, ": stribeck_exponent q = ", q,
                   " must be finite and > 0");
  }

  /// g(v) [N] (> 0, even in v).
  T operator()(const T& v) const {
    return coulomb +
           (static_force - coulomb) * stribeck_weight(v, stribeck_velocity, stribeck_exponent);
  }
};

}  // namespace friction
