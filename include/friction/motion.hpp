// The per-sample input every friction model is stepped with.
//
// A record gives displacement x(t) at sample times t_k.  Between two samples the motion is taken
// as piecewise linear, so over the interval (t_{k-1}, t_k] the velocity is constant and equal to
// v_k = (x_k - x_{k-1}) / (t_k - t_{k-1}) (a backward difference).  This is the one velocity that
// is consistent with the displacement increments the Maxwell Slip recursion (paper eq. 4) sees, and
// it is exactly the piecewise-constant velocity for which the LuGre state equation has the
// closed-form exponential step (methods.md section 1).  Its price is noise: white displacement
// noise of standard deviation s_x becomes velocity noise of standard deviation sqrt(2) s_x / Ts,
// and an encoder of resolution q makes slow motion look like pulses of q / Ts.  Models that use
// velocity only through |v| in a level (LuGre, GMS, Stribeck) are robust to that; see
// `differentiator.hpp` for the smoothing option used on noisy records.
#pragma once

#include <cstddef>
#include <span>

namespace friction {

template <typename T>
struct Motion {
  T dx;        ///< displacement increment over the sample interval [m]
  T velocity;  ///< velocity over the interval [m/s] (dx / dt for a piecewise-linear record)
  T dt;        ///< length of the interval [s]; 0 for the first sample of a record
  /// Slip-force scale factor from level effects (Stribeck, asymmetry, drift, ...; methods.md 7).
  /// 1 is the nominal model.  Models scale their slip forces (thresholds, s(v), g(v)) by it.
  T level = T(1);
  /// Direction-dependent slip forces (the `asymmetry` piece of methods.md 7): the slip limits are
  /// level (1 + a) moving in +x and level (1 - a) moving in -x.  For the Maxwell Slip operators that
  /// is the box [-(1 - a) level Delta_i, (1 + a) level Delta_i], for LuGre, GMS and the static
  /// curve the slip level times 1 + a sgn(v).  0 is the symmetric model.
  T asymmetry = T(0);
};

/// The Motion of sample k of a record (displacement x at `time`), with slip-force level `level`:
/// the increment from sample k-1 and the backward-difference velocity above; sample 0 is the
/// initial state (dx = v = dt = 0).  Every routine that steps a model over a record builds its
/// motions here, so that simulation, identification and tests see the same numbers.
template <typename T>
Motion<T> motion_at(std::span<const double> time, std::span<const T> x, std::size_t k,
                    T level = T(1)) {
  Motion<T> m{T(0), T(0), T(0), level};
  if (k > 0) {
    const double dt = time[k] - time[k - 1];
    m.dx = x[k] - x[k - 1];
    m.dt = T(dt);
    m.velocity = m.dx / dt;
  }
  return m;
}

}  // namespace friction
