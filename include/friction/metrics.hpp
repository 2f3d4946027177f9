// Errors of a free-run simulation against the measured force (methods.md section 6).
//
// The primary figure is the paper's normalised error
//
//     RSS/SSS % = 100 * sum_t (F(t) - Fhat(t))^2 / sum_t F(t)^2
//
// where Fhat is the model driven by displacement alone (never by the measured force), from an
// initial state estimated from the record itself, and every sample counts.  RMS [N], max |e| [N]
// and R^2 = 1 - RSS / sum (F - mean F)^2 are reported beside it.  Note that SSS is the sum of
// squares of F itself, not of its deviation from the mean: RSS/SSS and R^2 are different
// normalisations and both are kept.
//
// The floor any model can reach is the measurement noise.  For white noise of standard deviation
// sigma on F, RSS/SSS cannot be expected below 100 * N sigma^2 / sum F^2
// (`noise_floor_rss_sss_percent`).  sigma itself is estimated by
// `estimate_white_noise_sigma`: the d-th order difference of white noise has variance
// C(2d, d) sigma^2, while a signal that is smooth between a few kinks (reversals, saturations)
// contributes little to high-order differences except at the kinks.  The median absolute
// deviation of the differences ignores those few outliers, so
//
//     sigma ~= 1.4826 * MAD(nabla^d F) / sqrt(C(2d, d)).
//
// It overestimates sigma when the signal changes a lot within d samples (coarse sampling), so it
// is an upper estimate of the floor, never a target to tune against.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <span>
#include <vector>

#include "friction/error.hpp"

namespace friction {

/// Error figures of a simulated force against the measured one (methods.md section 6).
struct ErrorMetrics {
  double rss_sss_percent = 0;  ///< 100 * sum e^2 / sum F^2 [%]
  double rms = 0;              ///< sqrt(mean e^2) [N]
  double max_abs = 0;          ///< max |e| [N]
  double r_squared = 0;        ///< 1 - sum e^2 / sum (F - mean F)^2
  double rss = 0;              ///< sum e^2 [N^2]
  std::size_t samples = 0;     ///< samples counted (all of them)
};

/// Errors of `simulated` against `measured`; both must have the same, non-zero length and the
/// measured force must not be identically zero.
inline ErrorMetrics compute_errors(std::span<const double> measured,
                                   std::span<const double> simulated) {
  FRICTION_CHECK(measured.size() == simulated.size() && !measured.empty(),
                 "compute_errors: measured (", measured.size(), ") and simulated (",
                 simulated.size(), ") must have the same non-zero length");
  const std::size_t n = measured.size();
  double rss = 0, sss = 0, mean = 0, max_abs = 0;
  for (std::size_t t = 0; t < n; ++t) {
    const double e = measured[t] - simulated[t];
    rss += e * e;
    sss += measured[t] * measured[t];
    mean += measured[t];
    max_abs = std::max(max_abs, std::abs(e));
  }
  mean /= static_cast<double>(n);
  double centred = 0;
  for (double f : measured) centred += (f - mean) * (f - mean);
  FRICTION_CHECK(sss > 0.0, "compute_errors: the measured force is identically zero");
  ErrorMetrics m;
  m.rss = rss;
  m.samples = n;
  m.rss_sss_percent = 100.0 * rss / sss;
  m.rms = std::sqrt(rss / static_cast<double>(n));
  m.max_abs = max_abs;
  m.r_squared = centred > 0.0 ? 1.0 - rss / centred
                              : (rss == 0.0 ? 1.0 : -std::numeric_limits<double>::infinity());
  return m;
}

/// Robust estimate of the standard deviation of white noise on `signal` from the median absolute
/// deviation of its `order`-th differences (see the header comment).  Returns 0 for a signal
/// shorter than order + 2 samples.
inline double estimate_white_noise_sigma(std::span<const double> signal, int order = 4) {
  FRICTION_CHECK(order >= 1 && order <= 12, "estimate_white_noise_sigma: order ", order,
                 " must be in 1..12");
  const std::size_t d = static_cast<std::size_t>(order);
  if (signal.size() < d + 2) return 0.0;
  std::vector<double> diff(signal.begin(), signal.end());
  for (std::size_t k = 0; k < d; ++k) {
    for (std::size_t t = 0; t + 1 < diff.size(); ++t) diff[t] = diff[t + 1] - diff[t];
    diff.pop_back();
  }
  auto median = [](std::vector<double>& v) {
    const std::size_t mid = v.size() / 2;
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
    return v[mid];
  };
  const double centre = median(diff);
  for (double& v : diff) v = std::abs(v - centre);
  const double mad = median(diff);
  double binom = 1.0;  // C(2d, d)
  for (std::size_t k = 1; k <= d; ++k)
    binom = binom * static_cast<double>(d + k) / static_cast<double>(k);
  return 1.4826 * mad / std::sqrt(binom);
}

/// The q-quantile of `v` by nearest rank below (element floor(q (n - 1)) of the sorted values, q
/// clamped to [0, 1]); 0 for an empty vector.  Takes a copy: a partial sort reorders it.
inline double nearest_rank_quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const auto k =
      static_cast<std::size_t>(std::clamp(q, 0.0, 1.0) * static_cast<double>(v.size() - 1));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

/// Sum of squares of a signal (the SSS of RSS/SSS, or an RSS of a residual).
inline double sum_of_squares(std::span<const double> v) {
  double s = 0;
  for (double e : v) s += e * e;
  return s;
}

/// RSS/SSS [%] that white noise of standard deviation `sigma` alone gives on `force`:
/// 100 * N sigma^2 / sum F^2, the floor a perfect model reaches on a noisy record.
inline double noise_floor_rss_sss_percent(std::span<const double> force, double sigma) {
  double sss = 0;
  for (double f : force) sss += f * f;
  FRICTION_CHECK(sss > 0.0, "noise_floor_rss_sss_percent: the force is identically zero");
  return 100.0 * static_cast<double>(force.size()) * sigma * sigma / sss;
}

}  // namespace friction
