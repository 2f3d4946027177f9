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

/// The excitations, analytic in t so that velocity and acceleration are exact.  Four families:
///  * envelope (the default): two sinusoids under an envelope that alternates large strokes
///    (sliding at many speeds) and small loops (presliding);
///  * strokes: strokes at a few constant speeds in alternating directions, with a rest and a small
///    presliding loop between strokes.  The velocity is a sum of smooth steps,
///        v(t) = u_0 + sum_j (u_j - u_{j-1}) H((t - s_j) / w),   H(z) = (1 + tanh z) / 2,
///    so x(t) = u_0 (t - s_0) + sum_j (u_j - u_{j-1}) w G((t - s_j) / w) with
///    G(z) = (z + ln cosh z + ln 2) / 2 (0 long before the step, z long after it) and
///    a(t) = sum_j (u_j - u_{j-1}) / (2 w) sech^2((t - s_j) / w): the travel of each piece is
///    exactly u_j times its duration;
///  * sine: one sinusoid of amplitude `amplitude` at f1 (a single frequency);
///  * one_way: x = V t + B sin(2 pi f1 t), V = `speed`, B = `amplitude`, with B 2 pi f1 < V, so the
///    body slides in +x only and its speed ripples at a single frequency.
struct Excitation {
  enum class Kind { envelope, strokes, sine, one_way };
  Kind kind = Kind::envelope;
  double amplitude = 60e-6;  // m
  double f1 = 1.3, f2 = 3.1, phase = 0.4;
  double speed = 0.0;  // one_way: V [m/s]
  // strokes: step times s_j, velocities u_j after each step, width w.
  std::vector<double> step_time, step_velocity;
  double width = 4e-3;

  /// Strokes of `stroke` metres at the given speeds (their order shuffled by `seed`), directions
  /// alternating, each followed by a rest of `rest` s and a presliding loop of +-`loop` metres at
  /// `loop_speed`, repeated from t = -1 s to t = `until` s.
  static Excitation strokes(std::vector<double> speeds, unsigned seed, double stroke = 80e-6,
                            double until = 12.0, double loop = 4e-6, double loop_speed = 1e-4,
                            double rest = 0.05) {
    Excitation e;
    e.kind = Kind::strokes;
    std::mt19937 gen(seed);
    double t = -1.0, direction = (seed % 2) ? 1.0 : -1.0;
    auto piece = [&](double velocity, double duration) {
      e.step_time.push_back(t);
      e.step_velocity.push_back(velocity);
      t += duration;
    };
    piece(0.0, 0.2);
    while (t < until) {
      std::shuffle(speeds.begin(), speeds.end(), gen);
      for (double s : speeds) {
        piece(direction * s, stroke / s);
        piece(0.0, rest);
        piece(-direction * loop_speed, loop / loop_speed);
        piece(direction * loop_speed, loop / loop_speed);
        piece(0.0, rest);
        direction = -direction;
      }
    }
    piece(0.0, 1.0);
    return e;
  }
  static Excitation sine(double amplitude, double frequency) {
    Excitation e;
    e.kind = Kind::sine;
    e.amplitude = amplitude;
    e.f1 = frequency;
    return e;
  }
  static Excitation one_way(double speed, double ripple_amplitude, double frequency) {
    Excitation e;
    e.kind = Kind::one_way;
    e.speed = speed;
    e.amplitude = ripple_amplitude;
    e.f1 = frequency;
    return e;
  }

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
  double x(double t) const {
    switch (kind) {
      case Kind::envelope:
        return amplitude * envelope(t) * carrier(t);
      case Kind::sine:
        return amplitude * std::sin(2 * M_PI * f1 * t);
      case Kind::one_way:
        return speed * t + amplitude * std::sin(2 * M_PI * f1 * t);
      case Kind::strokes: {
        double x = 0, previous = 0;
        for (std::size_t j = 0; j < step_time.size(); ++j) {
          const double z = (t - step_time[j]) / width;
          const double g = 0.5 * (z + std::abs(z) + std::log1p(std::exp(-2 * std::abs(z))));
          x += (step_velocity[j] - previous) * width * g;
          previous = step_velocity[j];
        }
        return x;
      }
    }
    return 0;
  }
  double v(double t) const {
    switch (kind) {
      case Kind::envelope:
        return amplitude * (denv(t) * carrier(t) + envelope(t) * dcarrier(t));
      case Kind::sine:
        return amplitude * 2 * M_PI * f1 * std::cos(2 * M_PI * f1 * t);
      case Kind::one_way:
        return speed + amplitude * 2 * M_PI * f1 * std::cos(2 * M_PI * f1 * t);
      case Kind::strokes: {
        double v = 0, previous = 0;
        for (std::size_t j = 0; j < step_time.size(); ++j) {
          v += (step_velocity[j] - previous) * 0.5 * (1 + std::tanh((t - step_time[j]) / width));
          previous = step_velocity[j];
        }
        return v;
      }
    }
    return 0;
  }
  double a(double t) const {
    switch (kind) {
      case Kind::envelope:
        return amplitude *
               (ddenv(t) * carrier(t) + 2 * denv(t) * dcarrier(t) + envelope(t) * ddcarrier(t));
      case Kind::sine:
      case Kind::one_way:
        return -amplitude * std::pow(2 * M_PI * f1, 2) * std::sin(2 * M_PI * f1 * t);
      case Kind::strokes: {
        double a = 0, previous = 0;
        for (std::size_t j = 0; j < step_time.size(); ++j) {
          const double c = std::cosh((t - step_time[j]) / width);
          a += (step_velocity[j] - previous) * 0.5 / width / (c * c);
          previous = step_velocity[j];
        }
        return a;
      }
    }
    return 0;
  }
};

/// Per-sample threshold scale and clamp asymmetry of the written-out Maxwell Slip recursion.
struct SlipLevel {
  std::function<double(std::size_t k, double t, double x, double v)> scale;  // null: 1
  /// Direction-dependent slip limits: clamp bounds [-Delta c (1 - a), Delta c (1 + a)], an
  /// asperity whose friction depends on the direction of slip.  At a constant level c they are the
  /// symmetric operator shifted by a Delta c, i.e. exactly an offset of a F0 (the diagnosis must
  /// call the two ambiguous there); a changing level separates them.
  double asymmetry = 0;
};

/// F(t_k) = sum k_i delta_i with delta_i(t+1) = clamp(delta_i + dx, lower, upper) (paper eq. 4),
/// starting from the given deflections.  The level scale sees the drive's exact velocity at t_k
/// (`velocity`; empty: the interval velocity dx/dt, for callers without an analytic motion), and an
/// asymmetry a makes the slip limits direction-dependent, [-(1 - a) c Delta_i, (1 + a) c Delta_i]:
/// an asperity whose friction depends on the direction of slip.
inline std::vector<double> slip_force(const SlipSystem& s, const std::vector<double>& time,
                                      const std::vector<double>& x, const SlipLevel& level,
                                      std::vector<double> d,
                                      const std::vector<double>& velocity = {}) {
  std::vector<double> f(x.size());
  for (std::size_t k = 0; k < x.size(); ++k) {
    const double dx = k ? x[k] - x[k - 1] : 0.0;
    const double v = !velocity.empty() ? velocity[k] : k ? dx / (time[k] - time[k - 1]) : 0.0;
    const double c = level.scale ? level.scale(k, time[k] - time.front(), x[k], v) : 1.0;
    double force = 0;
    for (std::size_t i = 0; i < s.k.size(); ++i) {
      d[i] = std::clamp(d[i] + dx, -s.delta[i] * c * (1 - level.asymmetry),
                        s.delta[i] * c * (1 + level.asymmetry));
      force += s.k[i] * d[i];
    }
    f[k] = force;
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
  normal,
  frictional_lag
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
    case Injected::frictional_lag:
      return "frictional-lag";
  }
  return "";
}

/// One hidden effect: its main parameter `magnitude` (SI) and, for frictional-lag, the lag time.
struct Injection {
  Injected effect = Injected::none;
  double magnitude = 0;
  double lag_time = 0.02;  // s, frictional-lag only
};

/// Default lag time of the injected frictional lag [s].
inline constexpr double kDefaultLagTime = 0.02;

/// The velocity a first-order lag with time constant tau makes of the drive's velocity,
///     tau dv_l/dt = v(t) - v_l,
/// integrated by classical Runge-Kutta on the analytic v(t) with 20 sub-steps per sample, started
/// 12 tau before the first sample (the motion has been going on: the start is forgotten by then).
inline std::vector<double> lagged_velocity(const std::function<double(double)>& v,
                                           const std::vector<double>& time, double tau) {
  std::vector<double> out(time.size());
  if (time.empty()) return out;
  const double ts = time.size() > 1 ? time[1] - time[0] : 1e-3;
  const double h = ts / 20.0;
  double t = time.front() - 12.0 * tau;
  double vl = v(t);
  auto rhs = [&](double tt, double y) { return (v(tt) - y) / tau; };
  auto advance_to = [&](double target) {
    while (t < target - 1e-15) {
      const double step = std::min(h, target - t);
      const double k1 = rhs(t, vl), k2 = rhs(t + step / 2, vl + step / 2 * k1),
                   k3 = rhs(t + step / 2, vl + step / 2 * k2), k4 = rhs(t + step, vl + step * k3);
      vl += step / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
      t += step;
    }
  };
  for (std::size_t k = 0; k < time.size(); ++k) {
    advance_to(time[k]);
    out[k] = vl;
  }
  return out;
}

/// A record with the given hidden effects (each of size `magnitude`, its main parameter, SI)
/// starting at t0.  The drift restarts at each record (a run-in every experiment repeats); the
/// normal force varies slowly around N0 = F0 / mu.  Level effects scale the thresholds (their
/// factors multiply); added terms are summed.  A delay shifts the whole system (every term sees
/// x(t - D)).  Frictional lag is a viscous force magnitude * v_l with v_l the velocity through a
/// first-order lag of time constant `lag_time`, written with the analytic velocity of the drive.
/// Velocities are the drive's exact ones at t_k, never a difference of the samples.
inline Clean make_clean(const std::vector<Injection>& effects, const Excitation& ex, std::size_t n,
                        double t0, const SlipSystem& s = {}) {
  Clean c = base_clean(ex, n, t0);
  const std::vector<double> d0(s.k.size(), 0.0);
  SlipLevel level;
  std::vector<std::function<double(std::size_t, double, double, double)>> scales;
  double shift = 0;
  for (const Injection& in : effects)
    if (in.effect == Injected::delay) shift = in.magnitude;
  std::vector<double> xdrive = c.x;
  if (shift != 0)
    for (std::size_t k = 0; k < n; ++k) xdrive[k] = ex.x(c.time[k] - shift);
  const double f0 = s.f0();
  for (const Injection& in : effects) {
    const double magnitude = in.magnitude;
    switch (in.effect) {
      case Injected::asymmetry:
        level.asymmetry = magnitude;
        break;
      case Injected::stribeck:  // Fs = F0 (1 + magnitude), vs = 0.2 mm/s, q = 2
        scales.push_back([=](std::size_t, double, double, double v) {
          return 1.0 + magnitude * std::exp(-(v / 2e-4) * (v / 2e-4));
        });
        break;
      case Injected::drift:
        scales.push_back(
            [=](std::size_t, double t, double, double) { return 1.0 + magnitude * t; });
        break;
      case Injected::position:  // amplitude [N] at wavelength 40 um
        scales.push_back([=](std::size_t, double, double x, double) {
          return 1.0 + magnitude / f0 * std::sin(2 * M_PI * x / 40e-6 + 0.5);
        });
        break;
      case Injected::normal: {  // friction coefficient = magnitude, N0 = f0 / magnitude
        const double n0 = f0 / magnitude;
        c.normal.resize(n);
        for (std::size_t k = 0; k < n; ++k)
          c.normal[k] = n0 * (1.0 + 0.35 * std::sin(2 * M_PI * 0.31 * c.time[k] + 0.2));
        const std::vector<double> normal = c.normal;
        scales.push_back([=](std::size_t k, double, double, double) { return normal[k] / n0; });
        break;
      }
      default:
        break;
    }
  }
  if (!scales.empty())
    level.scale = [scales](std::size_t k, double t, double x, double v) {
      double product = 1.0;
      for (const auto& f : scales) product *= f(k, t, x, v);
      return product;
    };
  std::vector<double> vdrive(n);
  for (std::size_t k = 0; k < n; ++k) vdrive[k] = ex.v(c.time[k] - shift);
  c.force = slip_force(s, c.time, xdrive, level, d0, vdrive);
  for (const Injection& in : effects) {
    if (in.effect == Injected::frictional_lag) {
      const std::vector<double> vl =
          lagged_velocity([&](double t) { return ex.v(t - shift); }, c.time, in.lag_time);
      for (std::size_t k = 0; k < n; ++k) c.force[k] += in.magnitude * vl[k];
    }
    for (std::size_t k = 0; k < n; ++k) {
      const double v = vdrive[k];  // the drive's exact velocity at t_k (no library convention)
      if (in.effect == Injected::viscous) c.force[k] += in.magnitude * v;
      if (in.effect == Injected::offset) c.force[k] += in.magnitude;
      if (in.effect == Injected::inertia) c.force[k] += in.magnitude * ex.a(c.time[k] - shift);
    }
  }
  return c;
}

/// One hidden effect (see above).
inline Clean make_clean(Injected e, double magnitude, const Excitation& ex, std::size_t n,
                        double t0, const SlipSystem& s = {}) {
  return make_clean(std::vector<Injection>{{e, magnitude, kDefaultLagTime}}, ex, n, t0, s);
}

/// RMS of the force change an effect makes on n samples from t = 0: against the plain system,
/// except for the frictional lag, whose own part is the lagged minus the unlagged viscous force.
inline double effect_contribution(Injected e, double m, double lag, const Excitation& ex,
                                  std::size_t n) {
  const Clean reference = e == Injected::frictional_lag
                              ? make_clean({{Injected::viscous, m, 0}}, ex, n, 0.0)
                              : make_clean(Injected::none, 0, ex, n, 0.0);
  const Clean w = make_clean({{e, m, lag}}, ex, n, 0.0);
  std::vector<double> d(n);
  for (std::size_t k = 0; k < n; ++k) d[k] = w.force[k] - reference.force[k];
  return rms(d);
}

/// The magnitude (from `nominal`) whose contribution is `ratio` x `sigma`.
inline double magnitude_for_ratio(Injected e, double nominal, double ratio, double sigma,
                                  double lag, const Excitation& ex, std::size_t n) {
  double m = nominal;
  for (int it = 0; it < 4; ++it) m *= ratio * sigma / effect_contribution(e, m, lag, ex, n);
  return m;
}

}  // namespace friction::testing
