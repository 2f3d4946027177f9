// Turns between samples (motion.hpp): where the motion reverses between two samples, a Maxwell
// Slip model stepped on the samples alone anchors its sliding operators at the sampled extreme,
// short of the true one.  Judged on the independent simulator (tests/study), whose elements step
// on a grid 64 times finer than the sampling, with exact (unquantised) positions: the library's
// simulation with the true parameters against the simulator's clean force, and an NLR fit against
// the noise floor on a second record.  Slow sampling (a carrier of 40-70 samples per period,
// several excitations and systems) is where the miss, a T^2/8 at a turn, moves the stiff operators
// by more than the force noise.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <random>
#include <span>
#include <vector>

#include "friction/extensions.hpp"
#include "friction/initial_state.hpp"
#include "friction/maxwell_slip.hpp"
#include "friction/metrics.hpp"
#include "friction/nlr.hpp"
#include "friction/simulate.hpp"
#include "truth_simulator.hpp"

namespace friction {
namespace test_turns_between_samples {
namespace {

struct Case {
  truth::System system;
  std::unique_ptr<truth::Excitation> motion;
  double rate = 0;
};

// A random system of 4-7 elements (stiffnesses spread over two decades, shares at random) and an
// envelope or a multisine whose highest frequency has 40-70 samples per period; with a
// motion_seed, another motion of the same family for the same system and sampling.
Case random_case(std::uint64_t seed, std::uint64_t motion_seed = 0) {
  std::mt19937_64 g(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Case c;
  const std::size_t n = 4 + static_cast<std::size_t>(4 * u(g));
  c.system.coulomb = std::pow(10.0, -1.0 + 3.0 * u(g));
  // Thresholds at least 1.5 times apart: two elements of nearly one threshold act as one, and the
  // fit's question would be another (which of the equivalent models), not the turns.
  for (bool distinct = false; !distinct;) {
    c.system.elements.clear();
    double total = 0;
    for (std::size_t i = 0; i < n; ++i) {
      c.system.elements.push_back({std::pow(10.0, 5.0 + 2.0 * u(g)), 0.2 + u(g)});
      total += c.system.elements.back().share;
    }
    for (auto& e : c.system.elements) e.share /= total;
    // In the library's order, thresholds increasing (the element forces come in the same order).
    std::sort(c.system.elements.begin(), c.system.elements.end(),
              [](const truth::Element& a, const truth::Element& b) {
                return a.share / a.stiffness < b.share / b.stiffness;
              });
    distinct = true;
    for (std::size_t i = 1; i < n; ++i)
      distinct = distinct && c.system.threshold(i) >= 1.5 * c.system.threshold(i - 1);
  }
  c.rate = std::pow(10.0, 2.5 + u(g));  // 316 Hz to 3.2 kHz
  const double samples_per_period = 40.0 + 30.0 * u(g);
  const double top = c.rate / samples_per_period;  // the fastest component [Hz]
  // Travel a few times the largest threshold: presliding loops and sliding.
  double largest = 0;
  for (std::size_t i = 0; i < n; ++i) largest = std::max(largest, c.system.threshold(i));
  // Another motion of the same family, sampling and system: a validation record.
  if (motion_seed != 0) g.seed(motion_seed);
  const double amplitude = (2.0 + 4.0 * u(g)) * largest;
  if (seed % 2 == 0) {
    truth::EnvelopeProgram p;
    p.amplitude = amplitude;
    p.f2 = top;
    p.f1 = top / 2.3;
    p.fe = p.f1 / (5.0 + 5.0 * u(g));
    p.psi = 2.0 * M_PI * u(g);
    c.motion = truth::make_envelope(p);
  } else {
    truth::MultisineProgram p;
    for (int j = 0; j < 4; ++j) {
      p.amplitude.push_back(amplitude / 4.0 * (0.5 + u(g)));
      p.frequency.push_back(top / std::pow(2.0, j));
      p.phase.push_back(2.0 * M_PI * u(g));
    }
    c.motion = truth::make_multisine(p);
  }
  return c;
}

truth::Trace trace_of(const Case& c, double noise_sigma, std::uint64_t noise_seed) {
  truth::Measurement m;
  m.sampling_rate = c.rate;
  m.samples = 3000;
  m.warm_up = 2000.0 / c.rate;
  m.quantum = 0;  // exact positions: the only error left is the turn between samples
  m.noise_sigma = noise_sigma;
  m.noise_seed = noise_seed;
  m.refine = 64;
  return truth::simulate(c.system, *c.motion, nullptr, m);
}

MaxwellSlipParameters<double> true_parameters(const truth::System& s) {
  MaxwellSlipParameters<double> p;
  for (std::size_t i = 0; i < s.elements.size(); ++i) {
    p.stiffness.push_back(s.elements[i].stiffness);
    p.threshold.push_back(s.threshold(i));
  }
  return p;
}

double rms(const std::vector<double>& a, const std::vector<double>& b) {
  double s = 0;
  for (std::size_t k = 0; k < a.size(); ++k) s += (a[k] - b[k]) * (a[k] - b[k]);
  return std::sqrt(s / static_cast<double>(a.size()));
}

// The true model from the true state at the first sample, simulated by the library (through the
// turns) and stepped on the increments alone (as before them), against the clean force.
TEST(TurnsBetweenSamples, TheTrueModelFollowsTheTrueForceThroughTheTurns) {
  for (std::uint64_t seed = 0x51ed270fULL; seed < 0x51ed270fULL + 6; ++seed) {
    const Case c = random_case(seed);
    const truth::Trace t = trace_of(c, 0.0, 1);
    const MaxwellSlipParameters<double> p = true_parameters(c.system);
    const std::size_t m = p.size();
    std::vector<double> d0(m);
    for (std::size_t i = 0; i < m; ++i) d0[i] = t.element_force[i] / p.stiffness[i];
    MaxwellSlip<double> through(p, true), sampled(p, true);
    through.reset(std::span<const double>(d0));
    sampled.reset(std::span<const double>(d0));
    const std::size_t n = t.time.size();
    std::vector<double> f_through(n), f_sampled(n);
    std::size_t turns = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const Motion<double> mk =
          motion_at(std::span<const double>(t.time), std::span<const double>(t.position), k);
      turns += mk.turn != 0.0;
      f_through[k] = through.step(mk);
      f_sampled[k] = sampled.step(Motion<double>{mk.dx, mk.velocity, mk.dt});
    }
    // simulate() is the run every command uses: the same numbers.
    MaxwellSlip<double> again(p, true);
    again.reset(std::span<const double>(d0));
    std::vector<double> f_simulated(n);
    simulate(again, std::span<const double>(t.time), std::span<const double>(t.position),
             std::span<double>(f_simulated));
    const double e_through = rms(f_through, t.clean), e_sampled = rms(f_sampled, t.clean);
    std::printf("seed %#llx: %zu elements, %.0f Hz, %zu turns: RMS error %.3g N through the turns, "
                "%.3g N on the samples alone (Fc %.3g N)\n",
                static_cast<unsigned long long>(seed), m, c.rate, turns, e_through, e_sampled,
                c.system.coulomb);
    EXPECT_EQ(f_simulated, f_through) << "seed " << seed;
    EXPECT_GT(turns, 10u) << "seed " << seed;
    // The miss the turns mend is the larger part: the parabola's own error is third order.
    EXPECT_LT(e_through, 0.2 * e_sampled) << "seed " << seed;
  }
}

// NLR with the true number of operators on a record with force noise of 0.3 times the error the
// sampled extremes cause: its validation on a second record (another motion of the same family,
// the initial state estimated) reaches the noise floor.  Every routine of the fit steps through
// the same turns (slip_regression.hpp, initial_state.cpp, nlr.cpp's threshold grid), or the fit
// and its validation disagree.
TEST(TurnsBetweenSamples, NlrReachesTheNoiseFloorOnSlowlySampledRecords) {
  for (std::uint64_t seed = 0x7c3a91d2ULL; seed < 0x7c3a91d2ULL + 4; ++seed) {
    const Case c = random_case(seed);
    const MaxwellSlipParameters<double> p = true_parameters(c.system);
    // The noise: 0.3 times what the sampled extremes cost the true model (previous test): a fit on
    // the samples alone sits near (1 + 1/0.09) = 12 times the floor, one through the turns (whose
    // parabola leaves a 15th to a 50th of that error) near 1.05 times.
    const truth::Trace clean = trace_of(c, 0.0, 1);
    std::vector<double> f_sampled(clean.time.size());
    {
      MaxwellSlip<double> sampled(p, true);
      std::vector<double> d0(p.size());
      for (std::size_t i = 0; i < p.size(); ++i) d0[i] = clean.element_force[i] / p.stiffness[i];
      sampled.reset(std::span<const double>(d0));
      for (std::size_t k = 0; k < clean.time.size(); ++k) {
        const Motion<double> mk = motion_at(std::span<const double>(clean.time),
                                            std::span<const double>(clean.position), k);
        f_sampled[k] = sampled.step(Motion<double>{mk.dx, mk.velocity, mk.dt});
      }
    }
    const double sigma = 0.3 * rms(f_sampled, clean.clean);
    const truth::Trace est = trace_of(c, sigma, 2 * seed + 1);
    const truth::Trace val = trace_of(random_case(seed, seed + 1000), sigma, 2 * seed + 2);
    NlrOptions o;
    o.operators = p.size();
    const NlrResult fit = identify_maxwell_slip(est.time, est.position, est.force, o);
    const FreeRun run = free_run_maxwell_slip(fit.parameters, val.time, val.position, val.force);
    const double floor = noise_floor_rss_sss_percent(val.force, sigma);
    const FreeRun truth_run = free_run_maxwell_slip(p, val.time, val.position, val.force);
    std::printf("  estimation %.4g %% (floor %.4g %%), true model on validation %.4g %%\n",
                fit.report.estimation.rss_sss_percent,
                noise_floor_rss_sss_percent(est.force, sigma), truth_run.errors.rss_sss_percent);

    std::printf("seed %#llx: %zu elements, %.0f Hz: validation %.4g %% against a floor of %.4g %% "
                "(%.2f times)\n",
                static_cast<unsigned long long>(seed), p.size(), c.rate, run.errors.rss_sss_percent,
                floor, run.errors.rss_sss_percent / floor);
    EXPECT_LT(run.errors.rss_sss_percent, 1.2 * floor) << "seed " << seed;
  }
}

// The level at the turn (motion.hpp): a Stribeck curve is at its static level where the motion
// stops and reverses, and well below it at the sample after.  Random systems with a Stribeck curve
// (static level 1.5-3 times the Coulomb level, exponent 0.5-2, vs a tenth to a half of the peak
// speed) on the independent simulator's exact positions, against its clean force: the library's
// Extended<MaxwellSlip> with the true parameters, and the same operators stepped through the same
// turns at the sample's level (as before the level at the turn).  The extremum's step must be
// clamped at the static level: the error of the sample's level at the turns is the larger part
// (a quarter of it at least on every system, three quarters of the squares over all of them).
TEST(TurnsBetweenSamples, AStribeckCurveIsAtItsStaticLevelAtTheTurns) {
  double ss_model = 0, ss_sample_level = 0;  // relative to Fc, summed over the systems
  for (std::uint64_t seed = 0x3d1f6c07ULL; seed < 0x3d1f6c07ULL + 6; ++seed) {
    Case c = random_case(seed);
    std::mt19937_64 g(seed ^ 0x9e3779b97f4a7c15ULL);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    // The peak speed of a clean run without the curve sets its velocity scale.
    double peak = 0;
    {
      const truth::Trace t = trace_of(c, 0.0, 1);
      for (double v : t.velocity) peak = std::max(peak, std::abs(v));
    }
    const double fs = (1.5 + 1.5 * u(g)) * c.system.coulomb;
    const double vs = (0.1 + 0.4 * u(g)) * peak, q = 0.5 + 1.5 * u(g);
    c.system.effects.stribeck = truth::Effects::Stribeck{fs, vs, q};
    const truth::Trace t = trace_of(c, 0.0, 1);
    const MaxwellSlipParameters<double> p = true_parameters(c.system);
    const std::size_t m = p.size(), n = t.time.size();
    ExtensionParameters<double> ext;
    ext.reference_force = c.system.coulomb;
    ext.stribeck.emplace();
    ext.stribeck->static_force = fs;
    ext.stribeck->stribeck_velocity = vs;
    ext.stribeck->stribeck_exponent = q;
    // The true state at the first sample, given relative to the true level there (extensions.hpp,
    // Initial state).
    const double level0 =
        1.0 + (fs / c.system.coulomb - 1.0) * std::exp(-std::pow(std::abs(t.velocity[0]) / vs, q));
    std::vector<double> d0(m), relative(m);
    for (std::size_t i = 0; i < m; ++i) {
      d0[i] = t.element_force[i] / p.stiffness[i];
      relative[i] = d0[i] / level0;
    }
    Extended<MaxwellSlip<double>> model(MaxwellSlip<double>(p, true), ext, 2);
    model.base().reset(std::span<const double>(relative));
    model.set_initial_state_level(level0);
    MaxwellSlip<double> at_sample_level(p, true);
    at_sample_level.reset(std::span<const double>(relative));
    at_sample_level.scale_state(level0);
    std::vector<double> f_model(n), f_sample_level(n);
    std::size_t turns = 0, lowered = 0;
    for_each_extended_step(
        model, std::span<const double>(t.time), std::span<const double>(t.position), {}, nullptr,
        [&](std::size_t k, const ExtendedMotion<double>& ctx, double f) {
          f_model[k] = f;
          turns += ctx.turn != 0.0;
          lowered += ctx.turn != 0.0 && model.turn_level() > model.level();
          const double level = model.level();
          f_sample_level[k] = at_sample_level.step(
              Motion<double>{ctx.dx, ctx.velocity, ctx.dt, level, 0.0, ctx.turn, level});
        });
    const double e_model = rms(f_model, t.clean), e_sample_level = rms(f_sample_level, t.clean);
    std::printf("seed %#llx: %zu elements, %.0f Hz, %zu turns (%zu above the sample's level), "
                "Fs/Fc %.2f, q %.2f: RMS error %.3g N at the turn's level, %.3g N at the "
                "sample's (Fc %.3g N)\n",
                static_cast<unsigned long long>(seed), m, c.rate, turns, lowered,
                fs / c.system.coulomb, q, e_model, e_sample_level, c.system.coulomb);
    EXPECT_GT(turns, 10u) << "seed " << seed;
    EXPECT_EQ(lowered, turns) << "seed " << seed;  // at rest the curve is at its static level
    EXPECT_LT(e_model, 0.75 * e_sample_level) << "seed " << seed;
    ss_model += e_model * e_model / (c.system.coulomb * c.system.coulomb);
    ss_sample_level += e_sample_level * e_sample_level / (c.system.coulomb * c.system.coulomb);
  }
  // The rest: the level's change inside the sample intervals and the velocity's estimate at t_k.
  // Measured at these seeds: 1.9 to 4.7 times less error at the turn's level.
  EXPECT_LT(ss_model, 0.25 * ss_sample_level);
}

}  // namespace
}  // namespace test_turns_between_samples
}  // namespace friction
