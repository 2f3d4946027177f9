// `identify`, `validate` and `compare`: the paper's methods from the command line.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <future>
#include <iostream>
#include <optional>
#include <sstream>
#include <tuple>

#include "../number_format.hpp"
#include "../parallel_for.hpp"
#include "commands.hpp"
#include "friction/methods.hpp"
#include "friction/speed_coverage.hpp"
#include "progress.hpp"
#include "report_option.hpp"

namespace friction::cli {

namespace {

struct MethodCliOptions {
  std::size_t max_operators = 0;
  std::size_t operators = 0;
  long spring_order = -1;
  long input_order = -1;
  bool no_global = false;
  unsigned seed = 1;
  MethodOptions method() const {
    MethodOptions m;
    m.max_operators = max_operators;
    m.operators = operators;
    m.spring_order = spring_order;
    m.input_order = input_order;
    m.global_stage = !no_global;
    m.seed = seed;
    return m;
  }
};

void add_method_options(CLI::App& c, MethodCliOptions& m) {
  c.add_option("--max-operators", m.max_operators,
               "NLR/DNLRX: largest number of operators M tried by the order selection");
  c.add_option("--operators", m.operators, "NLR/DNLRX: fit this M only (no selection)");
  c.add_option("--spring-order", m.spring_order, "DNLRX: fix the spring-filter order n");
  c.add_option("--input-order", m.input_order, "DNLRX: fix the input-filter order nx");
  c.add_flag(
      "--no-global", m.no_global,
      "Skip the global stages: NLR's threshold moves, LG's NLopt search (faster, less robust)");
  c.add_option("--seed", m.seed, "Seed of the global stages")->capture_default_str();
}

std::string fixed(double v, int decimals = 3) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

// What reading and conditioning the record found (force sign, sampling, resolution, noise).
Json data_json(const Record& r, const std::string& role) {
  const auto& c = r.conditioning;
  Json gaps = Json::array();
  return {{"role", role},
          {"file", r.source},
          {"samples", r.size()},
          {"duration", r.size() > 1 ? r.time.back() - r.time.front() : 0.0},
          {"force_sign", c.force_sign},
          {"nominal_period", c.nominal_period},
          {"irregular_sampling", c.irregular},
          {"gaps", c.gaps.size()},
          {"displacement_resolution", c.displacement_resolution},
          // The displacement the models see (sample_derivatives.hpp): the local polynomial's
          // value, or the samples themselves.
          {"displacement_estimate",
           {{"as_measured", r.measured_displacement.empty()},
            {"half_width", c.displacement_half_width},
            {"degree", c.displacement_degree}}},
          {"force_noise", c.force_noise},
          {"normal_force", r.has_normal()}};
}

struct Records {
  Record estimation;
  Record validation;  // empty when there is none
  bool has_validation = false;
  std::vector<Json> data;
  std::vector<std::string> warnings;
};

// --data and --validate, or a hold-out of the last fraction of --data.
Records load_records(const std::string& data, const std::string& validate, double holdout,
                     bool hold_out_when_missing, const InputOptions& in) {
  Records rs;
  if (!validate.empty()) {
    std::tie(rs.estimation, rs.validation) = load_record_pair(data, validate, in);
    rs.warnings = rs.estimation.conditioning.warnings;
    for (const auto& w : rs.validation.conditioning.warnings)
      rs.warnings.push_back(validate + ": " + w);
    rs.has_validation = true;
  } else {
    Record all = load_record(data, in, /*require_force=*/true);
    rs.warnings = all.conditioning.warnings;
    if (!hold_out_when_missing) {
      rs.estimation = std::move(all);
    } else {
      if (!(holdout > 0 && holdout < 1))
        throw OptionError("--holdout must lie strictly between 0 and 1");
      const std::size_t n = all.size();
      const auto n_est = static_cast<std::size_t>(std::llround((1.0 - holdout) * n));
      if (n_est < 2 * kMinSamples || n - n_est < kMinSamples)
        throw DataError(data, 0, 0,
                        "too few samples to hold out " + fixed(100 * holdout, 0) +
                            " % for validation; give --validate");
      rs.estimation = all.slice(0, n_est);
      rs.validation = all.slice(n_est, n);
      rs.has_validation = true;
      rs.warnings.push_back("no --validate given: the last " + fixed(100 * holdout, 0) +
                            " % of " + data + " (from t = " +
                            format_number(rs.validation.time.front(), 6) +
                            " s) is held out for validation");
    }
  }
  rs.data.push_back(data_json(rs.estimation, "estimation"));
  if (rs.has_validation) rs.data.push_back(data_json(rs.validation, "validation"));
  return rs;
}

Json validation_json(const Validation& v) {
  Json j = errors_to_json(v.errors);
  j["initial_state"] = v.initial_state;
  j["initial_state_values"] = v.initial_state_values;
  j["noise"] = {{"sigma", v.noise_sigma}, {"floor_percent", v.noise_floor_percent}};
  return j;
}

void print_errors(std::ostream& os, const char* label, const ErrorMetrics& e, double floor) {
  os << "  " << label << ": RSS/SSS " << format_number(e.rss_sss_percent, 4) << " %, RMS "
     << format_number(e.rms, 4) << " N, max |e| " << format_number(e.max_abs, 4) << " N, R^2 "
     << fixed(e.r_squared, 5) << " (noise floor " << format_number(floor, 4) << " %)\n";
}

void print_report(std::ostream& os, const IdentifiedModel& m) {
  const auto& rep = m.report;
  if (!rep.selection.empty()) {
    os << "  order selection on the estimation record (" << rep.criterion << "):\n"
       << "      M   n  nx  params   RSS/SSS %         " << rep.criterion << "\n";
    for (const auto& s : rep.selection) {
      char line[160];
      std::snprintf(line, sizeof line, "    %3zu %3zu %3zu %7zu %11.4g %12.6g%s%s\n", s.operators,
                    s.spring_order, s.input_order, s.parameters, s.rss_sss_percent, s.criterion,
                    s.selected ? "  <- selected" : "", s.failed ? "  (failed)" : "");
      os << line;
    }
  }
  os << "  parameters (95 % intervals):\n";
  for (const auto& p : rep.parameters) {
    char line[240];
    // A standard error of 0 means "not available" (identification.hpp): say so rather than print
    // an interval of zero width that reads as perfect certainty.
    if (p.standard_error > 0.0)
      std::snprintf(line, sizeof line, "    %-22s %13.6g  +- %-11.3g [%11.4g, %11.4g] %s\n",
                    p.name.c_str(), p.value, p.standard_error, p.lower95, p.upper95,
                    p.unit.c_str());
    else
      std::snprintf(line, sizeof line, "    %-22s %13.6g  (no standard error: see warnings) %s\n",
                    p.name.c_str(), p.value, p.unit.c_str());
    os << line;
  }
  os << "  converged: " << (rep.convergence.converged ? "yes" : "NO") << " ("
     << rep.convergence.message << "), " << rep.convergence.local_searches << " local searches, "
     << rep.starts.size() << " starts logged, " << fixed(rep.seconds, 2) << " s\n";
}

struct IdentifyOptions {
  std::string model, report;
  std::vector<std::string> extensions;
  std::string data, validate;
  InputOptions input;
  OutputOptions output;
  MethodCliOptions method;
};

int run_identify(const IdentifyOptions& o) {
  // A bad --extension is bad usage: reported before any file is read.
  MethodOptions method = o.method.method();
  method.extensions = parse_extension_list(o.extensions);
  check_report_path(o.report);
  Records rs = load_records(o.data, o.validate, 0.3, /*hold_out_when_missing=*/false, o.input);
  Json doc = new_document("identify");
  add_warnings(doc, rs.warnings);
  doc["data"] = rs.data;
  Progress progress;
  progress.update("identifying " + method_name(method_type(o.model)) + " on " + o.data +
                  (method.extensions.empty() ? "" : " with extensions") + " ...");
  IdentifiedModel m = identify_model(o.model, rs.estimation, method);
  progress.done();
  add_warnings(doc, m.report.warnings);
  doc["method"] = method_name(m.model.type());
  doc["model"] = m.model.to_json();
  doc["estimation"] = errors_to_json(m.report.estimation);
  doc["estimation"]["initial_state"] = "estimated";
  doc["estimation"]["initial_state_values"] = m.initial_state;
  doc["estimation"]["noise"] = {{"sigma", m.report.noise_sigma},
                                {"floor_percent", m.report.noise_floor_percent}};
  doc["identification"] = report_to_json(m.report);
  if (!m.extensions.is_null()) doc["extensions"] = m.extensions;
  doc["seconds"] = m.report.seconds;
  // Kept in the document, so that `validate` given it can say when another record leaves it.
  const double largest = largest_speed(rs.estimation);
  doc["estimation"]["largest_speed"] = largest;
  std::optional<Validation> val;
  if (rs.has_validation) {
    val = validate_model(m.model, rs.validation);
    doc["validation"] = validation_json(*val);
    if (auto w = speed_extrapolation_warning(speed_coverage(largest, rs.validation),
                                             speed_dependent_terms(doc["model"])))
      add_warnings(doc, {*w});
  }
  if (!o.report.empty()) {
    // The estimation run the method reported; the validation run validate_model gave.
    std::vector<report::RecordFit> fits;
    fits.push_back({&rs.estimation, "estimation",
                    m.report.estimation_simulated.size() == rs.estimation.size()
                        ? m.report.estimation_simulated
                        : validate_model(m.model, rs.estimation).simulated});
    if (val) fits.push_back({&rs.validation, "validation", val->simulated});
    write_report_file(o.report, report::fit_report(doc, fits, run_info()));
  }
  if (o.output.format == "json") {
    emit(o.output, doc.dump(2) + "\n");
    return kExitOk;
  }
  std::ostringstream os;
  os << method_name(m.model.type()) << " (" << m.model.type() << ") identified on " << o.data
     << " (" << rs.estimation.size() << " samples) in " << fixed(m.report.seconds, 2) << " s\n";
  print_report(os, m);
  if (!m.extensions.is_null()) {
    const Json& x = m.extensions;
    os << "  extensions ";
    for (std::size_t i = 0; i < x["order"].size(); ++i)
      os << (i ? ", " : "") << x["order"][i].get<std::string>();
    os << " (base " << x["base"].get<std::string>() << "): estimation RSS/SSS "
       << format_number(x["estimation_before_percent"].get<double>(), 4) << " % without them, "
       << format_number(x["estimation_after_percent"].get<double>(), 4) << " % with them\n";
    for (const auto& name : x["no_evidence"])
      os << "  the record gives no evidence of " << name.get<std::string>() << "\n";
  }
  print_errors(os, "estimation", m.report.estimation, m.report.noise_floor_percent);
  if (val) print_errors(os, "validation", val->errors, val->noise_floor_percent);
  if (!doc["warnings"].empty()) os << "  " << doc["warnings"].size() << " warning(s), on stderr\n";
  emit_table(o.output, os.str(), doc);
  return kExitOk;
}

// The JSON of a file that load_model has already read (null when it cannot be read again).
Json read_json_file(const std::string& path) {
  std::ifstream in(path);
  return Json::parse(in, nullptr, /*allow_exceptions=*/false);
}

struct ValidateOptions {
  std::string model_file, data, report;
  InputOptions input;
  OutputOptions output;
};

int run_validate(const ValidateOptions& o) {
  check_report_path(o.report);
  const AnyModel model = load_model(o.model_file);
  const Record r = load_record(o.data, o.input, true);
  Json doc = new_document("validate");
  add_warnings(doc, r.conditioning.warnings);
  doc["data"] = {data_json(r, "validation")};
  doc["model"] = model.to_json();
  const Validation v = validate_model(model, r);
  doc["validation"] = validation_json(v);
  // An identify document carries the parameters' intervals (the report shows them) and the
  // largest speed of its estimation record.
  const Json file = read_json_file(o.model_file);
  if (file.is_object() && file.contains("estimation") && file["estimation"].is_object() &&
      file["estimation"].contains("largest_speed") &&
      file["estimation"]["largest_speed"].is_number())
    if (auto w = speed_extrapolation_warning(
            speed_coverage(file["estimation"]["largest_speed"].get<double>(), r),
            speed_dependent_terms(doc["model"])))
      add_warnings(doc, {*w});
  if (!o.report.empty()) {
    Json shown = doc;
    if (file.is_object() && file.contains("identification"))
      shown["identification"] = file["identification"];
    write_report_file(o.report,
                      report::fit_report(shown, {{&r, "validation", v.simulated}}, run_info()));
  }
  if (o.output.format == "json") {
    emit(o.output, doc.dump(2) + "\n");
    return kExitOk;
  }
  std::ostringstream os;
  os << model.type() << " model " << o.model_file << " on " << o.data << " (" << r.size()
     << " samples, initial state " << v.initial_state << ")\n";
  print_errors(os, "validation", v.errors, v.noise_floor_percent);
  emit(o.output, os.str());
  return kExitOk;
}

struct CompareOptions {
  std::string data, validate, report;
  double holdout = 0.3;
  std::vector<std::string> methods{"LG", "NLR", "DNLRX"};
  unsigned threads = 0;
  InputOptions input;
  OutputOptions output;
  MethodCliOptions method;
};

int run_compare(const CompareOptions& o) {
  check_report_path(o.report);
  Records rs = load_records(o.data, o.validate, o.holdout, /*hold_out_when_missing=*/true, o.input);
  Json doc = new_document("compare");
  add_warnings(doc, rs.warnings);
  doc["data"] = rs.data;
  doc["methods"] = Json::array();
  // The methods are independent, so they run on concurrent threads (`--threads`, one per core
  // by default); each writes only its own slot, and the rows, warnings and report are assembled
  // in the order asked, so the document does not depend on the thread count.
  struct Outcome {
    Json row;
    std::vector<std::string> warnings;
    std::string error;
    std::optional<report::MethodFit> fit;
  };
  std::vector<Outcome> outcomes(o.methods.size());
  const SpeedCoverage coverage = speed_coverage(largest_speed(rs.estimation), rs.validation);
  // DNLRX takes its thresholds from NLR's order selection.  When both are compared, DNLRX reuses
  // the NLR identified here (MethodOptions::maxwell_slip_report, the same result) instead of
  // fitting M = 1..6 again: it waits for NLR's report, which is signalled as soon as NLR's
  // identification ends, or fails.
  std::optional<std::size_t> nlr_index;
  for (std::size_t i = 0; i < o.methods.size() && !nlr_index; ++i)
    if (method_type(o.methods[i]) == "maxwell-slip") nlr_index = i;
  std::promise<void> nlr_done;
  const std::shared_future<void> nlr_ready = nlr_done.get_future().share();
  std::optional<IdentificationReport> nlr_report;  // written before nlr_done is signalled
  struct Signal {  // signals once, when it goes (so it cannot be copied)
    explicit Signal(std::promise<void>& p) : done(p) {}
    Signal(const Signal&) = delete;
    Signal& operator=(const Signal&) = delete;
    ~Signal() { done.set_value(); }
    std::promise<void>& done;
  };
  auto run_one = [&](std::size_t i) {
    const std::string type = method_type(o.methods[i]);
    Outcome& out = outcomes[i];
    Json& row = out.row;
    row["method"] = method_name(type);
    std::optional<Signal> signal;  // NLR's: set on every way out of the identification
    if (nlr_index && i == *nlr_index) signal.emplace(nlr_done);
    MethodOptions options = o.method.method();
    options.threads = o.threads;
    if (type == "dnlrx" && nlr_index) {
      nlr_ready.wait();
      if (nlr_report) options.maxwell_slip_report = &*nlr_report;
    }
    const auto start = std::chrono::steady_clock::now();
    try {
      IdentifiedModel m = identify_model(type, rs.estimation, options);
      if (signal) {
        nlr_report = m.report;
        signal.reset();
      }
      const Validation v = validate_model(m.model, rs.validation);
      for (const auto& w : m.report.warnings) out.warnings.push_back(method_name(type) + ": " + w);
      row["model"] = m.model.to_json();
      row["parameters"] = m.model.parameter_count();
      row["estimation"] = errors_to_json(m.report.estimation);
      row["estimation"]["initial_state"] = "estimated";
      row["validation"] = validation_json(v);
      row["identification"] = report_to_json(m.report);
      row["warnings"] = m.report.warnings;
      if (auto w = speed_extrapolation_warning(coverage, speed_dependent_terms(row["model"]))) {
        out.warnings.push_back(method_name(type) + ": " + *w);
        row["warnings"].push_back(*w);
      }
      if (!o.report.empty())
        out.fit = report::MethodFit{method_name(type),
                                    m.report.estimation_simulated.size() == rs.estimation.size()
                                        ? m.report.estimation_simulated
                                        : validate_model(m.model, rs.estimation).simulated,
                                    v.simulated};
    } catch (const std::exception& e) {
      row["error"] = e.what();
      out.error = method_name(type) + ": " + e.what();
    }
    row["seconds"] =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  Progress progress;
  {
    std::string names;
    for (const auto& name : o.methods)
      names += (names.empty() ? "" : ", ") + method_name(method_type(name));
    progress.update("compare: identifying and validating " + names + " ...");
  }
  // The costliest work starts first, so that the shortest is what fills the other thread's end.
  // With NLR among the methods: NLR (M = 1..8; on data/ 2.4-2.6 s with its validation), then LG
  // (one model of 7 parameters, 2.1 s), then DNLRX, whose own work after NLR's selection is the
  // filter orders and their thresholds (1.6 s, its operator counts on both cores); it must come
  // after NLR, which it waits for.  Without NLR, DNLRX (which then runs NLR's selection itself)
  // before LG.
  const auto cost_rank = [&](std::size_t i) {
    const std::string type = method_type(o.methods[i]);
    if (nlr_index) return type == "maxwell-slip" ? 0 : type == "dnlrx" ? 2 : 1;
    return type == "dnlrx" ? 0 : type == "maxwell-slip" ? 1 : 2;
  };
  std::vector<std::size_t> schedule(o.methods.size());
  for (std::size_t i = 0; i < schedule.size(); ++i) schedule[i] = i;
  std::stable_sort(schedule.begin(), schedule.end(),
                   [&](std::size_t a, std::size_t b) { return cost_rank(a) < cost_rank(b); });
  detail::parallel_for(o.methods.size(), o.threads, run_one, schedule);
  std::vector<report::MethodFit> fits;
  for (auto& out : outcomes) {
    for (const auto& w : out.warnings) {
      std::cerr << "warning: " << w << "\n";
      doc["warnings"].push_back(w);
    }
    if (!out.error.empty()) std::cerr << "error: " << out.error << "\n";
    if (out.fit) fits.push_back(std::move(*out.fit));
    doc["methods"].push_back(std::move(out.row));
  }
  progress.done();
  bool any = false;
  for (const auto& row : doc["methods"]) any = any || !row.contains("error");
  // No result at all is a failure (exit 1); a failed method among others is a row with an error.
  const int status = any ? kExitOk : kExitData;
  if (any && !o.report.empty())
    write_report_file(o.report,
                      report::compare_report(doc, rs.estimation, rs.validation, fits, run_info()));
  if (o.output.format == "json") {
    emit(o.output, doc.dump(2) + "\n");
    return status;
  }
  std::ostringstream os;
  os << "Estimation: " << rs.data[0]["file"].get<std::string>() << " (" << rs.estimation.size()
     << " samples); validation: "
     << (o.validate.empty() ? "last " + fixed(100 * o.holdout, 0) + " % held out" : o.validate)
     << " (" << rs.validation.size() << " samples)\n\n";
  char line[200];
  std::snprintf(line, sizeof line, "%-7s %7s %14s %14s %9s\n", "method", "params", "estim. RSS/SSS",
                "valid. RSS/SSS", "seconds");
  os << line;
  for (const auto& row : doc["methods"]) {
    if (row.contains("error")) {
      std::snprintf(line, sizeof line, "%-7s failed: %s\n",
                    row["method"].get<std::string>().c_str(),
                    row["error"].get<std::string>().c_str());
    } else {
      std::snprintf(line, sizeof line, "%-7s %7zu %13.4g%% %13.4g%% %9.2f\n",
                    row["method"].get<std::string>().c_str(), row["parameters"].get<std::size_t>(),
                    row["estimation"]["rss_sss_percent"].get<double>(),
                    row["validation"]["rss_sss_percent"].get<double>(),
                    row["seconds"].get<double>());
    }
    os << line;
  }
  for (const auto& row : doc["methods"]) {
    if (!row.contains("validation")) continue;
    os << "\nnoise floor of the validation record: RSS/SSS "
       << format_number(row["validation"]["noise"]["floor_percent"].get<double>(), 4)
       << " % (force noise " << format_number(row["validation"]["noise"]["sigma"].get<double>(), 4)
       << " N)\n";
    break;
  }
  if (!doc["warnings"].empty()) os << doc["warnings"].size() << " warning(s), on stderr\n";
  emit_table(o.output, os.str(), doc);
  return status;
}

}  // namespace

Action register_identify(CLI::App& root) {
  auto o = std::make_shared<IdentifyOptions>();
  CLI::App* c = root.add_subcommand("identify",
                                    "Estimate one model from --data, optionally "
                                    "scored on --validate");
  c->add_option("--model", o->model, "lugre (LG), maxwell-slip (NLR) or dnlrx (DNLRX)")->required();
  c->add_option("--data", o->data, "Estimation record (CSV)")->required();
  c->add_option("--validate", o->validate, "Validation record (CSV)");
  c->add_option("--extension", o->extensions,
                "Extension pieces to identify with the model (repeatable or a comma list): " +
                    extension_names())
      ->delimiter(',');
  add_method_options(*c, o->method);
  add_input_options(*c, o->input);
  add_output_options(*c, o->output);
  add_report_option(*c, o->report);
  return [o] { return run_identify(*o); };
}

Action register_validate(CLI::App& root) {
  auto o = std::make_shared<ValidateOptions>();
  CLI::App* c = root.add_subcommand("validate",
                                    "Score a saved model on a record (initial state "
                                    "estimated from the record)");
  c->add_option("--model-file", o->model_file, "Saved model (JSON), or an identify document")
      ->required();
  c->add_option("--data", o->data, "Record (CSV)")->required();
  add_input_options(*c, o->input);
  add_output_options(*c, o->output);
  add_report_option(*c, o->report);
  return [o] { return run_validate(*o); };
}

Action register_compare(CLI::App& root) {
  auto o = std::make_shared<CompareOptions>();
  CLI::App* c = root.add_subcommand(
      "compare",
      "Identify LG, NLR and DNLRX on --data and score each on --validate: the paper's "
      "comparison");
  c->add_option("--data", o->data, "Estimation record (CSV)")->required();
  c->add_option("--validate", o->validate, "Validation record (CSV)");
  c->add_option("--holdout", o->holdout,
                "Without --validate: fraction of --data held out at its end for validation")
      ->capture_default_str();
  c->add_option("--methods", o->methods, "Methods to compare (default LG,NLR,DNLRX)")
      ->delimiter(',');
  c->add_option("--threads", o->threads,
                "Methods (and DNLRX's operator counts) identified concurrently on this many "
                "threads (0: one per core); the result does not depend on it");
  add_method_options(*c, o->method);
  add_input_options(*c, o->input);
  add_output_options(*c, o->output);
  add_report_option(*c, o->report);
  return [o] { return run_compare(*o); };
}

}  // namespace friction::cli
