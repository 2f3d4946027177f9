#include "friction/methods.hpp"

#include <chrono>
#include <cmath>
#include <sstream>

#include "friction/dnlrx_identification.hpp"
#include "friction/initial_state.hpp"
#include "friction/lg.hpp"
#include "friction/metrics.hpp"
#include "friction/nlr.hpp"
#include "friction/signals.hpp"
#include "subnormals.hpp"

namespace friction {

std::string method_name(const std::string& type) {
  if (type == "lugre") return "LG";
  if (type == "maxwell-slip") return "NLR";
  if (type == "dnlrx") return "DNLRX";
  return type;
}

std::string method_type(const std::string& name) {
  if (name == "LG" || name == "lg") return "lugre";
  if (name == "NLR" || name == "nlr") return "maxwell-slip";
  if (name == "DNLRX" || name == "dnlrx") return "dnlrx";
  return check_model_type(name);
}

namespace {

void require_force(const Record& r) {
  FRICTION_CHECK(r.has_force(), r.source, ": the record has no force column to identify from");
}

Json values_json(const std::vector<double>& values, const char* unit) {
  return {{"kind", "estimated"}, {"values", values}, {"unit", unit}};
}

}  // namespace

namespace {

IdentifiedModel identify_base(const std::string& type, const Record& r, const MethodOptions& o);

// The restart of a Maxwell Slip base keeps the user's choice of M (or of its largest value).
ExtensionFitOptions fit_options(const MethodOptions& o) {
  ExtensionFitOptions f = o.extension_fit;
  if (f.operators == 0) f.operators = o.operators;
  if (f.max_operators == 0) f.max_operators = o.max_operators;
  f.global_stage = o.global_stage;
  f.threads = o.threads;
  return f;
}

// The base's report updated with the pieces: refitted figures, the pieces' parameters appended
// ("<effect>.<name>"), warnings and the correlation of the new parameter list.
IdentifiedModel with_extensions(IdentifiedModel base, const Record& r, const MethodOptions& o) {
  ExtensionIdentification x = identify_extensions(
      base.model, r, base.report.estimation_simulated,
      base.model.type() == "lugre" ? base.initial_state["values"].get<std::vector<double>>()
                                   : base.report.initial_deflections,
      o.extensions, fit_options(o));
  IdentifiedModel m{x.model, std::move(base.report), x.initial_state, Json()};
  IdentificationReport& rep = m.report;
  // The base's own warnings describe its fit before the pieces were added.
  for (auto& w : rep.warnings)
    w = method_name(m.model.type()) + " base, before the extensions: " + w;
  Eigen::MatrixXd base_corr = rep.correlation;
  if (!x.base_held) {
    // The Maxwell Slip parameters were refitted: their estimates replace the NLR ones.
    rep.parameters = x.base_parameters;
    base_corr.resize(0, 0);
  }
  const auto nb = static_cast<Eigen::Index>(rep.parameters.size());
  for (const auto& e : x.estimates) {
    ParameterEstimate p;
    p.name = std::string(effect_name(e.effect)) + "." + e.name;
    p.unit = e.unit;
    p.value = e.value;
    p.standard_error = e.standard_error;
    p.lower95 = e.lower95;  // covariance_report.hpp: symmetric, the pieces are fitted linearly
    p.upper95 = e.upper95;
    rep.parameters.push_back(p);
  }
  const auto nt = static_cast<Eigen::Index>(rep.parameters.size());
  Eigen::MatrixXd corr = Eigen::MatrixXd::Identity(nt, nt);
  if (x.base_held) {
    if (base_corr.rows() == nb && base_corr.cols() == nb) corr.topLeftCorner(nb, nb) = base_corr;
    const Eigen::Index ne = nt - nb;
    if (x.correlation_matrix.rows() == ne && x.correlation_matrix.cols() == ne)
      corr.bottomRightCorner(ne, ne) = x.correlation_matrix;
  } else if (x.correlation_matrix.rows() == nt && x.correlation_matrix.cols() == nt) {
    corr = x.correlation_matrix;
  }
  rep.correlation = corr;
  rep.estimation = x.estimation;
  rep.estimation_simulated = x.simulated;
  if (m.model.type() != "lugre") rep.initial_deflections = x.initial_values;
  for (auto& w : x.warnings) rep.warnings.push_back(std::move(w));
  rep.seconds += x.seconds;
  m.extensions = x.to_json();
  return m;
}

}  // namespace

IdentifiedModel identify_model(const std::string& type_or_name, const Record& r,
                               const MethodOptions& o) {
  const detail::SubnormalsFlushed subnormals_flushed;  // subnormals.hpp
  require_force(r);
  const std::string type = method_type(type_or_name);
  if (o.extensions.empty()) return identify_base(type, r, o);
  // A request the base cannot carry fails before the (long) base identification.
  check_extension_request(type, o.extensions, r);
  MethodOptions base = o;
  base.base_without_dominant_inertia = true;
  return with_extensions(identify_base(type, r, base), r, o);
}

namespace {

// NLR on the record, unless an inertial force dominates it: the sliding force regressed on
// sgn v, 1, v and a (signals.hpp) finds m > 0 by more than 4 standard errors and an m·a whose RMS
// exceeds the friction level c.  An m·a term is in phase with -x in an oscillation: it turns the
// hysteresis loops over, and NLR then ends with every stiffness at zero or with a relay that
// explains nothing.  With MethodOptions::base_without_dominant_inertia the base is then fitted to
// F - m·a, as a start for pieces that model the inertia; without it the result (or the error)
// says what dominates.
NlrResult maxwell_slip_base(const Record& r, const NlrOptions& n, const MethodOptions& o) {
  const SlidingForceRegression reg = sliding_force_regression(r.time, r.measured(), r.force);
  const double inertial_rms =
      reg.acceleration.empty()
          ? 0.0
          : std::abs(reg.mass) * std::sqrt(sum_of_squares(reg.acceleration) /
                                           static_cast<double>(reg.acceleration.size()));
  const bool dominant =
      reg.samples > 0 && reg.mass > 4.0 * reg.mass_se && inertial_rms > std::abs(reg.coulomb);
  std::ostringstream what;
  what << "an inertial force m·a dominates the force (m = " << reg.mass << " +/- " << reg.mass_se
       << " kg by regression of the sliding force on sgn v, 1, v and a; RMS " << inertial_rms
       << " N against a friction level of " << std::abs(reg.coulomb) << " N)";
  if (dominant && o.base_without_dominant_inertia) {
    std::vector<double> corrected(r.force);
    for (std::size_t k = 0; k < corrected.size(); ++k)
      corrected[k] -= reg.mass * reg.acceleration[k];
    NlrResult res = identify_maxwell_slip(r.time, r.displacement, corrected, n);
    // The figures of the report are those of the force as recorded.
    res.report.estimation = compute_errors(r.force, res.report.estimation_simulated);
    res.report.warnings.push_back(what.str() +
                                  ": the base was fitted to the force less that term, so that "
                                  "the pieces can start from it");
    return res;
  }
  try {
    NlrResult res = identify_maxwell_slip(r.time, r.displacement, r.force, n);
    if (dominant)
      res.report.warnings.push_back(what.str() +
                                    " that the base cannot carry: identify with --extension "
                                    "inertia, or run diagnose");
    return res;
  } catch (const NumericalError& e) {
    if (!dominant) throw;
    throw NumericalError(std::string(e.what()) + ": " + what.str() +
                         " that the base cannot carry: identify with --extension inertia, or run "
                         "diagnose");
  }
}

IdentifiedModel identify_base(const std::string& type, const Record& r, const MethodOptions& o) {
  const ExtensionParameters<double> none;
  if (type == "maxwell-slip") {
    NlrOptions n;
    if (o.max_operators > 0) n.max_operators = o.max_operators;
    n.operators = o.operators;
    n.global_stage = o.global_stage;
    n.threads = o.threads;
    n.displacement_resolution = record_resolution(r);
    NlrResult res = maxwell_slip_base(r, n, o);
    Json init = values_json(res.report.initial_deflections, "m");
    return {AnyModel(Extended<MaxwellSlip<double>>(MaxwellSlip<double>(res.parameters), none)),
            std::move(res.report), std::move(init), Json()};
  }
  if (type == "dnlrx") {
    DnlrxOptions d;
    if (o.max_operators > 0) d.max_operators = o.max_operators;
    d.operators = o.operators;
    d.spring_order = o.spring_order;
    d.input_order = o.input_order;
    d.nlr.global_stage = o.global_stage;
    d.nlr_report = o.maxwell_slip_report;
    d.threads = o.threads;
    d.nlr.displacement_resolution = record_resolution(r);
    DnlrxResult res = identify_dnlrx(r.time, r.displacement, r.force, d);
    Json init = values_json(res.report.initial_deflections, "m");
    return {AnyModel(Extended<Dnlrx<double>>(Dnlrx<double>(res.parameters), none)),
            std::move(res.report), std::move(init), Json()};
  }
  if (type == "lugre") {
    LgOptions l;
    l.global_stage = o.global_stage;
    l.seed = o.seed;
    l.displacement_resolution = record_resolution(r);
    LgResult res = identify_lugre(r.time, r.displacement, r.force, l);
    Json init = values_json({res.initial_state}, "m");
    return {AnyModel(Extended<LuGre<double>>(LuGre<double>(res.parameters), none)),
            std::move(res.report), std::move(init), Json()};
  }
  throw InvalidParameter("identify: model type '" + type +
                         "' cannot be identified yet (lugre, maxwell-slip and dnlrx can)");
}

}  // namespace

Validation validate_model(const AnyModel& model, const Record& r) {
  const detail::SubnormalsFlushed subnormals_flushed;  // subnormals.hpp
  require_force(r);
  Validation v;
  const bool plain = model.extensions().empty();
  std::visit(
      [&](const auto& ext) {
        using Base = std::decay_t<decltype(ext.base())>;
        const auto& p = ext.base().parameters();
        if constexpr (std::is_same_v<Base, MaxwellSlip<double>>) {
          if (plain) {
            FreeRun run = free_run_maxwell_slip(p, r.time, r.displacement, r.force);
            v.simulated = std::move(run.simulated);
            v.initial_state_values = values_json(run.initial_deflections, "m");
            v.initial_state = "estimated";
            return;
          }
        } else if constexpr (std::is_same_v<Base, Dnlrx<double>>) {
          if (plain) {
            DnlrxFreeRun run = free_run_dnlrx(p, r.time, r.displacement, r.force);
            v.simulated = std::move(run.simulated);
            v.initial_state_values = values_json(run.initial_deflections, "m");
            v.initial_state = "estimated";
            return;
          }
        } else if constexpr (std::is_same_v<Base, LuGre<double>>) {
          if (plain) {
            LuGreFreeRun run = free_run_lugre(p, r.time, r.displacement, r.force);
            v.simulated = std::move(run.simulated);
            v.initial_state_values = values_json({run.initial_state}, "m");
            v.initial_state = "estimated";
            return;
          }
        }
        if constexpr (std::is_same_v<Base, MaxwellSlip<double>> ||
                      std::is_same_v<Base, Dnlrx<double>> || std::is_same_v<Base, LuGre<double>>) {
          // Pieces on a base with a state estimator: the state is estimated through them.
          ExtendedFreeRun run = free_run_extended(model, r);
          v.simulated = std::move(run.simulated);
          v.initial_state_values = run.to_json();
          v.initial_state = "estimated";
          return;
        }
        AnyModel copy = model;
        v.simulated = copy.simulate(r);
        v.initial_state = "zero";
        v.initial_state_values = {{"kind", "zero"}};
      },
      model.variant());
  v.errors = compute_errors(r.force, v.simulated);
  v.noise_sigma = estimate_white_noise_sigma(r.force);
  v.noise_floor_percent = noise_floor_rss_sss_percent(r.force, v.noise_sigma);
  return v;
}

Json errors_to_json(const ErrorMetrics& e) {
  return {{"rss_sss_percent", e.rss_sss_percent},
          {"rms", e.rms},
          {"max_abs", e.max_abs},
          {"r_squared", e.r_squared},
          {"samples", e.samples}};
}

Json report_to_json(const IdentificationReport& rep) {
  Json j;
  Json params = Json::array();
  // A standard error of 0 means "not available" (identification.hpp): null, so that no script
  // reads a zero-width interval as certainty.
  for (const auto& p : rep.parameters) {
    const bool known = p.standard_error > 0.0;
    params.push_back({{"name", p.name},
                      {"unit", p.unit},
                      {"value", p.value},
                      {"standard_error", known ? Json(p.standard_error) : Json(nullptr)},
                      {"lower95", known ? Json(p.lower95) : Json(nullptr)},
                      {"upper95", known ? Json(p.upper95) : Json(nullptr)}});
  }
  j["parameters"] = params;
  Json corr = Json::array();
  for (Eigen::Index i = 0; i < rep.correlation.rows(); ++i) {
    Json row = Json::array();
    for (Eigen::Index k = 0; k < rep.correlation.cols(); ++k) {
      const double c = rep.correlation(i, k);
      row.push_back(std::isfinite(c) ? Json(c) : Json(nullptr));
    }
    corr.push_back(row);
  }
  j["correlation"] = corr;
  Json sel = Json::array();
  for (const auto& s : rep.selection)
    sel.push_back({{"operators", s.operators},
                   {"spring_order", s.spring_order},
                   {"input_order", s.input_order},
                   {"parameters", s.parameters},
                   {"rss_sss_percent", s.rss_sss_percent},
                   {"criterion", s.criterion},
                   {"selected", s.selected},
                   {"failed", s.failed}});
  j["selection"] = {{"criterion", rep.criterion}, {"table", sel}};
  j["convergence"] = {{"converged", rep.convergence.converged},
                      {"iterations", rep.convergence.iterations},
                      {"local_searches", rep.convergence.local_searches},
                      {"initial_cost_percent", rep.convergence.initial_cost},
                      {"final_cost_percent", rep.convergence.final_cost},
                      {"message", rep.convergence.message}};
  Json starts = Json::array();
  for (const auto& s : rep.starts)
    starts.push_back({{"operators", s.operators},
                      {"kind", s.kind},
                      {"start_percent", s.start_percent},
                      {"final_percent", s.final_percent},
                      {"distinct", s.distinct},
                      {"start_thresholds", s.start_thresholds},
                      {"final_thresholds", s.final_thresholds},
                      {"iterations", s.iterations},
                      {"seconds", s.seconds}});
  j["starts"] = starts;
  j["seconds"] = rep.seconds;
  j["noise"] = {{"sigma", rep.noise_sigma}, {"floor_percent", rep.noise_floor_percent}};
  j["data_scales"] = {{"displacement_resolution", rep.displacement_resolution},
                      {"largest_travel", rep.largest_travel},
                      {"presliding_travel", rep.presliding_travel}};
  return j;
}

}  // namespace friction
