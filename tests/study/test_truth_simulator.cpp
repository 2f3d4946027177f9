// The independent simulator checked against what it claims: exact motion, convergence as its grid
// is refined, the steady sliding forces that the effects' definitions give in closed form, the
// encoder, the noise and the study's records.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numeric>
#include <set>
#include <sstream>

#include "study_design.hpp"
#include "truth_simulator.hpp"

namespace truth {
namespace {

std::vector<std::unique_ptr<Excitation>> three_motions() {
  std::vector<std::unique_ptr<Excitation>> m;
  EnvelopeProgram e;
  e.amplitude = 50e-6;
  e.f1 = 1.7;
  e.f2 = 4.1;
  e.fe = 0.31;
  m.push_back(make_envelope(e));
  StrokeProgram s;
  s.start = -1;
  s.velocity = {0, 1e-3, 0, -2e-4, 0, 5e-4, 0};
  s.duration = {0.3, 0.05, 0.2, 0.25, 0.2, 0.1, 0.5};
  s.width = 4e-3;
  m.push_back(make_strokes(s));
  MultisineProgram ms;
  ms.amplitude = {30e-6, 12e-6, 5e-6};
  ms.frequency = {0.9, 2.6, 7.3};
  ms.phase = {0.1, 2.0, 4.0};
  m.push_back(make_multisine(ms));
  return m;
}

// v and a are the derivatives of x: centred differences of x and v agree with them to the
// differences' own truncation error.
TEST(TruthSimulator, VelocityAndAccelerationAreTheDerivativesOfTheDisplacement) {
  for (const auto& m : three_motions()) {
    double worst_v = 0, worst_a = 0, v_scale = 0, a_scale = 0;
    const double h = 1e-6;
    for (double t = -0.9; t < 3.0; t += 0.0137) {
      const double v_fd = (m->x(t + h) - m->x(t - h)) / (2 * h);
      const double a_fd = (m->v(t + h) - m->v(t - h)) / (2 * h);
      worst_v = std::max(worst_v, std::abs(v_fd - m->v(t)));
      worst_a = std::max(worst_a, std::abs(a_fd - m->a(t)));
      v_scale = std::max(v_scale, std::abs(m->v(t)));
      a_scale = std::max(a_scale, std::abs(m->a(t)));
    }
    EXPECT_LT(worst_v, 1e-6 * v_scale) << m->kind();
    EXPECT_LT(worst_a, 1e-5 * a_scale) << m->kind();
  }
}

// Each stroke piece travels its velocity times its duration, once its smooth steps are over.
TEST(TruthSimulator, StrokesTravelVelocityTimesDuration) {
  StrokeProgram s;
  s.start = 0;
  s.velocity = {2e-3, 0, -5e-4, 0};
  s.duration = {0.5, 0.5, 1.0, 2.0};
  s.width = 2e-3;
  const auto m = make_strokes(s);
  EXPECT_NEAR(m->x(0.75) - m->x(-0.5), 2e-3 * 0.5, 1e-12);
  EXPECT_NEAR(m->x(3.5) - m->x(0.75), -5e-4 * 1.0, 1e-12);
  EXPECT_NEAR(m->v(0.25), 2e-3, 1e-15);
  EXPECT_NEAR(m->v(1.5), -5e-4, 1e-15);
  EXPECT_NEAR(m->v(3.5), 0.0, 1e-15);
}

System four_elements() {
  System s;
  s.coulomb = 2.0;
  s.elements = {{2e5, 0.4}, {6e4, 0.3}, {2e4, 0.2}, {5e3, 0.1}};
  return s;
}

Measurement plain_measurement(double fs, std::size_t n, int refine) {
  Measurement m;
  m.sampling_rate = fs;
  m.samples = n;
  m.warm_up = 1.0;
  m.quantum = 0;
  m.refine = refine;
  return m;
}

// The force converges as the grid is refined: the difference to a 320x grid falls at least in
// proportion to the step from 10x to 80x, and at 16x (the study's grid) it is far below the
// smallest noise the study uses (0.1 % of Fc).
TEST(TruthSimulator, ForceConvergesAsTheGridIsRefined) {
  System s = four_elements();
  s.effects.stribeck = Effects::Stribeck{3.0, 2e-4, 1.5};
  s.effects.lag_time = 4e-3;
  s.effects.viscous = 300.0;
  s.effects.position = Effects::Position{0.1, 20e-6, 0.3};
  s.effects.drift_rate = 0.05;
  s.effects.asymmetry = 0.1;
  s.effects.delay = 0.37e-3;
  for (const auto& m : three_motions()) {
    const auto reference = simulate(s, *m, nullptr, plain_measurement(1000, 3000, 320)).clean;
    std::vector<double> error;
    for (int r : {10, 16, 20, 40, 80}) {
      const auto f = simulate(s, *m, nullptr, plain_measurement(1000, 3000, r)).clean;
      double worst = 0;
      for (std::size_t k = 0; k < f.size(); ++k)
        worst = std::max(worst, std::abs(f[k] - reference[k]));
      error.push_back(worst);
    }
    SCOPED_TRACE(m->kind());
    EXPECT_GT(error[0], 0.0);
    EXPECT_LT(error[2], error[0]);
    EXPECT_LT(error[3], error[2]);
    EXPECT_LT(error[4], error[0] / 4);  // at least first order from 10x to 80x
    EXPECT_LT(error[1], 1e-3 * s.coulomb);
  }
}

// One element dragged from its virgin state in one direction: F = min(k (x - x0), Fc) exactly,
// whatever the grid.
TEST(TruthSimulator, OneElementFromRestFollowsItsSpringThenSlips) {
  System s;
  s.coulomb = 1.5;
  s.elements = {{1e5, 1.0}};
  StrokeProgram p;
  p.start = -0.5;
  p.velocity = {0, 1e-4};
  p.duration = {0.6, 10};
  p.width = 1e-3;
  const auto m = make_strokes(p);
  Measurement meas = plain_measurement(1000, 400, 10);
  meas.warm_up = 0.5;
  const Trace t = simulate(s, *m, nullptr, meas);
  const double x0 = m->x(-0.5 - 1e-9);
  for (std::size_t k = 0; k < t.clean.size(); ++k) {
    const double x = m->x(static_cast<double>(k) * 1e-3);
    EXPECT_NEAR(t.clean[k], std::min(1e5 * (x - x0), 1.5), 1e-12) << k;
  }
}

// Steady sliding at constant speed v in either direction: every element sits at its limit, so
// F = +-Fc (1 +- a) g(v)/Fc + sigma2 v + c with g the Stribeck curve: the definitions of the
// effects, in closed form.
TEST(TruthSimulator, SteadySlidingForceIsTheDefinitionOfTheEffects) {
  System s = four_elements();
  s.effects.stribeck = Effects::Stribeck{2.8, 3e-4, 1.3};
  s.effects.asymmetry = -0.12;
  s.effects.viscous = 150.0;
  s.effects.offset = 0.07;
  s.effects.mass = 4.0;  // no acceleration mid-stroke
  StrokeProgram p;
  p.start = -1;
  p.velocity = {0, 2e-4, 0, -6e-4, 0};
  p.duration = {0.5, 1.0, 0.3, 0.4, 2.0};
  p.width = 2e-3;
  const auto m = make_strokes(p);
  const Trace t = simulate(s, *m, nullptr, plain_measurement(1000, 2200, 16));
  auto expected = [&](double v) {
    const double g = s.coulomb + (2.8 - s.coulomb) * std::exp(-std::pow(std::abs(v) / 3e-4, 1.3));
    return (v > 0 ? g * (1 - 0.12) : -g * (1 + 0.12)) + 150.0 * v + 0.07;
  };
  // Mid-stroke samples: the + stroke runs over t in (-0.5, 0.5), the - stroke over (0.8, 1.2).
  for (double tm : {0.3, 0.45}) {
    const auto k = static_cast<std::size_t>(tm * 1000);
    EXPECT_TRUE(t.sliding[k]);
    EXPECT_NEAR(t.clean[k], expected(2e-4), 1e-9);
  }
  for (double tm : {1.1, 1.15}) {
    const auto k = static_cast<std::size_t>(tm * 1000);
    EXPECT_TRUE(t.sliding[k]);
    EXPECT_NEAR(t.clean[k], expected(-6e-4), 1e-9);
  }
}

// Inertia adds m a(t_k) with the exact acceleration; a delay of exactly three samples shifts the
// force by three samples and leaves the displacement where it was.
TEST(TruthSimulator, InertiaAddsMassTimesExactAccelerationAndDelayShiftsTheForce) {
  const auto motions = three_motions();
  const Excitation& m = *motions[0];
  System s = four_elements();
  const Trace plain = simulate(s, m, nullptr, plain_measurement(1000, 1000, 16));
  s.effects.mass = 2.5;
  const Trace heavy = simulate(s, m, nullptr, plain_measurement(1000, 1000, 16));
  for (std::size_t k = 0; k < plain.clean.size(); ++k)
    EXPECT_NEAR(heavy.clean[k] - plain.clean[k], 2.5 * plain.acceleration[k], 1e-9);
  s.effects.mass.reset();
  s.effects.delay = 3e-3;
  const Trace late = simulate(s, m, nullptr, plain_measurement(1000, 1000, 16));
  for (std::size_t k = 3; k < plain.clean.size(); ++k) {
    EXPECT_NEAR(late.clean[k], plain.clean[k - 3], 1e-9) << k;
    EXPECT_EQ(late.position[k], plain.position[k]);
  }
}

// A frictional lag shorter and shorter tends to no lag.
TEST(TruthSimulator, VanishingLagIsNoLag) {
  const auto motions = three_motions();
  System s = four_elements();
  s.effects.stribeck = Effects::Stribeck{3.0, 2e-4, 2.0};
  const auto none = simulate(s, *motions[1], nullptr, plain_measurement(1000, 2000, 16)).clean;
  double previous = 1e300;
  for (double tau : {1e-2, 1e-3, 1e-4}) {
    s.effects.lag_time = tau;
    const auto lagged = simulate(s, *motions[1], nullptr, plain_measurement(1000, 2000, 16)).clean;
    double worst = 0;
    for (std::size_t k = 0; k < none.size(); ++k)
      worst = std::max(worst, std::abs(lagged[k] - none[k]));
    EXPECT_LT(worst, previous);
    previous = worst;
  }
  EXPECT_LT(previous, 0.05);
}

// The sampled replay of the true system differs from the simulation only where a sampled model
// must (a reversal between two samples is missed, by about k a Ts^2 / 8): small on the exact
// displacement, far larger on a coarse encoder's, and between samples that are not near a
// reversal it is the simulation itself.
TEST(TruthSimulator, ReachableForceDepartsFromTheSimulationOnlyAsASampledModelMust) {
  const auto motions = three_motions();
  System s = four_elements();
  s.effects.viscous = 200.0;
  s.effects.mass = 3.0;
  s.effects.offset = 0.05;
  s.effects.asymmetry = 0.1;
  s.effects.delay = 2e-3;
  for (const auto& m : motions) {
    Measurement meas = plain_measurement(1000, 2000, 16);
    const Trace exact = simulate(s, *m, nullptr, meas);
    const auto replay = reachable_force(s, exact, nullptr, meas);
    const double exact_gap = rms_difference(replay, exact.clean, false);
    meas.quantum = 2e-7;
    const Trace coarse = simulate(s, *m, nullptr, meas);
    const double coarse_gap =
        rms_difference(reachable_force(s, coarse, nullptr, meas), coarse.clean, false);
    std::printf("%s: replay gap %.3g N on the exact displacement, %.3g N with a 0.2 um encoder\n",
                m->kind().c_str(), exact_gap, coarse_gap);
    EXPECT_LT(exact_gap, 2e-3 * s.coulomb) << m->kind();
    EXPECT_GT(coarse_gap, 3 * exact_gap) << m->kind();
    // Away from reversals (the velocity keeps its sign over the last two samples) and sliding,
    // every element is at its limit in both: the replay is exact there.
    for (std::size_t k = 2; k < replay.size(); ++k)
      if (exact.sliding[k] && exact.velocity[k] * exact.velocity[k - 2] > 0 &&
          std::abs(exact.velocity[k]) > 1e-5) {
        ASSERT_NEAR(replay[k], exact.clean[k], 1e-6 * s.coulomb) << m->kind() << " " << k;
      }
  }
}

TEST(TruthSimulator, EncoderQuantisesTheAbsolutePosition) {
  const auto motions = three_motions();
  Measurement m = plain_measurement(2000, 3000, 10);
  m.quantum = 1e-7;
  m.x_offset = -0.1234567;
  const Trace t = simulate(four_elements(), *motions[2], nullptr, m);
  std::set<double> levels;
  for (std::size_t k = 0; k < t.position.size(); ++k) {
    const double steps = t.position[k] / m.quantum;
    EXPECT_NEAR(steps, std::nearbyint(steps), 1e-6);
    const double exact = motions[2]->x(static_cast<double>(k) / 2000) + m.x_offset;
    EXPECT_LE(std::abs(t.position[k] - exact), m.quantum / 2 * (1 + 1e-9));
    levels.insert(t.position[k]);
  }
  EXPECT_GT(levels.size(), 100u);
}

// White and AR(1) noise: standard deviation sigma and lag-one correlation phi, within what
// 40 000 samples allow (standard errors sqrt((1 - phi^2)/N) for the correlation).
TEST(TruthSimulator, NoiseHasItsStandardDeviationAndColour) {
  const auto motions = three_motions();
  for (double phi : {0.0, 0.5, 0.95}) {
    Measurement m = plain_measurement(1000, 40000, 10);
    m.noise_sigma = 0.01;
    m.noise_phi = phi;
    m.noise_seed = 77;
    const Trace t = simulate(four_elements(), *motions[2], nullptr, m);
    std::vector<double> e(t.force.size());
    for (std::size_t k = 0; k < e.size(); ++k) e[k] = t.force[k] - t.clean[k];
    double s2 = 0, c1 = 0;
    for (std::size_t k = 0; k < e.size(); ++k) {
      s2 += e[k] * e[k];
      if (k) c1 += e[k] * e[k - 1];
    }
    const double n = static_cast<double>(e.size());
    // The variance of an AR(1) sample variance is larger by (1 + phi^2)/(1 - phi^2).
    const double sd_rel = std::sqrt(2 / n * (1 + phi * phi) / (1 - phi * phi));
    EXPECT_NEAR(std::sqrt(s2 / n), 0.01, 0.01 * 2.5 * sd_rel) << phi;
    EXPECT_NEAR(c1 / s2, phi, 4 * std::sqrt((1 - phi * phi) / n) + 1e-3) << phi;
  }
}

// The study's records: every effect alone and the lag with its partners make records whose
// effects contribute at least six times the noise, with their truth and a readable file.
TEST(StudyDesign, EveryEffectMakesARecordItContributesTo) {
  std::uint64_t seed = 1000;
  std::vector<std::vector<std::string>> sets;
  for (const std::string& e : injectable_effects())
    if (e != "frictional-lag") sets.push_back({e});
  sets.push_back({"frictional-lag", "viscous"});
  sets.push_back({"frictional-lag", "stribeck"});
  sets.push_back({"offset", "inertia"});
  int family = 0;
  for (const auto& effects : sets) {
    RecordSpec spec;
    spec.id = effects.front();
    spec.effects = effects;
    spec.family = static_cast<Family>(family++ % 3);
    spec.seed = ++seed;
    const StudyRecord r = make_record(spec);
    SCOPED_TRACE(spec.id + ": " + r.summary());
    ASSERT_EQ(r.expected.size(), effects.size());
    for (const auto& e : effects) {
      ASSERT_TRUE(r.contribution.count(e));
      EXPECT_GE(r.contribution.at(e), 5.99 * r.validation.noise_sigma) << e;
      bool has_truth = false;
      for (const auto& p : r.truth) has_truth |= p.effect == e;
      EXPECT_TRUE(has_truth) << e;
    }
    EXPECT_GE(r.system.elements.size(), 3u);
    EXPECT_LE(r.system.elements.size(), 12u);
    EXPECT_EQ(r.trace_estimation.force.size(), r.estimation.samples);
    EXPECT_GT(r.true_floor_percent, 0.0);
  }
}

TEST(StudyDesign, FilesCarryTheirUnitsNamesAndSign) {
  int written = 0;
  for (std::uint64_t seed = 500; seed < 560 && written < 60; ++seed, ++written) {
    RecordSpec spec;
    spec.id = "none";
    spec.family = static_cast<Family>(seed % 3);
    spec.seed = seed;
    const StudyRecord r = make_record(spec);
    const std::string path = ::testing::TempDir() + "/truth-record.csv";
    write_csv(r, true, path);
    std::ifstream in(path);
    std::string header, first;
    std::getline(in, header);
    std::getline(in, first);
    EXPECT_NE(header.find(r.format.force_name), std::string::npos);
    EXPECT_NE(header.find(r.format.displacement_name), std::string::npos);
    const bool non_si = r.format.time_unit != "s" || r.format.displacement_unit != "m" ||
                        r.format.force_unit != "N";
    EXPECT_EQ(non_si, r.read_options().find("--units") != std::string::npos) << header;
    EXPECT_EQ(r.format.names_need_columns_option,
              r.read_options().find("--columns") != std::string::npos);
    std::size_t lines = 1;
    for (std::string line; std::getline(in, line);) ++lines;
    EXPECT_EQ(lines, r.estimation.samples);
  }
}

}  // namespace
}  // namespace truth
