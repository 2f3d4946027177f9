// Signal conditioning of a record: force sign, sampling regularity, resolution and noise.
//
// Force sign (methods.md, "Sign convention").  Every model gives the force that resists the motion
// as the drive sees it, so while sliding F and v have the same sign.  A tribometer often records
// the force on the moving specimen instead, i.e. the opposite sign.  The sign is decided from
// sliding samples only (presliding is elastic: F and v have either sign there):
//
//   v_k      = (x_{k+2} - x_{k-2}) / (t_{k+2} - t_{k-2})   centred over 4 intervals, which divides
//                                                          encoder steps and noise by 4 at no cost
//                                                          for a sign decision
//   sliding  : |v_k| > thr = 0.2 * q98(|v|)   (q98: the 98th percentile of |v|, so the rule
//                                              scales with the record's own speed and ignores a
//                                              few spikes)
//   decision : D = median(F | v > +thr) - median(F | v < -thr), sign = sgn(D).
//
// D is the sign of F·v while sliding, made insensitive to a constant force offset (an offset moves
// both medians alike; a plain sum of F·v would pick up offset · net travel).  When the record
// slides in one direction only, D falls back to sgn(v) · median(F) over the sliding samples.  D
// decides only when it is clear of the scatter: |D| > 4 standard errors of the difference of the
// medians (1.2533 · spread / sqrt(n) per group, spread = 1.4826 · MAD of the group's forces, so
// real variation of the sliding force counts as scatter too); otherwise (or with fewer than 5
// sliding samples per direction used) the medians do not decide.
//
// A force that varies strongly while sliding (a drive's m·a many times the Coulomb level, a steep
// viscous term) widens the medians' spread until they cannot decide.  The sliding force is then
// regressed on what varies it (sliding_force_regression below):
//
//   F_k = c sgn(v_k) + f0 + b v_k + m a_k + e_k     over the sliding samples,
//
// with v and a at the sample instants (sample_derivatives.hpp), and D = 2 c, its standard error
// 2 se(c) from the residual scatter; the same 4-standard-error rule decides.  When neither decides,
// +1 is kept and a warning says so.
//
// Irregular sampling.  The nominal period Ts is the median interval; an interval is a *gap* when
// |dt - Ts| > tol · Ts (tol = 1 % by default).  The models step with each interval's own dt
// (motion.hpp), so irregular records are kept as they are, never resampled (resampling would
// invent displacement the sensor never saw and smear the elastic presliding response); the gaps
// are counted and reported.  Only dt <= 0 (or non-finite time) is refused, as a DataError.
//
// Displacement resolution.  Encoders and digitised sensors step in a quantum q: every nonzero
// increment |dx| is an integer multiple of q.  Candidate q0 = the smallest |dx| that occurs at
// least max(3, 0.1 %) times (rare tiny increments are rounding artefacts, not the quantum); then
// q = q0 / m for the smallest m in 1..64 such that >= 90 % of the nonzero |dx| lie within 0.02 q of
// a multiple of q; q is refined as the median of |dx| / round(|dx| / q).  If no quantum exists
// (analog, noisy signal) the resolution is the noise level below.  The resolution reported is
// max(quantum, noise): a threshold below either cannot be seen in the data.
//
// Noise level.  For white noise of standard deviation s on a signal that is smooth on the scale of
// a sample, the second difference e_{k+1} - 2 e_k + e_{k-1} has standard deviation sqrt(6) s.  Its
// median absolute deviation (MAD), times 1.4826 for a normal distribution, ignores up to half the
// samples being outliers (stick-slip jumps, reversals), so s = 1.4826 · MAD(d2) / sqrt(6).  Bias:
// on a signal that curves within a few samples the estimate includes that curvature (an upper bound
// on the noise).  A quantised, quiet signal has MAD = 0: its noise is then the quantisation noise
// q / sqrt(12), or 0 for a noiseless synthetic signal.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "friction/record.hpp"
#include "friction/sample_derivatives.hpp"

namespace friction {

/// How to treat the sign of the recorded force (`--force-sign +1|-1|auto`).
enum class ForceSign { automatic, positive, negative };

/// "auto", "+1" or "-1".
const char* to_string(ForceSign s) noexcept;

/// Default relative tolerance of the regular-sampling rule.
inline constexpr double kDefaultPeriodTolerance = 0.01;

/// Sampling analysis of a time vector.
struct SamplingReport {
  double nominal_period = 0.0;                 ///< median interval [s]
  double min_period = 0.0;                     ///< [s]
  double max_period = 0.0;                     ///< [s]
  double tolerance = kDefaultPeriodTolerance;  ///< relative tolerance used
  std::vector<SamplingGap> gaps;               ///< intervals with |dt - Ts| > tolerance * Ts
  bool irregular() const noexcept { return !gaps.empty(); }
};

/// Nominal period and gaps of `time` (>= 2 samples).  Throws DataError(source, line, 0, ...) on a
/// non-finite time or an interval <= 0; `first_line` (0 if unknown) locates sample 0 in `source`.
SamplingReport analyse_sampling(std::span<const double> time,
                                double tolerance = kDefaultPeriodTolerance,
                                const std::string& source = {}, long first_line = 0);

/// One sentence describing the gaps (count and sizes), empty when the sampling is regular.
std::string describe_sampling(const SamplingReport& report, std::size_t intervals);

/// The sign of the recorded force relative to the model's convention, as decided from the data.
struct ForceSignEstimate {
  int sign = 1;                     ///< +1 or -1 (+1 when undecided)
  bool decided = false;             ///< the data were clear enough to decide
  bool both_directions = false;     ///< decided from sliding in both directions (offset-robust)
  std::size_t sliding_samples = 0;  ///< samples that counted as sliding
  double sliding_velocity = 0.0;    ///< the |v| threshold [m/s]
  double difference = 0.0;          ///< D [N] (see the header comment)
  double standard_error = 0.0;      ///< its standard error [N]
};

/// The sliding force regressed on sgn(v), 1, v and a (see the header comment); the coefficients in
/// the order coulomb, offset, viscous, mass, each with its standard error.
struct SlidingForceRegression {
  std::size_t samples = 0;  ///< sliding samples used (0: too few, nothing estimated)
  double coulomb = 0, offset = 0, viscous = 0, mass = 0;
  double coulomb_se = 0, offset_se = 0, viscous_se = 0, mass_se = 0;
  std::vector<double> acceleration;  ///< a(t_k) over the whole record [m/s^2]
};
SlidingForceRegression sliding_force_regression(std::span<const double> time,
                                                std::span<const double> displacement,
                                                std::span<const double> force);

/// The displacement the models see, from a measured one (condition_record's rule,
/// sample_derivatives.hpp): the local polynomial's value at each t_k when the record's window rule
/// gives a window longer than three samples; empty when the measured displacement is used as it is
/// (then, and below 16 samples, `windows` is left unchanged).
std::vector<double> displacement_the_models_see(std::span<const double> time,
                                                std::span<const double> measured,
                                                DerivativeWindows* windows = nullptr);

/// Decide the force sign of a record (see the header comment).
ForceSignEstimate estimate_force_sign(std::span<const double> time,
                                      std::span<const double> displacement,
                                      std::span<const double> force);

/// The quantum of a digitised signal (every nonzero step a multiple of it), if there is one.
std::optional<double> signal_quantum(std::span<const double> signal);

/// Standard deviation of white noise on a smooth signal: 1.4826 MAD(second differences)/sqrt(6).
double noise_level(std::span<const double> signal);

/// Displacement resolution [m] (see the header comment).
struct Resolution {
  double value = 0.0;             ///< max(quantum, noise) [m]
  std::optional<double> quantum;  ///< the encoder-like quantum, when there is one
  double noise = 0.0;             ///< noise_level(displacement)
};
Resolution estimate_displacement_resolution(std::span<const double> displacement);

/// The smoothest motion an encoder's readings allow: the displacement b with the least sum of
/// squared second divided differences (in time) subject to |b_k - m_k| < q / 2, m the readings
/// as measured and q the encoder's step (a reading is the motion rounded to its grid).  Solved by
/// a log-barrier method whose Newton steps are pentadiagonal solves: O(N) each, 17-19 of them on
/// the 6,000-sample strokes records of test_signals.cpp.
///
/// Why: the replicas that measure what the encoder does to a fit (remeasured_replica) need a
/// motion to requantise.  The conditioned displacement, the best estimate of the motion sample by
/// sample, keeps the staircase's plateaus where the motion is slow (a local polynomial cannot
/// remove a step that is wider than its window); requantised, a plateau reads one level for its
/// whole length, so replicas made from it carry less of the staircase's error than the record
/// did.  On a strokes record of the discovery study (12 elements, 404 Hz, q = 1e-9 m, noise-free),
/// the replicas' spread of the fitted delay was 0.018 ms from the conditioned displacement,
/// 0.037 ms from the true motion, and 0.036 ms from this one (README, "The replicas' motion").
std::vector<double> smoothest_motion_within_quanta(std::span<const double> time,
                                                   std::span<const double> measured,
                                                   double quantum);

/// A replica of `record` measured again by its own displacement sensor: the displacement the models
/// see, `r.displacement` (the best estimate of the motion there is), quantised again by the
/// record's encoder step with a random phase (q round((x + u)/q) - u, u uniform in [0, q)), or,
/// without a quantum, with white noise of the record's displacement noise added; then conditioned
/// as condition_record conditions (displacement_the_models_see: the window rule run on the
/// replica).  Time, force and normal force are the record's.  What the models' input error does to
/// a fit is measured on such replicas (the covariance of extension_families.hpp): the errors of a
/// staircase depend on the motion (constant at rest, correlated over a slow presliding loop), which
/// white noise of q / sqrt(12) would not reproduce (the covariance passes the smoothest motion
/// within the quanta instead, above, to the overload that takes a motion).  `seed` picks the
/// replica; the same seed gives the same replica.  False (the record unchanged) when the sensor
/// has neither a quantum nor noise.
///
/// `sensor`: estimate_displacement_resolution(record.measured()), when the caller makes many
/// replicas of one record.  `windows` (when given) receives the windows the rule chose on the
/// replica, which a simulation of the replica needs (simulate_extended would choose them again).
/// The rule's choice on a replica is remembered for the last few records (by a fingerprint of
/// their time and displacement, record_fingerprint.hpp) and the seed: a diagnosis asks for the
/// same 24 replicas of its estimation record at every report, and choosing the windows was a
/// tenth of it.
bool remeasured_replica(const Record& record, std::uint64_t seed, Record& replica,
                        const Resolution& sensor, DerivativeWindows* windows = nullptr);
/// The seed of replica j (j = 0, 1, ...) as the covariance's replicas and the diagnosis's sensor
/// floor draw them: one sequence, so that a replica the one made has its windows remembered for
/// the other.
inline std::uint64_t replica_seed(std::size_t j) { return 0x9e3779b97f4a7c15ULL * (j + 1); }
/// The same for another motion at the record's time stamps (`motion`, one value per sample, in
/// place of the record's displacement): the smoothest motion within an encoder's quanta, without
/// a copy of the record to hold it.
bool remeasured_replica(const Record& record, std::span<const double> motion, std::uint64_t seed,
                        Record& replica, const Resolution& sensor,
                        DerivativeWindows* windows = nullptr);
bool remeasured_replica(const Record& record, std::uint64_t seed, Record& replica);

/// Force noise standard deviation [N]: noise_level, or quantum / sqrt(12) when that is 0.
double estimate_force_noise(std::span<const double> force);

/// What `condition_record` does.
struct ConditioningOptions {
  ForceSign force_sign = ForceSign::automatic;
  double period_tolerance = kDefaultPeriodTolerance;
};

/// Condition `record` in place and return (and store in record.conditioning) what was found and
/// done: checks sizes, finiteness and dt > 0 (DataError naming record.source and the line), applies
/// the force sign (flips the force when it is -1), analyses sampling, estimates resolution and
/// noise, and writes the warnings.  Call it once per record as read (read_record does).
const Conditioning& condition_record(Record& record, const ConditioningOptions& options = {});

}  // namespace friction
