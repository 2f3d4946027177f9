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
// The estimator.  At each t_k a polynomial of degree 2 or 4 is fitted by least squares to the
// 2m+1 samples around it (actual sample times, so gaps are handled) and differentiated at t_k: a
// Savitzky-Golay filter.  For uniform sampling and a symmetric window the quadratic's slope is
// v = sum i x_{k+i} / (Ts S2), S2 = sum i^2 = m(m+1)(2m+1)/3, and its curvature
// a = sum c_i x_{k+i}, c_i = 2 (i^2 - S2/(2m+1)) / (Ts^2 D), D = sum (i^2 - S2/(2m+1))^2.  White
// displacement noise of standard deviation s gives them noise s/(Ts sqrt(S2)) and
// 2 s/(Ts^2 sqrt(D)): sqrt(D) grows as m^2.5, so a window of 20 samples divides the second
// difference's noise by ~1000.  The quartic is exact for polynomials of degree 4 (v for degree 5):
// at a frequency w its response departs from the derivative as (w m Ts)^4 where the quadratic's
// does as (w m Ts)^2, for about the same noise at 1.5 times the window.  Why it matters: a term
// fitted by least squares on an attenuated signal comes out too large by the attenuation itself
// (first order), while the signal's RMS error sees only its square; the quadratics the RMS rule
// chose made masses 1-4 % too large on independent records (z = 13-20).  Near the ends the window
// keeps its length and slides inside the record (the polynomial is evaluated off its centre there:
// no lag, somewhat more noise).  Velocity and acceleration have windows of their own.
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
//   6. The same for the quartic; the (degree, m) of least E is chosen for v and for a.
// The predicted RMS errors sqrt(E(m)) are returned with the windows.
//
// Regression factors.  A term c s fitted by least squares on the estimate s_hat of a signal s
// comes out as c sum(s s_hat)/sum(s_hat^2): a filter's attenuation makes the ratio > 1, the noise
// it passes < 1 (errors in variables).  The ratio is 1 - L/sum(s_hat^2), L = sum |H|^2 P -
// sum Re(H D*) S what the filter loses against the ideal derivative (from the spectra above;
// it lies high in the band, where they are reliable), and the estimates are multiplied by it:
// f s_hat is the least-squares prediction of s from s_hat ("regression calibration"), so a
// coefficient fitted on it is unbiased to first order and the RMS error can only fall.  Measured
// (test_sample_derivatives) on 60 records not used to develop it: median relative bias of a
// fitted viscous coefficient 2e-5, of a mass 5e-4 (without the factors about 2e-3, and 0.5-2 % on
// stroke records); a few stroke records whose jerks hide under an encoder's noise keep up to
// 1.2 %.
//
// Acceptance (test_sample_derivatives): on records of the independent simulator (envelope,
// strokes, multisine; 200 Hz-5 kHz; encoders of travel/30 000 to travel/1000), against the exact
// v(t_k) and a(t_k), the errors with the chosen windows are within 1.5 times those of the best
// fixed window of either degree.
//
// The displacement the models see.  An encoder's staircase x_k = q round(x(t_k) / q) errs by up
// to q/2, and not as noise that a fit averages out: through a stiff presliding curve it is a force
// error of about k q / sqrt(12) (seven times the force noise on one discovery-study record), and
// after a reversal the staircase holds its level until the motion crosses the next step, a lag
// that the pieces absorb (a delay 5 % short, an asymmetry, an offset, a mass biased by 3 to 6
// standard errors, where the same records simulated without the encoder gave |z| < 1.7).  So
// signal conditioning (condition_record) gives the models the value at t_k of a local polynomial
// too, with a window by the same rule: for the value filter H (D = 1 in step 5)
//     E_x(m) = (1/L) sum_j |H_m(w_j) - 1|^2 S_x(w_j) + |H_m|^2 N(w_j),
// minimised over m and the degree.  Without displacement noise the rule keeps m = 1 and degree 2,
// a quadratic through three samples, which passes them unchanged.  The record keeps what was
// measured beside it (Record::measured_displacement), and velocity and acceleration are still
// taken of the measurement, with the windows chosen on it.  Chosen on the estimate, the rule sees
// noise that the value filter has already coloured, and the acceleration errors came out 1.6
// times larger (geometric mean over 30 records of the independent simulator, seeds 9100-9129, up
// to 6 times); chosen on the measurement and applied to the estimate, they were 0.97 times those
// of the measurement there but worse than 1.5 times the best fixed window on 2 of the 30 records
// of seeds 5100-5129.  The displacement resolution q that bounds the thresholds and detects
// reversals is that of the measurement (record_resolution).  A controller's `step` sees what its
// encoder gives; a model identified on the estimate is the better one for it all the same, as its
// parameters are not biased by the staircase.
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
#include <cmath>
#include <cstddef>
#include <deque>
#include <span>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "friction/error.hpp"

namespace friction {

/// The windows the rule chose for a record, and what it expects of them.
struct DerivativeWindows {
  std::size_t velocity_half_width = 1;      ///< m for v (2m+1 samples)
  std::size_t acceleration_half_width = 1;  ///< m for a
  std::size_t velocity_degree = 2;          ///< of the local polynomial for v: 2 or 4
  std::size_t acceleration_degree = 2;      ///< of the local polynomial for a: 2 or 4
  /// m and degree of the local polynomial whose value at t_k is the displacement the models see
  /// (m = 1 with degree 2 passes the samples unchanged: three points, a quadratic through them).
  std::size_t displacement_half_width = 1;
  std::size_t displacement_degree = 2;
  double sampling_period = 0;         ///< Ts, the median interval [s]
  double displacement_noise = 0;      ///< s, standard deviation [m]
  double velocity_rms_error = 0;      ///< predicted [m/s]
  double acceleration_rms_error = 0;  ///< predicted [m/s^2]
  /// sum(s s_hat) / sum(s_hat^2) predicted for the exact signal s and its estimate s_hat: what a
  /// coefficient fitted by least squares on s_hat comes out times the true one.
  double velocity_regression_factor = 1;
  double acceleration_regression_factor = 1;

  bool operator==(const DerivativeWindows&) const = default;
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

/// The derivative windows simulate_extended uses on a record (choose_derivative_windows; the
/// backward difference, half width 1, on records too short for the rule).  Fits that simulate the
/// same record many times compute them once and pass them in.
inline DerivativeWindows record_derivative_windows(std::span<const double> time,
                                                   std::span<const double> x) {
  if (x.size() >= 16) return choose_derivative_windows(time, x);
  DerivativeWindows w;
  if (x.size() >= 2) w.sampling_period = (time.back() - time.front()) / double(x.size() - 1);
  return w;
}

/// v and a at every sample by local polynomial fits with the given half widths (>= 1) and degrees
/// (2 or 4; a degree 4 needs a half width >= 2).
void local_polynomial_derivatives(std::span<const double> time, std::span<const double> x,
                                  const DerivativeWindows& windows, std::span<double> velocity,
                                  std::span<double> acceleration);

/// v and a at every sample, windows by the rule.
SampleDerivatives sample_derivatives(std::span<const double> time, std::span<const double> x);

/// The weights of one local polynomial fit (the displacement's, order 0; the velocity's, 1; the
/// acceleration's, 2) at the samples of a record, visited in increasing order: the window of
/// sample k starts at `lo` and its weights w give the estimate as sum_i w_i (x_{lo+i} - x_k)
/// (plus x_k for the value).  The weights come from the sample times alone (each window's normal
/// equations), so the same filter serves any scalar (a delay's shifted record of ceres::Jet
/// carries its derivatives through) and a record streamed sample by sample.  Powers are of
/// (t_i - t_k) / (Ts h), h the half width, so that the normal equations stay well conditioned for
/// long windows.
class LocalPolynomialWeights {
 public:
  LocalPolynomialWeights(std::span<const double> time, const DerivativeWindows& w, int order)
      : time_(time), order_(order) {
    n_ = time.size();
    ts_ = w.sampling_period > 0 ? w.sampling_period : 1.0;
    m_ = order == 0 ? w.displacement_half_width
         : order == 1 ? w.velocity_half_width
                      : w.acceleration_half_width;
    const std::size_t degree = order == 0   ? w.displacement_degree
                               : order == 1 ? w.velocity_degree
                                            : w.acceleration_degree;
    FRICTION_CHECK(degree == 2 || degree == 4, "sample derivatives: degree ", degree,
                   " (2 or 4 expected)");
    width_ = std::min(2 * m_ + 1, n_);
    trivial_ = width_ < degree + 1;
    scale_ = ts_ * static_cast<double>(std::max<std::size_t>(m_, 1));
    factor_ = order == 0   ? 1.0
              : order == 1 ? w.velocity_regression_factor / scale_
                           : 2 * w.acceleration_regression_factor / (scale_ * scale_);
    p_ = static_cast<int>(degree);
    weights_.resize(width_);
  }

  /// Too few samples for the polynomial: nothing to differentiate (the value is x_k, the
  /// derivatives 0).
  bool trivial() const { return trivial_; }
  /// The samples a window reaches on either side of its own: 2m (windows at the record's edges
  /// are shifted inside it).
  std::size_t reach() const { return width_ > 0 ? width_ - 1 : 0; }

  /// `start` plus sum_i w_i (x_i - x_k) over sample k's window (k not below the last call's):
  /// the estimate at sample k, with start x_k for the value and 0 for a derivative.  `x(i)`:
  /// sample i (a whole record's, or a ring's that holds the window).
  template <typename V, class Sample>
  V filter(std::size_t k, V start, const Sample& x) {
    std::size_t lo = 0;
    const double* w = at(k, lo);
    // The value's weights sum to one and the derivatives' to zero: either way the sum over
    // x_i - x_k keeps the digits of a displacement far from the origin.
    for (std::size_t i = lo; i < lo + width_; ++i) start += w[i - lo] * (x(i) - x(k));
    return start;
  }

  /// The weights of sample k's window (k not below the last call's), `lo` its first sample.
  const double* at(std::size_t k, std::size_t& lo) {
    lo = k >= m_ ? k - m_ : 0;
    if (lo + width_ > n_) lo = n_ - width_;
    // A window is uniform when every r_i in it lies within 1e-6 Ts of its centre's (r below):
    // the window's largest and smallest r, kept over the sliding window by two monotone queues,
    // so that the test costs O(1) per sample and not a pass over the window (which cost as much
    // as the filter itself).  "Uniform" within 1e-6 Ts: time stamps written with a few
    // significant digits jitter by 1e-8 Ts and more, and the derivative moves by about the
    // relative jitter.
    for (; next_ < lo + width_; ++next_) {
      while (!largest_.empty() && r(largest_.back()) <= r(next_)) largest_.pop_back();
      while (!smallest_.empty() && r(smallest_.back()) >= r(next_)) smallest_.pop_back();
      largest_.push_back(next_);
      smallest_.push_back(next_);
    }
    while (largest_.front() < lo) largest_.pop_front();
    while (smallest_.front() < lo) smallest_.pop_front();
    const bool uniform = lo + width_ / 2 == k && r(largest_.front()) - r(k) <= 1e-6 * ts_ &&
                         r(k) - r(smallest_.front()) <= 1e-6 * ts_;
    // The weights of a window of uniform spacing Ts centred on its sample: most windows of a
    // regularly sampled record, computed once.
    if (uniform) {
      if (centred_.empty()) {
        centred_.resize(width_);
        solve(lo, k, centred_);
      }
      return centred_.data();
    }
    solve(lo, k, weights_);
    return weights_.data();
  }

 private:
  // r_i = t_i - t_0 - i Ts: the departure of each time stamp from a regular grid.
  double r(std::size_t i) const {
    return time_[i] - time_[0] - static_cast<double>(i) * ts_;
  }

  void solve(std::size_t lo, std::size_t k, std::vector<double>& out_w) const {
    double moments[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    for (std::size_t i = lo; i < lo + width_; ++i) {
      const double tau = (time_[i] - time_[k]) / scale_;
      double q = 1;
      for (int j = 0; j <= 2 * p_; ++j) moments[j] += q, q *= tau;
    }
    Eigen::Matrix<double, 5, 5> g = Eigen::Matrix<double, 5, 5>::Identity();
    for (int a = 0; a <= p_; ++a)
      for (int b = 0; b <= p_; ++b) g(a, b) = moments[a + b];
    Eigen::Matrix<double, 5, 1> e = Eigen::Matrix<double, 5, 1>::Zero();
    e[order_] = 1;
    const Eigen::Matrix<double, 5, 1> c = g.ldlt().solve(e);  // row `order` of G^-1
    for (std::size_t i = lo; i < lo + width_; ++i) {
      const double tau = (time_[i] - time_[k]) / scale_;
      double q = 1, sum = 0;
      for (int j = 0; j <= p_; ++j) sum += c[j] * q, q *= tau;
      out_w[i - lo] = sum * factor_;
    }
  }

  std::span<const double> time_;
  int order_ = 0, p_ = 2;
  std::size_t n_ = 0, m_ = 1, width_ = 0;
  bool trivial_ = false;
  double ts_ = 1, scale_ = 1, factor_ = 1;
  std::vector<double> centred_, weights_;
  std::deque<std::size_t> largest_, smallest_;  // indices into the current window, r monotone
  std::size_t next_ = 0;                        // the first index not yet in the queues
};

/// The local polynomial fits as linear filters on any scalar (LocalPolynomialWeights).
template <typename T>
void apply_local_polynomials(std::span<const double> time, std::span<const T> x,
                             const DerivativeWindows& w, std::span<T> displacement,
                             std::span<T> velocity, std::span<T> acceleration) {
  const std::size_t n = x.size();
  FRICTION_CHECK(time.size() == n, "sample derivatives: time and displacement differ in length");
  for (int order = 0; order <= 2; ++order) {
    std::span<T> out = order == 0 ? displacement : order == 1 ? velocity : acceleration;
    if (out.empty()) continue;
    LocalPolynomialWeights filter(time, w, order);
    if (filter.trivial()) {
      for (std::size_t k = 0; k < n; ++k) out[k] = order == 0 ? x[k] : T(0);
      continue;
    }
    const auto sample = [&](std::size_t i) -> const T& { return x[i]; };
    for (std::size_t k = 0; k < n; ++k)
      out[k] = filter.filter(k, order == 0 ? x[k] : T(0), sample);
  }
}

template <typename T>
void apply_local_derivatives(std::span<const double> time, std::span<const T> x,
                             const DerivativeWindows& w, std::span<T> velocity,
                             std::span<T> acceleration) {
  apply_local_polynomials<T>(time, x, w, {}, velocity, acceleration);
}

/// The displacement the models see: the local polynomial's value at each t_k, with the
/// displacement window of `w` (header comment, "The displacement the models see").
template <typename T>
void apply_local_displacement(std::span<const double> time, std::span<const T> x,
                              const DerivativeWindows& w, std::span<T> displacement) {
  apply_local_polynomials<T>(time, x, w, displacement, {}, {});
}

}  // namespace friction
