// Velocity and acceleration AT the sample instants t_k, for the terms of a model that use them.
//
// Why at t_k.  A record gives the force F_k at t_k.  The Maxwell Slip recursion (paper eq. 4) is
// rate independent: it needs only the increments x_k - x_{k-1}, and its state after the increment
// is the state at t_k, so it is consistent with F_k as it stands.  A term that uses the velocity or
// the acceleration -- viscous sigma2 v, inertia m a, the Stribeck level g(|v|), the frictional lag
// driven by v -- must use them at t_k too.  The backward difference (x_k - x_{k-1})/Ts is the
// velocity at t_{k-1/2}, half a sample behind the force: sigma2 v(t_k - Ts/2) ~ sigma2 v(t_k) -
// sigma2 (Ts/2) a(t_k), so a fitted model buys a spurious mass sigma2 Ts/2 (5.9 kg at
// sigma2 = 11 800 N s/m, Ts = 1 ms; 6.9 kg was found on an independent record).  The second
// difference (x_{k+1} - 2 x_k + x_{k-1})/Ts^2 is centred, but a quantised record (step q) gives it
// a noise of about q/(sqrt(2) Ts^2) per sample (0.007 m/s^2 at q = 10 nm, Ts = 1 ms, i.e. 24 N at
// 3400 kg): a least-squares mass is then diluted towards zero (141 kg were found for ~3400 kg).
//
// The estimator.  At each t_k a quadratic is fitted by least squares to the 2m+1 samples around it
// (actual sample times, so gaps are handled) and differentiated at t_k: a Savitzky-Golay filter of
// degree 2.  For uniform sampling and a symmetric window it is exact for quadratics (the velocity
// for cubics); the velocity is the least-squares slope  v = sum i x_{k+i} / (Ts S2),
// S2 = sum i^2 = m(m+1)(2m+1)/3, and the acceleration  a = sum c_i x_{k+i},
// c_i = 2 (i^2 - S2/(2m+1)) / (Ts^2 D),  D = sum (i^2 - S2/(2m+1))^2.  White displacement noise of
// standard deviation s gives them noise s/(Ts sqrt(S2)) and 2 s/(Ts^2 sqrt(D)): sqrt(D) grows as
// m^2.5, so a window of 20 samples divides the second difference's noise by ~1000.  Near the ends
// the window keeps its length and slides inside the record (the polynomial is evaluated off its
// centre there: no lag, somewhat more noise).  Velocity and acceleration have windows of their own.
//
// The window rule (choose_derivative_windows).  What the study measures, and a user wants, is the
// RMS error of v and a over the record; for a stationary signal it is, for a linear filter h,
//     E(m) = (1/L) sum_j |H_m(w_j) - D(w_j)|^2 S_x(w_j)  +  s^2 sum_i h_i^2
// (bias from the signal's spectrum S_x, variance from the noise; D(w) = i w / Ts or -w^2 / Ts^2 the
// ideal derivative).  Both parts are estimated from the record and E(m) is minimised over m:
//   1. Ts: the median sample interval.
//   2. A Welch spectrum of the displacement increments d_k = x_k - x_{k-1} (segments of up to 4096
//      samples, Hann taper, half overlap): increments, not x, because they are stationary where x
//      drifts or strokes, and P_x(w) = P_d(w) / (4 sin^2(w/2)).
//   3. The displacement noise s^2 (encoder quantisation q^2/12 and any sensor noise): the median of
//      P_d(w) / (4 sin^2(w/2)) over the top of the band, w in [0.7 pi, pi], where a friction
//      experiment's motion has no power, corrected from median to mean for the Welch average.
//   4. The signal spectrum S_x(w) = max(P_x(w) - s^2, 0).
//   5. E_v(m) and E_a(m) for m = 1, 2, ... (up to a quarter of the segment, and (N-1)/2); the
//      windows are their minimisers.  The excitation's bandwidth, the sampling and the encoder
//      enter through S_x and s^2 and nothing is tuned: a fast, smooth multisine gets short windows,
//      a slow quantised stroke record long ones.
// The predicted RMS errors sqrt(E(m)) are returned with the windows.  Acceptance
// (test_sample_derivatives): on records of the independent simulator (envelope, strokes, multisine;
// 200 Hz-5 kHz; encoders of travel/30 000 to travel/1000), against the exact v(t_k) and a(t_k),
// the errors with the chosen windows are within 1.5 times those of the best fixed window.
//
// Which velocity each model uses.  Off-line (simulate, validate, compare, identify, diagnose), the
// base models keep the increments (Maxwell Slip, DNLRX) or the interval velocity over
// (t_{k-1}, t_k] that their exact steps are written for (LuGre's exponential step, GMS's slip
// step: methods.md 1 and 5); the added and level terms of extensions.hpp (viscous, inertia,
// Stribeck, frictional lag) use v(t_k) and a(t_k) from this header.  A controller's `step` is
// causal and has only the past: there the extension pieces use the backward difference and the
// causal second difference, i.e. v and a half a sample and one sample late.  The force error this
// implies for a controller, at acceleration a and jerk j: sigma2 (Ts/2) a from a viscous term
// (0.6 N at sigma2 = 1000 N s/m, Ts = 1 ms, a = 1.2 m/s^2) and m Ts j from an inertia term;
// identified off-line at t_k, the parameters themselves carry no such bias.
#pragma once

#include <algorithm>
#include <cstddef>
#include <span>
#include <vector>

namespace friction {

/// The windows the rule chose for a record, and what it expects of them.
struct DerivativeWindows {
  std::size_t velocity_half_width = 1;      ///< m for v (2m+1 samples)
  std::size_t acceleration_half_width = 1;  ///< m for a
  double sampling_period = 0;               ///< Ts, the median interval [s]
  double displacement_noise = 0;            ///< s, standard deviation [m]
  double velocity_rms_error = 0;            ///< predicted [m/s]
  double acceleration_rms_error = 0;        ///< predicted [m/s^2]
};

struct SampleDerivatives {
  std::vector<double> velocity;      ///< v(t_k) [m/s]
  std::vector<double> acceleration;  ///< a(t_k) [m/s^2]
  DerivativeWindows windows;
};

/// The windows of the rule in the header comment.  Needs at least 16 samples; strictly increasing
/// time (throws InvalidParameter otherwise).
DerivativeWindows choose_derivative_windows(std::span<const double> time,
                                            std::span<const double> x);

/// v and a at every sample by local quadratic fits with the given half widths (>= 1).
void local_polynomial_derivatives(std::span<const double> time, std::span<const double> x,
                                  std::size_t velocity_half_width,
                                  std::size_t acceleration_half_width, std::span<double> velocity,
                                  std::span<double> acceleration);

/// v and a at every sample, windows by the rule.
SampleDerivatives sample_derivatives(std::span<const double> time, std::span<const double> x);

/// The local quadratic fits as linear filters on any scalar: the weights come from the sample
/// times alone (each window's 3 x 3 normal equations), so a displacement of ceres::Jet (a delay's
/// shifted record) carries its derivatives through.  Same numbers as local_polynomial_derivatives
/// for double.  `ts` is the nominal period the powers are scaled by (for conditioning only).
template <typename T>
void apply_local_derivatives(std::span<const double> time, std::span<const T> x,
                             const DerivativeWindows& w, std::span<T> velocity,
                             std::span<T> acceleration) {
  const std::size_t n = x.size();
  const double ts = w.sampling_period > 0 ? w.sampling_period : 1.0;
  for (int order = 1; order <= 2; ++order) {
    const std::size_t m = order == 1 ? w.velocity_half_width : w.acceleration_half_width;
    const std::size_t width = std::min(2 * m + 1, n);
    std::span<T> out = order == 1 ? velocity : acceleration;
    for (std::size_t k = 0; k < n; ++k) {
      if (width < 3) {  // fewer than three samples: nothing to differentiate
        out[k] = T(0);
        continue;
      }
      std::size_t lo = k >= m ? k - m : 0;
      if (lo + width > n) lo = n - width;
      double s[5] = {0, 0, 0, 0, 0};
      for (std::size_t i = lo; i < lo + width; ++i) {
        const double tau = (time[i] - time[k]) / ts;
        double p = 1;
        for (double& q : s) q += p, p *= tau;
      }
      // Row `order` of the inverse of the symmetric 3 x 3 matrix [s0 s1 s2; s1 s2 s3; s2 s3 s4].
      const double a = s[0], b = s[1], c = s[2], d = s[3], e = s[4];
      const double c00 = c * e - d * d, c01 = -(b * e - c * d), c02 = b * d - c * c;
      const double det = a * c00 + b * c01 + c * c02;
      double r0, r1, r2;
      if (order == 1) {
        r0 = c01, r1 = a * e - c * c, r2 = -(a * d - b * c);
      } else {
        r0 = c02, r1 = -(a * d - c * b), r2 = a * c - b * b;
      }
      T sum = T(0);
      for (std::size_t i = lo; i < lo + width; ++i) {
        const double tau = (time[i] - time[k]) / ts;
        const double weight = (r0 + r1 * tau + r2 * tau * tau) / det;
        sum += weight * (x[i] - x[k]);
      }
      out[k] = order == 1 ? T(sum / ts) : T(2.0 * sum / (ts * ts));
    }
  }
}

}  // namespace friction
