// Velocity of a sampled displacement record, per sample interval.
//
// The models are stepped with one velocity per interval (t_{k-1}, t_k] (motion.hpp); the LuGre
// exact step and the CVODES integration both hold it constant over the interval.  Two estimators of
// it:
//
// 1. Backward difference (the base convention, what `simulate` uses):
//        v_k = (x_k - x_{k-1}) / (t_k - t_{k-1}),   v_0 = 0.
//    It is the exact velocity of the piecewise-linear displacement through the samples, so it loses
//    nothing on a clean record and is consistent with the increments Maxwell Slip sees.  Noise:
//    white displacement noise of standard deviation s_x gives velocity noise of standard deviation
//    sqrt(2) s_x / Ts (successive values correlated -1/2), i.e. the noise is amplified by
//    1.41 / Ts: at Ts = 1 ms, 0.1 um of noise becomes 0.14 mm/s, the order of a Stribeck velocity.
//    A quantised record (encoder step q) at a speed below q/Ts reads as pulses of q/Ts separated by
//    zeros.  LuGre's s(v) then sees the pulses' speed, not the true one.
//
// 2. Smoothed (`smoothed_interval_velocity`, offline records): the least-squares slope of a
// straight
//    line through the 2m samples k-m .. k+m-1, i.e. centred on the interval's midpoint t_{k-1/2} (a
//    Savitzky-Golay first derivative on an even window).  m = 1 is exactly the backward difference.
//    Being centred it has no phase lag (reversals stay where they are); being a symmetric fit it is
//    exact for quadratics, so on smooth motion its bias is O(x''' (m Ts)^2).  For uniform sampling:
//      noise gain  s_v / s_x = 1 / (Ts sqrt(m (4m^2 - 1) / 6))     (`velocity_noise_gain`)
//                  m = 1: 1.414/Ts,  2: 0.447/Ts,  5: 0.110/Ts,  10: 0.0388/Ts,  20: 0.0137/Ts
//      -3 dB cutoff of its gain relative to an ideal differentiator
//                  m = 1: 0.443/Ts,  2: 0.155/Ts,  5: 0.0584/Ts, 10: 0.0290/Ts,  ~0.58/(2m Ts)
//      quantisation: a staircase of step q gives a slope error at most 3 q m / ((4m^2 - 1) Ts)
//                  (q/Ts for m = 1, 0.15 q/Ts for m = 5).
//    The price is bandwidth: velocity content above ~0.58/(2m Ts) (a reversal sharper than 2m
//    samples, a stick-slip jump) is smeared over the window.  Choose m so that 0.58/(2m Ts) stays
//    above the excitation's highest significant frequency.  Not for real-time use (it needs m-1
//    future samples).  Near the ends the window shrinks symmetrically (m_eff = min(m, k, N-k)), so
//    the first interval always uses the backward difference.  Non-uniform sampling is handled (the
//    fit uses the actual sample times); the noise figures above are for uniform sampling.
//
// The velocity only replaces `Motion::velocity`; the displacement increments stay those of the
// record.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <span>
#include <vector>

#include "friction/error.hpp"

namespace friction {

namespace detail {
inline void check_record(std::span<const double> time, std::span<const double> x,
                         std::span<double> velocity) {
  FRICTION_CHECK(time.size() == x.size() && velocity.size() == x.size(),
                 "velocity: time, displacement and velocity must have the same length");
  for (std::size_t k = 1; k < time.size(); ++k)
    FRICTION_CHECK(time[k] > time[k - 1], "velocity: time must increase strictly (sample ", k, ")");
}
}  // namespace detail

/// v_k = (x_k - x_{k-1}) / (t_k - t_{k-1}) for k >= 1, v_0 = 0 [m/s].
inline void backward_difference_velocity(std::span<const double> time, std::span<const double> x,
                                         std::span<double> velocity) {
  detail::check_record(time, x, velocity);
  if (!velocity.empty()) velocity[0] = 0.0;
  for (std::size_t k = 1; k < x.size(); ++k)
    velocity[k] = (x[k] - x[k - 1]) / (time[k] - time[k - 1]);
}

inline std::vector<double> backward_difference_velocity(std::span<const double> time,
                                                        std::span<const double> x) {
  std::vector<double> v(x.size());
  backward_difference_velocity(time, x, v);
  return v;
}

/// Least-squares slope over the 2m samples centred on each interval (see the header); v_0 = 0.
/// `half_width` m >= 1; m = 1 is the backward difference.
inline void smoothed_interval_velocity(std::span<const double> time, std::span<const double> x,
                                       std::size_t half_width, std::span<double> velocity) {
  FRICTION_CHECK(half_width >= 1, "smoothed_interval_velocity: half_width must be >= 1");
  detail::check_record(time, x, velocity);
  const std::size_t n = x.size();
  if (n == 0) return;
  velocity[0] = 0.0;
  for (std::size_t k = 1; k < n; ++k) {
    const std::size_t m = std::min({half_width, k, n - k});
    const std::size_t first = k - m, last = k + m - 1;  // 2m samples
    // Centre on the interval's midpoint to keep the sums well conditioned.
    const double tc = 0.5 * (time[k - 1] + time[k]);
    double st = 0, sx = 0;
    for (std::size_t i = first; i <= last; ++i) {
      st += time[i] - tc;
      sx += x[i];
    }
    const double count = static_cast<double>(2 * m);
    const double tm = st / count, xm = sx / count;
    double stt = 0, stx = 0;
    for (std::size_t i = first; i <= last; ++i) {
      const double dt = time[i] - tc - tm;
      stt += dt * dt;
      stx += dt * (x[i] - xm);
    }
    velocity[k] = stx / stt;
  }
}

inline std::vector<double> smoothed_interval_velocity(std::span<const double> time,
                                                      std::span<const double> x,
                                                      std::size_t half_width) {
  std::vector<double> v(x.size());
  smoothed_interval_velocity(time, x, half_width, v);
  return v;
}

/// Standard deviation of the velocity error per unit standard deviation of white displacement
/// noise, times Ts, for uniform sampling: 1 / sqrt(m (4m^2 - 1) / 6).  sqrt(2) for m = 1.
inline double velocity_noise_gain(std::size_t half_width) {
  const double m = static_cast<double>(half_width);
  return 1.0 / std::sqrt(m * (4.0 * m * m - 1.0) / 6.0);
}

}  // namespace friction
