// Synthetic records for the identification tests: a known Maxwell Slip system driven by a
// presliding + sliding excitation (decaying sinusoids, then strokes), plus white force noise.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <random>
#include <vector>

#include "friction/maxwell_slip.hpp"
#include "friction/record.hpp"
#include "friction/simulate.hpp"

namespace friction::testing {

inline MaxwellSlipParameters<double> four_operator_system() {
  return {{4e4, 3e4, 2e4, 1e4}, {1e-6, 3e-6, 7e-6, 15e-6}};
}

/// Displacement: `n` samples at 1 kHz.  The first 60 % are sinusoids whose amplitude decays
/// from `amplitude` to a tenth of it (nested presliding loops), the rest strokes of full
/// amplitude at two speeds (sliding).  `variant` changes frequencies and phases.
inline std::vector<double> excitation(std::size_t n, double amplitude, int variant,
                                      std::size_t fade_in = 0) {
  std::vector<double> x(n);
  const double f1 = variant == 0 ? 7.0 : 9.5, f2 = variant == 0 ? 17.0 : 23.0;
  const std::size_t n1 = n * 6 / 10;
  for (std::size_t k = 0; k < n1; ++k) {
    const double u = static_cast<double>(k) / static_cast<double>(n1);
    const double env = amplitude * std::pow(0.1, u);
    x[k] = env *
           (0.8 * std::sin(2 * M_PI * f1 * u + 0.3 * variant) + 0.2 * std::sin(2 * M_PI * f2 * u));
  }
  // Strokes: triangle waves between -amplitude and +amplitude, slow then fast.
  double pos = x[n1 - 1];
  double dir = 1.0;
  for (std::size_t k = n1; k < n; ++k) {
    const bool fast = (k - n1) > (n - n1) / 2;
    const double speed = amplitude * (fast ? 0.02 : 0.008) * (variant == 0 ? 1.0 : 1.3);
    pos += dir * speed;
    if (pos > amplitude) pos = amplitude, dir = -1.0;
    if (pos < -amplitude) pos = -amplitude, dir = 1.0;
    x[k] = pos;
  }
  // Optional slow start: the motion grows from rest over `fade_in` samples.
  for (std::size_t k = 0; k < std::min(fade_in, n); ++k) {
    const double w = static_cast<double>(k) / static_cast<double>(fade_in);
    x[k] *= w * w;
  }
  return x;
}

/// Record of the system from a given initial state, with white noise of std `sigma` on F.
/// `noise` receives the noise realisation.
inline Record synthetic_record(const MaxwellSlipParameters<double>& p, std::size_t n,
                               double amplitude, int variant, double sigma, unsigned seed,
                               const std::vector<double>& initial, std::vector<double>* noise,
                               std::size_t fade_in = 0) {
  Record r;
  r.displacement = excitation(n, amplitude, variant, fade_in);
  r.time.resize(n);
  for (std::size_t k = 0; k < n; ++k) r.time[k] = 1e-3 * static_cast<double>(k);
  MaxwellSlip<double> model(p);
  model.reset(std::span<const double>(initial));
  r.force =
      simulate(model, std::span<const double>(r.time), std::span<const double>(r.displacement));
  std::mt19937 gen(seed);
  std::normal_distribution<double> normal(0.0, sigma);
  if (noise) noise->resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const double e = normal(gen);
    r.force[k] += e;
    if (noise) (*noise)[k] = e;
  }
  return r;
}

inline double sum_of_squares(const std::vector<double>& v) {
  double s = 0;
  for (double e : v) s += e * e;
  return s;
}

}  // namespace friction::testing
