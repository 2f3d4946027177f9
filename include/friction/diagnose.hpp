// Diagnosis: what a baseline model's simulation gets wrong, which effect of methods.md section 7
// causes it, and how much an extension of the model gains (the `diagnose` command, cli.md).
//
// 1. Baseline.  NLR (maxwell-slip) by default, identified on the estimation record with the
//    methods of methods.hpp.  A LuGre baseline (`baseline = "lugre"`) is scored and analysed the
//    same way; its one candidate is `nonlocal-memory` (an NLR Maxwell Slip model with `elements`
//    operators), after which the analysis continues on that Maxwell Slip model.
//
// 2. Evidence.  The current model runs free on a record from an estimated initial state and the
//    residual e = F - Fhat is examined:
//      * by regime, from the model's own operator states (sliding when every operator sits at its
//        threshold, presliding otherwise): mean and RMS of e in each;
//      * against velocity (sliding samples binned by |v| in each direction: mean e per bin),
//        acceleration, position, time and the normal force when there is one: the share of the
//        residual's sum of squares that each effect's signature explains by linear regression
//        (`explained`, 0..1), and its regression coefficient, which gives the start of the fit;
//      * across time shifts: the normalised cross-correlation of e with the displacement
//        increments at lags of +-L samples, and the lag that best explains e as a shift of the
//        simulated force (the delay's signature).
//    Each effect's signature, its grid (the one Stribeck start grid of the library, with the
//    measurement behind it) and the start it gives are rows of effect_table.hpp.  The candidates
//    are ranked by `explained`.  The
//    ranking is not trusted alone: every candidate the record can support (normal-load needs a
//    normal force) is fitted.
//
// 3. Fitting an extension.  The Maxwell Slip parameters (log k_i, log Delta_i, relative initial
//    deflections rho_i = delta_i(0) / Delta_i in [-1, 1]) are refitted jointly with the
//    extension's parameters by Ceres (Levenberg-Marquardt, automatic derivatives through
//    Extended<MaxwellSlip<Jet>> and simulate_extended), from the current solution plus a
//    data-driven start for the new piece (its regression coefficient, a grid over the wavelength,
//    the lag of the cross-correlation).  Level effects scale the thresholds (methods.md 7 and 8:
//    scaling and refitting named the right effect where added regressors on fixed thresholds did
//    not). During the fit the level pieces refer to a fixed F0 (the current model's sliding force)
//    so that a common scale of the thresholds stays identifiable; the reported parameters are
//    converted to the model's own F0 at the end.  `frictional-lag` is a lag of the velocity that
//    the viscous or Stribeck piece sees: without one of them it is fitted together with a viscous
//    piece.
//    A candidate's fit stops early when, at the pace of its last ten iterations, those it has
//    left would not take its RSS below the largest RSS1 that could pass rules (a) and (b) of
//    section 4: RSS0 exp(-p ln N / N), and RSS0 minus the least drop (b) asks (its noise part at
//    the white-noise variance, which coloured noise only raises).  Such a candidate fails the
//    rules; its verdict says that it stopped, and its figures are where it stopped.  The pace is
//    an extrapolation, not a bound, so it is only read over ten iterations in which the fit's
//    trust region settled (shrank by less than 4; bounded_solver.hpp, HopelessSearch): a region
//    still collapsing is a search that has not yet found its descent.  Judged on any ten
//    iterations, a Stribeck curve on a study record's offset model was stopped that would have
//    passed the rules (seed 20261207, stribeck+offset, which then named the offset alone).  On
//    data/ the position term of the third round ran to the 60 iterations allowed (1.2 of the
//    diagnosis's 5.9 s) and now stops after 12.  `stop_hopeless_candidates` switches it off.
//
// 4. Acceptance rule.  With N estimation samples, RSS0 the current model's estimation RSS, RSS1
//    the candidate's, p its extra parameters, sigma the white-noise estimate of the force
//    (metrics.hpp) and floor = N sigma^2, a candidate earns its place when ALL of
//      (a) it lowers BIC on the estimation record: N ln(RSS1/RSS0) + p ln N < 0;
//      (b) the drop RSS0 - RSS1 is real: larger than what p parameters buy on noise,
//          chi2_{p, 0.999} sigma^2, and larger than `min_excess_share` (10 %) of the part of RSS0
//          above the noise floor, max(RSS0 - floor, 0), and larger than what one more Maxwell
//          Slip operator buys on the same record, RSS(M) - RSS(M+1) (`operator_reference`; from
//          the order selection's table, or from a fit with M + 1 operators when M is the largest
//          the selection tried, i.e. when max_operators capped it).  The second and third parts
//          keep a model whose M is short of the system's from buying spurious extensions
//          (methods.md 8).  The share alone did not: on records with no hidden effect (4-operator
//          system, 4000 samples, noise 2 mN, test_diagnose_effects) and the baseline capped at
//          M <= 2 or M <= 3, the residual stayed 20-400 times the noise floor, a delay of -1 to
//          -4 ms (the force leading), an asymmetry or a position term took 10-19 % of it, over
//          the 10 % share, and validated slightly better (gain x1.03-1.43): false findings on
//          4/20 and 3/20 records.  The reference needs no tuned number: an extension that
//          explains less of the residual than one more element would is more likely standing in
//          for the missing element than describing an effect, and the finding is then withheld
//          with a warning that the baseline may be short of operators.  When the selection chose
//          M freely, BIC already judged M + 1 not worth its two parameters, so its drop is below
//          2 ln N RSS/N (0.4 % of RSS here) and the third part changes nothing.  The reference is
//          measured on the baseline; once pieces are accepted it is scaled by the share of the
//          baseline's misfit (RSS above the floor) that is left, i.e. one more operator is taken
//          to remove the same share of what remains (unscaled, a normal-load piece that removed
//          99 % of the misfit left a real viscous term below the baseline's figure).  No drop
//          is real on a model whose RSS0 is within three standard deviations of the noise's RSS
//          (sqrt(2 N) sigma^2 each) of the estimation record's floor, N sigma^2 plus what the
//          displacement's sampling puts into the baseline's force there (the measurement floor
//          of (c) below, on the estimation record): nothing is left there for a piece to explain
//          that the noise and the sampling would not, and a piece with a free parameter fits
//          them instead.  Without it, an offset (z = 3.3) entered on a LuGre-study record whose
//          NLR model sat 1.5 standard deviations above that floor, validating 5 % better (discovery
//          study seed 3827228095007739670, nonlocal-memory-6), and a position term on a no-effect
//          record of the main study (seed 990001, none-01);
//      (c) it lowers the validation error (RSS/SSS % on the validation record, initial state
//          estimated there) by at least the share of rule (b) of what lies above that record's
//          noise floor: the gain must hold on the record the fit did not see in the measure it
//          had on the one it saw.  A plain fall let the model's structural misfit in: on
//          records of the independent simulator without any effect (its elements are not
//          Maxwell Slip operators, so the baseline stops 2-4 times above the noise floor) a
//          Stribeck curve bought 10-30 % of the estimation misfit and 4-8 % of the validation's
//          (3 of 22 records named an effect they do not hold).  A model that already validates
//          at or below the record's floor has nothing above it to explain, and no candidate
//          earns its place: with the plain share (zero there) an inertia entered beside a delay
//          and a position term that were at the floor, for a 1 % fall of an error already below
//          it.  That floor is the force noise's plus what the displacement's sampling puts into
//          the baseline's force, which no model driven by the measured displacement removes:
//          its sensor's error (the baseline run on replicas of the record remeasured by its own
//          sensor, remeasured_replica, against the baseline on the record; the mean sum of
//          squared changes over eight replicas) and its stepping once per sample (the baseline
//          on the displacement refined to four cubic-interpolated steps per sample against the
//          baseline per sample).  Without it, at the discovery study's seed of 17bdcec
//          (1710750793468752286), 3 of 22 records without any effect named one (an asymmetry, a
//          position term, validating 0.5-11 % better), on records whose encoder step q moved the
//          stiffness sum's force K q by 2 to 24 times the force noise, and whose baselines
//          validated below the error of the true system stepped per sample on the recorded
//          displacement; with it, one.  The share asked for stays a share of what lies above the
//          noise floor alone: the measurement floor is an estimate good to its order of
//          magnitude, which may say that nothing is left but not how much of it to ask for (as
//          a share of what lies above the larger floor, two other no-effect records of that
//          seed named a position term and an asymmetry).
//    Greedy: each round fits every remaining candidate on top of the accepted ones and accepts,
//    among those that earn their place, the one with the largest gain (the lowest validation
//    error); rounds repeat until none does.  Ranking by estimation Delta BIC instead was tried: on
//    a `generate` record with a viscous effect (30k samples, five stroke speeds) a rising
//    Stribeck-shaped level fitted the estimation record slightly better than the viscous term
//    (Delta BIC -94910 vs -86170) but validated at 0.027 % against 0.0019 %.  Then a backward pass
//    refits the model without each accepted extension in turn and removes any that no longer earns
//    its place against the others (same rule); the chain of findings is then recomputed for what
//    remains. Note: the validation record takes part in the acceptance (rule c) and in the choice
//    between candidates that all earn their place, so the reported validation errors are not fully
//    independent of the choice (methods.md 6 prefers estimation-only choices; see above why).
//
// 5. Ambiguity.  For the pairs of methods.md 7 that poor excitation confuses (offset/asymmetry,
//    inertia/position-dependence, delay/frictional-lag), when the partner earns its place too and
//    the two fits of the same round are within `ambiguity_evidence` (10) of each other in
//    2 ln(likelihood ratio) = N |ln(RSS_partner / RSS_accepted)|, the finding names the partner in
//    `ambiguous_with` and the excitation that would separate them (the statistic goes into the
//    finding's evidence as `partner.log_likelihood_ratio`).  The comparison deliberately leaves
//    out BIC's parameter penalty: it was BIC at first, and on a record sliding one way at constant
//    speed with a 0.2 % speed ripple at one frequency (test_diagnose_pairs), where a mass and a
//    position term at the wavelength V / f fit to within 1e-6 of each other (RSS/SSS 0.002332 %
//    vs 0.002331 %), the position term's two extra parameters put it 2 ln N = 16.6 behind and the
//    finding was not flagged.  Whether the record can tell two causes apart is a question about
//    the fits, not about which cause is simpler; the simpler one still wins the round when the
//    validation errors say so (rule c and the greedy choice).  On the envelope excitation the same
//    pair is about 9e3 apart (RSS 10 times larger) and is not flagged.  A viscous or Stribeck
//    finding on a record whose sliding speeds span less than a factor 1.5 is ambiguous with a
//    higher Coulomb level (the thresholds), and says so.
//
// Nested candidates: `frictional-lag` on a model without a velocity piece is fitted with a
// viscous companion, and, when the round's Stribeck candidate passes the estimation rules on its
// own and the nested checks below, also on that Stribeck curve (a curve behind a long lag: neither the viscous pair nor the
// curve alone describes it, and one-at-a-time rounds turned both down); the lag candidate is the
// one of the two with the lower BIC, and its companion is reported with it.  It contains its
// companion, and earns its place only when its lag exceeds one sample period, its BIC beats the
// companion candidate's of the same round, and a Stribeck companion passes the curve's own check
// (below).
//
// A Stribeck curve names a fall of the sliding force with speed, so the record must show the fall
// where it slides: what is left of the drop at the lowest sliding speeds the record holds must
// exceed the force noise,
//     |Fs - F0| exp(-(v05 / vs)^q) > sigma,
// v05 the 5 % quantile of the speed while the candidate's model slides on the estimation record,
// sigma the estimation record's white-noise level.  A curve that has fallen before that acts only
// around reversals, where the elements' presliding describes the force: it corrects the base's
// presliding there and is not named.  (On the discovery study's records without an effect such
// curves bought 9-22 % of the validation error with a visible drop below 0.1 sigma; true
// curves were fitted with 2 to 350 sigma of it.  One true curve is turned down: beside an
// inertia, a 3 % bump whose own drop is down to 1e-4 of itself at the record's lowest sliding
// speed, i.e. a curve the record shows at reversals only.)
//
// A delay must be larger than the shift that stepping the model once per sample imitates.  The
// model sees the displacement at the samples only: at a reversal between two samples its operators
// miss the excursion to the extreme and reverse late, which a small negative delay partly mends.
// On the discovery study's records without a delay fits named delays of -0.006 to -0.025 sample
// periods with validation gains of 4-150 %.  That shift is measured on the record: the current
// model is run on the displacement refined to four steps per sample (cubic interpolation) and
// on the samples, and D_step is the least-squares time shift between the two forces; the
// per-sample model imitates -D_step.  A fitted delay D is named only when |D + D_step| > |D_step|:
// what it adds beyond the artefact exceeds the artefact.
//
// Drift: the extension's time runs from each record's start (extensions.hpp), i.e. it describes a
// run-in that every experiment repeats.  A drift that continues across records (a held-out end of
// one long record) cannot be predicted by a level fitted on the estimation part; rule (c) then
// usually rejects it and the table shows why.
//
// A finding's `parameters` are those of the model at its step of the chain; the final model holds
// the values refitted with every accepted piece.
//
// The validation error of every model here (baseline included) is computed the same way: the
// initial deflections are estimated from the validation record (estimate_initial_deflections
// for the plain model as a start, refined by Ceres through the extended model), nothing else is
// re-estimated, and every sample counts.
//
// 6. Uncertainty.  Every finding carries the standard errors and 95 % intervals of its parameters
//    in the fit of its step of the chain, and the final model the standard errors of all its
//    pieces (`final.pieces`, the shape `identify --extension` uses): the covariance of that joint
//    fit on the estimation record (report_extended_slip, covariance_report.hpp), each variance
//    the larger of the AR(1) sandwich's and the block scores' (noise_colour.hpp: the residual
//    holds the model's misfit as well as noise); the pieces are fitted linearly, so the
//    intervals are symmetric.  A parameter at a bound of its
//    box, or a rank-deficient fit, has none (null).
//
// Stages.  diagnose() runs named stages over typed data (src/diagnose_stages.hpp): the baseline,
// the evidence of the current model, the candidate fits (each takes its inputs by const reference
// and returns a value, so candidates can be fitted concurrently), the acceptance rule (a Verdict),
// the greedy forward pass, the backward pass, and the report.  Findings, evidence and verdicts are
// structs and enums; text and JSON are made only by to_json / to_table / Verdict::to_text.
#pragma once

#include <nlohmann/json.hpp>

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "friction/effect_table.hpp"
#include "friction/extension_fit.hpp"
#include "friction/extensions.hpp"
#include "friction/maxwell_slip.hpp"
#include "friction/methods.hpp"
#include "friction/model_io.hpp"
#include "friction/record.hpp"

namespace friction {

struct DiagnoseOptions {
  std::string baseline = "maxwell-slip";  ///< "maxwell-slip" or "lugre"
  MethodOptions method;                   ///< for the baseline identification
  /// Candidate effects; empty: every effect the record can support.
  std::vector<Effect> candidates;
  std::size_t max_findings = 4;    ///< greedy rounds
  double min_excess_share = 0.10;  ///< rule (b): share of the RSS above the noise floor
  /// Rule (b): a candidate must also drop the estimation RSS more than one more Maxwell Slip
  /// operator does (section 4 of the header).
  bool operator_reference = true;
  /// Rule (c): the validation record's floor includes what the displacement's sampling puts into
  /// the baseline's force (section 4); false: the force noise's floor alone.
  bool measurement_floor = true;
  /// Ambiguous when the partner also earns its place and the two fits' 2 ln(likelihood ratio),
  /// N |ln(RSS_partner / RSS_accepted)|, is below this (10 is "very strong" evidence on the
  /// Kass & Raftery 1995 scale; section 5 of the header).
  double ambiguity_evidence = 10.0;
  int max_iterations = 60;  ///< Ceres iterations per fit
  /// A candidate's fit stops once it can no longer reach what rules (a) and (b) ask (section 3);
  /// false: every candidate's fit runs to its minimum (slower; only the figures of candidates
  /// that fail those rules differ).
  bool stop_hopeless_candidates = true;
  bool backward_pass = true;
  /// The candidates of a round are independent fits of const inputs: they run on this many
  /// threads (0: std::thread::hardware_concurrency()), each writing its own slot, so the result
  /// is the same bit for bit for any count.  The other stages' concurrent work (the baseline's
  /// order selection, the restarts, the findings' reports) runs on as many; `method.threads` is
  /// not read.
  unsigned threads = 0;
};

/// One effect's signature in the residual (section 2 of the header).
struct EffectEvidence {
  Effect effect{};
  double explained = 0;    ///< share of the residual sum of squares explained, 0..1
  double coefficient = 0;  ///< regression coefficient (the fit's start), SI
  EffectStart start;       ///< the typed start (grid point, wavelength, shift) of the fit
};

/// What the current model's simulation gets wrong on one record.
struct ResidualEvidence {
  double rss_sss_percent = 0;
  double noise_sigma = 0;
  double noise_floor_percent = 0;
  std::size_t sliding_samples = 0, presliding_samples = 0;
  double sliding_rms = 0, presliding_rms = 0;           ///< RMS residual per regime [N]
  double sliding_mean = 0, presliding_mean = 0;         ///< mean residual per regime [N]
  double sliding_speed_min = 0, sliding_speed_max = 0;  ///< 5 % / 95 % quantiles of |v| sliding
  struct Bin {
    int direction = 0;  ///< +1 / -1
    double speed_low = 0, speed_high = 0;
    double mean_residual = 0;
    std::size_t samples = 0;
  };
  std::vector<Bin> velocity_bins;
  std::vector<double> xcorr_lags;       ///< [s]
  std::vector<double> xcorr_values;     ///< corr(e(t), dx(t - lag))
  double best_shift = 0;                ///< [s]: Fhat shifted by it explains e best
  std::vector<EffectEvidence> effects;  ///< ranked, largest `explained` first
  Json to_json() const;
};

/// Why a candidate earns its place or not: the rules of section 4 and the nested checks.
struct Verdict {
  /// Rule (c): the validation record is consulted only when rules (a) and (b) pass.
  enum class Validation {
    not_evaluated,        ///< rules (a) or (b) failed first
    falls,                ///< lower than the current model's
    does_not_fall,        ///< not lower
    at_floor,             ///< the current model already validates at or below the noise floor
    computed_for_report,  ///< computed afterwards, for a warning only (never for the acceptance)
  };
  /// Nested candidates (header comment): checks after the rules.
  enum class Nested {
    none,
    lag_below_one_sample,    ///< frictional-lag's lag fitted below one sample period
    no_better_than_viscous,  ///< frictional-lag no better than its companion alone (BIC)
    drop_below_sliding,      ///< a Stribeck curve that has fallen before the record slides
    delay_within_stepping,   ///< a delay no larger than the shift per-sample stepping imitates
  };
  bool fitted = true;    ///< false: the fit found no usable solution
  std::string failure;   ///< what the fit threw (empty: it ended unusable)
  double delta_bic = 0;  ///< rule (a): BIC(candidate) - BIC(current)
  double drop = 0;       ///< rule (b): RSS0 - RSS1 [N^2]
  double required = 0;   ///< rule (b): what the drop must exceed [N^2]
  /// Lag-one correlation of the candidate's estimation residual (AR(1) phi, noise_colour.hpp):
  /// rules (a) and (b) count (1 - phi)/(1 + phi) of the samples as independent.
  double residual_colour = 0;
  /// A parameter of the candidate the fit left on an edge of its range (e.g. a Stribeck exponent
  /// at 5, a mass at 0): on its own the effect as defined does not describe the record.  Such a
  /// candidate is accepted only when no other earns its place, and stays only if a later finding
  /// brings the parameter inside its range (a Stribeck curve fitted without the viscous term
  /// beside it runs to an edge; diagnose.cpp, forward_pass).
  std::string at_bound;
  bool operator_limited = false;  ///< (b) failed only on what one more operator buys
  /// The candidate's fit was stopped early: at the pace of its last iterations it could not have
  /// reached what rules (a) and (b) ask (section 3).  It fails them; its figures are where it
  /// stopped, not at a minimum.
  bool stopped_short = false;
  /// (b) the current model's estimation RSS is within the force noise's spread of the record's
  /// floor (noise and the displacement's sampling): nothing above it for any drop to be real.
  bool estimation_at_floor = false;
  Validation validation = Validation::not_evaluated;
  double validation_before = 0;    ///< RSS/SSS % of the current model (rule c)
  double validation_after = 0;     ///< RSS/SSS % of the candidate (rule c)
  double validation_required = 0;  ///< rule (c): what validation_after must be below [%] (the
                                   ///< validation record's noise floor when at_floor)
  Nested nested = Nested::none;

  bool bic_falls() const { return delta_bic < 0; }
  bool drop_exceeds() const { return drop > required; }
  /// Rules (a) and (b): the validation record may be consulted.
  bool passes_estimation_rules() const {
    return fitted && bic_falls() && drop_exceeds() && !estimation_at_floor;
  }
  /// All three rules and the nesting checks, whatever the edges.
  bool earns_place_but_for_an_edge() const {
    return passes_estimation_rules() && validation == Validation::falls && nested == Nested::none;
  }
  bool earns_place() const { return earns_place_but_for_an_edge() && at_bound.empty(); }
  /// The reasons, for people (the `verdict` of the document).
  std::string to_text() const;
};

/// One candidate fitted on top of the accepted extensions.
struct CandidateFit {
  Effect effect{};
  bool nonlocal_memory = false;            ///< the LuGre baseline's candidate (elements = M)
  ExtensionParameters<double> extensions;  ///< all pieces of the fitted model (accepted + this)
  MaxwellSlipParameters<double> base;
  std::size_t extra_parameters = 0;
  double estimation_rss = 0;
  double estimation_percent = 0;
  double delta_bic = 0;
  double required_drop = 0;  ///< rule (b) [N^2]
  double validation_percent = 0;
  bool earns_place = false;
  Verdict verdict;     ///< why it was accepted or not
  double seconds = 0;  ///< fit and validation of this candidate
};

/// What a finding may be confused with: its partner effect (methods.md 7), or, for a velocity
/// piece at one speed, a higher Coulomb level (no effect).
struct Alternative {
  std::optional<Effect> effect;
  std::string name() const;
};

/// The partner's fit in the round that accepted a finding (section 5).
struct PartnerEvidence {
  Effect effect{};
  bool earns_place = false;
  double log_likelihood_ratio = 0;  ///< N ln(RSS_partner / RSS_accepted)
};

struct Finding {
  std::optional<Effect> effect;  ///< nullopt: nonlocal-memory (the LuGre baseline's finding)
  std::size_t elements = 0;      ///< nonlocal-memory: the Maxwell Slip elements that replace LuGre
  /// The piece's parameters (and a companion's, effect table), methods.md 7 names, SI, the model's
  /// own F0, with standard errors and intervals of the fit at this step (section 6).
  std::vector<ExtensionEstimate> parameters;
  double validation_before = 0, validation_after = 0;  ///< RSS/SSS %
  double estimation_before = 0, estimation_after = 0;  ///< RSS/SSS %
  double delta_bic = 0;                                ///< on the estimation record
  double noise_floor_rss = 0;                          ///< N sigma^2 of the estimation record
  /// The residual of the model before this finding on the validation record (none for
  /// nonlocal-memory), and the share of it this effect's signature explains.
  std::optional<ResidualEvidence> residual;
  double signature_explained = 0;
  std::optional<PartnerEvidence> partner;
  std::vector<Alternative> ambiguous_with;
  /// Free runs on the validation record of the model before and after this finding (initial
  /// state estimated there), for the report's panels [N]; empty for nonlocal-memory.
  std::vector<double> validation_run_before, validation_run_after;

  /// methods.md 7 name ("viscous", ..., "nonlocal-memory").
  std::string name() const;
  bool has_parameter(std::string_view name) const;
  /// Value of a parameter (throws InvalidParameter when the finding has none of that name).
  double parameter(std::string_view name) const;
  std::vector<std::string> ambiguous_with_names() const;
  /// How the model was extended (effect table).
  std::string extension() const;
  /// The excitation that would separate the alternatives (empty when not ambiguous).
  std::string separating_excitation() const;
  /// One sentence for people.
  std::string sentence() const;
  Json to_json() const;
};

struct Diagnosis {
  std::optional<AnyModel> baseline_model;
  double baseline_validation_percent = 0;
  double baseline_estimation_percent = 0;
  ResidualEvidence baseline_evidence;  ///< on the validation record
  std::vector<Finding> findings;
  std::optional<AnyModel> final_model;
  double final_validation_percent = 0;
  double final_estimation_percent = 0;
  /// The final model's pieces with the standard errors of the final joint fit (section 6).
  std::vector<ExtensionEstimate> final_pieces;
  std::vector<CandidateFit> first_round;  ///< every candidate of the first round, for reporting
  std::vector<std::string> warnings;
  double seconds = 0;
  double baseline_seconds = 0;  ///< of the baseline identification
  /// What one more operator drops the baseline's estimation RSS by [N^2] (rule b).
  double operator_drop = 0;
  /// What the displacement's sampling (its sensor's error and the stepping once per sample) puts
  /// into the baseline's force, RSS/SSS % of each record (rule c, the floor).
  double estimation_measurement_floor_percent = 0;
  double validation_measurement_floor_percent = 0;

  /// The diagnose document's body (baseline, findings, final, candidates); the caller adds
  /// schema_version and warnings.
  Json to_json() const;
  /// One sentence per finding and a summary, for people.
  std::string to_table() const;
};

/// Fits the baseline on `estimation`, diagnoses its residual on `validation` and extends it
/// (see the header comment).  Both records need force; throws InvalidParameter or
/// NumericalError when no result can be produced.
Diagnosis diagnose(const Record& estimation, const Record& validation,
                   const DiagnoseOptions& options = {});

/// The residual evidence of a Maxwell Slip model with extensions on a record (initial state
/// estimated there).  Exposed for tests.
ResidualEvidence analyse_residual(const MaxwellSlipParameters<double>& base,
                                  const ExtensionParameters<double>& extensions,
                                  const Record& record);

/// The pieces of `current` plus effect e's piece, started from the residual evidence `ev` of the
/// current model on record r (the effect's regression coefficient, the wavelength of the best
/// grid point, the lag of the cross-correlation); f0 is the reference force of the level pieces.
/// `frictional-lag` brings a viscous companion when `current` has no viscous or Stribeck piece.
ExtensionParameters<double> extension_start(Effect e, const ExtensionParameters<double>& current,
                                            const ResidualEvidence& ev, const Record& r, double f0);

/// Validation error (RSS/SSS %) of an extended Maxwell Slip model on a record, initial
/// deflections estimated from the record.  `simulated` receives the free run when not null.
double extended_validation_percent(const MaxwellSlipParameters<double>& base,
                                   const ExtensionParameters<double>& extensions,
                                   const Record& record, std::vector<double>* simulated = nullptr);

}  // namespace friction
