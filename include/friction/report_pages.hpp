// The reports of `identify`, `validate`, `compare` and `diagnose` (--report FILE.html): what a
// person looks at to judge a friction model, built from the command's JSON document (the contract
// for scripts; the report says nothing the document does not) and the forces the models simulate
// on the records.
//
// Every report opens with one or two sentences on what the run found, then shows, per record:
//   * the measured and simulated force over time with the residual beneath, and a zoom on a
//     presliding stretch (the longest run of reversals shorter than the presliding travel, where
//     the Maxwell Slip elements' hysteresis shows; a reversal from sliding where there is none);
//   * force against displacement (the hysteresis loops), measured and simulated;
//   * force and residual against velocity while sliding;
// then the parameters with units and 95 % intervals, the warnings, the command line and the
// version.  `compare` adds the paper's table and a chart of each method's errors against the noise
// floor; `diagnose` shows the baseline against the final model, the findings and the candidates
// as the document gives them, and one panel per finding (add_finding_panel).
//
// Which samples slide.  Sliding is decided from the record alone, the same way for every model and
// view: a sample slides when the displacement since the last reversal exceeds the record's
// presliding travel (the travel at which the force has covered 95 % of its swing after the
// reversal with the largest swing, identification.hpp) and the velocity is above three times its
// predicted RMS error (sample_derivatives.hpp).  A model's own operator states would serve
// Maxwell Slip models only, and a velocity threshold alone counts the presliding stretch of every
// slow stroke as sliding.
//
// Velocity is taken at the sample instants by local quadratic fits (sample_derivatives.hpp), the
// velocity that the extension terms use; the backward difference would show an encoder's quantum
// as pulses at slow speed.
#pragma once

#include <nlohmann/json.hpp>

#include <span>
#include <string>
#include <vector>

#include "friction/record.hpp"
#include "friction/report.hpp"

namespace friction::report {

using Json = nlohmann::json;

/// A record as the report shows it, computed once per record.
struct RecordView {
  std::string role;  ///< "estimation" or "validation"
  const Record* record = nullptr;
  std::vector<double> velocity;      ///< v(t_k) [m/s]
  std::vector<double> acceleration;  ///< a(t_k) [m/s^2]
  std::vector<bool> sliding;         ///< see the header comment
  double presliding_travel = 0;      ///< [m]
  double zoom_lo = 0, zoom_hi = 0;   ///< the stretch the zoom shows [s]
  std::string zoom_what;             ///< what it holds, for the caption
};
/// The record must carry a force and at least two samples; it must outlive the view.
RecordView view_record(const Record& record, std::string role);

/// A model's free run on a record, as one colour (Role::simulated alone; before/after for two).
struct Trace {
  std::string label;  ///< legend text, e.g. "simulated", "baseline", "final"
  Role role = Role::simulated;
  std::span<const double> force;  ///< one value per sample of the record [N]
};

/// The figures of one or two models on one record.  `id` prefixes the figures' ids; `what` names
/// the record and model in the titles ("validation record, NLR").
void add_time_figures(Document& doc, const std::string& id, const RecordView& view,
                      const std::vector<Trace>& traces, const std::string& what);
void add_loop_figures(Document& doc, const std::string& id, const RecordView& view,
                      const std::vector<Trace>& traces, const std::string& what);
void add_sliding_figure(Document& doc, const std::string& id, const RecordView& view,
                        const std::vector<Trace>& traces, const std::string& what);

/// The command line and the version, for the report's last section.
struct RunInfo {
  std::string command_line;
  std::string version;
};

/// A record and the force the model simulated on it (identify: estimation and validation;
/// validate: one record).
struct RecordFit {
  const Record* record = nullptr;
  std::string role;
  std::vector<double> simulated;
};

/// `identify` and `validate`: `document` is the command's JSON document.
Document fit_report(const Json& document, const std::vector<RecordFit>& fits, const RunInfo& run);

/// One method of `compare` and its free runs (empty when the method failed).
struct MethodFit {
  std::string method;  ///< "LG", "NLR", "DNLRX"
  std::vector<double> estimation, validation;
};
Document compare_report(const Json& document, const Record& estimation, const Record& validation,
                        const std::vector<MethodFit>& methods, const RunInfo& run);

/// What one finding's panel needs (the per-finding hook).  `before` and `after` are the free runs
/// on the validation record of the model just before and just after the finding was accepted;
/// `before_label` / `after_label` say which models they are.  `finding` is the finding's entry of
/// the document (effect, parameters, validation_before/after, gain, ambiguity).
struct FindingPanelInput {
  std::string effect;  ///< a methods.md 7 name
  const Record* validation = nullptr;
  std::span<const double> before, after;
  std::string before_label = "before", after_label = "after";
  Json finding;
};
/// One finding's panel: the signature it explained, before and after, where the effect shows
/// (against velocity for viscous, Stribeck and asymmetry; force-velocity loops for frictional lag;
/// the residual at rest for an offset; against position, time, acceleration or the normal force;
/// the cross-correlation with the motion for a delay), its parameters, its gain and any ambiguity.
void add_finding_panel(Document& doc, const std::string& id, const RecordView& validation,
                       const FindingPanelInput& input);

/// The general panels of `diagnose`: the baseline and the final model on each record.
struct DiagnoseFits {
  std::vector<double> baseline_estimation, baseline_validation;
  std::vector<double> final_estimation, final_validation;
  std::string baseline_label = "baseline", final_label = "final";
};
/// `findings` are the per-finding inputs the caller can provide (in the document's order; a
/// finding without one is listed in the findings table only).
Document diagnose_report(const Json& document, const Record& estimation, const Record& validation,
                         const DiagnoseFits& fits, const std::vector<FindingPanelInput>& findings,
                         const RunInfo& run);

}  // namespace friction::report
