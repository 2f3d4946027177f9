// Scalar helpers that work for `double` and for automatic-differentiation scalars alike.
//
// Every model is a class template on its scalar `T`, so that Ceres' `Jet` (or any type with the
// usual arithmetic, comparisons against `T` and the functions found by argument-dependent lookup:
// abs, exp, log, pow, sqrt) flows through the same code that a controller runs with `double`.
// Branches compare values only (a Jet compares by its value part), so a piecewise model such as the
// elasto-slide operator differentiates as the branch that is taken, which is what the
// identification needs.
#pragma once

#include <cmath>
#include <type_traits>

namespace friction {

/// Value part of a scalar: the double itself, or the `.a` member of a Jet (recursively).
template <typename T>
constexpr double value_of(const T& x) {
  if constexpr (std::is_arithmetic_v<T>) {
    return static_cast<double>(x);
  } else {
    return value_of(x.a);
  }
}

/// Whether a scalar carries a nonzero derivative part (never, for a double).
template <typename T>
bool has_derivative(const T& x) {
  if constexpr (std::is_arithmetic_v<T>) {
    return false;
  } else {
    if (has_derivative(x.a)) return true;
    for (int i = 0; i < x.v.size(); ++i)
      if (x.v[i] != 0) return true;
    return false;
  }
}

/// sgn(x) in {-1, 0, 1}, as a plain number: its derivative is zero almost everywhere.
template <typename T>
constexpr double sign_of(const T& x) {
  const double v = value_of(x);
  return (v > 0.0) - (v < 0.0);
}

/// min(max(x, lo), hi) for lo <= hi, keeping the derivative of the branch taken.
template <typename T>
constexpr T clamp(const T& x, const T& lo, const T& hi) {
  if (x > hi) return hi;
  if (x < lo) return lo;
  return x;
}

/// clamp(x, minus_down * limit, up * limit): a slip limit's product formed only when it binds.
/// clamp compares values, and the value of a product of Jets is the product of their values, so
/// the result is clamp's with both limits formed, to the bit; with Jets (a fit's derivatives) the
/// products of the limits not taken were most of a Maxwell Slip step's arithmetic.
template <typename T>
constexpr T clamp_to_limits(const T& x, const T& minus_down, const T& up, const T& limit) {
  const double v = value_of(x), l = value_of(limit);
  if (v > value_of(up) * l) return up * limit;
  if (v < value_of(minus_down) * l) return minus_down * limit;
  return x;
}

/// |x| for double and Jets (Jets find their own `abs` by ADL).
template <typename T>
T abs_of(const T& x) {
  using std::abs;
  return abs(x);
}

}  // namespace friction
