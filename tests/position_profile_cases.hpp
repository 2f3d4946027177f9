// Records for the position-dependence start tests (test_position_profile, and the rest of its
// seeds in test_position_profile_study): strokes over many periods of the profile, made by the
// independent simulator (tests/study), and the check that `identify --extension
// position-dependence` ends in the right basin.
//
// Across a travel T a relative error e of the wavelength puts the far end e T / lambda periods
// out of step, so a start from the coarse profile grid (16 wavelengths over two decades) can miss
// the basin entirely when T / lambda is large: on a study record the fit ended at a quarter of the
// true wavelength, 77x the noise floor (extension_profile.cpp, position_scan).  The fit must end
// within an eighth of a period over the travel of the true wavelength:
// |lambda_hat / lambda - 1| <= lambda / (8 T).  Six random systems with 10.5-15.5 periods over the
// travel (seeds k * 104729, k = 1..6, not used while the scan was developed).  With the coarse grid
// alone (the scan disabled) 4 of these 6 fail, and 5 of 12 records of 5-16 periods of the seeds
// the scan was developed on.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <random>
#include <vector>

#include "friction/effect_table.hpp"
#include "friction/methods.hpp"
#include "friction/model_io.hpp"
#include "truth_records.hpp"
#include "truth_simulator.hpp"

namespace friction::position_profile_cases {

struct Case {
  truth::Trace trace;
  double wavelength = 0;
};

// Strokes with rests in both directions over a travel of `periods` wavelengths; elements, scales,
// sampling, offset of the position and noise drawn from `seed`.
inline Case make_case(std::uint64_t seed, double periods) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  truth::System system;
  const std::size_t n_el = 3 + static_cast<std::size_t>(u(rng) * 4);  // 3..6 elements
  system.coulomb = std::pow(10.0, -1.0 + 3.0 * u(rng));               // 0.1 .. 100 N
  std::vector<double> shares(n_el);
  double share_sum = 0;
  for (double& s : shares) share_sum += (s = 0.3 + u(rng));
  const double travel_scale = std::pow(10.0, -6.0 + u(rng));  // slip travel 1-10 um
  for (std::size_t i = 0; i < n_el; ++i) {
    const double share = shares[i] / share_sum;
    const double threshold = travel_scale * (0.2 + 1.8 * u(rng));
    system.elements.push_back({share * system.coulomb / threshold, share});
  }
  const double stroke_travel = travel_scale * (20 + 20 * u(rng));
  Case c;
  c.wavelength = stroke_travel / periods;
  system.effects.position =
      truth::Effects::Position{0.04 + 0.06 * u(rng), c.wavelength, 2 * M_PI * u(rng)};

  truth::Measurement m;
  const double speed = travel_scale * (200 + 800 * u(rng));
  // Inside the range the profile covers (effect_table.hpp: a wavelength of at least 10 samples'
  // travel), with a margin: 20-60 samples per period while sliding.
  m.sampling_rate = std::max(500 + 4500 * u(rng), (20 + 40 * u(rng)) * speed / c.wavelength);
  const double stroke = stroke_travel / speed;
  truth::StrokeProgram p;
  p.width = 0.05 * stroke;
  p.velocity = {0.0, speed, 0.0, -speed, 0.0, speed, 0.0, -speed, 0.0};
  p.duration = {0.05 * stroke, stroke,       0.3 * stroke, stroke,      0.3 * stroke,
                stroke,        0.3 * stroke, stroke,       0.1 * stroke};
  m.warm_up = 1.0 / m.sampling_rate;
  const double total = std::accumulate(p.duration.begin(), p.duration.end(), 0.0);
  m.samples = static_cast<std::size_t>(total * m.sampling_rate);
  m.quantum = travel_scale * 1e-3;
  m.x_offset = stroke_travel * (u(rng) - 0.5) * 10;  // the absolute position matters
  m.noise_sigma = 0.003 * system.coulomb;
  m.noise_seed = seed ^ 0x9e3779b97f4a7c15ULL;
  m.refine = 16;
  c.trace = truth::simulate(system, *truth::make_strokes(p), nullptr, m);
  return c;
}

/// The seed and the periods over the travel of case k (1..6).
inline std::pair<std::uint64_t, double> case_seed(std::uint64_t k) {
  return {k * 104729u, 9.5 + k};
}

/// The case's record moved to start at x = 0 (`near`) and the same record moved 10^4 travels from
/// the origin (`far`, by `x0`): only the absolute position differs, as a fit about the origin sees
/// it.
struct NearAndFar {
  Record near, far;
  double x0 = 0;
};
inline NearAndFar near_and_far(const Case& c) {
  NearAndFar r;
  r.near = testing::record_of(c.trace);
  const double start = r.near.displacement.front();
  for (double& v : r.near.displacement) v -= start;
  const auto [lo, hi] = std::minmax_element(r.near.displacement.begin(), r.near.displacement.end());
  r.x0 = 1e4 * (*hi - *lo);
  r.far = r.near;
  for (double& v : r.far.displacement) v += r.x0;
  return r;
}

/// Fits case k and checks its wavelength.
inline void expect_right_basin(std::uint64_t k) {
  const auto [seed, periods] = case_seed(k);
  const Case c = make_case(seed, periods);
  const Record r = testing::record_of(c.trace);
  const auto [lo, hi] = std::minmax_element(r.displacement.begin(), r.displacement.end());
  const double travel = *hi - *lo;
  MethodOptions o;
  o.extensions = {Effect::position_dependence};
  const IdentifiedModel id = identify_model("maxwell-slip", r, o);
  ASSERT_TRUE(id.extensions.contains("pieces")) << "seed " << seed;
  const double got =
      id.extensions["pieces"]["position-dependence"]["wavelength"]["value"].get<double>();
  EXPECT_LE(std::abs(got / c.wavelength - 1.0), c.wavelength / (8.0 * travel))
      << "seed " << seed << ": wavelength " << got << " m for " << c.wavelength << " m ("
      << travel / c.wavelength << " periods over the travel of " << travel << " m)";
}

}  // namespace friction::position_profile_cases
