// `diagnose`: fit a baseline, show what its simulation gets wrong on the validation record, name
// the causes, extend the model and measure the gain (cli.md; the method is in diagnose.hpp).
#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>
#include <tuple>

#include "../number_format.hpp"
#include "commands.hpp"
#include "friction/atomic_file.hpp"
#include "friction/diagnose.hpp"
#include "friction/speed_coverage.hpp"
#include "progress.hpp"
#include "report_option.hpp"

namespace friction::cli {

namespace {

struct DiagnoseCliOptions {
  std::string data, validate, baseline = "maxwell-slip", svg, report;
  double holdout = 0.3;
  std::size_t max_operators = 0;
  bool no_global = false;
  unsigned seed = 1;
  unsigned threads = 0;
  InputOptions input;
  OutputOptions output;
};

// Residual of the baseline and of the final model against velocity on the validation record: two
// scatter plots side by side (SVG, no dependencies).
std::string residual_svg(const Record& val, const std::vector<double>& before,
                         const std::vector<double>& after, double before_pct, double after_pct) {
  const std::size_t n = val.size();
  std::vector<double> v(n, 0.0);
  for (std::size_t k = 1; k < n; ++k)
    v[k] = (val.displacement[k] - val.displacement[k - 1]) / (val.time[k] - val.time[k - 1]);
  double vmax = 1e-300, emax = 1e-300;
  for (std::size_t k = 0; k < n; ++k) {
    vmax = std::max(vmax, std::abs(v[k]));
    emax = std::max({emax, std::abs(val.force[k] - before[k]), std::abs(val.force[k] - after[k])});
  }
  const double w = 420, h = 300, pad = 40;
  std::ostringstream s;
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << 2 * w << "\" height=\"" << h
    << "\" font-family=\"sans-serif\" font-size=\"11\">\n";
  const std::size_t stride = std::max<std::size_t>(1, n / 3000);
  for (int panel = 0; panel < 2; ++panel) {
    const auto& sim = panel == 0 ? before : after;
    const double ox = panel * w;
    s << "<rect x=\"" << ox + pad << "\" y=\"" << pad / 2 << "\" width=\"" << w - 1.5 * pad
      << "\" height=\"" << h - 1.5 * pad << "\" fill=\"none\" stroke=\"#888\"/>\n";
    s << "<text x=\"" << ox + pad << "\" y=\"" << pad / 2 - 6 << "\">"
      << (panel == 0 ? "baseline" : "final") << " residual [N] vs velocity [m/s], RSS/SSS "
      << format_number(panel == 0 ? before_pct : after_pct, 3) << " %</text>\n";
    s << "<text x=\"" << ox + pad << "\" y=\"" << h - 4 << "\">|v| max " << format_number(vmax, 3)
      << " m/s, |e| max " << format_number(emax, 3) << " N</text>\n";
    const double cx = ox + pad + (w - 1.5 * pad) / 2, cy = pad / 2 + (h - 1.5 * pad) / 2;
    s << "<line x1=\"" << ox + pad << "\" y1=\"" << cy << "\" x2=\"" << ox + w - pad / 2
      << "\" y2=\"" << cy << "\" stroke=\"#ccc\"/>\n";
    for (std::size_t k = 0; k < n; k += stride) {
      const double px = cx + v[k] / vmax * (w - 1.5 * pad) / 2;
      const double py = cy - (val.force[k] - sim[k]) / emax * (h - 1.5 * pad) / 2;
      s << "<circle cx=\"" << format_number(px, 6) << "\" cy=\"" << format_number(py, 6)
        << "\" r=\"1\" fill=\"#1f77b4\" fill-opacity=\"0.5\"/>\n";
    }
  }
  s << "</svg>\n";
  return s.str();
}

// The free run of one of the diagnosis' models on a record, initial state estimated there: for a
// Maxwell Slip model with pieces the way the diagnosis scored it (extended_validation_percent),
// otherwise the way `validate` does.
std::vector<double> free_run(const AnyModel& model, const Record& r) {
  if (const auto* m = std::get_if<Extended<MaxwellSlip<double>>>(&model.variant())) {
    std::vector<double> sim;
    extended_validation_percent(m->base().parameters(), m->extensions(), r, &sim);
    return sim;
  }
  return validate_model(model, r).simulated;
}

// The report: the baseline and the final model on both records, and one panel per finding.
report::Document diagnose_report(const Json& doc, const Diagnosis& d, const Record& est,
                                 const Record& val) {
  FRICTION_CHECK_AS(NumericalError, d.baseline_model && d.final_model,
                    "diagnose: no baseline or final model to report");
  report::DiagnoseFits fits;
  fits.baseline_estimation = free_run(*d.baseline_model, est);
  fits.baseline_validation = free_run(*d.baseline_model, val);
  fits.final_estimation = free_run(*d.final_model, est);
  fits.final_validation = free_run(*d.final_model, val);
  fits.baseline_label = "baseline (" + d.baseline_model->type() + ")";
  fits.final_label = d.findings.empty() ? "final (= baseline)" : "final";
  // Per-finding panels: each finding's signature before and after its own step of the chain.
  std::vector<report::FindingPanelInput> panels;
  const Json& findings = doc["findings"];
  for (std::size_t k = 0; k < findings.size() && k < d.findings.size(); ++k) {
    const Finding& f = d.findings[k];
    report::FindingPanelInput in;
    in.effect = findings[k].value("effect", std::string());
    in.validation = &val;
    const bool own_runs = !f.validation_run_before.empty() && !f.validation_run_after.empty();
    in.before = own_runs ? std::span<const double>(f.validation_run_before)
                         : std::span<const double>(fits.baseline_validation);
    in.after = own_runs ? std::span<const double>(f.validation_run_after)
                        : std::span<const double>(fits.final_validation);
    in.before_label = own_runs ? "before" : "baseline";
    in.after_label = own_runs ? "after" : "final";
    in.finding = findings[k];
    panels.push_back(std::move(in));
  }
  return report::diagnose_report(doc, est, val, fits, panels, run_info());
}

int run_diagnose(const DiagnoseCliOptions& o) {
  check_report_path(o.report);
  Record est, val;
  std::vector<std::string> warnings;
  if (!o.validate.empty()) {
    std::tie(est, val) = load_record_pair(o.data, o.validate, o.input);
    warnings = est.conditioning.warnings;
    for (const auto& w : val.conditioning.warnings) warnings.push_back(o.validate + ": " + w);
  } else {
    Record all = load_record(o.data, o.input, /*require_force=*/true);
    warnings = all.conditioning.warnings;
    if (!(o.holdout > 0 && o.holdout < 1))
      throw OptionError("--holdout must lie strictly between 0 and 1");
    const std::size_t n = all.size();
    const auto n_est =
        static_cast<std::size_t>(std::llround((1.0 - o.holdout) * static_cast<double>(n)));
    if (n_est < 2 * kMinSamples || n - n_est < kMinSamples)
      throw DataError(o.data, 0, 0, "too few samples to hold out for validation; give --validate");
    est = all.slice(0, n_est);
    val = all.slice(n_est, n);
    warnings.push_back("no --validate given: the last " + format_number(100 * o.holdout, 3) +
                       " % of " + o.data + " (from t = " + format_number(val.time.front(), 6) +
                       " s) is held out for validation");
  }
  DiagnoseOptions opt;
  opt.baseline = check_model_type(o.baseline);
  opt.method.max_operators = o.max_operators;
  opt.method.global_stage = !o.no_global;
  opt.method.seed = o.seed;
  opt.threads = o.threads;
  Progress progress;
  progress.update("diagnose: fitting the " + opt.baseline + " baseline and its extensions ...");
  const Diagnosis d = diagnose(est, val, opt);
  progress.done();

  Json doc = new_document("diagnose");
  add_warnings(doc, warnings);
  add_warnings(doc, d.warnings);
  // The final model's speed-dependent terms (a LuGre baseline's curve, the pieces named) on a
  // validation record faster than the estimation record (speed_coverage.hpp).
  if (d.final_model)
    if (auto w = speed_extrapolation_warning(speed_coverage(largest_speed(est), val),
                                             speed_dependent_terms(d.final_model->to_json())))
      add_warnings(doc, {*w});
  Json body = d.to_json();
  for (auto it = body.begin(); it != body.end(); ++it) doc[it.key()] = it.value();
  doc["data"] = {{"estimation", {{"file", o.data}, {"samples", est.size()}}},
                 {"validation",
                  {{"file", o.validate.empty() ? o.data : o.validate},
                   {"samples", val.size()},
                   {"held_out", o.validate.empty()}}}};

  if (!o.svg.empty()) {
    // Both free runs from the initial state estimated on the validation record.
    std::vector<double> before, after;
    if (d.baseline_model && d.baseline_model->type() == "maxwell-slip" && d.final_model &&
        d.final_model->type() == "maxwell-slip") {
      const auto& b = std::get<Extended<MaxwellSlip<double>>>(d.baseline_model->variant());
      const auto& f = std::get<Extended<MaxwellSlip<double>>>(d.final_model->variant());
      extended_validation_percent(b.base().parameters(), b.extensions(), val, &before);
      extended_validation_percent(f.base().parameters(), f.extensions(), val, &after);
      write_file_atomically(o.svg, residual_svg(val, before, after, d.baseline_validation_percent,
                                                d.final_validation_percent));
    } else {
      add_warnings(doc, {"--svg: the plot needs a maxwell-slip baseline; not written"});
    }
  }

  if (!o.report.empty()) write_report_file(o.report, diagnose_report(doc, d, est, val));

  if (o.output.format == "json") {
    emit(o.output, doc.dump(2) + "\n");
    return kExitOk;
  }
  std::ostringstream os;
  os << "diagnose: estimation " << o.data << " (" << est.size() << " samples), validation "
     << (o.validate.empty() ? "held out" : o.validate) << " (" << val.size() << " samples), "
     << format_number(d.seconds, 3) << " s\n"
     << d.to_table();
  if (!doc["warnings"].empty()) os << doc["warnings"].size() << " warning(s), on stderr\n";
  emit_table(o.output, os.str(), doc);
  return kExitOk;
}

}  // namespace

Action register_diagnose(CLI::App& root) {
  auto o = std::make_shared<DiagnoseCliOptions>();
  CLI::App* c = root.add_subcommand(
      "diagnose",
      "Fit a baseline on --data, show what its simulation gets wrong on --validate, "
      "name the causes, extend the model and measure the gain");
  c->add_option("--data", o->data, "Estimation record (CSV)")->required();
  c->add_option("--validate", o->validate, "Validation record (CSV)");
  c->add_option("--holdout", o->holdout,
                "Without --validate: fraction of --data held out at its end for validation")
      ->capture_default_str();
  c->add_option("--baseline", o->baseline, "Baseline model: maxwell-slip (NLR) or lugre (LG)")
      ->capture_default_str();
  c->add_option("--max-operators", o->max_operators, "NLR: largest M tried by the order selection");
  c->add_flag(
      "--no-global", o->no_global,
      "Skip the global stages: NLR's threshold moves, LG's NLopt search (faster, less robust)");
  c->add_option("--seed", o->seed, "Seed of the global stages")->capture_default_str();
  c->add_option("--threads", o->threads,
                "Candidate fits run on this many threads (0: one per core); the result does not "
                "depend on it")
      ->capture_default_str();
  c->add_option("--svg", o->svg, "Write a plot of the residual against velocity (before/after)");
  add_input_options(*c, o->input);
  add_output_options(*c, o->output);
  add_report_option(*c, o->report);
  return [o] { return run_diagnose(*o); };
}

}  // namespace friction::cli
