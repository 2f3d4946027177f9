// The report stage of diagnose (diagnose.hpp, sections 5 and 6) and the edge where its typed
// results become text and JSON: findings with their evidence, ambiguity and standard errors, the
// warnings on strong but rejected candidates, the final model with its pieces.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <vector>

#include "diagnose_stages.hpp"
#include "friction/extension_identification.hpp"
#include "friction/identification.hpp"
#include "number_format.hpp"
#include "parallel_for.hpp"
#include "position_origin.hpp"
#include "sample_statistics.hpp"

namespace friction {

namespace diagnose_detail {

namespace {

// Ambiguity with the partner of methods.md 7, from the round that accepted the finding: the two
// fits' 2 ln(likelihood ratio) for Gaussian errors, without the parameter penalty of BIC (the
// question is whether the record can tell the causes apart, not which one is simpler: a position
// term has two parameters more than a mass and fits a one-frequency record as well, which a BIC
// gap would hide behind 2 ln N).
void judge_ambiguity(const Context& c, const std::vector<Tried>* round, const State& before,
                     const State& after, double speed_span, Finding& f) {
  const Effect e = *f.effect;
  const EffectInfo& info = effect_info(e);
  // The partner's fit from the state before this finding: the round's, or (the chain was rebuilt
  // after the backward pass removed a piece, and the rounds are those of another chain) a fresh
  // one.
  std::vector<Tried> fresh;
  if (info.partner && !before.ext.has(*info.partner) && !after.ext.has(*info.partner)) {
    bool in_round = false;
    if (round)
      for (const auto& t : *round) in_round = in_round || t.fit.effect == *info.partner;
    if (!in_round) {
      fresh.push_back(fit_one_candidate(c, before, *info.partner));
      round = &fresh;
    }
  }
  if (round && info.partner) {
    for (const auto& t : *round) {
      if (t.fit.effect != *info.partner || !t.result.ok) continue;
      // Whether the record tells the two apart is a question about the best fit of each, not
      // about where two local searches stopped: the partner is refitted from the accepted model
      // (its operators, state and other pieces) and the better of its two fits counts.  An offset
      // and an asymmetry at a constant level are the same force (extensions.hpp); fitted each
      // from its own start they stopped 0.9 % apart in RSS, 31 in 2 ln(likelihood ratio).  The
      // ratio is counted on the effective number of samples, as the rules count (section 4).
      // Each refitted from the other's best solution, both ways (the same minimum is then
      // reached from either side when the two are one force).
      auto cross = [&](const ExtendedSlipFit& from, Effect out, Effect in,
                       const ExtensionParameters<double>& values) {
        ExtendedSlipFit none;
        none.rss = std::numeric_limits<double>::infinity();
        try {
          ExtensionParameters<double> start = from.ext;
          start.disable(out);
          start.enable(in);
          values.for_each_parameter([&](Effect pe, std::string_view name, const double& v) {
            start.for_each_parameter([&](Effect se, std::string_view sn, double& w) {
              if (pe == se && name == sn) w = v;
            });
          });
          const ProfiledStart p = profile_start(c.est, from.base, from.rho,
                                                first_level(from.base, from.ext, c.est, &c.windows),
                                                start, in, c.windows, c.scales);
          ExtendedSlipFit fit = fit_extended_slip(
              c.est, p.base,
              carried_state(c.est, from.base, from.ext, from.rho, p.base, p.ext, &c.windows), p.ext,
              false, c.options.max_iterations);
          if (fit.ok) return fit;
        } catch (const Error&) {
          // The refit failed: the other fit stands.
        }
        return none;
      };
      ExtendedSlipFit accepted_best = fit_of(after), partner_best = t.result;
      partner_best.rss = t.fit.estimation_rss;
      const ExtendedSlipFit p2 = cross(accepted_best, e, *info.partner, t.result.ext);
      if (p2.rss < partner_best.rss) partner_best = p2;
      const ExtendedSlipFit a2 = cross(partner_best, *info.partner, e, after.ext);
      if (a2.rss < accepted_best.rss) accepted_best = a2;
      const double phi = residual_phi(c, after.base, after.ext, after.rho);
      const double n_eff = static_cast<double>(c.n) * (1 - phi) / (1 + phi);
      const double gap = n_eff * std::log(partner_best.rss / accepted_best.rss);
      f.partner = PartnerEvidence{*info.partner, t.fit.earns_place, gap};
      if (t.fit.earns_place && std::abs(gap) < c.options.ambiguity_evidence)
        f.ambiguous_with.push_back({*info.partner});
    }
  }
  // A velocity piece on a record sliding at one speed: a higher Coulomb level does the same.
  if (info.ambiguous_with_coulomb_level && speed_span > 0 && speed_span < 1.5)
    f.ambiguous_with.push_back({std::nullopt});
}

// The standard errors of a state's joint fit, its phase carried to the position origin of the
// records as given (position_origin.hpp).
ExtendedSlipReport report_at_origin(const Context& c, const State& s) {
  ExtendedSlipReport rep = report_extended_slip(c.est, fit_of(s));
  if (c.position_origin == 0.0 || !s.ext.position_dependence) return rep;
  ExtensionParameters<double> ext = s.ext;
  detail::phase_to_origin(ext, c.position_origin);
  std::vector<double> base_se;
  for (const auto& p : rep.base) base_se.push_back(p.standard_error);
  detail::phase_estimate_to_origin(rep.pieces, base_se, rep.correlation, c.position_origin,
                                   ext.position_dependence->phase);
  return rep;
}

// The parts of a finding that do not depend on each other, the slowest first.  Each fills its own
// fields of the finding, so the parts of all findings can run concurrently (report, below).
enum class FindingPart { ambiguity, standard_errors, evidence, validation_runs };
constexpr std::size_t kFindingParts = 4;

// The finding of step i of the chain (states[i - 1] -> states[i]): what every part reads.
Finding finding_head(const Context& c, const Chain& chain, std::size_t i) {
  const State& before = chain.states[i - 1];
  const State& after = chain.states[i];
  Finding f;
  f.effect = after.order.back();
  f.validation_before = before.validation;
  f.validation_after = after.validation;
  f.estimation_before = statistics::rss_sss_percent(c.est.force, before.rss);
  f.estimation_after = statistics::rss_sss_percent(c.est.force, after.rss);
  f.delta_bic = bayesian_information_criterion(
                    after.rss, c.n, after.ext.parameter_count() - before.ext.parameter_count()) -
                bayesian_information_criterion(before.rss, c.n, 0);
  f.noise_floor_rss = c.floor_rss;
  return f;
}

// One part of the finding of step i.  `rep`: receives the joint fit's report of states[i] (for
// the last step, the final model's).  `baseline_evidence`: the evidence of states[0] on the
// validation record when diagnose() has it already (an NLR baseline), or null.
void make_finding_part(const Context& c, const Chain& chain, std::size_t i, double speed_span,
                       FindingPart part, const ResidualEvidence* baseline_evidence, Finding& f,
                       ExtendedSlipReport& rep) {
  const State& before = chain.states[i - 1];
  const State& after = chain.states[i];
  const Effect e = *f.effect;
  switch (part) {
    case FindingPart::standard_errors:
      // Its parameters with standard errors from the joint fit of this step (section 6).
      rep = report_at_origin(c, after);
      for (const auto& est : rep.pieces)
        if (est.effect == e) f.parameters.push_back(est);
      // A companion (a velocity lag's viscous term or Stribeck curve): a piece this step added
      // that no finding names.
      for (const auto& est : rep.pieces)
        if (est.effect != e && !before.ext.has(est.effect) &&
            std::find(after.order.begin(), after.order.end(), est.effect) == after.order.end())
          f.parameters.push_back(est);
      return;
    case FindingPart::validation_runs:
      extended_validation_percent(before.base, before.ext, c.val, &f.validation_run_before);
      extended_validation_percent(after.base, after.ext, c.val, &f.validation_run_after);
      return;
    case FindingPart::evidence: {
      // Evidence on the validation record, from the model before this finding: for the first,
      // the baseline's, which diagnose() has gathered already (0.16 s on data/).
      if (i == 1 && baseline_evidence) {
        f.residual = *baseline_evidence;
      } else {
        const std::vector<double> rho_v =
            estimate_relative_deflections(before.base, before.ext, c.val, nullptr);
        f.residual = gather_evidence(before.base, before.ext, c.val, rho_v);
      }
      for (const auto& w : f.residual->effects)
        if (w.effect == e) f.signature_explained = w.explained;
      return;
    }
    case FindingPart::ambiguity: {
      const bool same_rounds = !chain.removed && i - 1 < chain.rounds.size();
      judge_ambiguity(c, same_rounds ? &chain.rounds[i - 1] : nullptr, before, after, speed_span,
                      f);
      return;
    }
  }
}

// Strong estimation evidence that rule (b) turned down.  A candidate whose BIC falls by more
// than 10 ("very strong", Kass & Raftery) but whose drop is below the share rule (b) asks is
// not accepted, yet the user should hear of it: on the tribometer halves normal-load lowered
// BIC by 1248 but its drop was too small because the estimation half holds the load constant,
// and the validation half's unloaded end is where the baseline fails most.  Its validation
// error alone on the baseline is computed for the report (never for the acceptance).
void warn_of_strong_rejected(const Context& c, const State& last, Diagnosis& dx) {
  for (auto& cand : dx.first_round) {
    if (cand.earns_place || !(cand.delta_bic < -10.0) || !std::isnan(cand.validation_percent) ||
        !cand.verdict.fitted || cand.verdict.drop_exceeds() ||
        std::find(last.order.begin(), last.order.end(), cand.effect) != last.order.end())
      continue;
    cand.validation_percent = extended_validation_percent(cand.base, cand.extensions, c.val);
    if (cand.verdict.validation == Verdict::Validation::not_evaluated)
      cand.verdict.validation = Verdict::Validation::computed_for_report;
    std::ostringstream w;
    w << effect_name(cand.effect) << ": the estimation record supports it (BIC falls by "
      << format_number(-cand.delta_bic, 3)
      << ") but its drop there is below what rule (b) asks, so it was not "
      << "accepted; alone on the baseline it gives a validation RSS/SSS of "
      << format_number(cand.validation_percent, 4) << " % against "
      << format_number(dx.baseline_validation_percent, 4)
      << " %. An estimation record in which it acts more ("
      << effect_info(cand.effect).would_establish << ") would decide; `identify --extension "
      << effect_name(cand.effect) << "` fits it on request.";
    dx.warnings.push_back(w.str());
  }
}

}  // namespace

ExtendedSlipFit fit_of(const State& s) {
  return {s.base, s.rho, s.ext, s.rss, true, {}};
}

void report(const Context& c, const Chain& chain, Diagnosis& dx) {
  const double speed_span =
      dx.baseline_evidence.sliding_speed_min > 0
          ? dx.baseline_evidence.sliding_speed_max / dx.baseline_evidence.sliding_speed_min
          : 0.0;
  // The findings are independent of each other (each reads two states of the chain and the
  // rounds), and so are the parts of each: all parts of all findings are made concurrently, each
  // into its own fields, so the result does not depend on the thread count.  The slowest parts
  // first (on data/: the ambiguity's refits and the standard errors 0.21 s each, the others 0.03
  // to 0.07 s), so that no thread is left with one of them at the end; with one task per finding
  // the first finding alone took most of the stage on two threads.  The last finding's report is
  // the final model's.
  const std::size_t steps = chain.states.size() - 1;
  std::vector<Finding> findings(steps);
  for (std::size_t k = 0; k < steps; ++k) findings[k] = finding_head(c, chain, k + 1);
  std::vector<ExtendedSlipReport> reports(steps);
  const ResidualEvidence* baseline_evidence =
      c.options.baseline == "lugre" ? nullptr : &dx.baseline_evidence;
  // Task t: part t / steps (FindingPart's order is the slowest first) of finding t % steps.
  detail::parallel_for(steps * kFindingParts, c.options.threads, [&](std::size_t t) {
    const std::size_t k = t % steps;
    make_finding_part(c, chain, k + 1, speed_span, static_cast<FindingPart>(t / steps),
                      baseline_evidence, findings[k], reports[k]);
  });
  for (Finding& f : findings) dx.findings.push_back(std::move(f));
  const State& last = chain.states.back();
  warn_of_strong_rejected(c, last, dx);
  ExtensionParameters<double> final_ext = to_own_reference(last.ext, last.base.sliding_force());
  detail::phase_to_origin(final_ext, c.position_origin);
  dx.final_model =
      AnyModel(Extended<MaxwellSlip<double>>(MaxwellSlip<double>(last.base), final_ext));
  dx.final_validation_percent = last.validation;
  dx.final_estimation_percent = statistics::rss_sss_percent(c.est.force, last.rss);
  if (!last.ext.empty())
    dx.final_pieces = steps > 0 ? reports.back().pieces : report_at_origin(c, last).pieces;
  // The final model's pieces are what a user takes away: one without a standard error is said
  // (a study record, position-dependence beside a delay: the amplitude's s.e. was written as 0).
  if (const std::string without = pieces_of_unknown_uncertainty(dx.final_pieces); !without.empty())
    dx.warnings.push_back("final model: no standard error for " + without +
                          ": not estimable from this record's covariance (it trades off with "
                          "other parameters); the value stands, its uncertainty is unknown");
}

}  // namespace diagnose_detail

// -----------------------------------------------------------------------------------------------
// The edge: text and JSON.

std::string Verdict::to_text() const {
  if (!fitted) return failure.empty() ? "fit failed" : "fit failed: " + failure;
  if (nested == Nested::lag_below_one_sample)
    return "lag_time fitted below one sample: no lag (the velocity piece covers it)";
  if (nested == Nested::drop_below_sliding)
    return "what is left of the Stribeck drop at the record's lowest sliding speeds (5 % "
           "quantile) is below the force noise: it corrects the presliding, not the sliding force";
  if (nested == Nested::delay_within_stepping)
    return "the delay is no larger than the shift that stepping the model once per sample "
           "imitates (a reversal between two samples): not a delay of the record";
  if (nested == Nested::no_better_than_viscous)
    return "no better than the velocity piece it came with (viscous or Stribeck) alone (BIC)";
  std::ostringstream s;
  if (!at_bound.empty())
    s << at_bound << " ended at the edge of its range (on its own the effect as defined does not "
      << "describe this record); ";
  if (!bic_falls()) s << "BIC does not fall (" << format_number(delta_bic, 3) << "); ";
  if (estimation_at_floor)
    s << "the estimation error is already within the noise's spread of the floor of the force "
      << "noise and the displacement's sampling: nothing above it to explain; ";
  if (!drop_exceeds()) {
    s << "estimation drop " << format_number(drop, 3) << " N^2 below the required "
      << format_number(required, 3) << " N^2";
    if (operator_limited)
      s << " (what one more operator buys: the baseline may be short of operators)";
    s << "; ";
  }
  if (stopped_short)
    s << "its fit was stopped where, at its pace, it could no longer pass rules (a) and (b) (the "
      << "figures are where it stopped); ";
  switch (validation) {
    case Validation::not_evaluated:
      s << "(validation not evaluated)";
      break;
    case Validation::computed_for_report:
      s << "(validation computed for the report only)";
      break;
    case Validation::does_not_fall:
      s << "validation error does not fall enough (" << format_number(validation_before, 3)
        << " -> " << format_number(validation_after, 3) << " %, needs < "
        << format_number(validation_required, 3) << " %); ";
      break;
    case Validation::at_floor:
      s << "the validation error is already at the floor of the force noise and the "
        << "displacement's sampling ("
        << format_number(validation_before, 3) << " %, floor "
        << format_number(validation_required, 3) << " %): nothing above it to explain; ";
      break;
    case Validation::falls:
      break;
  }
  if (earns_place()) s << "earns its place";
  return s.str();
}

std::string Alternative::name() const {
  return effect ? std::string(effect_name(*effect)) : std::string(kCoulombLevelAlternative);
}

std::string Finding::name() const {
  return effect ? std::string(effect_name(*effect)) : std::string("nonlocal-memory");
}

bool Finding::has_parameter(std::string_view n) const {
  if (!effect) return n == "elements";
  return std::any_of(parameters.begin(), parameters.end(),
                     [&](const ExtensionEstimate& p) { return p.name == n; });
}

double Finding::parameter(std::string_view n) const {
  if (!effect && n == "elements") return static_cast<double>(elements);
  for (const auto& p : parameters)
    if (p.name == n) return p.value;
  throw InvalidParameter("finding " + name() + " has no parameter " + std::string(n));
}

std::vector<std::string> Finding::ambiguous_with_names() const {
  std::vector<std::string> out;
  for (const auto& a : ambiguous_with) out.push_back(a.name());
  return out;
}

std::string Finding::extension() const {
  if (!effect) return "Maxwell Slip elements (NLR) replace the single LuGre state";
  std::string s(effect_info(*effect).extension);
  // A velocity lag's companion (the viscous term or the Stribeck curve it acts on) is part of
  // what the finding adds: said, not only listed among the parameters.
  std::vector<Effect> companions;
  for (const auto& p : parameters)
    if (p.effect != *effect &&
        std::find(companions.begin(), companions.end(), p.effect) == companions.end())
      companions.push_back(p.effect);
  for (Effect e : companions)
    s += std::string(", acting on its companion ") + std::string(effect_name(e)) + " (" +
         std::string(effect_info(e).extension) + ")";
  return s;
}

std::string Finding::separating_excitation() const {
  if (ambiguous_with.empty() || !effect) return "";
  return std::string(effect_info(*effect).separating_excitation);
}

std::string Finding::sentence() const {
  std::ostringstream s;
  if (!effect) {
    s << "The LuGre simulation misses the presliding hysteresis with nonlocal memory; " << elements
      << " Maxwell Slip elements take validation error from " << format_number(validation_before, 3)
      << " % to " << format_number(validation_after, 3) << " %.";
    return s.str();
  }
  const ResidualEvidence& ev = *residual;
  const char* regime = ev.sliding_rms > 1.5 * ev.presliding_rms   ? "while sliding"
                       : ev.presliding_rms > 1.5 * ev.sliding_rms ? "in presliding"
                                                                  : "in both regimes";
  s << "The simulation is off by " << format_number(std::max(ev.sliding_rms, ev.presliding_rms), 3)
    << " N RMS " << regime;
  if (ev.sliding_samples)
    s << " (sliding speeds " << format_number(ev.sliding_speed_min, 3) << "-"
      << format_number(ev.sliding_speed_max, 3) << " m/s)";
  s << "; cause: " << name() << "; extension: " << extension() << " with";
  std::vector<const ExtensionEstimate*> by_name;
  for (const auto& p : parameters) by_name.push_back(&p);
  std::stable_sort(by_name.begin(), by_name.end(),
                   [](const auto* a, const auto* b) { return a->name < b->name; });
  for (const auto* p : by_name)
    s << " " << p->name << " = " << format_number(p->value, 4) << " " << parameter_unit(p->name);
  s << "; validation RSS/SSS " << format_number(validation_before, 3) << " % -> "
    << format_number(validation_after, 3) << " % (gain x"
    << format_number(validation_after > 0 ? validation_before / validation_after : 0.0, 3) << ")";
  if (!ambiguous_with.empty())
    s << "; ambiguous with " << ambiguous_with.front().name()
      << ", to separate: " << separating_excitation();
  s << ".";
  return s.str();
}

Json Finding::to_json() const {
  Json evidence, params = Json::object(), errors = Json::object(), intervals = Json::object();
  if (!effect) {
    evidence = {{"estimation_before", estimation_before},
                {"estimation_after", estimation_after},
                {"delta_bic", delta_bic}};
    params = {{"elements", elements}};
    errors["elements"] = nullptr;
    intervals["elements"] = nullptr;
  } else {
    evidence = {{"validation_residual", residual->to_json()},
                {"signature_explained", signature_explained},
                {"estimation_before", estimation_before},
                {"estimation_after", estimation_after},
                {"delta_bic", delta_bic},
                {"noise_floor_rss", noise_floor_rss}};
    if (partner)
      evidence["partner"] = {{"effect", std::string(effect_name(partner->effect))},
                             {"earns_place", partner->earns_place},
                             {"log_likelihood_ratio", partner->log_likelihood_ratio}};
    for (const auto& p : parameters) {
      params[p.name] = p.value;
      errors[p.name] = p.available ? Json(p.standard_error) : Json(nullptr);
      intervals[p.name] = p.available ? Json::array({p.lower95, p.upper95}) : Json(nullptr);
    }
  }
  Json x = {{"effect", name()},
            {"evidence", evidence},
            {"extension", extension()},
            {"parameters", params},
            {"standard_errors", errors},
            {"intervals", intervals},
            {"validation_before", validation_before},
            {"validation_after", validation_after},
            {"gain", validation_after > 0 ? validation_before / validation_after : 0.0},
            {"sentence", sentence()}};
  if (!ambiguous_with.empty()) {
    x["ambiguous_with"] = ambiguous_with_names();
    x["separating_excitation"] = separating_excitation();
  }
  return x;
}

Json Diagnosis::to_json() const {
  Json j;
  j["baseline"] = {
      {"model", baseline_model ? baseline_model->to_json() : Json()},
      {"validation",
       {{"rss_sss_percent", baseline_validation_percent}, {"initial_state", "estimated"}}},
      {"estimation", {{"rss_sss_percent", baseline_estimation_percent}}},
      {"one_more_operator_rss_drop", operator_drop},
      {"measurement_floor",
       {{"estimation_rss_sss_percent", estimation_measurement_floor_percent},
        {"validation_rss_sss_percent", validation_measurement_floor_percent}}},
      {"residual", baseline_evidence.to_json()}};
  Json fs = Json::array();
  for (const auto& f : findings) fs.push_back(f.to_json());
  j["findings"] = fs;
  Json cands = Json::array();
  for (const auto& c : first_round)
    cands.push_back({{"effect", c.nonlocal_memory ? std::string("nonlocal-memory")
                                                  : std::string(effect_name(c.effect))},
                     {"estimation_rss_sss_percent", c.estimation_percent},
                     {"validation_rss_sss_percent",
                      std::isnan(c.validation_percent) ? Json() : Json(c.validation_percent)},
                     {"delta_bic", c.delta_bic},
                     {"extra_parameters", c.extra_parameters},
                     {"earns_place", c.earns_place},
                     {"seconds", c.seconds},
                     {"verdict", c.verdict.to_text()}});
  j["candidates"] = cands;
  j["final"] = {{"model", final_model ? final_model->to_json() : Json()},
                {"validation",
                 {{"rss_sss_percent", final_validation_percent}, {"initial_state", "estimated"}}},
                {"estimation", {{"rss_sss_percent", final_estimation_percent}}},
                {"pieces", pieces_to_json(final_pieces)}};
  j["seconds"] = seconds;
  return j;
}

std::string Diagnosis::to_table() const {
  std::ostringstream s;
  s << "Baseline " << (baseline_model ? baseline_model->type() : std::string("?"))
    << ": validation RSS/SSS " << format_number(baseline_validation_percent, 4) << " % (estimation "
    << format_number(baseline_estimation_percent, 4) << " %, noise floor "
    << format_number(baseline_evidence.noise_floor_percent, 3)
    << " %, the displacement's sampling "
    << format_number(validation_measurement_floor_percent, 3) << " % more)\n";
  if (findings.empty())
    s << "No finding: no candidate extension earned its place (the baseline explains the data "
         "as far as this record can tell).\n";
  for (std::size_t i = 0; i < findings.size(); ++i)
    s << (i + 1) << ". " << findings[i].sentence() << "\n";
  s << "(" << format_number(seconds, 3) << " s, of which baseline "
    << format_number(baseline_seconds, 3) << " s)\n";
  s << "Final model: validation RSS/SSS " << format_number(final_validation_percent, 4) << " %";
  if (final_validation_percent > 0)
    s << " (gain x" << format_number(baseline_validation_percent / final_validation_percent, 3)
      << ")";
  s << "\n";
  if (!first_round.empty()) {
    s << "Candidates of the first round (estimation %, validation %, delta BIC, verdict):\n";
    for (const auto& c : first_round) {
      // The columns in a buffer of their own: the verdict is as long as its reasons (a buffer
      // for the whole line cut a long one, and its newline with it).
      char columns[128];
      std::snprintf(
          columns, sizeof columns, "  %-20s %10.4g %10.4g %10.4g %6.2fs  ",
          c.nonlocal_memory ? "nonlocal-memory" : std::string(effect_name(c.effect)).c_str(),
          c.estimation_percent, c.validation_percent, c.delta_bic, c.seconds);
      s << columns << c.verdict.to_text() << "\n";
    }
  }
  return s.str();
}

}  // namespace friction
