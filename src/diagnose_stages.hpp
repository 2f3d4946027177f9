// The stages of diagnose() (diagnose.hpp), private to the library, over typed data:
//
//   fit_baseline       the NLR baseline and what one more operator buys    diagnose_baseline.cpp
//   fit_lugre_baseline a LuGre baseline and its one candidate, nonlocal-memory
//                                                                           diagnose_baseline.cpp
//   gather_evidence    the residual of a model on a record                 residual_evidence.cpp
//   fit_candidates     every remaining candidate on top of the current model
//                                                                         diagnose_candidates.cpp
//   accept             the acceptance rule of section 4, as a Verdict     diagnose_candidates.cpp
//   forward_pass       greedy rounds                                      diagnose_candidates.cpp
//   backward_pass      removal of pieces that no longer earn their place  diagnose_candidates.cpp
//   polish_final       the final model's restart with global stage and growth
//                                                                         diagnose_candidates.cpp
//   report             findings, warnings and the final model               diagnose_report.cpp
//
// No stage shares mutable state with another: each takes its inputs by const reference (the
// records, the options and the immutable Context) and returns a value.  The candidates of a round
// are independent fits (fit_candidate), which is what lets them run concurrently; the optimisers
// hold no global state that one candidate could change for another (Ceres runs single-threaded per
// fit, the residual buffers are per thread, and the only random numbers are those of LG's global
// stage, drawn from a generator of its own, seeded by LgOptions::seed).
#pragma once

#include <cmath>
#include <cstddef>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "friction/diagnose.hpp"
#include "friction/extension_fit.hpp"
#include "friction/methods.hpp"

namespace friction::extension_detail {
class JointFitMemo;  // joint_fit_memo.hpp
}  // namespace friction::extension_detail

namespace friction::diagnose_detail {

/// One model of the chain: the Maxwell Slip base, its relative initial deflections, its pieces
/// (reference_force = F0 of the baseline), its estimation RSS and validation error.
struct State {
  MaxwellSlipParameters<double> base;
  std::vector<double> rho;
  ExtensionParameters<double> ext;
  double rss = 0;
  double validation = 0;      ///< RSS/SSS %
  std::vector<Effect> order;  ///< accepted pieces, in order
  /// Parameters the fit of this state left on an edge of their range.
  std::vector<std::pair<Effect, std::string>> at_bound;
};

/// What every stage after the baseline reads and none changes.
struct Context {
  const Record& est;
  const Record& val;
  const DiagnoseOptions& options;
  std::size_t n = 0;           ///< estimation samples
  double sigma = 0;            ///< white-noise estimate of the estimation force [N]
  double floor_rss = 0;        ///< N sigma^2 [N^2]
  double f0ref = 0;            ///< F0 of the baseline: the level pieces' reference force [N]
  double operator_drop = 0;    ///< what one more operator drops the baseline's RSS by [N^2]
  double baseline_excess = 0;  ///< the baseline's RSS above the noise floor [N^2]
  /// What the displacement's sampling puts into the baseline's force on `est`
  /// (measurement_floor_rss) [N^2]: with floor_rss, the estimation record's floor.
  double estimation_measurement_rss = 0;
  DerivativeWindows windows;   ///< the estimation record's (sample_derivatives.hpp)
  ProfileScales scales;        ///< the estimation record's, for the profiled starts
  double validation_floor_percent = 0;        ///< the validation record's noise floor, RSS/SSS %
  /// What the displacement's sampling puts into the baseline's force there (measurement_floor_rss),
  /// RSS/SSS %.
  double validation_measurement_percent = 0;
  /// The position subtracted from both records (position_origin.hpp): 0 when not shifted.
  double position_origin = 0;
  /// The restarts' joint fits on `est`, remembered for the final polish (joint_fit_memo.hpp).
  extension_detail::JointFitMemo* joint_fits = nullptr;
  /// The derivative windows of `est` refined as stepped_finely refines it.
  const DerivativeWindows* fine_windows_est = nullptr;

  /// The validation floor with the displacement's sampling in it: a model validating at or below
  /// it leaves nothing for a piece to explain, so no candidate on it passes rule (c).
  double validation_floor_with_sampling() const {
    return validation_floor_percent + validation_measurement_percent;
  }
  /// Whether a model of estimation RSS `rss` is within three standard deviations of the noise's
  /// RSS (sqrt(2 N) sigma^2 each) of the estimation record's floor, the noise's plus what the
  /// displacement's sampling puts there: no drop from it is real (rule b).
  bool estimation_at_floor(double rss) const {
    return floor_rss > 0.0 &&
           rss <= floor_rss * (1.0 + 3.0 * std::sqrt(2.0 / static_cast<double>(n))) +
                      estimation_measurement_rss;
  }
};

// ---- baseline -----------------------------------------------------------------------------

struct Baseline {
  IdentifiedModel nlr;  ///< the maxwell-slip identification
  State state;          ///< its model as the chain's first state
  double operator_drop = 0;
  std::vector<std::string> warnings;
  double seconds = 0;  ///< of the NLR identification
};

/// NLR on the estimation record, its errors, and what one more operator buys (section 4, b).
Baseline fit_baseline(const Record& est, const Record& val, const DiagnoseOptions& o);

/// What the displacement's sampling puts into the force of the model of `s` started from the
/// relative deflections `rho` on record `r` whose derivative windows are `w` [N^2] (section 4, the
/// floors): its sensor's error, the mean over replicas of the record remeasured by its own sensor
/// (remeasured_replica; nothing when the sensor has neither a quantum nor noise) of the sum of
/// squared changes of the model's force, plus its stepping once per sample, the sum of squared
/// differences between the force stepped per sample and stepped_finely (`fine_windows`: as
/// there).  The replicas run on `threads` threads; the result does not depend on it.
double measurement_floor_rss(const State& s, const std::vector<double>& rho, const Record& r,
                             const DerivativeWindows& w, unsigned threads,
                             const DerivativeWindows* fine_windows = nullptr);

/// The model of `s` from the deflections `initial` run on the record refined to four steps per
/// sample (displacement by interpolate_displacement, normal force linearly), its force at the
/// record's samples: the model as stepping once per sample does not see it.  `fine_windows`: the
/// refined record's derivative windows (fine_grid_windows) when the caller has them; chosen for
/// it otherwise.
std::vector<double> stepped_finely(const State& s, std::span<const double> initial,
                                   const Record& r,
                                   const DerivativeWindows* fine_windows = nullptr);

/// The derivative windows of the record refined as stepped_finely refines it.
DerivativeWindows fine_grid_windows(const Record& r);

/// Replica j of the sensor floor (measurement_floor_rss) made once, so that remeasured_replica
/// remembers its derivative windows: they depend on the record alone, and the rule that chooses
/// them was most of the floors' time.
void warm_sensor_replica(const Record& r, std::size_t j);

// Replicas of the sensor floor.  Its relative sampling error is about sqrt(2 / 8) = 0.5 for a
// floor made by a few stiff operators at a few reversals, less where many samples contribute: a
// floor, unlike a standard error, only needs its order of magnitude.  The seeds are those of the
// covariance's replicas (replica_seed, signals.hpp); with an encoder those are made from the
// smoothest motion within its quanta, not from the record, so their windows are chosen again.
inline constexpr std::size_t kSensorReplicas = 8;

/// A LuGre baseline: LG, its validation, and its one candidate (Maxwell Slip elements, from the
/// NLR baseline).  Fills the baseline part of `dx` and its first round; returns the finding when
/// the candidate earns its place.
std::optional<Finding> fit_lugre_baseline(const Context& c, const Baseline& nlr, Diagnosis& dx);

// ---- evidence -----------------------------------------------------------------------------

/// The residual evidence of a model of the chain on a record, from relative deflections `rho`.
ResidualEvidence gather_evidence(const MaxwellSlipParameters<double>& base,
                                 const ExtensionParameters<double>& ext, const Record& r,
                                 const std::vector<double>& rho);

// ---- candidates and acceptance --------------------------------------------------------------

/// A candidate's record and its fit.
struct Tried {
  CandidateFit fit;
  ExtendedSlipFit result;
  bool stopped = false;  ///< result's fit stopped early (candidate_target: it cannot pass)
};

/// Effect e fitted on top of state s as a candidate of a round is (evidence, profile, fit, rules).
Tried fit_one_candidate(const Context& c, const State& s, Effect e);

/// The rule of section 4: from RSS0 to RSS1 with p extra parameters, validation val0 -> val1 (NaN:
/// not evaluated).
Verdict accept(const Context& c, double rss0, double rss1, std::size_t p, double val0, double val1,
               double phi = 0);

/// AR(1) coefficient of the estimation residual of a Maxwell Slip model with pieces.
double residual_phi(const Context& c, const MaxwellSlipParameters<double>& base,
                    const ExtensionParameters<double>& ext, const std::vector<double>& rho);

/// Every candidate of `pool` not yet in `s`, fitted on top of `s` (independent fits), with the
/// nested checks applied.
std::vector<Tried> fit_candidates(const Context& c, const State& s,
                                  const std::vector<Effect>& pool);

/// The chain of accepted models and the rounds that accepted them.
struct Chain {
  std::vector<State> states;               ///< baseline first
  std::vector<std::vector<Tried>> rounds;  ///< rounds[i] accepted states[i + 1]
  bool removed = false;                    ///< the backward pass removed a piece
  std::vector<std::string> warnings;
};

/// Greedy rounds from `start` (section 4); the first round's candidates go to `first_round`.
Chain forward_pass(const Context& c, const State& start, const std::vector<Effect>& pool,
                   std::vector<CandidateFit>& first_round);

/// Removes accepted pieces that no longer earn their place against the others, and recomputes
/// the chain for what remains.
Chain backward_pass(const Context& c, Chain chain);

/// The final model's restart with the global stage and the order growth of identify
/// (extension_identification.hpp, section 1), once, after the backward pass: kept when its BIC
/// is lower.
void polish_final(const Context& c, Chain& chain);

// ---- report ---------------------------------------------------------------------------------

/// The findings of the chain, the warnings on strong but rejected candidates, and the final model
/// with its standard errors.
void report(const Context& c, const Chain& chain, Diagnosis& dx);

/// The fit a state of the chain holds, as extension_fit.hpp reports it.
ExtendedSlipFit fit_of(const State& s);

}  // namespace friction::diagnose_detail
