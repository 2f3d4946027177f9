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

namespace friction {

template <typename T>
struct Motion {
  T dx;        ///< displacement increment over the sample interval [m]
  T velocity;  ///< velocity over the interval [m/s] (dx / dt for a piecewise-linear record)
  T dt;        ///< length of the interval [s]; 0 for the first sample of a record
  /// Slip-force scale factor from level effects (Stribeck, asymmetry, drift, ...; methods.md 7).
  /// 1 is the nominal model.  Models scale their slip forces (thresholds, s(v), g(v)) by it.
  T level = T(1);
};

}  // namespace friction
