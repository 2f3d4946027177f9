// Scales derived from the data and the information criterion (identification.hpp).
#include "friction/identification.hpp"

#include <algorithm>
#include <cmath>

#include "friction/error.hpp"
#include "friction/record.hpp"

namespace friction {

double largest_travel(std::span<const double> x) {
  FRICTION_CHECK(!x.empty(), "largest_travel: empty record");
  const auto [lo, hi] = std::minmax_element(x.begin(), x.end());
  return 0.5 * (*hi - *lo);
}

double displacement_resolution(std::span<const double> x) {
  FRICTION_CHECK(x.size() >= 2, "displacement_resolution: the record needs two samples");
  const double range = 2.0 * largest_travel(x);
  FRICTION_CHECK(range > 0.0, "displacement_resolution: the displacement never changes");
  const double floor = 1e-9 * range;
  std::vector<double> steps;
  for (std::size_t k = 1; k < x.size(); ++k) {
    const double d = std::abs(x[k] - x[k - 1]);
    if (d > floor) steps.push_back(d);
  }
  if (steps.empty()) return floor;
  std::sort(steps.begin(), steps.end());
  const double q = steps.front();
  // Quantised: (almost) every increment is an integer multiple of the smallest one.
  std::size_t on_grid = 0;
  for (double d : steps) {
    const double r = d / q;
    if (std::abs(r - std::round(r)) < 0.02) ++on_grid;
  }
  if (on_grid >= steps.size() - steps.size() / 100) return q;
  return std::max(floor, steps[steps.size() / 100]);
}

double record_resolution(const Record& r) {
  const std::vector<double>& x = r.measured_displacement;
  if (x.size() < 2 || !(largest_travel(x) > 0.0)) return 0.0;
  return displacement_resolution(x);
}

std::vector<std::size_t> turning_points(std::span<const double> x, double h) {
  std::vector<std::size_t> turns{0};
  int dir = 0;
  std::size_t ext = 0;
  for (std::size_t t = 1; t < x.size(); ++t) {
    if (dir == 0) {
      if (x[t] - x[0] > h)
        dir = +1, ext = t;
      else if (x[0] - x[t] > h)
        dir = -1, ext = t;
    } else if (dir > 0) {
      if (x[t] > x[ext])
        ext = t;
      else if (x[ext] - x[t] > h)
        turns.push_back(ext), dir = -1, ext = t;
    } else {
      if (x[t] < x[ext])
        ext = t;
      else if (x[t] - x[ext] > h)
        turns.push_back(ext), dir = +1, ext = t;
    }
  }
  if (turns.back() != x.size() - 1) turns.push_back(x.size() - 1);
  return turns;
}

double travel_at_force_fraction(std::span<const double> x, std::span<const double> force,
                                double fraction) {
  FRICTION_CHECK(x.size() == force.size() && x.size() >= 2,
                 "travel_at_force_fraction: displacement and force lengths differ");
  FRICTION_CHECK(fraction > 0.0 && fraction <= 1.0, "travel_at_force_fraction: fraction ", fraction,
                 " must be in (0, 1]");
  const double range = 2.0 * largest_travel(x);
  const double h = std::max(3.0 * displacement_resolution(x), 1e-4 * range);
  const std::vector<std::size_t> turns = turning_points(x, h);
  double best_swing = 0.0, travel = range;
  for (std::size_t s = 0; s + 1 < turns.size(); ++s) {
    const std::size_t a = turns[s], b = turns[s + 1];
    if (b <= a) continue;
    const double sgn = x[b] >= x[a] ? 1.0 : -1.0;
    double swing = 0.0;
    for (std::size_t t = a; t <= b; ++t) swing = std::max(swing, sgn * (force[t] - force[a]));
    if (swing <= best_swing) continue;
    best_swing = swing;
    for (std::size_t t = a; t <= b; ++t)
      if (sgn * (force[t] - force[a]) >= fraction * swing) {
        travel = std::abs(x[t] - x[a]);
        break;
      }
  }
  return travel;
}

double bayesian_information_criterion(double rss, std::size_t samples, std::size_t parameters) {
  FRICTION_CHECK(samples > 0, "bayesian_information_criterion: no samples");
  const double n = static_cast<double>(samples);
  const double floor = 1e-300;
  return n * std::log(std::max(rss, floor) / n) + static_cast<double>(parameters) * std::log(n);
}

}  // namespace friction
