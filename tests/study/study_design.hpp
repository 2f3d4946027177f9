// The records of the discovery study: random systems, excitations, effects and files, drawn from a
// seed, each with the set of effects a diagnosis should name written down.
//
// Everything a record is made of is drawn here, in this simulator's own terms
// (truth_simulator.hpp):
//   * scales: a Coulomb level Fc from 3 mN to 1 kN, a travel X from 5 um to 2 mm, sampling from
//     200 Hz to 5 kHz, 3000-5000 samples per record;
//   * a system of 3-12 elements whose thresholds spread over one to two decades below 5-25 % of
//     the travel, with random shares (the slip forces);
//   * an encoder step from X/30000 to X/1000 (never below 1 nm), an absolute position offset;
//   * force noise of 0.1-2 % of Fc, white on half of the records and AR(1) with phi 0.3-0.95 on
//     the other half;
//   * an excitation family (envelope, strokes with rests, multisine) and its design (carrier and
//     envelope frequencies; tones and amplitudes; stroke speeds, lengths, loops and rests), the
//     validation record another realisation of the estimation record's design (new phases, a new
//     order of the strokes; ValidationDesign says why);
//   * each injected effect's shape at random (Stribeck exponent 0.5-2.5, Stribeck velocity over
//     two decades around the median sliding speed, wavelength 6-30 % of the travel, ...) and its
//     magnitude set so that its contribution to the validation record -- the RMS of the force with
//     all effects minus the force without this one, after the best common scale is taken out, which
//     a change of the friction level alone would explain -- is 6-60 times the noise (up to 150 for
//     viscous and inertia, whose strong forms users meet); where a physical bound caps the
//     magnitude (asymmetry 0.3, Stribeck peak 3 Fc, ...) the noise is lowered until the
//     contribution is at least 6 times the noise;
//   * the file: units (m, mm or um; N, mN or kN; sometimes ms), column names from the accepted
//     aliases or others named by --columns, extra columns, column order, and on one file in six the
//     opposite force sign (the force on the moving body).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "truth_simulator.hpp"

namespace truth {

enum class Family { envelope, strokes, multisine };
std::string family_name(Family f);

/// What the study asks for: the injected effects by their methods.md section 7 names.
/// How the validation record's motion relates to the estimation record's.
enum class ValidationDesign {
  /// The same excitation design, another realisation (new phases, a new order of the strokes):
  /// the validation record moves at the speeds and accelerations the estimation record holds, as
  /// the validation record of one experiment does.
  another_realisation,
  /// The same family, its design drawn again: speeds up to 5x apart from the estimation
  /// record's, so a speed-dependent piece is validated where the estimation record never went.
  /// Every record made before 2026-11-29; kept for the regression tests that name such records.
  independent_design,
};

struct RecordSpec {
  std::string id;
  std::vector<std::string> effects;  ///< "frictional-lag" needs "viscous" or "stribeck" with it
  std::string baseline = "maxwell-slip";
  Family family = Family::envelope;
  std::uint64_t seed = 1;
  ValidationDesign validation = ValidationDesign::another_realisation;
};

/// How a record's files are written and how the CLI is told to read them.
struct FileFormat {
  std::string time_unit = "s", displacement_unit = "m", force_unit = "N";
  double time_factor = 1, displacement_factor = 1, force_factor = 1;  ///< SI per file unit
  std::string time_name = "time", displacement_name = "displacement", force_name = "force",
              normal_name = "normal_force";
  bool names_need_columns_option = false;
  bool extra_column = false;
  bool reversed_order = false;
  int force_sign = 1;
};

/// One parameter's true value, in SI and the library's names ("viscous", "mass", ...).
struct TrueParameter {
  std::string effect, name;
  double value = 0;
  bool model_free = false;  ///< defined without reference to a model's form (study coverage)
};

struct StudyRecord {
  RecordSpec spec;
  std::vector<std::string> expected;  ///< sorted names a diagnosis should give
  System system;
  Measurement estimation, validation;
  std::shared_ptr<const Excitation> motion_estimation, motion_validation;
  std::optional<NormalProgram> normal_estimation, normal_validation;
  Trace trace_estimation, trace_validation;
  std::vector<TrueParameter> truth;
  std::map<std::string, double> contribution;  ///< effect -> scale-free RMS on validation [N]
  double travel = 0;                           ///< X [m]
  double median_sliding_speed = 0;             ///< [m/s], validation record
  /// 100 N sigma^2 / sum F^2 on the validation record: the error a perfect model reaches.
  double true_floor_percent = 0;
  /// 100 sum (F - F_reachable)^2 / sum F^2 on the validation record (reachable_force): the error
  /// of the true system driven by the recorded displacement, its speed-dependent terms fed the
  /// velocity and acceleration that the best fixed window of a local quadratic estimates from it
  /// (best_local_derivatives).  What a model fed the measured displacement can reach; above the
  /// noise floor where the encoder's steps are a visible force in presliding (k q against the force
  /// noise) or a large m a turns the acceleration's estimation error into force.
  double reachable_floor_percent = 0;
  FileFormat format;
  /// Features that decide whether a pair of look-alike effects can be told apart.
  bool has_presliding_reversals = true, has_rests = false, both_directions = true;
  /// The friction level changes along the record (a level effect is injected): the only thing
  /// that tells an asymmetry from an offset (see pair_separated in the study).
  bool level_varies = false;
  int distinct_speeds = 0;

  /// The CLI options that make the files readable (--units, --columns), shell-quoted.
  std::string read_options() const;
  /// One line for people: family, fs, N, elements, Fc, noise, units.
  std::string summary() const;
};

/// SplitMix64: the study's seed mixer (record seeds from the study seed).
std::uint64_t splitmix(std::uint64_t x);

/// The discovery study's plan for `seed` (test_discovery_study.cpp says what it holds): every
/// effect alone (three records each), frictional lag with viscous or Stribeck, nine random pairs
/// and 22 records with no effect.  Shared with resimulate_record, which rebuilds one of them.
std::vector<RecordSpec> study_plan(std::uint64_t seed);

/// The record `id` of study_plan(seed), or nothing when the plan has no such record.  A record
/// of a study run before 2026-11-29 is drawn again with ValidationDesign::independent_design.
std::optional<RecordSpec> plan_record(
    std::uint64_t seed, const std::string& id,
    ValidationDesign validation = ValidationDesign::another_realisation);

/// Draws and simulates the record `spec` describes.
StudyRecord make_record(const RecordSpec& spec);

/// Simulates r's system under its motions, normal programs and measurements into its two traces
/// (again after a measurement is changed, e.g. its encoder or noise).
void simulate_traces(StudyRecord& r);

/// Writes the estimation or validation trace as the record's file format says.
void write_csv(const StudyRecord& r, bool estimation, const std::string& path);

/// Writes the record's truth (TrueParameter list and summary) as JSON: {"summary": ...,
/// "parameters": [{"effect", "name", "value"}, ...]}.
void write_truth(const StudyRecord& r, const std::string& path);

/// The same record without `effects` (the same system otherwise, the same motions and the same
/// noise realisation): what a base model without those pieces can reach.  Its expected set and
/// truth drop the effects; its true floor is recomputed.
StudyRecord twin_without(const StudyRecord& r, const std::vector<std::string>& effects);

/// The section 7 names the study injects (nonlocal-memory is a baseline question, not a piece).
const std::vector<std::string>& injectable_effects();

}  // namespace truth
