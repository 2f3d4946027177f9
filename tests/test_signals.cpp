// Signal conditioning (signals.hpp): force-sign detection, irregular sampling, displacement
// resolution and force noise, on synthetic records with known answers, and on the real tribometer
// record when it is present.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <numbers>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "friction/csv.hpp"
#include "friction/maxwell_slip.hpp"
#include "friction/signals.hpp"
#include "friction/simulate.hpp"

namespace test_signals {
namespace {

using friction::ConditioningOptions;
using friction::DataError;
using friction::ForceSign;
using friction::Record;

constexpr double kPi = std::numbers::pi;

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

bool any_warning_contains(const Record& r, const std::string& part) {
  for (const auto& w : r.conditioning.warnings)
    if (contains(w, part)) return true;
  return false;
}

// Friction of a 3-operator Maxwell Slip system (sliding force 0.7 N), model convention.
std::vector<double> maxwell_slip_force(const std::vector<double>& t, const std::vector<double>& x) {
  friction::MaxwellSlip<double> m({{2e4, 1e4, 5e3}, {5e-6, 2e-5, 6e-5}});
  return friction::simulate(m, std::span<const double>(t), std::span<const double>(x));
}

// Sinusoidal reciprocating record: 4000 samples at 1 kHz, 8 cycles of 100 um, force with noise.
Record reciprocating(double offset = 0.0, double noise = 0.01, unsigned seed = 1) {
  Record r;
  r.source = "synthetic";
  for (int k = 0; k < 4000; ++k) {
    r.time.push_back(1e-3 * k);
    r.displacement.push_back(1e-4 * std::sin(2 * kPi * 2.0 * r.time.back()));
  }
  r.force = maxwell_slip_force(r.time, r.displacement);
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, noise);
  for (double& f : r.force) f += offset + n(rng);
  return r;
}

// ------------------------------------------------------------------ force sign

TEST(ForceSign, KeepsAForceThatResistsTheMotion) {
  Record r = reciprocating();
  const std::vector<double> before = r.force;
  const auto& c = friction::condition_record(r);
  EXPECT_EQ(c.force_sign, 1);
  EXPECT_TRUE(c.force_sign_decided);
  EXPECT_FALSE(c.force_sign_given);
  EXPECT_GT(c.sliding_samples, 1000u);
  EXPECT_EQ(r.force, before);
  EXPECT_FALSE(any_warning_contains(r, "force_sign"));
}

TEST(ForceSign, DetectsAndFlipsAnOpposedForce) {
  Record r = reciprocating(0.2);
  const std::vector<double> truth = r.force;
  for (double& f : r.force) f = -f;
  const auto& c = friction::condition_record(r);
  EXPECT_EQ(c.force_sign, -1);
  EXPECT_TRUE(c.force_sign_decided);
  EXPECT_EQ(r.force, truth);  // flipped back exactly
  EXPECT_TRUE(any_warning_contains(r, "force_sign: -1"));
}

TEST(ForceSign, AnOffsetTimesNetTravelDoesNotFoolTheDecision) {
  // Up 10 units of travel, down 2 (1 mm and 0.2 mm): a plain sum of F*v over sliding would see
  // offset * 8 units against friction * 12 units.  With the offset three times the friction that
  // sum is positive although the (recorded, opposed) friction is negative; the per-direction
  // medians are not.
  Record r;
  r.source = "ramp";
  double x = 0;
  for (int k = 0; k < 1200; ++k) {
    r.time.push_back(1e-3 * k);
    x += k < 1000 ? 1e-6 : -1e-6;  // 1 mm/s: up for 1 s, then down for 0.2 s
    r.displacement.push_back(x);
  }
  const std::vector<double> truth = maxwell_slip_force(r.time, r.displacement);
  const double offset = 3.0 * 0.7;
  r.force.clear();
  for (double f : truth) r.force.push_back(-f + offset);
  double plain = 0;
  for (std::size_t k = 1; k < r.size(); ++k)
    plain += r.force[k] * (r.displacement[k] - r.displacement[k - 1]);
  ASSERT_GT(plain, 0.0) << "the test needs a record where the naive rule is wrong";
  const auto e = friction::estimate_force_sign(r.time, r.displacement, r.force);
  EXPECT_TRUE(e.decided);
  EXPECT_TRUE(e.both_directions);
  EXPECT_EQ(e.sign, -1);
  // -2 x 0.7 N in full sliding; the short down stroke is partly presliding, which shrinks it.
  EXPECT_LT(e.difference, -0.7);
  EXPECT_GE(e.difference, -1.4 - 1e-9);
}

TEST(ForceSign, ExplicitSignIsHonoured) {
  Record opposed = reciprocating();
  for (double& f : opposed.force) f = -f;
  const std::vector<double> recorded = opposed.force;

  Record keep = opposed;
  const auto& c = friction::condition_record(keep, ConditioningOptions{ForceSign::positive});
  EXPECT_EQ(c.force_sign, 1);
  EXPECT_TRUE(c.force_sign_given);
  EXPECT_EQ(keep.force, recorded);
  EXPECT_TRUE(any_warning_contains(keep, "suggest -1"));

  Record flip = opposed;
  friction::condition_record(flip, ConditioningOptions{ForceSign::negative});
  EXPECT_EQ(flip.conditioning.force_sign, -1);
  EXPECT_EQ(flip.force[10], -recorded[10]);
  EXPECT_FALSE(any_warning_contains(flip, "suggest"));
}

TEST(ForceSign, UndecidableKeepsPlusOneAndWarns) {
  Record r = reciprocating();
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, 0.5);
  for (double& f : r.force) f = n(rng);  // force unrelated to the motion
  const std::vector<double> before = r.force;
  const auto& c = friction::condition_record(r);
  EXPECT_FALSE(c.force_sign_decided);
  EXPECT_EQ(c.force_sign, 1);
  EXPECT_EQ(r.force, before);
  EXPECT_TRUE(any_warning_contains(r, "could not be detected"));
}

TEST(ForceSign, NoForceNoSignWork) {
  Record r = reciprocating();
  r.force.clear();
  const auto& c = friction::condition_record(r, ConditioningOptions{ForceSign::negative});
  EXPECT_EQ(c.force_sign, 1);
  EXPECT_TRUE(c.warnings.empty());
}

// ------------------------------------------------------------------ sampling

Record regular(std::size_t n, double ts) {
  Record r;
  r.source = "mem";
  for (std::size_t k = 0; k < n; ++k) {
    r.time.push_back(ts * static_cast<double>(k));
    r.displacement.push_back(1e-4 * std::sin(0.01 * static_cast<double>(k)));
  }
  return r;
}

TEST(Sampling, IrregularGapsCountedAndKept) {
  Record r = regular(1000, 5e-3);
  // Shift everything after sample 100 and 200 by 5 ms (10 ms intervals) and after 300 by 4 ms.
  for (std::size_t k = 0; k < r.size(); ++k)
    r.time[k] += (k >= 100 ? 5e-3 : 0) + (k >= 200 ? 5e-3 : 0) + (k >= 300 ? 4e-3 : 0);
  const std::size_t n = r.size();
  const auto& c = friction::condition_record(r);
  EXPECT_EQ(r.size(), n);  // nothing resampled or dropped
  EXPECT_TRUE(c.irregular);
  EXPECT_NEAR(c.nominal_period, 5e-3, 1e-15);
  ASSERT_EQ(c.gaps.size(), 3u);
  EXPECT_EQ(c.gaps[0].index, 100u);
  EXPECT_EQ(c.gaps[1].index, 200u);
  EXPECT_EQ(c.gaps[2].index, 300u);
  EXPECT_NEAR(c.gaps[2].dt, 9e-3, 1e-12);
  EXPECT_NEAR(c.max_period, 10e-3, 1e-12);
  EXPECT_TRUE(any_warning_contains(r, "3 of 999 intervals")) << c.warnings.front();
  EXPECT_TRUE(any_warning_contains(r, "2 x 0.01 s, 1 x 0.009 s"));
}

TEST(Sampling, SmallJitterIsRegular) {
  Record r = regular(1000, 1e-3);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.4e-6, 0.4e-6);  // +-0.04 % of the period per stamp
  for (auto& t : r.time) t += u(rng);
  const auto& c = friction::condition_record(r);
  EXPECT_FALSE(c.irregular);
  EXPECT_TRUE(c.gaps.empty());
  // A tighter tolerance calls the same record irregular.
  const auto strict = friction::analyse_sampling(r.time, 1e-5);
  EXPECT_TRUE(strict.irregular());
}

TEST(Sampling, NonIncreasingTimeIsADataErrorWithTheLine) {
  Record r = regular(100, 1e-3);
  r.first_line = 2;  // as if read from a file with a header on line 1
  r.time[50] = r.time[49];
  try {
    friction::condition_record(r);
    ADD_FAILURE() << "no exception";
  } catch (const DataError& e) {
    EXPECT_EQ(e.line(), 52);
    EXPECT_EQ(std::string(e.what()).rfind("mem:52:", 0), 0u) << e.what();
  }
}

TEST(Sampling, MalformedInMemoryRecordsAreDataErrors) {
  Record sizes = regular(100, 1e-3);
  sizes.force.assign(99, 0.0);
  EXPECT_THROW(friction::condition_record(sizes), DataError);
  Record nan = regular(100, 1e-3);
  nan.force.assign(100, 0.0);
  nan.force[7] = std::nan("");
  EXPECT_THROW(friction::condition_record(nan), DataError);
  Record one = regular(1, 1e-3);
  EXPECT_THROW(friction::condition_record(one), DataError);
}

// ------------------------------------------------------------------ resolution and noise

TEST(Resolution, FindsTheEncoderQuantum) {
  const double q = 1e-7;
  std::vector<double> x;
  for (int k = 0; k < 5000; ++k)
    x.push_back(-0.11 + q * std::round(2e-5 * std::sin(2 * kPi * k / 2000.0) / q));
  const auto r = friction::estimate_displacement_resolution(x);
  ASSERT_TRUE(r.quantum.has_value());
  EXPECT_NEAR(*r.quantum, q, 1e-6 * q);
  EXPECT_NEAR(r.value, q, 1e-6 * q);
}

TEST(Resolution, QuantumFoundWhenOnlyMultiplesOccur) {
  // Fast motion: every step is 2 or 3 quanta, never one.  The quantum is their common divisor.
  const double q = 2.5e-8;
  std::vector<double> x = {0.0};
  for (int k = 1; k < 3000; ++k) {
    const int dir = (k / 500) % 2 ? -1 : 1;
    const int steps = (k % 3 == 0) ? 3 : 2;
    x.push_back(x.back() + dir * steps * q);
  }
  const auto quantum = friction::signal_quantum(x);
  ASSERT_TRUE(quantum.has_value());
  EXPECT_NEAR(*quantum, q, 1e-6 * q);
}

TEST(Resolution, UnquantisedNoiseGivesTheNoiseLevel) {
  const double sigma = 1e-8;
  std::mt19937 rng(11);
  std::normal_distribution<double> n(0.0, sigma);
  std::vector<double> x;
  for (int k = 0; k < 20000; ++k) x.push_back(1e-4 * std::sin(2 * kPi * 0.5 * k * 1e-3) + n(rng));
  const auto r = friction::estimate_displacement_resolution(x);
  EXPECT_FALSE(r.quantum.has_value());
  EXPECT_NEAR(r.noise, sigma, 0.05 * sigma);
  EXPECT_EQ(r.value, r.noise);
}

TEST(Noise, ForceNoiseIgnoresStickSlipJumps) {
  const double sigma = 0.02;
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0.0, sigma);
  std::vector<double> f;
  for (int k = 0; k < 20000; ++k) {
    const double square = ((k / 250) % 2) ? 1.0 : -1.0;  // a jump of 2 N every 250 samples
    f.push_back(square + 0.3 * std::sin(2 * kPi * k / 5000.0) + n(rng));
  }
  EXPECT_NEAR(friction::estimate_force_noise(f), sigma, 0.05 * sigma);
  EXPECT_NEAR(friction::noise_level(f), sigma, 0.05 * sigma);
}

TEST(Noise, QuietQuantisedForceHasQuantisationNoise) {
  const double q = 1e-3;
  std::vector<double> f;
  for (int k = 0; k < 20000; ++k)
    f.push_back(q * std::round(0.5 * std::sin(2 * kPi * 0.1 * k * 1e-3) / q));
  EXPECT_EQ(friction::noise_level(f), 0.0);
  EXPECT_NEAR(friction::estimate_force_noise(f), q / std::sqrt(12.0), 1e-6 * q);
  // A noiseless, unquantised smooth signal has (almost) no noise.
  std::vector<double> smooth;
  for (int k = 0; k < 2000; ++k) smooth.push_back(std::sin(1e-3 * k));
  EXPECT_LT(friction::estimate_force_noise(smooth), 1e-6);
}

TEST(Conditioning, RecordsResolutionAndNoise) {
  Record r = reciprocating(0.0, 0.01);
  const auto& c = friction::condition_record(r);
  EXPECT_NEAR(c.force_noise, 0.01, 0.002);  // the Maxwell Slip kinks add a little
  EXPECT_FALSE(c.displacement_quantised);
  EXPECT_GT(c.displacement_resolution, 0.0);
  EXPECT_LT(c.displacement_resolution, 1e-8);  // a smooth noiseless sine: curvature per sample
}

// A replica measured again by the record's own encoder errs as the record does: the exact motion
// is known here, so the record's own error (its conditioned displacement against the motion) is
// the yardstick for the replicas' differences from the record; the raw staircase's error,
// q / sqrt(12), is the wrong answer a replica without the conditioning would give.
TEST(Conditioning, ARemeasuredReplicaErrsAsTheRecordsOwnEncoder) {
  const double q = 5e-8, phase0 = 0.37 * q;
  Record r;
  std::vector<double> exact;
  for (int k = 0; k < 4000; ++k) {
    const double t = 1e-3 * k;
    r.time.push_back(t);
    exact.push_back(1e-5 * std::sin(2 * kPi * 0.8 * t) + 3e-6 * std::sin(2 * kPi * 3.1 * t + 1.0));
    r.displacement.push_back(q * std::round((exact.back() + phase0) / q) - phase0);
  }
  r.force = maxwell_slip_force(r.time, exact);
  friction::condition_record(r);
  ASSERT_TRUE(r.conditioning.displacement_quantised);
  ASSERT_FALSE(r.measured_displacement.empty()) << "the rule kept the staircase";
  auto rms = [](const std::vector<double>& a, const std::vector<double>& b) {
    double s = 0;
    for (std::size_t k = 0; k < a.size(); ++k) s += (a[k] - b[k]) * (a[k] - b[k]);
    return std::sqrt(s / static_cast<double>(a.size()));
  };
  const double own = rms(r.displacement, exact);
  ASSERT_LT(own, 0.7 * q / std::sqrt(12.0)) << "the conditioning did not reduce the error";
  Record a, b, c;
  ASSERT_TRUE(friction::remeasured_replica(r, 1, a));
  ASSERT_TRUE(friction::remeasured_replica(r, 1, b));
  ASSERT_TRUE(friction::remeasured_replica(r, 2, c));
  EXPECT_EQ(a.displacement, b.displacement);  // the seed picks the replica
  EXPECT_NE(a.displacement, c.displacement);
  EXPECT_EQ(a.force, r.force);
  EXPECT_EQ(a.time, r.time);
  // Quantised by the record's step: every step of the remeasured signal a multiple of q.
  ASSERT_EQ(a.measured_displacement.size(), r.size());
  for (std::size_t k = 1; k < r.size(); ++k) {
    const double steps = (a.measured_displacement[k] - a.measured_displacement[k - 1]) / q;
    ASSERT_NEAR(steps, std::round(steps), 1e-6) << k;
  }
  // The replicas' error about the record has the size of the record's own error (each is one
  // draw of the same process: within a factor of two), not the staircase's.
  for (std::uint64_t seed = 1; seed <= 8; ++seed) {
    Record rep;
    ASSERT_TRUE(friction::remeasured_replica(r, seed, rep));
    const double e = rms(rep.displacement, r.displacement);
    EXPECT_GT(e, 0.5 * own) << seed;
    EXPECT_LT(e, 2.0 * own) << seed;
  }
}

// A replica is conditioned as condition_record conditions a record: the rule's windows chosen on
// the replica, the displacement the models see their local polynomial.  The windows are remembered
// per record, sensor and seed (a diagnosis asks for the same replicas at every report): asked
// again, the same replica; another record, or the same record through a coarser sensor, with the
// same seeds gets its own windows, not the first one's.
TEST(Conditioning, AReplicaIsConditionedByTheRuleAndItsWindowsAreRememberedPerRecord) {
  const double q = 2e-8;
  auto make = [&](double frequency) {
    Record r;
    for (int k = 0; k < 3000; ++k) {
      const double t = 5e-4 * k;
      const double x =
          4e-6 * std::sin(2 * kPi * frequency * t) * (1 + 0.5 * std::sin(2 * kPi * 0.21 * t));
      r.time.push_back(t);
      r.displacement.push_back(q * std::round(x / q));
    }
    r.force = maxwell_slip_force(r.time, r.displacement);
    friction::condition_record(r);
    return r;
  };
  for (const Record& r : {make(1.3), make(7.0), make(1.3)}) {
    ASSERT_FALSE(r.measured_displacement.empty()) << "the rule kept the staircase";
    const friction::Resolution own_sensor =
        friction::estimate_displacement_resolution(r.measured());
    ASSERT_TRUE(own_sensor.quantum.has_value());
    EXPECT_NEAR(*own_sensor.quantum, q, 1e-3 * q);
    // A coarser sensor makes other replicas of the same record: not given the first one's windows.
    friction::Resolution coarse = own_sensor;
    coarse.quantum = 8 * q;
    for (const friction::Resolution& sensor : {own_sensor, coarse}) {
      for (std::uint64_t seed = 1; seed <= 6; ++seed) {
        Record a, b;
        friction::DerivativeWindows wa, wb;
        ASSERT_TRUE(friction::remeasured_replica(r, seed, a, sensor, &wa));
        ASSERT_TRUE(friction::remeasured_replica(r, seed, b, sensor, &wb));
        EXPECT_EQ(wa, wb) << seed;
        EXPECT_EQ(a.displacement, b.displacement) << seed;
        ASSERT_EQ(a.measured_displacement.size(), r.size()) << seed;
        // The rule's own choice on this replica, computed here without the library's memory.
        EXPECT_EQ(wa, friction::choose_derivative_windows(a.time, a.measured_displacement))
            << seed;
        std::vector<double> own(r.size());
        friction::apply_local_displacement<double>(a.time, a.measured_displacement, wa, own);
        EXPECT_EQ(a.displacement, own) << seed;
        if (sensor.quantum == own_sensor.quantum) {
          Record c;
          ASSERT_TRUE(friction::remeasured_replica(r, seed, c));
          EXPECT_EQ(c.displacement, a.displacement) << seed;
        }
      }
    }
  }
}

// A replica of another motion at a record's time stamps (the overload the covariance uses for the
// smoothest motion within the quanta) is the replica of a record holding that motion, windows
// included; and another motion at the same time stamps is not given the remembered one's windows
// (the memory knows a record by a fingerprint of its time and displacement, not by copies).
TEST(Conditioning, AReplicaOfAMotionIsTheReplicaOfARecordHoldingIt) {
  const double q = 2e-8;
  Record r;
  for (int k = 0; k < 3000; ++k) {
    const double t = 5e-4 * k;
    r.time.push_back(t);
    r.displacement.push_back(q * std::round(4e-6 * std::sin(2 * kPi * 1.7 * t) / q));
  }
  r.force = maxwell_slip_force(r.time, r.displacement);
  friction::condition_record(r);
  const friction::Resolution sensor = friction::estimate_displacement_resolution(r.measured());
  ASSERT_TRUE(sensor.quantum.has_value());
  const auto motion_at = [&](double frequency) {
    std::vector<double> x(r.size());
    for (std::size_t k = 0; k < r.size(); ++k)
      x[k] = 4e-6 * std::sin(2 * kPi * frequency * r.time[k]) * (1 + 0.3 * std::sin(r.time[k]));
    return x;
  };
  const std::vector<double> slow = motion_at(1.7), fast = motion_at(9.0);
  Record holding = r;
  holding.displacement = slow;
  int differ = 0;
  for (std::uint64_t seed = 11; seed <= 14; ++seed) {
    Record a, b, c;
    friction::DerivativeWindows wa, wb, wc;
    ASSERT_TRUE(friction::remeasured_replica(r, slow, seed, a, sensor, &wa));
    ASSERT_TRUE(friction::remeasured_replica(holding, seed, b, sensor, &wb));
    EXPECT_EQ(wa, wb) << seed;
    EXPECT_EQ(a.displacement, b.displacement) << seed;
    EXPECT_EQ(a.measured_displacement, b.measured_displacement) << seed;
    EXPECT_EQ(a.force, r.force) << seed;
    // With the slow motion's windows remembered for this seed, the fast one gets the rule's own.
    ASSERT_TRUE(friction::remeasured_replica(r, fast, seed, c, sensor, &wc));
    EXPECT_EQ(wc, friction::choose_derivative_windows(c.time, c.measured_displacement)) << seed;
    differ += wc == wa ? 0 : 1;
  }
  EXPECT_GT(differ, 0) << "the two motions' replicas should get different windows";
  const std::vector<double> short_motion(slow.begin(), slow.end() - 1);
  Record e;
  EXPECT_THROW(friction::remeasured_replica(r, short_motion, 1, e, sensor), friction::Error);
}

// The smoothest motion within an encoder's readings (smoothest_motion_within_quanta), checked
// against its own definition without the library's solver: it lies inside every tube, it is no
// rougher than the true motion (which lies inside them too), and it satisfies the optimality
// conditions of the constrained problem: where it is well inside its tube the gradient of the
// roughness vanishes.  A strokes motion with rests (the slow parts where the staircase's plateaus
// matter), at regular and at jittered sampling, strokes of 40 and 400 steps.  What it is for, the
// spread of the replicas' fits, is judged by the discovery study's coverage (README, "The
// replicas' motion"): the displacement's own rms does not tell the two motions apart.
namespace {
struct StrokesRecord {
  Record record;               // the encoder's readings, not conditioned
  std::vector<double> exact;   // the motion
};
StrokesRecord strokes_with_rests(double quantum, double stroke_quanta, double jitter,
                                 std::uint64_t seed) {
  StrokesRecord out;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  for (int k = 0; k < 6000; ++k) {
    const double t = 1e-3 * (k + jitter * u(rng));
    // Period 2 s: rest 0.4 s, a 0.6 s stroke up with a cosine profile, rest, a stroke down.
    const double p = std::fmod(t + 2.0, 2.0);
    double s = 0;
    if (p >= 0.4 && p < 1.0) s = 0.5 * (1 - std::cos(kPi * (p - 0.4) / 0.6));
    else if (p >= 1.0 && p < 1.4) s = 1;
    else if (p >= 1.4) s = 0.5 * (1 + std::cos(kPi * (p - 1.4) / 0.6));
    const double x = quantum * (stroke_quanta * s + 0.3 * std::sin(2 * kPi * 0.37 * t));
    out.record.time.push_back(t);
    out.exact.push_back(x);
    out.record.displacement.push_back(quantum * std::round(x / quantum + 0.37) - 0.37 * quantum);
  }
  out.record.force.assign(out.exact.size(), 0.0);
  return out;
}
// Sum of squared second divided differences times Ts^2 (Ts the median interval), in units of q,
// and its gradient.
double roughness(const std::vector<double>& t, const std::vector<double>& x, double q,
                 std::vector<double>* gradient = nullptr) {
  const std::size_t n = x.size();
  std::vector<double> h(n - 1);
  for (std::size_t k = 0; k + 1 < n; ++k) h[k] = t[k + 1] - t[k];
  std::vector<double> sorted(h);
  std::sort(sorted.begin(), sorted.end());
  const double ts = sorted[sorted.size() / 2];
  double sum = 0;
  if (gradient) gradient->assign(n, 0.0);
  for (std::size_t k = 0; k + 2 < n; ++k) {
    const double h0 = h[k] / ts, h1 = h[k + 1] / ts, c = 2 / (h0 + h1);
    const double w[3] = {c / h0, -c / h0 - c / h1, c / h1};
    const double d = (w[0] * x[k] + w[1] * x[k + 1] + w[2] * x[k + 2]) / q;
    sum += d * d;
    if (gradient)
      for (int j = 0; j < 3; ++j) (*gradient)[k + static_cast<std::size_t>(j)] += 2 * d * w[j];
  }
  return sum;
}
}  // namespace

TEST(Conditioning, TheSmoothestMotionWithinTheQuantaSolvesItsProblem) {
  const double q = 1e-8;
  for (const double jitter : {0.0, 0.3}) {
    for (const double stroke : {40.0, 400.0}) {
      SCOPED_TRACE(testing::Message() << "jitter " << jitter << ", stroke " << stroke << " q");
      const StrokesRecord s = strokes_with_rests(q, stroke, jitter, 7);
      const std::vector<double>& m = s.record.displacement;
      const std::vector<double> b =
          friction::smoothest_motion_within_quanta(s.record.time, m, q);
      ASSERT_EQ(b.size(), m.size());
      for (std::size_t k = 0; k < m.size(); ++k)
        ASSERT_LT(std::abs(b[k] - m[k]), 0.5 * q) << k;
      std::vector<double> gradient;
      const double rough = roughness(s.record.time, b, q, &gradient);
      EXPECT_LT(rough, roughness(s.record.time, s.exact, q)) << "rougher than the true motion";
      // Optimality: with the walls 0.05 q away or more, the gradient is that of the barrier at
      // its last weight mu, below 2 mu / 0.05.  The bound is that of mu = 1e-6 (4e-5), the
      // weight the stopping rule (2 N mu below a thousandth of the roughness) passes below on
      // any of these records; at the walls the gradient is what holds the motion there, several
      // orders larger.
      double inside = 0, largest = 0;
      std::size_t free = 0;
      for (std::size_t k = 0; k < m.size(); ++k) {
        const double wall = 0.5 - std::abs(b[k] - m[k]) / q;
        largest = std::max(largest, std::abs(gradient[k]));
        if (wall >= 0.05) {
          inside = std::max(inside, std::abs(gradient[k]));
          ++free;
        }
      }
      EXPECT_GT(free, m.size() / 4);
      EXPECT_LT(inside, 4e-5) << "largest at the walls " << largest;
      EXPECT_GT(largest, 100 * inside);
      // The same problem in other units (time in ms, displacement in um) has the same solution.
      std::vector<double> t_ms(m.size()), m_um(m.size());
      for (std::size_t k = 0; k < m.size(); ++k) {
        t_ms[k] = 1e3 * s.record.time[k];
        m_um[k] = 1e6 * m[k];
      }
      const std::vector<double> b_um =
          friction::smoothest_motion_within_quanta(t_ms, m_um, 1e6 * q);
      for (std::size_t k = 0; k < m.size(); ++k) ASSERT_NEAR(1e-6 * b_um[k], b[k], 1e-3 * q) << k;
    }
  }
}

// ------------------------------------------------------------------ the real tribometer record

TEST(Tribometer, ReadsTheReciprocatingRecord) {
  const std::filesystem::path path =
      std::filesystem::path(FRICTION_SHARED_DIR) / "data/tribometer/reciprocating.csv";
  if (!std::filesystem::exists(path))
    GTEST_SKIP() << "tribometer record not present at " << path.string() << "; test skipped";
  const Record r = friction::read_record(path);
  EXPECT_EQ(r.size(), 42579u);
  EXPECT_EQ(r.time_column, "time_s");
  EXPECT_EQ(r.displacement_column, "position_m");
  EXPECT_EQ(r.force_column, "friction_force_N");
  ASSERT_TRUE(r.has_normal());
  EXPECT_EQ(r.normal_column, "normal_force_N");
  const auto& c = r.conditioning;
  EXPECT_EQ(c.force_sign, -1);
  EXPECT_TRUE(c.force_sign_decided);
  EXPECT_TRUE(c.irregular);
  EXPECT_EQ(c.gaps.size(), 178u + 1u);
  std::size_t ten_ms = 0, nine_ms = 0;
  for (const auto& g : c.gaps) {
    if (std::abs(g.dt - 0.010) < 1e-9) ++ten_ms;
    if (std::abs(g.dt - 0.009) < 1e-9) ++nine_ms;
  }
  EXPECT_EQ(ten_ms, 178u);
  EXPECT_EQ(nine_ms, 1u);
  EXPECT_NEAR(c.nominal_period, 0.005, 1e-12);
  EXPECT_TRUE(c.displacement_quantised);
  EXPECT_NEAR(c.displacement_resolution, 1e-7, 1e-12);  // 1e-4 mm in the original file
  EXPECT_GT(c.force_noise, 0.0);
  EXPECT_LT(c.force_noise, 0.05);  // against a sliding force of about 2.5 N
  EXPECT_TRUE(any_warning_contains(r, "force_sign: -1"));
  EXPECT_TRUE(any_warning_contains(r, "178 x 0.01 s, 1 x 0.009 s"));
  // Loaded sliding in the model's convention: F*v > 0 in sliding.
  double work = 0;
  for (std::size_t k = 1; k < r.size(); ++k)
    work += r.force[k] * (r.displacement[k] - r.displacement[k - 1]);
  EXPECT_GT(work, 0.0);
}

}  // namespace
}  // namespace test_signals
