// Identification with requested extension pieces (see extension_identification.hpp): the
// public entry points, the report, and the steps both paths share.  The Maxwell Slip path is in
// extension_identify_slip.cpp, the held LuGre / DNLRX path in extension_identify_held.cpp, the
// model families, their fit and covariance in extension_families.hpp.
#include "friction/extension_identification.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "extension_families.hpp"
#include "extension_steps.hpp"
#include "friction/dnlrx_identification.hpp"
#include "friction/initial_state.hpp"
#include "friction/lg.hpp"
#include "number_format.hpp"
#include "position_origin.hpp"
#include "subnormals.hpp"

namespace friction {

namespace extension_detail {

RecordSignals record_signals(const Record& r) {
  const std::size_t n = r.size();
  FRICTION_CHECK(n >= 3, "identify: too few samples (", n, ") for extension pieces");
  RecordSignals s;
  s.v.assign(n, 0.0);
  s.a.assign(n, 0.0);
  // Of the displacement as measured, like the pieces' (extensions.hpp, for_each_extended_step).
  apply_local_derivatives<double>(r.time, r.measured(), record_derivative_windows(r), s.v, s.a);
  return s;
}

std::vector<double> state_from(const std::vector<double>& values,
                               const std::vector<double>& thresholds) {
  std::vector<double> s(thresholds.size(), 0.0);
  for (std::size_t i = 0; i < thresholds.size() && i < values.size(); ++i)
    s[i] = values[i] / thresholds[i];
  return s;
}

// Order of a joint start: the velocity pieces before the lag that acts through them.
std::vector<Effect> velocity_pieces_first(std::vector<Effect> effects) {
  std::stable_partition(effects.begin(), effects.end(),
                        [](Effect e) { return effect_info(e).kind != EffectKind::velocity_lag; });
  return effects;
}

namespace {

// The main parameter of a piece and its null value (no effect); false when it has none
// (normal-load: mu only rescales the level).
bool main_parameter(Effect e, std::string_view* name, double f0, double* null_value) {
  const EffectInfo& info = effect_info(e);
  *name = info.main_parameter;
  *null_value = info.null_value == NullValue::reference_force ? f0 : 0.0;
  return info.null_value != NullValue::none;
}

}  // namespace

void note_rank_deficiency(ExtensionIdentification& res, bool rank_deficient) {
  if (!rank_deficient) return;
  const std::string without = friction::pieces_of_unknown_uncertainty(res.estimates);
  res.warnings.push_back(
      "the joint fit's covariance is rank deficient (some parameters trade off against each other "
      "on this record): " +
      (without.empty() ? std::string("the pieces' standard errors are those of the estimable "
                                     "parameters (widened to what its bounds allow where one "
                                     "trades off against an initial state), the base's that "
                                     "trade off get none")
                       : "no standard error for " + without));
}

// Warnings about the pieces: bounds and missing evidence (header comment, 3).
void judge_evidence(ExtensionIdentification& res, const std::vector<Effect>& effects, double f0,
                    double sigmas) {
  for (Effect e : effects) {
    std::string_view main;
    double null_value = 0;
    const bool testable = main_parameter(e, &main, f0, &null_value);
    bool no_evidence = false;
    for (const auto& est : res.estimates) {
      if (est.effect != e) continue;
      if (est.at_bound) {
        if (testable && est.name == main && at_bound(est.value, null_value))
          no_evidence = true;
        else
          res.warnings.push_back("extension " + std::string(effect_name(e)) + ": " + est.name +
                                 " = " + format_number(est.value, 4) + " " + est.unit +
                                 " ends at a bound of the fit (not identified by this record)");
      }
      if (testable && est.name == main && !est.at_bound && est.standard_error > 0 &&
          std::abs(est.value - null_value) < sigmas * est.standard_error)
        no_evidence = true;
    }
    if (no_evidence) {
      res.without_evidence.push_back(e);
      res.warnings.push_back("the record gives no evidence of " + std::string(effect_name(e)) +
                             " (its fitted value is within " + format_number(sigmas, 2) +
                             " standard errors of none, or at the bound that means none)");
    }
  }
}

}  // namespace extension_detail

// -----------------------------------------------------------------------------------------------

using namespace extension_detail;

std::string extension_parameter_unit(std::string_view name) {
  return std::string(parameter_unit(name));
}

std::string extension_names() {
  return effect_names();
}

std::vector<Effect> parse_extension_list(const std::vector<std::string>& names) {
  std::vector<Effect> out;
  for (const auto& item : names) {
    std::size_t begin = 0;
    while (begin <= item.size()) {
      std::size_t end = item.find(',', begin);
      if (end == std::string::npos) end = item.size();
      std::string name = item.substr(begin, end - begin);
      name.erase(0, name.find_first_not_of(" \t"));
      name.erase(name.find_last_not_of(" \t") + 1);
      begin = end + 1;
      if (name.empty()) continue;
      const auto e = effect_from_name(name);
      if (!e)
        throw InvalidParameter("unknown extension '" + name + "' (expected one of " +
                               extension_names() + ")");
      if (std::find(out.begin(), out.end(), *e) == out.end()) out.push_back(*e);
    }
  }
  return out;
}

void check_extension_request(const std::string& type, const std::vector<Effect>& effects,
                             const Record& r) {
  const auto has = [&](Effect e) {
    return std::find(effects.begin(), effects.end(), e) != effects.end();
  };
  if (effects.empty()) return;
  FRICTION_CHECK(type == "maxwell-slip" || type == "lugre" || type == "dnlrx",
                 "identify: extensions can be identified on maxwell-slip, lugre and dnlrx, not ",
                 type);
  if (type == "lugre") {
    if (has(Effect::viscous))
      throw InvalidParameter(
          "identify: lugre already carries viscous friction in its base (sigma2 v, the "
          "'viscous' parameter); ask for viscous on maxwell-slip");
    if (has(Effect::stribeck))
      throw InvalidParameter(
          "identify: lugre already carries the Stribeck effect in its base (static, "
          "stribeck_velocity, stribeck_exponent); ask for stribeck on maxwell-slip");
    if (has(Effect::frictional_lag))
      throw InvalidParameter(
          "identify: frictional-lag acts through the viscous and Stribeck pieces, which lugre "
          "holds in its base (and its bristle dynamics already lag); ask for it on "
          "maxwell-slip");
  }
  if (type == "dnlrx") {
    if (has(Effect::viscous))
      throw InvalidParameter(
          "identify: dnlrx already carries viscous friction in its input filter (sum_j g_j "
          "dx(t-j) = (sum_j g_j) Ts v at constant speed; --input-order sets it); ask for "
          "viscous on maxwell-slip");
    if (has(Effect::frictional_lag) && !has(Effect::stribeck))
      throw InvalidParameter(
          "identify: on dnlrx frictional-lag needs the stribeck piece it acts through (the "
          "input filter is its own viscous lag); ask for stribeck,frictional-lag");
  }
  const bool needs_normal = std::any_of(effects.begin(), effects.end(),
                                        [](Effect e) { return effect_info(e).needs_normal_force; });
  if (needs_normal && !r.has_normal())
    throw DataError(r.source, 0, 0,
                    "the normal-load extension needs a normal force column (normal, "
                    "normal_force or normal_force_n; --columns normal=NAME), and the record "
                    "has none");
}

namespace {

// The fitted pieces' phase carried to the origin (position_origin.hpp), with its estimate.
void phase_to_origin(ExtensionIdentification& res, double x_ref) {
  ExtensionParameters<double> ext = res.model.extensions();
  detail::phase_to_origin(ext, x_ref);
  res.model = res.model.with_extensions(ext);
  std::vector<double> base_se;
  for (const auto& p : res.base_parameters) base_se.push_back(p.standard_error);
  detail::phase_estimate_to_origin(res.estimates, base_se, res.correlation_matrix, x_ref,
                                   ext.position_dependence->phase);
}

}  // namespace

ExtensionIdentification identify_extensions(const AnyModel& base, const Record& r,
                                            const std::vector<double>& base_simulated,
                                            const std::vector<double>& base_initial,
                                            const std::vector<Effect>& effects,
                                            const ExtensionFitOptions& o) {
  const detail::SubnormalsFlushed subnormals_flushed;  // subnormals.hpp
  const auto started = std::chrono::steady_clock::now();
  FRICTION_CHECK(r.has_force(), r.source, ": the record has no force to identify from");
  FRICTION_CHECK(base.extensions().empty(), "identify_extensions: the base carries pieces already");
  FRICTION_CHECK(base_simulated.size() == r.size(),
                 "identify_extensions: the base's free run does not match the record");
  check_extension_request(base.type(), effects, r);
  ExtensionIdentification res{base};
  res.base_estimation_percent = 100.0 * rss_of(r, base_simulated) / sum_sq(r.force);
  // Position dependence sees the absolute position: fitted about the record's first position
  // (position_origin.hpp).
  const bool position =
      std::find(effects.begin(), effects.end(), Effect::position_dependence) != effects.end();
  const double x_ref = position ? r.displacement.front() : 0.0;
  Record shifted;
  if (x_ref != 0.0) shifted = detail::shifted_record(r, x_ref);
  const Record& fitted_on = x_ref != 0.0 ? shifted : r;
  if (effects.empty()) {
    res.model = base;
    res.simulated = base_simulated;
    res.estimation = compute_errors(r.force, base_simulated);
    res.initial_values = base_initial;
    return res;
  }
  std::visit(
      [&](const auto& ext) {
        using B = std::decay_t<decltype(ext.base())>;
        const auto& p = ext.base().parameters();
        if constexpr (std::is_same_v<B, MaxwellSlip<double>>) {
          identify_on_maxwell_slip(res, p, fitted_on, base_initial, effects, o);
        } else if constexpr (std::is_same_v<B, Dnlrx<double>>) {
          identify_on_dnlrx(res, p, fitted_on, base_simulated, base_initial, effects, o);
        } else if constexpr (std::is_same_v<B, LuGre<double>>) {
          identify_on_lugre(res, p, fitted_on, base_simulated, base_initial, effects, o);
        } else {
          throw InvalidParameter("identify: extensions cannot be identified on " + base.type());
        }
      },
      base.variant());
  if (x_ref != 0.0 && res.model.extensions().position_dependence) phase_to_origin(res, x_ref);
  const ExtendedFreeRun run = free_run_extended(res.model, r);
  res.simulated = run.simulated;
  res.initial_values = run.initial;
  res.estimation = compute_errors(r.force, res.simulated);
  res.initial_state = run.to_json();
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return res;
}

ExtendedFreeRun free_run_extended(const AnyModel& model, const Record& r) {
  FRICTION_CHECK(r.has_force(), r.source, ": the record has no force to estimate the state from");
  ExtendedFreeRun out;
  std::visit(
      [&](const auto& ext) {
        using B = std::decay_t<decltype(ext.base())>;
        const auto& p = ext.base().parameters();
        const ExtensionParameters<double>& pieces = ext.extensions();
        if constexpr (std::is_same_v<B, MaxwellSlip<double>>) {
          const SlipFamily fam{p, false, pieces.frictional_lag.has_value()};
          const std::vector<double> s = estimate_family_state(
              r, fam, pieces, plain_relative_state(p, pieces, r), value_of(ext.reference_force()));
          out.simulated = family_run(r, fam, pieces, nullptr, s);
          if (fam.lag_state) out.lag_offset = s.back();  // the last state entry (set_state)
          // The deflections at the first sample: deflections_from_relative gives them at level 1,
          // and the model's first step scales them by its level (extensions.hpp, Initial state).
          out.initial = deflections_from_relative(p, s, pieces);
          out.initial.resize(p.size());  // the lag's offset, if any, is reported apart
          const double level = first_level(p, pieces, r);
          for (double& d : out.initial) d *= level;
        } else if constexpr (std::is_same_v<B, Dnlrx<double>>) {
          const DnlrxFamily fam{p, false, pieces.frictional_lag.has_value()};
          const DnlrxFreeRun plain = free_run_dnlrx(
              p, r.time, displacement_the_base_sees(r, pieces, record_derivative_windows(r)),
              r.force);
          const std::vector<double> s = estimate_family_state(
              r, fam, pieces, state_from(plain.initial_deflections, p.threshold),
              value_of(ext.reference_force()));
          out.simulated = family_run(r, fam, pieces, nullptr, s);
          if (fam.lag_state) out.lag_offset = s.back();  // the last state entry (set_state)
          for (std::size_t i = 0; i < p.size(); ++i) out.initial.push_back(s[i] * p.threshold[i]);
        } else if constexpr (std::is_same_v<B, LuGre<double>>) {
          const LuGreFamily fam{p, false, pieces.frictional_lag.has_value()};
          const double z0 = estimate_lugre_initial_state(
              p, r.time, displacement_the_base_sees(r, pieces, record_derivative_windows(r)),
              r.force);
          const std::vector<double> s = estimate_family_state(r, fam, pieces, {z0 / fam.zref()},
                                                              value_of(ext.reference_force()));
          out.simulated = family_run(r, fam, pieces, nullptr, s);
          if (fam.lag_state) out.lag_offset = s.back();  // the last state entry (set_state)
          out.initial = {s[0] * fam.zref()};
        } else {
          throw InvalidParameter("free_run_extended: no initial-state estimator for " +
                                 model.type());
        }
      },
      model.variant());
  return out;
}

Json ExtendedFreeRun::to_json() const {
  Json j = {{"kind", "estimated"}, {"values", initial}, {"unit", "m"}};
  if (lag_offset) j["lag_offset"] = {{"value", *lag_offset}, {"unit", "m/s"}};
  return j;
}

std::string pieces_of_unknown_uncertainty(const std::vector<ExtensionEstimate>& estimates) {
  std::string list;
  for (const auto& e : estimates)
    if (e.uncertainty_unknown())
      list += (list.empty() ? "" : ", ") + std::string(effect_name(e.effect)) + "." + e.name;
  return list;
}

Json pieces_to_json(const std::vector<ExtensionEstimate>& estimates) {
  Json pieces = Json::object();
  for (const auto& est : estimates) {
    // A piece at a bound says so and keeps 0; one whose standard error could not be had (not
    // estimable where the covariance is rank deficient) gets null, not a 0 that reads as exact.
    Json v = {{"value", est.value},
              {"unit", est.unit},
              {"standard_error",
               est.uncertainty_unknown() ? Json(nullptr) : Json(est.standard_error)},
              {"at_bound", est.at_bound}};
    pieces[std::string(effect_name(est.effect))][est.name] = v;
  }
  return pieces;
}

Json ExtensionIdentification::to_json() const {
  Json j;
  j["base"] = base_held ? "held" : "refitted jointly";
  Json ord = Json::array();
  for (Effect e : order) ord.push_back(std::string(effect_name(e)));
  j["order"] = ord;
  j["pieces"] = pieces_to_json(estimates);
  Json none = Json::array();
  for (Effect e : without_evidence) none.push_back(std::string(effect_name(e)));
  j["no_evidence"] = none;
  j["estimation_before_percent"] = base_estimation_percent;
  j["estimation_after_percent"] = estimation.rss_sss_percent;
  j["fit_rss_sss_percent"] = fit_rss_sss_percent;
  if (!base_held) j["restarted"] = restarted;
  j["seconds"] = seconds;
  return j;
}

}  // namespace friction
