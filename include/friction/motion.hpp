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
//
// Turns between samples.  Where the motion reverses between two samples, the sampled displacement
// misses the extremum: x_k is at most a T^2/8 short of it (a the acceleration at the turn), and a
// Maxwell Slip operator that was sliding takes its new anchor at the sampled extreme instead of
// the true one.  Its force then stays off by k_i times the miss, with the sign of the motion,
// until it slides again.  At 834 Hz with a 13 Hz stroke (a study record: 11 operators, Fc 0.1 N)
// that error was 3e-4 N RMS, twice the force noise, and it looks like viscous friction (the
// viscous coefficient came out 4.6 % high, 24.5 against 23.4 N s/m, with exact, noise-free data).
// So an off-line run passes through the turn: at a sample i where the increments change sign, the
// parabola through x_{i-1}, x_i, x_{i+1} has its vertex within half a sample of t_i, on one side
// of it; the interval on that side is stepped as x_{k-1} -> x_turn -> x_k (Motion::turn, filled by
// motion_at and every record-level run; zero when the interval holds no turn, or two, which is
// noise).  The parabola is in sample index, not time, so that routines given the displacement
// alone (slip_regression.hpp, initial_state.hpp) find the same turns.  A controller's causal step
// cannot see x_{k+1} and steps with turn = 0: after a reversal its force differs from the off-line
// model's by at most sum_i k_i a T^2 / 8 until the operators slide again (README, Signals).  Only
// the Maxwell Slip operators (and the DNLRX operators built on them) pass through the turn: LuGre
// and GMS integrate a rate equation over the interval, for which the missed extremum is a
// second-order error in the state, not a lost anchor.
//
// The level at the turn.  The step to the extremum happens while the motion slows to a stop, and a
// level that depends on the speed is not the sample's there: a Stribeck curve is at its static
// level at the turn and well below it at t_k, after the reversal.  Clamped at the sample's level,
// every operator that slid into the reversal was cut down to it at the turn, a force drop at each
// reversal that the true system does not have (a study record, static level 2.2 times the Coulomb
// level, exponent 0.52: with the true parameters 0.0018 % of the validation force against the
// 0.0002 % of the same recursion clamped at the static level, exact noise-free data; the told fit
// validated 1.33 times the floor).  So the step to the turn is clamped at Motion::turn_level, the
// level with the motion at rest at the extremum (extensions.hpp computes it), and the step back at
// the sample's level.
#pragma once

#include <cstddef>
#include <span>

#include "friction/scalar.hpp"

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
  /// The increment from x_{k-1} to an extremum passed inside the interval (header: Turns between
  /// samples); 0 when there is none.  A Maxwell Slip operator steps by `turn`, then by dx - turn.
  T turn = T(0);
  /// The slip-force level at that extremum, which bounds the step by `turn` (header: Turns between
  /// samples); 0: `level`.  A level that depends on the speed is not the sample's there: the
  /// motion stands still at the turn (a Stribeck curve is at its static level).
  T turn_level = T(0);
};

namespace detail {
/// At a reversal at sample i (the increments on either side of x_i of opposite sign): the vertex
/// of the parabola through x_{i-1}, x_i, x_{i+1}, its offset u from i in samples (|u| < 1/2) and
/// its value.  False when sample i is no reversal.  `x(i)`: sample i of a record of n samples.
template <typename T, class Sample>
bool reversal_vertex(const Sample& x, std::size_t n, std::size_t i, double& u, T& peak) {
  if (i == 0 || i + 1 >= n) return false;
  // The test on the values first: most samples are no reversal, and a Jet's difference is its
  // values' difference.
  const double before = value_of(x(i)) - value_of(x(i - 1));
  const double after = value_of(x(i + 1)) - value_of(x(i));
  if (!(before * after < 0.0)) return false;
  const T d1 = x(i) - x(i - 1), d2 = x(i + 1) - x(i);
  const T a = (d2 - d1) * 0.5, b = (d2 + d1) * 0.5;  // x(i + u) = x_i + b u + a u^2
  u = -value_of(b) / (2.0 * value_of(a));
  peak = x(i) - b * b / (a * 4.0);
  return true;
}

/// turn_increment on samples given by `x(i)` (samples k - 2 .. k + 1 are read): what a record
/// streamed through a short buffer uses.
template <typename T, class Sample>
T turn_increment_at(const Sample& x, std::size_t n, std::size_t k) {
  if (k == 0 || k >= n) return T(0);
  double u_here = 0.0, u_before = 0.0;
  T at_here(0), at_before(0);
  const bool here = reversal_vertex<T>(x, n, k, u_here, at_here) && u_here < 0.0;
  const bool before = reversal_vertex<T>(x, n, k - 1, u_before, at_before) && u_before > 0.0;
  if (here == before) return T(0);
  return (here ? at_here : at_before) - x(k - 1);
}
}  // namespace detail

/// Motion::turn of the interval (t_{k-1}, t_k] of displacement x (header: Turns between samples).
template <typename T>
T turn_increment(std::span<const T> x, std::size_t k) {
  return detail::turn_increment_at<T>([&](std::size_t i) -> const T& { return x[i]; }, x.size(),
                                      k);
}

/// The Motion of sample k of a record (displacement x at `time`), with slip-force level `level`:
/// the increment from sample k-1 and the backward-difference velocity above; sample 0 is the
/// initial state (dx = v = dt = 0).  The turn inside the interval, if any, comes with it.  Every
/// routine that steps a model over a record builds its motions here, so that simulation,
/// identification and tests see the same numbers.
template <typename T>
Motion<T> motion_at(std::span<const double> time, std::span<const T> x, std::size_t k,
                    T level = T(1)) {
  Motion<T> m{T(0), T(0), T(0), level};
  m.turn_level = level;
  if (k > 0) {
    const double dt = time[k] - time[k - 1];
    m.dx = x[k] - x[k - 1];
    m.dt = T(dt);
    m.velocity = m.dx / dt;
    m.turn = turn_increment(x, k);
  }
  return m;
}

}  // namespace friction
