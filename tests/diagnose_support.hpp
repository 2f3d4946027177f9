// Synthetic records for the diagnosis tests.  Every effect is written here by its own formula, on
// top of a 4-operator Maxwell Slip system coded in this file (not through extensions.hpp or
// `generate`), so that a test checks the library against an independent statement of the effect.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "friction/record.hpp"

namespace friction::testing {

struct SlipSystem {
  std::vector<double> k{4e4, 3e4, 2e4, 1e4};           // N/m
  std::vector<double> delta{1e-6, 3e-6, 7e-6, 15e-6};  // m
  double f0() const {
    double s = 0;
    for (std::size_t i = 0; i < k.size(); ++i) s += k[i] * delta[i];
    return s;
  }
};

/// The excitation, analytic in t so that velocity and acceleration are exact: two sinusoids under
/// an envelope that alternates large strokes (sliding at many speeds) and small loops (presliding).
struct Excitation {
  double amplitude = 60e-6;  // m
  double f1 = 1.3, f2 = 3.1, phase = 0.4;
  double envelope(double t) const { return 0.55 + 0.45 * std::sin(2 * M_PI * 0.23 * t + phase); }
  double denv(double t) const {
    return 0.45 * 2 * M_PI * 0.23 * std::cos(2 * M_PI * 0.23 * t + phase);
  }
  double ddenv(double t) const {
    return -0.45 * std::pow(2 * M_PI * 0.23, 2) * std::sin(2 * M_PI * 0.23 * t + phase);
  }
  double carrier(double t) const {
    return 0.7 * std::sin(2 * M_PI * f1 * t) + 0.3 * std::sin(2 * M_PI * f2 * t + 1.1);
  }
  double dcarrier(double t) const {
    return 0.7 * 2 * M_PI * f1 * std::cos(2 * M_PI * f1 * t) +
           0.3 * 2 * M_PI * f2 * std::cos(2 * M_PI * f2 * t + 1.1);
  }
  double ddcarrier(double t) const {
    return -0.7 * std::pow(2 * M_PI * f1, 2) * std::sin(2 * M_PI * f1 * t) -
           0.3 * std::pow(2 * M_PI * f2, 2) * std::sin(2 * M_PI * f2 * t + 1.1);
  }
  double x(double t) const { return amplitude * envelope(t) * carrier(t); }
  double a(double t) const {
    return amplitude *
           (ddenv(t) * carrier(t) + 2 * denv(t) * dcarrier(t) + envelope(t) * ddcarrier(t));
  }
};

/// Per-sample threshold scale and clamp asymmetry of the written-out Maxwell Slip recursion.
struct SlipLevel {
  std::function<double(std::size_t k, double t, double x, double v)> scale;  // null: 1
  /// Direction-dependent sliding levels with presliding centred: thresholds scaled by 1 + a d,
  /// d = clamp(F(t-1) / (L(t-1) F0), -1, 1) the previous force relative to its sliding level, so
  /// the level follows the force through presliding (+1 / -1 while sliding in +x / -x).  Note that
  /// clamp bounds [-Delta (1 - a), Delta (1 + a)] would not do: they are the symmetric operator
  /// shifted by a Delta, i.e. exactly an offset of a F0.
  double asymmetry = 0;
};

/// F(t_k) = sum k_i delta_i with delta_i(t+1) = clamp(delta_i + dx, lower, upper) (paper eq. 4),
/// starting from the given deflections.
inline std::vector<double> slip_force(const SlipSystem& s, const std::vector<double>& time,
                                      const std::vector<double>& x, const SlipLevel& level,
                                      std::vector<double> d) {
  std::vector<double> f(x.size());
  double f0 = 0;
  for (std::size_t i = 0; i < s.k.size(); ++i) f0 += s.k[i] * s.delta[i];
  double previous_force = 0, previous_level = 1;
  for (std::size_t k = 0; k < x.size(); ++k) {
    const double dx = k ? x[k] - x[k - 1] : 0.0;
    const double v = k ? dx / (time[k] - time[k - 1]) : 0.0;
    double c = level.scale ? level.scale(k, time[k] - time.front(), x[k], v) : 1.0;
    if (level.asymmetry != 0) {
      const double dir = std::clamp(previous_force / (previous_level * f0), -1.0, 1.0);
      c *= 1 + level.asymmetry * dir;
    }
    double force = 0;
    for (std::size_t i = 0; i < s.k.size(); ++i) {
      d[i] = std::clamp(d[i] + dx, -s.delta[i] * c, s.delta[i] * c);
      force += s.k[i] * d[i];
    }
    f[k] = force;
    previous_force = force;
    previous_level = c;
  }
  return f;
}

inline double rms(const std::vector<double>& v) {
  double s = 0;
  for (double e : v) s += e * e;
  return std::sqrt(s / static_cast<double>(v.size()));
}

/// The part of a record an effect is written into: time, displacement, optional normal force and
/// the force without noise.  `make(magnitude, t0, excitation)` builds it for one record.
struct Clean {
  std::vector<double> time, x, normal, force;
};

inline Clean base_clean(const Excitation& ex, std::size_t n, double t0, double rate = 1000.0) {
  Clean c;
  c.time.resize(n);
  c.x.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    c.time[k] = t0 + static_cast<double>(k) / rate;
    c.x[k] = ex.x(c.time[k]);
  }
  return c;
}

inline Record with_noise(const Clean& c, double sigma, unsigned seed) {
  Record r;
  r.time = c.time;
  r.displacement = c.x;
  r.normal = c.normal;
  r.force = c.force;
  std::mt19937 gen(seed);
  std::normal_distribution<double> noise(0.0, sigma);
  for (double& f : r.force) f += noise(gen);
  r.source = "synthetic";
  return r;
}

/// The effects the tests inject, each by its own formula.
enum class Injected {
  none,
  viscous,
  offset,
  inertia,
  asymmetry,
  stribeck,
  drift,
  delay,
  position,
  normal
};

inline std::string injected_name(Injected e) {
  switch (e) {
    case Injected::none:
      return "none";
    case Injected::viscous:
      return "viscous";
    case Injected::offset:
      return "offset";
    case Injected::inertia:
      return "inertia";
    case Injected::asymmetry:
      return "asymmetry";
    case Injected::stribeck:
      return "stribeck";
    case Injected::drift:
      return "drift";
    case Injected::delay:
      return "delay";
    case Injected::position:
      return "position-dependence";
    case Injected::normal:
      return "normal-load";
  }
  return "";
}

/// One record with effect `e` of size `magnitude` (its main parameter, SI) starting at t0.  The
/// drift restarts at each record (a run-in every experiment repeats); the normal force varies
/// slowly around N0 = 10 N.
inline Clean make_clean(Injected e, double magnitude, const Excitation& ex, std::size_t n,
                        double t0, const SlipSystem& s = {}) {
  Clean c = base_clean(ex, n, t0);
  const std::vector<double> d0(s.k.size(), 0.0);
  SlipLevel level;
  std::vector<double> xdrive = c.x;
  const double f0 = s.f0();
  switch (e) {
    case Injected::asymmetry:
      level.asymmetry = magnitude;
      break;
    case Injected::stribeck: {  // Fs = F0 (1 + magnitude), vs = 0.2 mm/s, q = 2
      level.scale = [=](std::size_t, double, double, double v) {
        return 1.0 + magnitude * std::exp(-(v / 2e-4) * (v / 2e-4));
      };
      break;
    }
    case Injected::drift:
      level.scale = [=](std::size_t, double t, double, double) { return 1.0 + magnitude * t; };
      break;
    case Injected::position:  // amplitude [N] at wavelength 40 um
      level.scale = [=](std::size_t, double, double x, double) {
        return 1.0 + magnitude / f0 * std::sin(2 * M_PI * x / 40e-6 + 0.5);
      };
      break;
    case Injected::normal: {  // friction coefficient = magnitude, N0 = f0 / magnitude
      const double n0 = f0 / magnitude;
      c.normal.resize(n);
      for (std::size_t k = 0; k < n; ++k)
        c.normal[k] = n0 * (1.0 + 0.35 * std::sin(2 * M_PI * 0.31 * c.time[k] + 0.2));
      const std::vector<double> normal = c.normal;
      level.scale = [=](std::size_t k, double, double, double) { return normal[k] / n0; };
      break;
    }
    case Injected::delay:  // the force is the system's response to x(t - D)
      for (std::size_t k = 0; k < n; ++k) xdrive[k] = ex.x(c.time[k] - magnitude);
      break;
    default:
      break;
  }
  c.force = slip_force(s, c.time, xdrive, level, d0);
  for (std::size_t k = 0; k < n; ++k) {
    const double v = k ? (c.x[k] - c.x[k - 1]) / (c.time[k] - c.time[k - 1]) : 0.0;
    if (e == Injected::viscous) c.force[k] += magnitude * v;
    if (e == Injected::offset) c.force[k] += magnitude;
    if (e == Injected::inertia) c.force[k] += magnitude * ex.a(c.time[k]);
  }
  return c;
}

}  // namespace friction::testing
