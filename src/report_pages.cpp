#include "friction/report_pages.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "friction/error.hpp"
#include "friction/extension_identification.hpp"
#include "friction/identification.hpp"
#include "friction/metrics.hpp"
#include "friction/sample_derivatives.hpp"

namespace friction::report {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string pct(double v) {
  return format_number(v, 4) + " %";
}

std::string unit_suffix(const std::string& unit) {
  return unit.empty() || unit == "1" ? std::string() : " " + unit;
}

// Small counts in words, as a sentence reads them.
std::string count_words(std::size_t n) {
  static const char* words[] = {"no",  "one",   "two",   "three", "four", "five",
                                "six", "seven", "eight", "nine",  "ten"};
  return n < std::size(words) ? words[n] : std::to_string(n);
}

std::string capitalised(std::string s) {
  if (!s.empty() && s[0] >= 'a' && s[0] <= 'z') s[0] = static_cast<char>(s[0] - 'a' + 'A');
  return s;
}

double number_at(const Json& j, std::initializer_list<const char*> path, double fallback = kNaN) {
  const Json* p = &j;
  for (const char* key : path) {
    if (!p->is_object() || !p->contains(key)) return fallback;
    p = &p->at(key);
  }
  return p->is_number() ? p->get<double>() : fallback;
}

std::string string_at(const Json& j, const char* key, const std::string& fallback = "") {
  return j.is_object() && j.contains(key) && j.at(key).is_string() ? j.at(key).get<std::string>()
                                                                   : fallback;
}

// "110 times its noise floor (0.0037 %)", and what that means for a reader.
std::string against_floor(double percent, double floor) {
  if (!(floor > 0) || !std::isfinite(percent)) return "";
  const double r = percent / floor;
  std::string s = format_number(r, 3) + " times the noise floor (" + pct(floor) + ")";
  if (r < 1.5)
    s += ": the model explains all but the measurement noise";
  else if (r < 10)
    s += ": close to it, a little of the force is not explained";
  else
    s += ": the model misses something the data contain";
  return s;
}

// Errors of a free run, recomputed from exactly what the figure draws.
ErrorMetrics errors_of(const Record& r, std::span<const double> simulated) {
  return compute_errors(r.force, simulated);
}

std::vector<double> residual_of(const Record& r, std::span<const double> simulated) {
  std::vector<double> e(r.size());
  for (std::size_t k = 0; k < r.size(); ++k) e[k] = r.force[k] - simulated[k];
  return e;
}

// A copy of `v` with NaN where `keep` is false (masked samples are not drawn, and break lines).
std::vector<double> masked(std::span<const double> v, const std::vector<bool>& keep) {
  std::vector<double> out(v.begin(), v.end());
  for (std::size_t k = 0; k < out.size(); ++k)
    if (!keep[k]) out[k] = kNaN;
  return out;
}

std::size_t count(const std::vector<bool>& mask) {
  return static_cast<std::size_t>(std::count(mask.begin(), mask.end(), true));
}

void check_trace(const RecordView& view, const Trace& t) {
  FRICTION_CHECK(t.force.size() == view.record->size(), "report: the ", t.label, " force has ",
                 t.force.size(), " samples, the ", view.role, " record ", view.record->size());
}

Role residual_role(const std::vector<Trace>& traces, const Trace& t) {
  return traces.size() == 1 ? Role::residual : t.role;
}

std::string residual_label(const std::vector<Trace>& traces, const Trace& t) {
  return traces.size() == 1 ? std::string("residual") : "residual, " + t.label;
}

std::string errors_sentence(const std::vector<Trace>& traces, const Record& r) {
  std::string s;
  for (const auto& t : traces) {
    const ErrorMetrics e = errors_of(r, t.force);
    if (!s.empty()) s += "; ";
    s += (traces.size() > 1 ? t.label + ": " : std::string()) + "RSS/SSS " +
         pct(e.rss_sss_percent) + ", RMS " + format_number(e.rms, 3) + " N, max |e| " +
         format_number(e.max_abs, 3) + " N";
  }
  return s + ".";
}

}  // namespace

RecordView view_record(const Record& record, std::string role) {
  FRICTION_CHECK(record.size() >= 2 && record.has_force(), "report: the ", role,
                 " record needs a force and two samples");
  RecordView v;
  v.role = std::move(role);
  v.record = &record;
  const std::size_t n = record.size();
  const auto& x = record.displacement;
  const auto& t = record.time;
  v.velocity.assign(n, 0.0);
  v.acceleration.assign(n, 0.0);
  double v_noise = 0;
  if (n >= 16) {
    // Of the displacement as measured, as every fit's pieces take them.
    const SampleDerivatives d = sample_derivatives(t, record.measured());
    v.velocity = d.velocity;
    v.acceleration = d.acceleration;
    v_noise = d.windows.velocity_rms_error;
  } else {
    for (std::size_t k = 1; k < n; ++k) v.velocity[k] = (x[k] - x[k - 1]) / (t[k] - t[k - 1]);
  }
  double v_max = 0;
  for (const double u : v.velocity) v_max = std::max(v_max, std::abs(u));
  const double v_min = std::max(3.0 * v_noise, 1e-3 * v_max);

  const double range = 2.0 * largest_travel(x);
  v.sliding.assign(n, false);
  if (!(range > 0)) {
    v.zoom_lo = t.front();
    v.zoom_hi = t.back();
    v.zoom_what = "the whole record (the displacement never changes)";
    return v;
  }
  v.presliding_travel = travel_at_force_fraction(x, record.force, 0.95);
  const double h = std::max(3.0 * displacement_resolution(record.measured()), 1e-4 * range);
  const std::vector<std::size_t> turns = turning_points(x, h);

  // Sliding: beyond the presliding travel since the last reversal, moving away from it.
  for (std::size_t s = 0; s + 1 < turns.size(); ++s) {
    const std::size_t a = turns[s], b = turns[s + 1];
    const double dir = x[b] >= x[a] ? 1.0 : -1.0;
    for (std::size_t k = a + 1; k <= b; ++k)
      v.sliding[k] = dir * (x[k] - x[a]) > v.presliding_travel && dir * v.velocity[k] > v_min;
  }

  // The zoom: the longest run of consecutive reversals closer than the presliding travel (the
  // first eight of its segments), or the reversal from sliding with the largest force swing.
  std::size_t best_start = 0, best_len = 0, start = 0, len = 0;
  for (std::size_t s = 0; s + 1 < turns.size(); ++s) {
    const bool small = std::abs(x[turns[s + 1]] - x[turns[s]]) < v.presliding_travel;
    if (small) {
      if (len == 0) start = s;
      ++len;
      if (len > best_len) best_len = len, best_start = start;
    } else {
      len = 0;
    }
  }
  if (best_len >= 2) {
    const std::size_t last =
        std::min(best_start + std::min<std::size_t>(best_len, 8), turns.size() - 1);
    const double t0 = t[turns[best_start]], t1 = t[turns[last]];
    const double pad = 0.05 * (t1 - t0);
    v.zoom_lo = std::max(t.front(), t0 - pad);
    v.zoom_hi = std::min(t.back(), t1 + pad);
    v.zoom_what = std::to_string(last - best_start) +
                  " presliding reversals (travel below the presliding travel of " +
                  format_quantity(v.presliding_travel, "m") + ")";
    return v;
  }
  double best_swing = -1;
  std::size_t best_turn = 0, best_end = n - 1;
  for (std::size_t s = 1; s + 1 < turns.size(); ++s) {
    const std::size_t a = turns[s], b = turns[s + 1];
    const double dir = x[b] >= x[a] ? 1.0 : -1.0;
    double swing = 0;
    std::size_t end = b;
    bool ended = false;
    for (std::size_t k = a; k <= b; ++k) {
      swing = std::max(swing, dir * (record.force[k] - record.force[a]));
      if (!ended && dir * (x[k] - x[a]) > 3.0 * v.presliding_travel) end = k, ended = true;
    }
    if (swing > best_swing) best_swing = swing, best_turn = a, best_end = end;
  }
  if (best_swing >= 0 && best_end > best_turn) {
    const double t0 = t[best_turn], t1 = t[best_end];
    v.zoom_lo = std::max(t.front(), t0 - 0.25 * (t1 - t0));
    v.zoom_hi = t1;
    v.zoom_what =
        "the reversal with the largest force swing, up to three presliding travels "
        "after it";
    return v;
  }
  v.zoom_lo = t.front();
  v.zoom_hi = t.front() + 0.1 * (t.back() - t.front());
  v.zoom_what = "the first tenth of the record (it has no reversal)";
  return v;
}

void add_time_figures(Document& doc, const std::string& id, const RecordView& view,
                      const std::vector<Trace>& traces, const std::string& what) {
  const Record& r = *view.record;
  std::vector<std::vector<double>> residuals;
  for (const auto& t : traces) {
    check_trace(view, t);
    residuals.push_back(residual_of(r, t.force));
  }
  double e_max = 0;
  for (const auto& e : residuals)
    for (const double v : e)
      if (std::isfinite(v)) e_max = std::max(e_max, std::abs(v));

  Figure f;
  f.id = id + "-time";
  f.kind = "time";
  f.x = {"time", "s"};
  Panel force{"force", {"force", "N"}, {}, 230};
  force.series.push_back({"measured", Role::measured, Mark::line, r.time, r.force});
  for (const auto& t : traces)
    force.series.push_back({t.label, t.role, Mark::line, r.time, t.force});
  Panel residual{"residual", {"residual F \u2212 F\u0302", "N"}, {}, 130};
  residual.y.symmetric = true;
  for (std::size_t k = 0; k < traces.size(); ++k)
    residual.series.push_back({residual_label(traces, traces[k]), residual_role(traces, traces[k]),
                               Mark::line, r.time, residuals[k]});
  f.panels = {force, residual};
  f.title = "Force over time, " + what;
  f.caption =
      "The measured force and the model's free run (driven by the displacement alone, "
      "initial state estimated from the record), the residual beneath on one scale for "
      "every model shown. " +
      errors_sentence(traces, r) + " Shaded: the stretch the zoom below shows.";
  f.band = Band{view.zoom_lo, view.zoom_hi, "zoom"};
  doc.add(f);

  Figure z = f;
  z.id = id + "-zoom";
  z.kind = "zoom";
  z.band.reset();
  z.x.lo = view.zoom_lo;
  z.x.hi = view.zoom_hi;
  // The residual keeps the full record's scale: a zoom that rescaled it would make a small misfit
  // look as large as the worst one.
  z.panels[1].y.lo = -1.04 * e_max;
  z.panels[1].y.hi = 1.04 * e_max;
  if (!(e_max > 0)) z.panels[1].y.lo.reset(), z.panels[1].y.hi.reset();
  z.title = "Zoom on " + view.zoom_what + ", " + what;
  z.caption =
      "From t = " + format_number(view.zoom_lo, 5) + " s to " + format_number(view.zoom_hi, 5) +
      " s: presliding, where the hysteresis of the elements decides the force; the residual "
      "on the scale of the whole record.";
  doc.add(z);
}

void add_loop_figures(Document& doc, const std::string& id, const RecordView& view,
                      const std::vector<Trace>& traces, const std::string& what) {
  const Record& r = *view.record;
  // The samples of the zoom stretch, for the presliding loops.
  const auto b = static_cast<std::size_t>(
      std::lower_bound(r.time.begin(), r.time.end(), view.zoom_lo) - r.time.begin());
  const auto e = static_cast<std::size_t>(
      std::upper_bound(r.time.begin(), r.time.end(), view.zoom_hi) - r.time.begin());
  const std::span<const double> x(r.displacement), F(r.force);
  for (std::size_t k = 0; k < traces.size(); ++k) {
    check_trace(view, traces[k]);
    const std::string suffix = traces.size() > 1 ? "-" + std::to_string(k + 1) : "";
    const std::string who = traces.size() > 1 ? ", " + traces[k].label : "";
    Figure f;
    f.id = id + "-loops" + suffix;
    f.kind = "loops";
    f.width = 480;
    f.x = {"displacement", "m"};
    Panel p{"force", {"force", "N"}, {}, 300};
    p.series.push_back({"measured", Role::measured, Mark::polyline, x, F});
    p.series.push_back({traces[k].label, traces[k].role, Mark::polyline, x, traces[k].force});
    f.panels = {p};
    f.title = "Hysteresis loops, " + what + who;
    f.caption = "Force against displacement over the whole record.";
    doc.add(f);
    if (e > b + 2) {
      Figure z = f;
      z.id = id + "-loops-zoom" + suffix;
      z.kind = "loops-zoom";
      z.panels[0].series[0].x = x.subspan(b, e - b);
      z.panels[0].series[0].y = F.subspan(b, e - b);
      z.panels[0].series[1].x = x.subspan(b, e - b);
      z.panels[0].series[1].y = traces[k].force.subspan(b, e - b);
      z.title = "Presliding loops, " + what + who;
      z.caption = "Force against displacement over the zoom stretch (" + view.zoom_what + ").";
      doc.add(z);
    }
  }
}

void add_sliding_figure(Document& doc, const std::string& id, const RecordView& view,
                        const std::vector<Trace>& traces, const std::string& what) {
  const Record& r = *view.record;
  const std::size_t n_sliding = count(view.sliding);
  if (n_sliding < 10) {
    doc.paragraph("Force against velocity, " + what + ": the record hardly slides (" +
                  std::to_string(n_sliding) + " sliding samples); nothing to show.");
    return;
  }
  const std::vector<double> v = masked(view.velocity, view.sliding);
  std::vector<std::vector<double>> residuals;
  for (const auto& t : traces) {
    check_trace(view, t);
    residuals.push_back(residual_of(r, t.force));
  }
  Figure f;
  f.id = id + "-sliding";
  f.kind = "sliding";
  f.x = {"velocity", "m/s"};
  Panel force{"force", {"force", "N"}, {}, 230};
  force.series.push_back({"measured", Role::measured, Mark::points, v, r.force});
  for (const auto& t : traces) force.series.push_back({t.label, t.role, Mark::points, v, t.force});
  Panel residual{"residual", {"residual F \u2212 F\u0302", "N"}, {}, 150};
  residual.y.symmetric = true;
  for (std::size_t k = 0; k < traces.size(); ++k)
    residual.series.push_back({residual_label(traces, traces[k]), residual_role(traces, traces[k]),
                               Mark::points, v, residuals[k]});
  f.panels = {force, residual};
  f.title = "Force and residual against velocity while sliding, " + what;
  f.caption = std::to_string(n_sliding) + " of " + std::to_string(r.size()) +
              " samples slide (beyond the presliding travel of " +
              format_quantity(view.presliding_travel, "m") +
              " since the last reversal, and moving). The friction curve: a level that changes "
              "with speed is Stribeck or viscous friction; a residual that follows the velocity "
              "is what the model lacks.";
  doc.add(f);
}

namespace {

// ---- tables ----------------------------------------------------------------------------------

std::string interval(const Json& p) {
  if (!p.contains("lower95") || !p.at("lower95").is_number() || !p.contains("upper95") ||
      !p.at("upper95").is_number())
    return "not available (see the warnings)";
  return "[" + format_number(p.at("lower95").get<double>(), 4) + ", " +
         format_number(p.at("upper95").get<double>(), 4) + "]";
}

// The parameters of an identification (identification.parameters of a document).
Table estimates_table(const Json& params, const std::string& id, const std::string& caption) {
  Table t;
  t.id = id;
  t.caption = caption;
  t.header = {"parameter", "value", "unit", "standard error", "95 % interval"};
  t.numeric = {false, true, false, true, true};
  for (const auto& p : params) {
    const double se = number_at(p, {"standard_error"});
    t.rows.push_back({string_at(p, "name"), format_number(number_at(p, {"value"}), 6),
                      string_at(p, "unit"), std::isfinite(se) ? format_number(se, 3) : "\u2013",
                      interval(p)});
  }
  return t;
}

// A model's parameters from its document (model.parameters, model.units, model.extensions),
// for a model that carries no intervals (a saved model, the diagnosis' models).
Table model_table(const Json& model, const std::string& id, const std::string& caption) {
  Table t;
  t.id = id;
  t.caption = caption;
  t.header = {"parameter", "value", "unit"};
  t.numeric = {false, true, false};
  const Json units = model.value("units", Json::object());
  const auto unit_of = [&](const std::string& key) {
    return units.contains(key) && units[key].is_string() ? units[key].get<std::string>() : "";
  };
  if (model.contains("parameters") && model["parameters"].is_object()) {
    for (const auto& [key, value] : model["parameters"].items()) {
      // Operators count from 1 (stiffness[1]); filter taps from 0 (input_filter[0]), as the
      // identification reports name them.
      const std::size_t base = key.find("filter") != std::string::npos ? 0 : 1;
      if (value.is_number()) {
        t.rows.push_back({key, format_number(value.get<double>(), 6), unit_of(key)});
      } else if (value.is_string()) {
        t.rows.push_back({key, value.get<std::string>(), ""});
      } else if (value.is_array()) {
        for (std::size_t i = 0; i < value.size(); ++i) {
          if (value[i].is_number()) {
            t.rows.push_back({key + "[" + std::to_string(i + base) + "]",
                              format_number(value[i].get<double>(), 6), unit_of(key)});
          } else if (value[i].is_array()) {
            for (std::size_t j = 0; j < value[i].size(); ++j)
              if (value[i][j].is_number())
                t.rows.push_back(
                    {key + "[" + std::to_string(i + 1) + "][" + std::to_string(j) + "]",
                     format_number(value[i][j].get<double>(), 6), unit_of(key)});
          }
        }
      }
    }
  }
  if (model.contains("extensions") && model["extensions"].is_object()) {
    for (const auto& [effect, params] : model["extensions"].items()) {
      if (!params.is_object()) {
        if (params.is_number())
          t.rows.push_back({effect, format_number(params.get<double>(), 6), "N"});
        continue;
      }
      for (const auto& [name, value] : params.items())
        if (value.is_number())
          t.rows.push_back({effect + "." + name, format_number(value.get<double>(), 6),
                            extension_parameter_unit(name)});
    }
  }
  return t;
}

std::vector<std::string> warnings_of(const Json& doc) {
  std::vector<std::string> w;
  if (doc.contains("warnings") && doc["warnings"].is_array())
    for (const auto& s : doc["warnings"])
      if (s.is_string()) w.push_back(s.get<std::string>());
  return w;
}

void add_warnings_and_run(Document& doc, const Json& document, const RunInfo& run) {
  doc.section("warnings", "Warnings");
  const auto w = warnings_of(document);
  if (w.empty())
    doc.paragraph("None.");
  else
    doc.list("warnings", w);
  doc.section("run", "Run");
  doc.paragraph("Command line:");
  doc.preformatted(run.command_line);
  doc.paragraph("friction-identify " + run.version +
                ". The JSON document of the run (--out, or "
                "--format json) holds every number shown here and more; it is the contract for "
                "scripts, this report is for people.");
}

std::string what_of(const RecordView& view, const std::string& model) {
  std::string s = view.role + " record";
  if (!view.record->source.empty()) s += " (" + view.record->source + ")";
  if (!model.empty()) s += ", " + model;
  return s;
}

}  // namespace

Document fit_report(const Json& document, const std::vector<RecordFit>& fits, const RunInfo& run) {
  FRICTION_CHECK(!fits.empty(), "fit_report: no record");
  const std::string command = string_at(document, "command", "identify");
  const Json model = document.value("model", Json::object());
  const std::string type = string_at(model, "type", "model");
  const std::string method = string_at(document, "method", type);
  const std::string name = method == type ? type : method + " (" + type + ")";

  Document doc("friction-identify " + command + ": " + name);
  // The summary: the validation figure when there is one, else the estimation figure.
  std::string summary;
  const double est = number_at(document, {"estimation", "rss_sss_percent"});
  const double est_floor = number_at(document, {"estimation", "noise", "floor_percent"});
  const double val = number_at(document, {"validation", "rss_sss_percent"});
  const double val_floor = number_at(document, {"validation", "noise", "floor_percent"});
  const std::string first_file = fits.front().record->source;
  if (command == "validate") {
    summary = "The " + name + " model simulates " + first_file + " (" +
              std::to_string(fits.front().record->size()) + " samples) with RSS/SSS " + pct(val);
    const std::string f = against_floor(val, val_floor);
    summary += f.empty() ? "." : ", " + f + ".";
  } else {
    summary = name + " identified on " + first_file + " (" +
              std::to_string(fits.front().record->size()) + " samples): estimation RSS/SSS " +
              pct(est);
    if (std::isfinite(val)) {
      summary += ", validation " + pct(val);
      const std::string f = against_floor(val, val_floor);
      summary += f.empty() ? "." : ", " + f + ".";
    } else {
      const std::string f = against_floor(est, est_floor);
      summary += f.empty() ? "." : ", " + f + ".";
    }
  }
  const auto w = warnings_of(document);
  if (!w.empty()) summary += " " + std::to_string(w.size()) + " warning(s), listed below.";
  doc.summary(summary);

  std::vector<RecordView> views;
  for (const auto& f : fits) views.push_back(view_record(*f.record, f.role));

  doc.section("time", "Measured and simulated force");
  for (std::size_t k = 0; k < fits.size(); ++k)
    add_time_figures(doc, views[k].role, views[k],
                     {{"simulated", Role::simulated, fits[k].simulated}}, what_of(views[k], ""));
  doc.section("loops", "Hysteresis loops");
  doc.begin_grid();
  for (std::size_t k = 0; k < fits.size(); ++k)
    add_loop_figures(doc, views[k].role, views[k],
                     {{"simulated", Role::simulated, fits[k].simulated}}, what_of(views[k], ""));
  doc.end_grid();
  doc.section("sliding", "Friction against velocity while sliding");
  for (std::size_t k = 0; k < fits.size(); ++k)
    add_sliding_figure(doc, views[k].role, views[k],
                       {{"simulated", Role::simulated, fits[k].simulated}}, what_of(views[k], ""));

  doc.section("parameters", "Parameters");
  if (document.contains("identification") && document["identification"].contains("parameters")) {
    doc.add(estimates_table(document["identification"]["parameters"], "parameter-table",
                            "The " + name +
                                " model's parameters with standard errors and 95 % "
                                "intervals"));
  } else {
    doc.add(model_table(model, "parameter-table",
                        "The " + name +
                            " model's parameters (a saved model carries no intervals; "
                            "the document of `identify` does)"));
  }
  add_warnings_and_run(doc, document, run);
  return doc;
}

Document compare_report(const Json& document, const Record& estimation, const Record& validation,
                        const std::vector<MethodFit>& methods, const RunInfo& run) {
  Document doc("friction-identify compare: LG, NLR and DNLRX");
  const Json rows = document.value("methods", Json::array());

  // The ranking on the validation record, and the noise floor.
  struct Ranked {
    std::string method;
    double validation;
  };
  std::vector<Ranked> ranked;
  std::vector<std::string> failed;
  double floor = kNaN;
  for (const auto& row : rows) {
    const std::string m = string_at(row, "method");
    if (row.contains("error")) {
      failed.push_back(m + " failed (" + string_at(row, "error") + ")");
      continue;
    }
    ranked.push_back({m, number_at(row, {"validation", "rss_sss_percent"})});
    if (!std::isfinite(floor)) floor = number_at(row, {"validation", "noise", "floor_percent"});
  }
  std::sort(ranked.begin(), ranked.end(),
            [](const Ranked& a, const Ranked& b) { return a.validation < b.validation; });
  std::string summary;
  if (ranked.empty()) {
    summary = "No method produced a model.";
  } else {
    summary = "On the validation record " + ranked[0].method + " fits best (RSS/SSS " +
              pct(ranked[0].validation) + ")";
    for (std::size_t k = 1; k < ranked.size(); ++k)
      summary += (k == 1 ? ", then " : (k + 1 == ranked.size() ? " and " : ", ")) +
                 ranked[k].method + " (" + pct(ranked[k].validation) + ")";
    summary += ".";
    if (std::isfinite(floor) && floor > 0) {
      const double r = ranked[0].validation / floor;
      summary += " The noise floor is " + pct(floor) + "; " +
                 (r < 1.5 ? ranked[0].method + " reaches it."
                          : "none reaches it (the best is " + format_number(r, 3) +
                                " times above it): the data hold an effect none of these "
                                "structures contains (diagnose can name it).");
    }
  }
  for (const auto& f : failed) summary += " " + f + ".";
  doc.summary(summary);

  doc.section("comparison", "The paper's comparison");
  Table t;
  t.id = "compare-table";
  t.caption = "Free-run errors (RSS/SSS %, initial state estimated from each record)";
  t.header = {"method",
              "parameters",
              "estimation RSS/SSS %",
              "validation RSS/SSS %",
              "validation / noise floor",
              "seconds"};
  t.numeric = {false, true, true, true, true, true};
  BarChart chart;
  chart.id = "compare-errors";
  chart.title = "Each method's error against the noise floor";
  chart.caption =
      "RSS/SSS % of the free run on each record (log scale); the dashed line is the "
      "validation record's noise floor, the error white measurement noise alone "
      "would give.";
  chart.value = {"RSS/SSS", "%"};
  chart.value.log = true;
  BarGroup g_est{"estimation", Role::estimation, {}}, g_val{"validation", Role::validation, {}};
  for (const auto& row : rows) {
    const std::string m = string_at(row, "method");
    if (row.contains("error")) {
      t.rows.push_back({m, "failed: " + string_at(row, "error"), "", "", "",
                        format_number(number_at(row, {"seconds"}), 3)});
      continue;
    }
    const double v = number_at(row, {"validation", "rss_sss_percent"});
    t.rows.push_back({m, format_number(number_at(row, {"parameters"}), 6),
                      format_number(number_at(row, {"estimation", "rss_sss_percent"}), 4),
                      format_number(v, 4), format_number(v / floor, 3),
                      format_number(number_at(row, {"seconds"}), 3)});
    chart.categories.push_back(m);
    g_est.values.push_back(number_at(row, {"estimation", "rss_sss_percent"}));
    g_val.values.push_back(v);
  }
  doc.add(t);
  if (!chart.categories.empty()) {
    chart.groups = {g_est, g_val};
    if (std::isfinite(floor) && floor > 0) chart.references.push_back({"noise floor", floor});
    doc.add(chart);
  }

  const RecordView val_view = view_record(validation, "validation");
  const RecordView est_view = view_record(estimation, "estimation");
  struct Pair {
    const RecordView* view;
    bool estimation;
  };
  const Pair records[] = {{&val_view, false}, {&est_view, true}};
  const auto traces_of = [](const MethodFit& m, bool est) {
    return std::vector<Trace>{{"simulated", Role::simulated, est ? m.estimation : m.validation}};
  };
  for (const auto& rec : records) {
    const std::string role = rec.view->role;
    doc.section(role + "-time", "Force over time, " + role + " record");
    for (const auto& m : methods)
      if (!(rec.estimation ? m.estimation : m.validation).empty())
        add_time_figures(doc, role + "-" + m.method, *rec.view, traces_of(m, rec.estimation),
                         what_of(*rec.view, m.method));
    doc.section(role + "-loops", "Hysteresis loops, " + role + " record");
    doc.begin_grid();
    for (const auto& m : methods)
      if (!(rec.estimation ? m.estimation : m.validation).empty())
        add_loop_figures(doc, role + "-" + m.method, *rec.view, traces_of(m, rec.estimation),
                         what_of(*rec.view, m.method));
    doc.end_grid();
    doc.section(role + "-sliding", "Friction against velocity while sliding, " + role + " record");
    for (const auto& m : methods)
      if (!(rec.estimation ? m.estimation : m.validation).empty())
        add_sliding_figure(doc, role + "-" + m.method, *rec.view, traces_of(m, rec.estimation),
                           what_of(*rec.view, m.method));
  }

  doc.section("parameters", "Parameters");
  for (const auto& row : rows) {
    if (row.contains("error")) continue;
    const std::string m = string_at(row, "method");
    if (row.contains("identification") && row["identification"].contains("parameters"))
      doc.add(estimates_table(row["identification"]["parameters"], "parameters-" + m,
                              m + " (" + string_at(row.value("model", Json::object()), "type") +
                                  "): parameters with standard errors and 95 % intervals"));
  }
  add_warnings_and_run(doc, document, run);
  return doc;
}

namespace {

// Normalised cross-correlation of e(t) with u(t - lag) for lags -L..L samples.
std::vector<double> cross_correlation(std::span<const double> e, std::span<const double> u,
                                      long L) {
  const long n = static_cast<long>(e.size());
  double ee = 0, uu = 0;
  for (long k = 0; k < n; ++k) ee += e[k] * e[k], uu += u[k] * u[k];
  std::vector<double> c;
  for (long lag = -L; lag <= L; ++lag) {
    double s = 0;
    for (long k = std::max(0L, lag); k < std::min(n, n + lag); ++k) s += e[k] * u[k - lag];
    c.push_back(ee > 0 && uu > 0 ? s / std::sqrt(ee * uu) : 0.0);
  }
  return c;
}

std::string parameter_value(const Json& v) {
  if (v.is_number()) return format_number(v.get<double>(), 5);
  if (v.is_object() && v.contains("value")) return format_number(number_at(v, {"value"}), 5);
  if (v.is_string()) return v.get<std::string>();
  return v.dump();
}

// Interval of a finding's parameter: its `intervals` entry ([low, high]) when the document gives
// one, or the parameter's own {value, lower95, upper95}.
std::string parameter_interval(const Json& finding, const std::string& name, const Json& v) {
  if (finding.contains("intervals") && finding["intervals"].contains(name)) {
    const Json& i = finding["intervals"][name];
    if (i.is_array() && i.size() == 2 && i[0].is_number() && i[1].is_number())
      return "[" + format_number(i[0].get<double>(), 4) + ", " +
             format_number(i[1].get<double>(), 4) + "]";
    return "no standard error";
  }
  if (v.is_object()) return interval(v);
  return "not given by the diagnosis";
}

}  // namespace

void add_finding_panel(Document& doc, const std::string& id, const RecordView& view,
                       const FindingPanelInput& in) {
  FRICTION_CHECK(in.validation == view.record,
                 "add_finding_panel: the view is not of the "
                 "finding's validation record");
  const Record& r = *view.record;
  const Trace before{in.before_label, Role::before, in.before};
  const Trace after{in.after_label, Role::after, in.after};
  check_trace(view, before);
  check_trace(view, after);
  const std::vector<double> eb = residual_of(r, in.before), ea = residual_of(r, in.after);
  const std::string& effect = in.effect;
  const double vb = number_at(in.finding, {"validation_before"});
  const double va = number_at(in.finding, {"validation_after"});

  doc.subheading(effect + ": validation RSS/SSS " + pct(vb) + " \u2192 " + pct(va) +
                 (va > 0 ? " (gain \u00d7" + format_number(vb / va, 3) + ")" : ""));
  const std::string sentence = string_at(in.finding, "sentence");
  if (!sentence.empty()) doc.paragraph(sentence);

  Figure f;
  f.id = id;
  f.kind = "signature";
  const std::string models = in.before_label + " and " + in.after_label;
  std::vector<double> xs, cb, ca;  // storage the figure's spans point into
  const auto residual_panel = [&](Mark mark, std::span<const double> x) {
    Panel p{"residual", {"residual F \u2212 F\u0302", "N"}, {}, 220};
    p.y.symmetric = true;
    p.series.push_back({"residual, " + in.before_label, Role::before, mark, x, eb});
    p.series.push_back({"residual, " + in.after_label, Role::after, mark, x, ea});
    return p;
  };
  if (effect == "viscous" || effect == "stribeck" || effect == "asymmetry") {
    xs = masked(view.velocity, view.sliding);
    f.x = {"velocity", "m/s"};
    f.panels = {residual_panel(Mark::points, xs)};
    f.title = "Residual against velocity while sliding";
    f.caption =
        "A residual that follows the speed (rising: viscous; falling from a peak at low "
        "speed: Stribeck) or differs by direction (asymmetry) is this effect's signature; "
        "the " +
        in.after_label + " model should leave noise around zero.";
  } else if (effect == "frictional-lag") {
    xs = masked(view.velocity, view.sliding);
    f.x = {"velocity", "m/s"};
    Panel p{"force", {"force", "N"}, {}, 260};
    p.series.push_back({"measured", Role::measured, Mark::polyline, xs, r.force});
    p.series.push_back({in.before_label, Role::before, Mark::polyline, xs, in.before});
    p.series.push_back({in.after_label, Role::after, Mark::polyline, xs, in.after});
    f.panels = {p};
    f.title = "Force against velocity while sliding, in time order";
    f.caption =
        "Friction that lags the velocity traces loops in this plane (higher while "
        "accelerating than while decelerating, or the reverse); a model without the lag "
        "draws a single curve.";
  } else if (effect == "offset") {
    std::vector<bool> rest(r.size());
    double v_max = 0;
    for (const double u : view.velocity) v_max = std::max(v_max, std::abs(u));
    for (std::size_t k = 0; k < r.size(); ++k)
      rest[k] = !view.sliding[k] && std::abs(view.velocity[k]) <= 0.02 * v_max;
    if (count(rest) < 10) rest.assign(r.size(), true);
    xs = masked(r.time, rest);
    f.x = {"time", "s"};
    f.panels = {residual_panel(Mark::points, xs)};
    f.title = "Residual at rest";
    f.caption =
        "Samples where the displacement hardly moves: a constant bias here, whatever the "
        "direction of the last motion, is an offset.";
  } else if (effect == "position-dependence" || effect == "nonlocal-memory") {
    if (effect == "position-dependence") {
      xs = masked(r.displacement, view.sliding);
      f.x = {"displacement", "m"};
      f.panels = {residual_panel(Mark::points, xs)};
      f.title = "Residual against position while sliding";
      f.caption =
          "Friction that varies along the travel leaves a residual that repeats with the "
          "position on every stroke.";
    } else {
      std::vector<bool> zoom(r.size());
      for (std::size_t k = 0; k < r.size(); ++k)
        zoom[k] = r.time[k] >= view.zoom_lo && r.time[k] <= view.zoom_hi;
      xs = masked(r.displacement, zoom);
      f.x = {"displacement", "m"};
      Panel p{"force", {"force", "N"}, {}, 260};
      p.series.push_back({"measured", Role::measured, Mark::polyline, xs, r.force});
      p.series.push_back({in.before_label, Role::before, Mark::polyline, xs, in.before});
      p.series.push_back({in.after_label, Role::after, Mark::polyline, xs, in.after});
      f.panels = {p};
      f.title = "Presliding loops";
      f.caption =
          "Hysteresis with nonlocal memory: inner loops close on the reversal points of "
          "the outer ones, which one LuGre state cannot reproduce.";
    }
  } else if (effect == "drift") {
    f.x = {"time", "s"};
    f.panels = {residual_panel(Mark::line, r.time)};
    f.title = "Residual over time";
    f.caption =
        "A friction level that changes slowly over the record leaves a residual that "
        "grows with time.";
  } else if (effect == "inertia") {
    f.x = {"acceleration", "m/s^2"};
    f.panels = {residual_panel(Mark::points, view.acceleration)};
    f.title = "Residual against acceleration";
    f.caption =
        "A force that contains m\u00b7a leaves a residual proportional to the "
        "acceleration.";
  } else if (effect == "normal-load" && r.has_normal()) {
    f.x = {"normal force", "N"};
    f.panels = {residual_panel(Mark::points, r.normal)};
    f.title = "Residual against the normal force";
    f.caption = "Friction proportional to the normal load leaves a residual that follows it.";
  } else if (effect == "delay") {
    const long n = static_cast<long>(r.size());
    const long L = std::max(1L, std::min(50L, n / 10));
    cb = cross_correlation(eb, view.velocity, L);
    ca = cross_correlation(ea, view.velocity, L);
    const double ts = (r.time.back() - r.time.front()) / static_cast<double>(n - 1);
    for (long lag = -L; lag <= L; ++lag) xs.push_back(static_cast<double>(lag) * ts);
    f.x = {"lag", "s"};
    Panel p{"cross-correlation", {"correlation of residual and velocity", ""}, {}, 220};
    p.y.symmetric = true;
    p.series.push_back({"residual, " + in.before_label, Role::before, Mark::line, xs, cb});
    p.series.push_back({"residual, " + in.after_label, Role::after, Mark::line, xs, ca});
    f.panels = {p};
    f.title = "Cross-correlation of the residual with the velocity";
    f.caption =
        "A force shifted in time against the displacement leaves a residual correlated "
        "with the motion at a lag; after the finding it should be flat.";
  } else {
    f.x = {"time", "s"};
    f.panels = {residual_panel(Mark::line, r.time)};
    f.title = "Residual over time";
    f.caption = "The residual of both models over the validation record.";
  }
  f.title += " (" + effect + ", " + models + ")";
  doc.add(f);

  Table t;
  t.id = id + "-parameters";
  t.caption = effect + ": parameters";
  t.header = {"parameter", "value", "unit", "95 % interval"};
  t.numeric = {false, true, false, true};
  if (in.finding.contains("parameters") && in.finding["parameters"].is_object())
    for (const auto& [name, value] : in.finding["parameters"].items())
      t.rows.push_back({name, parameter_value(value), extension_parameter_unit(name),
                        parameter_interval(in.finding, name, value)});
  if (!t.rows.empty()) doc.add(t);
  if (in.finding.contains("ambiguous_with") && in.finding["ambiguous_with"].is_array() &&
      !in.finding["ambiguous_with"].empty()) {
    std::string partners;
    for (const auto& p : in.finding["ambiguous_with"])
      partners +=
          (partners.empty() ? "" : ", ") + (p.is_string() ? p.get<std::string>() : p.dump());
    doc.paragraph("Ambiguous with " + partners +
                  ": this record cannot tell them apart. What would: " +
                  string_at(in.finding, "separating_excitation", "(not given)") + ".");
  }
}

Document diagnose_report(const Json& document, const Record& estimation, const Record& validation,
                         const DiagnoseFits& fits, const std::vector<FindingPanelInput>& panels,
                         const RunInfo& run) {
  const Json baseline = document.value("baseline", Json::object());
  const Json final_ = document.value("final", Json::object());
  const Json findings = document.value("findings", Json::array());
  const std::string base_type = string_at(baseline.value("model", Json::object()), "type", "?");
  const double base_val = number_at(baseline, {"validation", "rss_sss_percent"});
  const double final_val = number_at(final_, {"validation", "rss_sss_percent"});
  const double floor = number_at(baseline, {"residual", "noise", "floor_percent"});

  Document doc("friction-identify diagnose: " + base_type + " baseline");
  std::string summary = "The " + base_type +
                        " baseline simulates the validation record with "
                        "RSS/SSS " +
                        pct(base_val);
  if (findings.empty()) {
    summary += "; no candidate extension earned its place";
    summary += std::isfinite(floor) && floor > 0
                   ? " (" + format_number(base_val / floor, 3) + " times the noise floor of " +
                         pct(floor) + ")."
                   : ".";
  } else {
    summary += ". " + capitalised(count_words(findings.size())) +
               (findings.size() == 1 ? " effect explains" : " effects explain") +
               " what it misses: ";
    for (std::size_t k = 0; k < findings.size(); ++k)
      summary += (k == 0 ? "" : (k + 1 == findings.size() ? " and " : ", ")) +
                 string_at(findings[k], "effect") + " (" +
                 pct(number_at(findings[k], {"validation_before"})) + " \u2192 " +
                 pct(number_at(findings[k], {"validation_after"})) + ")";
    summary += "; the final model validates at " + pct(final_val);
    if (final_val > 0) summary += " (gain \u00d7" + format_number(base_val / final_val, 3) + ")";
    if (std::isfinite(floor) && floor > 0)
      summary += ", " + format_number(final_val / floor, 3) + " times the noise floor (" +
                 pct(floor) + ")";
    summary += ".";
  }
  doc.summary(summary);

  doc.section("findings", "Findings");
  if (findings.empty()) {
    doc.paragraph(
        "No finding: no candidate extension earned its place (see the candidates "
        "below and the warnings).");
  } else {
    Table t;
    t.id = "findings-table";
    t.caption =
        "In the order they were accepted; the validation errors chain from the baseline "
        "to the final model";
    t.header = {"#",    "effect",     "validation before %", "validation after %",
                "gain", "parameters", "extension",           "ambiguous with"};
    t.numeric = {true, false, true, true, true, false, false, false};
    for (std::size_t k = 0; k < findings.size(); ++k) {
      const Json& f = findings[k];
      std::string params;
      if (f.contains("parameters") && f["parameters"].is_object())
        for (const auto& [name, value] : f["parameters"].items())
          params += (params.empty() ? "" : ", ") + name + " = " + parameter_value(value) +
                    unit_suffix(extension_parameter_unit(name));
      std::string amb;
      if (f.contains("ambiguous_with") && f["ambiguous_with"].is_array())
        for (const auto& p : f["ambiguous_with"])
          amb += (amb.empty() ? "" : ", ") + (p.is_string() ? p.get<std::string>() : p.dump());
      if (!amb.empty()) amb += " (" + string_at(f, "separating_excitation") + ")";
      const double b = number_at(f, {"validation_before"}), a = number_at(f, {"validation_after"});
      t.rows.push_back({std::to_string(k + 1), string_at(f, "effect"), format_number(b, 4),
                        format_number(a, 4), a > 0 ? "\u00d7" + format_number(b / a, 3) : "",
                        params, string_at(f, "extension"), amb.empty() ? "\u2013" : amb});
    }
    doc.add(t);
  }

  const RecordView val_view = view_record(validation, "validation");
  const RecordView est_view = view_record(estimation, "estimation");
  if (!panels.empty()) {
    doc.section("finding-panels", "What each finding explained");
    for (std::size_t k = 0; k < panels.size(); ++k)
      add_finding_panel(doc, "finding-" + std::to_string(k + 1), val_view, panels[k]);
  }

  const auto traces = [&](bool est) {
    return std::vector<Trace>{
        {fits.baseline_label, Role::before,
         est ? fits.baseline_estimation : fits.baseline_validation},
        {fits.final_label, Role::after, est ? fits.final_estimation : fits.final_validation}};
  };
  const struct {
    const RecordView* view;
    bool estimation;
  } records[] = {{&val_view, false}, {&est_view, true}};
  for (const auto& rec : records) {
    const std::string role = rec.view->role;
    const std::string what = what_of(*rec.view, fits.baseline_label + " and " + fits.final_label);
    doc.section(role + "-panels", "Baseline and final model on the " + role + " record");
    add_time_figures(doc, role, *rec.view, traces(rec.estimation), what);
    doc.begin_grid();
    add_loop_figures(doc, role, *rec.view, traces(rec.estimation), what_of(*rec.view, ""));
    doc.end_grid();
    add_sliding_figure(doc, role, *rec.view, traces(rec.estimation), what);
  }

  doc.section("candidates", "Candidates of the first round");
  const Json cands = document.value("candidates", Json::array());
  if (cands.empty()) {
    doc.paragraph("None was fitted.");
  } else {
    Table t;
    t.id = "candidates-table";
    t.caption =
        "Every candidate fitted on top of the baseline, and why it earned its place or "
        "did not";
    t.header = {"effect",           "estimation %",    "validation %", "\u0394BIC",
                "extra parameters", "earns its place", "verdict"};
    t.numeric = {false, true, true, true, true, false, false};
    for (const auto& c : cands) {
      const double v = number_at(c, {"validation_rss_sss_percent"});
      t.rows.push_back({string_at(c, "effect"),
                        format_number(number_at(c, {"estimation_rss_sss_percent"}), 4),
                        std::isfinite(v) ? format_number(v, 4) : "not evaluated",
                        format_number(number_at(c, {"delta_bic"}), 4),
                        format_number(number_at(c, {"extra_parameters"}), 3),
                        c.value("earns_place", false) ? "yes" : "no", string_at(c, "verdict")});
    }
    doc.add(t);
  }

  doc.section("parameters", "Parameters");
  doc.add(model_table(final_.value("model", Json::object()), "final-parameters",
                      "Final model (" + string_at(final_.value("model", Json::object()), "type") +
                          " with its extensions)"));
  doc.add(model_table(baseline.value("model", Json::object()), "baseline-parameters",
                      "Baseline model (" + base_type + ")"));
  add_warnings_and_run(doc, document, run);
  return doc;
}

}  // namespace friction::report
