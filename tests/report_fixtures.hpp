// Records and documents for the report tests and the report benchmark (bench_report.cpp includes
// this file): a record of the reference Maxwell Slip system under the combined excitation
// (strokes at five speeds, then presliding loops), resampled to the number of samples asked for,
// with white force noise, and the free runs of three other reference models on it (LuGre, DNLRX,
// GMS), which miss it the way identified models do: in presliding and in the sliding levels.
#pragma once

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstddef>
#include <string>
#include <vector>

#include "friction/excitation.hpp"
#include "friction/model_io.hpp"
#include "friction/record.hpp"
#include "friction/report_pages.hpp"

namespace friction::testing {

/// `samples` samples of the combined excitation (the sampling rate chosen to give that many),
/// force of the reference Maxwell Slip model plus white noise of 0.01 N.
inline Record synthetic_report_record(std::size_t samples, std::uint64_t seed,
                                      const std::string& name) {
  ExcitationOptions o;
  o.kind = ExcitationKind::Combined;
  o.rate = 1000.0;
  const std::size_t at_1k = make_excitation(o).time.size();
  o.rate = 1000.0 * static_cast<double>(samples) / static_cast<double>(at_1k) * 1.001;
  Signal s = make_excitation(o);
  s.time.resize(std::min(samples, s.time.size()));
  s.displacement.resize(s.time.size());
  Record r;
  r.time = s.time;
  r.displacement = s.displacement;
  r.source = name;
  AnyModel truth = reference_model("maxwell-slip", o.rate);
  r.force = truth.simulate(r);
  NormalSource noise(seed);
  add_white_noise(r.force, 0.01, noise);
  return r;
}

/// The free run of a reference model of `type` on the record.
inline std::vector<double> reference_run(const std::string& type, const Record& r) {
  const double rate = 1.0 / (r.time[1] - r.time[0]);
  AnyModel m = reference_model(type, rate);
  return m.simulate(r);
}

/// A compare document of the shape `compare` writes (the keys the report reads).
inline nlohmann::json compare_document(const Record& est, const Record& val,
                                       const std::vector<report::MethodFit>& fits) {
  nlohmann::json doc = {{"schema_version", 1}, {"command", "compare"}, {"warnings", {"a warning"}}};
  doc["methods"] = nlohmann::json::array();
  const auto pct = [](const Record& r, const std::vector<double>& sim) {
    double rss = 0, sss = 0;
    for (std::size_t k = 0; k < r.size(); ++k)
      rss += (r.force[k] - sim[k]) * (r.force[k] - sim[k]), sss += r.force[k] * r.force[k];
    return 100 * rss / sss;
  };
  for (const auto& f : fits) {
    nlohmann::json row = {{"method", f.method},
                          {"parameters", 8},
                          {"seconds", 1.5},
                          {"model", {{"type", "maxwell-slip"}}}};
    row["estimation"]["rss_sss_percent"] = pct(est, f.estimation);
    row["validation"]["rss_sss_percent"] = pct(val, f.validation);
    row["validation"]["noise"]["floor_percent"] = 0.004;
    row["identification"]["parameters"] = {{{"name", "stiffness[1]"},
                                            {"unit", "N/m"},
                                            {"value", 1e5},
                                            {"standard_error", 1e3},
                                            {"lower95", 9.8e4},
                                            {"upper95", 1.02e5}}};
    doc["methods"].push_back(row);
  }
  return doc;
}

/// The compare report of the three reference models on two records of `samples` samples each.
inline report::Document synthetic_compare_report(std::size_t samples, Record& est, Record& val) {
  est = synthetic_report_record(samples, 1, "est.csv");
  val = synthetic_report_record(samples, 2, "val.csv");
  std::vector<report::MethodFit> fits;
  for (const auto& [method, type] : std::vector<std::pair<std::string, std::string>>{
           {"LG", "lugre"}, {"NLR", "gms"}, {"DNLRX", "dnlrx"}})
    fits.push_back({method, reference_run(type, est), reference_run(type, val)});
  return report::compare_report(compare_document(est, val, fits), est, val, fits,
                                {"friction-identify compare --data est.csv", "test"});
}

}  // namespace friction::testing
