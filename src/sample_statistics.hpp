// Order statistics of a sample, and the error measure every stage reports.  Private to the
// library: one definition instead of a copy in each source file that needs one.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

#include "friction/error.hpp"

namespace friction::statistics {

/// The median: the mean of the two middle values when the count is even; 0 for no values (a
/// robust spread of nothing is nothing).
inline double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const std::size_t n = v.size();
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(n / 2);
  std::nth_element(v.begin(), mid, v.end());
  if (n % 2 == 1) return *mid;
  const double upper = *mid;
  const double lower = *std::max_element(v.begin(), mid);
  return 0.5 * (lower + upper);
}

/// The upper median, element n/2 of the sorted values: always one of the values, which the
/// starting-value rules want (a level that was measured, not the mean of two).
inline double upper_median(std::vector<double> v) {
  FRICTION_ASSERT(!v.empty());
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

/// RSS/SSS in percent: 100 * rss / sum F^2, the paper's error measure.
inline double rss_sss_percent(const std::vector<double>& force, double rss) {
  double s = 0;
  for (double f : force) s += f * f;
  return 100.0 * rss / s;
}

}  // namespace friction::statistics
