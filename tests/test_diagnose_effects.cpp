// Diagnosis studies (ctest label `long`): every effect of methods.md 7 that the tests can write
// by formula is injected on top of a 4-operator Maxwell Slip system with white force noise, at a
// randomised magnitude whose RMS contribution is 3-6 times the noise RMS; the diagnosis must name
// it first, recover its parameter within a tolerance stated per effect and gain on validation.  A
// false-finding study runs the same on records with no hidden effect.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <random>

#include "diagnose_support.hpp"
#include "friction/diagnose.hpp"

namespace friction::testing {
namespace {

constexpr double kSigma = 2e-3;         // N, force noise
constexpr std::size_t kSamples = 4000;  // per record, 1 kHz

struct Case {
  Injected effect;
  double nominal;  // starting magnitude for the RMS search
  const char* parameter;
  double tolerance;                 // relative
  const char* secondary = nullptr;  // a second parameter with a known value, or null
  double secondary_value = 0, secondary_tolerance = 0;
};

// Readable test names in ctest: the case prints as its effect (not as the bytes of the struct).
void PrintTo(const Case& c, std::ostream* os) { *os << injected_name(c.effect); }

// The magnitude whose contribution (RMS of the force change) is `ratio` x the noise RMS.
double magnitude_for(const Case& c, double ratio, const Excitation& ex) {
  if (c.effect == Injected::normal) return c.nominal;  // the normal force's swing sets the size
  const Clean none = make_clean(Injected::none, 0, ex, kSamples, 0.0);
  double m = c.nominal;
  for (int it = 0; it < 4; ++it) {
    const Clean w = make_clean(c.effect, m, ex, kSamples, 0.0);
    std::vector<double> d(kSamples);
    for (std::size_t k = 0; k < kSamples; ++k) d[k] = w.force[k] - none.force[k];
    m *= ratio * kSigma / rms(d);
  }
  return m;
}

double contribution(Injected e, double m, const Excitation& ex) {
  const Clean none = make_clean(Injected::none, 0, ex, kSamples, 0.0);
  const Clean w = make_clean(e, m, ex, kSamples, 0.0);
  std::vector<double> d(kSamples);
  for (std::size_t k = 0; k < kSamples; ++k) d[k] = w.force[k] - none.force[k];
  return rms(d);
}

// The value the diagnosis should recover for `parameter`.
double truth(const Case& c, double m, const SlipSystem& s) {
  if (c.effect == Injected::stribeck) return s.f0() * (1.0 + m);  // "static": the force at rest
  return m;
}

class EffectStudy : public ::testing::TestWithParam<std::tuple<Case, unsigned>> {};

TEST_P(EffectStudy, NamesTheEffectFirstRecoversItsParameterAndGains) {
  const auto [c, seed] = GetParam();
  std::mt19937 gen(seed * 7919u + static_cast<unsigned>(c.effect));
  std::uniform_real_distribution<double> u(3.0, 6.0), ph(0.0, 6.0);
  Excitation ex;
  ex.phase = ph(gen);
  double m = magnitude_for(c, u(gen), ex);
  if (c.effect == Injected::normal) m = std::uniform_real_distribution<double>(0.2, 0.6)(gen);
  const double ratio = contribution(c.effect, m, ex) / kSigma;
  ASSERT_GE(ratio, 2.95) << "the injected effect must be >= 3x the noise";
  const SlipSystem sys;
  const Record est = with_noise(make_clean(c.effect, m, ex, kSamples, 0.0), kSigma, seed);
  const Record val = with_noise(make_clean(c.effect, m, ex, kSamples, 4.0), kSigma, seed + 1000);

  const auto t0 = std::chrono::steady_clock::now();
  const Diagnosis d = diagnose(est, val);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("[ %s seed %u ] magnitude %.4g (%.1fx noise), %.1f s\n%s",
              injected_name(c.effect).c_str(), seed, m, ratio, secs, d.to_table().c_str());
  ASSERT_FALSE(d.findings.empty()) << "nothing found";
  const Finding& f = d.findings.front();
  EXPECT_EQ(f.effect, injected_name(c.effect));
  if (f.effect == injected_name(c.effect)) {
    ASSERT_TRUE(f.parameters.contains(c.parameter)) << f.parameters.dump();
    const double got = f.parameters[c.parameter].get<double>();
    const double want = truth(c, m, sys);
    EXPECT_NEAR(got, want, c.tolerance * std::abs(want))
        << c.parameter << ": recovered " << got << ", injected " << want;
    if (c.secondary) {
      ASSERT_TRUE(f.parameters.contains(c.secondary)) << f.parameters.dump();
      const double g2 = f.parameters[c.secondary].get<double>();
      EXPECT_NEAR(g2, c.secondary_value, c.secondary_tolerance * c.secondary_value) << c.secondary;
      std::printf("RECOVERY %s %s injected %.5g recovered %.5g (%.1f %%)\n",
                  injected_name(c.effect).c_str(), c.secondary, c.secondary_value, g2,
                  100.0 * (g2 - c.secondary_value) / c.secondary_value);
    }
    std::printf("RECOVERY %s %s injected %.5g recovered %.5g (%.1f %%)\n",
                injected_name(c.effect).c_str(), c.parameter, want, got,
                100.0 * (got - want) / want);
  }
  EXPECT_GT(f.validation_before / f.validation_after, 1.0);
  // The chain of cli.md.
  EXPECT_DOUBLE_EQ(f.validation_before, d.baseline_validation_percent);
  EXPECT_DOUBLE_EQ(d.findings.back().validation_after, d.final_validation_percent);
}

const Case kCases[] = {
    {Injected::viscous, 20.0, "viscous", 0.15},
    {Injected::offset, 0.01, "offset", 0.10},
    {Injected::inertia, 1.0, "mass", 0.10},
    {Injected::asymmetry, 0.03, "asymmetry", 0.20},
    {Injected::stribeck, 0.1, "static", 0.10, "stribeck_velocity", 2e-4, 0.25},
    {Injected::drift, 0.02, "relative_rate", 0.20},
    {Injected::delay, 0.005, "delay", 0.15},
    {Injected::position, 0.02, "amplitude", 0.25, "wavelength", 40e-6, 0.05},
    {Injected::normal, 0.4, "friction_coefficient", 0.10},
};

INSTANTIATE_TEST_SUITE_P(Effects, EffectStudy,
                         ::testing::Combine(::testing::ValuesIn(kCases), ::testing::Values(1u, 2u)),
                         [](const auto& info) {
                           std::string n = injected_name(std::get<0>(info.param).effect);
                           for (char& ch : n)
                             if (ch == '-') ch = '_';
                           return n + "_seed" + std::to_string(std::get<1>(info.param));
                         });

// Two effects at once: the greedy rounds must find both (in either order), the backward pass
// must keep both, and the chain of validation errors must hold.
TEST(TwoEffects, ViscousAndOffsetAreBothFound) {
  Excitation ex;
  ex.phase = 2.0;
  auto make = [&](double t0, unsigned seed) {
    Clean c = make_clean(Injected::viscous, 40.0, ex, kSamples, t0);
    for (double& f : c.force) f += 0.008;
    return with_noise(c, kSigma, seed);
  };
  const Diagnosis d = diagnose(make(0.0, 11), make(4.0, 12));
  std::printf("%s", d.to_table().c_str());
  ASSERT_EQ(d.findings.size(), 2u);
  std::vector<std::string> names{d.findings[0].effect, d.findings[1].effect};
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"offset", "viscous"}));
  EXPECT_DOUBLE_EQ(d.findings[0].validation_after, d.findings[1].validation_before);
  EXPECT_DOUBLE_EQ(d.findings[1].validation_after, d.final_validation_percent);
  const auto& ext = std::get<Extended<MaxwellSlip<double>>>(d.final_model->variant()).extensions();
  ASSERT_TRUE(ext.viscous && ext.offset);
  EXPECT_NEAR(ext.viscous->viscous, 40.0, 6.0);
  EXPECT_NEAR(ext.offset->offset, 0.008, 0.0008);
}

TEST(FalseFindings, RecordsWithoutAHiddenEffectRarelyGetAFinding) {
  const int runs = 20;
  int with_finding = 0;
  for (int seed = 1; seed <= runs; ++seed) {
    std::mt19937 gen(static_cast<unsigned>(seed));
    Excitation ex;
    ex.phase = std::uniform_real_distribution<double>(0.0, 6.0)(gen);
    ex.f1 = std::uniform_real_distribution<double>(1.0, 1.6)(gen);
    const Record est = with_noise(make_clean(Injected::none, 0, ex, kSamples, 0.0), kSigma,
                                  100u + static_cast<unsigned>(seed));
    const Record val = with_noise(make_clean(Injected::none, 0, ex, kSamples, 4.0), kSigma,
                                  200u + static_cast<unsigned>(seed));
    const Diagnosis d = diagnose(est, val);
    if (!d.findings.empty()) {
      ++with_finding;
      std::printf("false finding on seed %d:\n%s", seed, d.to_table().c_str());
    }
  }
  const double rate = static_cast<double>(with_finding) / runs;
  std::printf("FALSE-FINDING RATE %d / %d = %.1f %%\n", with_finding, runs, 100.0 * rate);
  EXPECT_LE(rate, 0.05);
}

}  // namespace
}  // namespace friction::testing
