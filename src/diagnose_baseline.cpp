// The baseline stages of diagnose (diagnose.hpp, section 1): NLR and what one more operator buys;
// a LuGre baseline and its one candidate, nonlocal-memory.
#include <chrono>
#include <cmath>
#include <limits>

#include "diagnose_stages.hpp"
#include "friction/identification.hpp"
#include "sample_statistics.hpp"

namespace friction::diagnose_detail {

namespace {

// Rule (b), third part (section 4): what one more Maxwell Slip element buys on the estimation
// record.  The order selection's table holds M + 1 unless M is the largest M it tried (the cap of
// max_operators); then M + 1 is fitted here.
double one_more_operator(const Record& est, const IdentifiedModel& nlr, std::size_t m,
                         const DiagnoseOptions& o, std::vector<std::string>& warnings) {
  const SelectionRow* at = nullptr;
  const SelectionRow* next = nullptr;
  for (const auto& row : nlr.report.selection) {
    if (row.failed) continue;
    if (row.operators == m) at = &row;
    if (row.operators == m + 1) next = &row;
  }
  if (at && next) return std::max(at->rss - next->rss, 0.0);
  if (next) return 0.0;
  MethodOptions more = o.method;
  more.operators = m + 1;
  more.max_operators = 0;
  more.extensions = {};
  try {
    const IdentifiedModel bigger = identify_model("maxwell-slip", est, more);
    return std::max(nlr.report.estimation.rss - bigger.report.estimation.rss, 0.0);
  } catch (const std::exception& ex) {
    warnings.push_back("the reference fit with " + std::to_string(m + 1) + " operators failed (" +
                       ex.what() + "); rule (b) without it");
  }
  return 0.0;
}

}  // namespace

Baseline fit_baseline(const Record& est, const Record& val, const DiagnoseOptions& o) {
  const auto started = std::chrono::steady_clock::now();
  MethodOptions base = o.method;
  base.base_without_dominant_inertia = true;  // a dominant m·a is a finding, not a failure
  Baseline b{identify_model("maxwell-slip", est, base), {}, 0.0, {}, 0.0};
  b.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  const auto& ms = std::get<Extended<MaxwellSlip<double>>>(b.nlr.model.variant());
  State& s = b.state;
  s.base = ms.base().parameters();
  s.rho.resize(s.base.size());
  for (std::size_t i = 0; i < s.base.size(); ++i)
    s.rho[i] = i < b.nlr.report.initial_deflections.size()
                   ? b.nlr.report.initial_deflections[i] / s.base.threshold[i]
                   : 0.0;
  s.ext.reference_force = s.base.sliding_force();
  const ExtendedSlipRun run =
      run_extended_slip(s.base, s.ext, deflections_from_relative(s.base, s.rho, s.ext), est);
  s.rss = 0;
  for (std::size_t k = 0; k < est.size(); ++k)
    s.rss += (est.force[k] - run.force[k]) * (est.force[k] - run.force[k]);
  s.validation = extended_validation_percent(s.base, s.ext, val);
  for (const auto& w : b.nlr.report.warnings) b.warnings.push_back("baseline NLR: " + w);
  b.operator_drop = one_more_operator(est, b.nlr, s.base.size(), o, b.warnings);
  return b;
}

std::optional<Finding> fit_lugre_baseline(const Context& c, const Baseline& nlr, Diagnosis& dx) {
  const IdentifiedModel lg = identify_model("lugre", c.est, c.options.method);
  const Validation lv = validate_model(lg.model, c.val);
  dx.baseline_model = lg.model;
  dx.baseline_validation_percent = lv.errors.rss_sss_percent;
  dx.baseline_estimation_percent = lg.report.estimation.rss_sss_percent;
  dx.baseline_evidence.rss_sss_percent = lv.errors.rss_sss_percent;
  dx.baseline_evidence.noise_sigma = lv.noise_sigma;
  dx.baseline_evidence.noise_floor_percent = lv.noise_floor_percent;
  for (const auto& w : lg.report.warnings) dx.warnings.push_back("baseline LG: " + w);

  // The one candidate: Maxwell Slip elements (nonlocal memory), i.e. the NLR baseline.
  const State& ms = nlr.state;
  const double rss_lg = lg.report.estimation.rss;
  const std::size_t p_lg = lg.model.parameter_count(), p_ms = 2 * ms.base.size();
  const double dbic_full = bayesian_information_criterion(ms.rss, c.n, p_ms) -
                           bayesian_information_criterion(rss_lg, c.n, p_lg);
  CandidateFit cf;
  cf.nonlocal_memory = true;
  cf.base = ms.base;
  cf.estimation_rss = ms.rss;
  cf.estimation_percent = statistics::rss_sss_percent(c.est.force, ms.rss);
  cf.delta_bic = dbic_full;
  cf.verdict = accept(c, rss_lg, ms.rss, 0, lv.errors.rss_sss_percent, ms.validation);
  cf.required_drop = cf.verdict.required;
  cf.validation_percent = ms.validation;
  cf.earns_place = cf.verdict.earns_place() && dbic_full < 0;
  dx.first_round.push_back(cf);
  if (!cf.earns_place) return std::nullopt;

  Finding f;
  f.elements = ms.base.size();
  f.validation_before = lv.errors.rss_sss_percent;
  f.validation_after = ms.validation;
  f.estimation_before = dx.baseline_estimation_percent;
  f.estimation_after = cf.estimation_percent;
  f.delta_bic = dbic_full;
  return f;
}

}  // namespace friction::diagnose_detail
