// Writing the HTML reports of 100k-sample records: the time to build and write each page and its
// size (counter `bytes`; the README and test_report hold it under 3 MB).  The records are those
// of tests/report_fixtures.hpp: the reference Maxwell Slip system under the combined excitation,
// 100,000 samples each, with the free runs of three other reference models as the "fits".
//
// With FRICTION_REPORT_BENCH_DIR set, the last report of each kind is left there
// (compare-100k.html, diagnose-100k.html, validate-100k.html) for bench/report-render.sh, which
// times their rendering in Chromium.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "../tests/report_fixtures.hpp"
#include "friction/report_pages.hpp"

namespace {

using namespace friction;

constexpr std::size_t kSamples = 100000;

std::string output_path(const std::string& name) {
  if (const char* dir = std::getenv("FRICTION_REPORT_BENCH_DIR"))
    return std::string(dir) + "/" + name;
  return (std::filesystem::temp_directory_path() / ("friction-bench-" + name)).string();
}

struct Records {
  Record est = testing::synthetic_report_record(kSamples, 1, "est.csv");
  Record val = testing::synthetic_report_record(kSamples, 2, "val.csv");
  std::vector<report::MethodFit> fits;
  Records() {
    for (const auto& [m, type] : std::vector<std::pair<std::string, std::string>>{
             {"LG", "lugre"}, {"NLR", "gms"}, {"DNLRX", "dnlrx"}})
      fits.push_back({m, testing::reference_run(type, est), testing::reference_run(type, val)});
  }
};

const Records& records() {
  static const Records r;
  return r;
}

void BM_CompareReport100k(benchmark::State& state) {
  const Records& r = records();
  const Json doc = testing::compare_document(r.est, r.val, r.fits);
  const std::string path = output_path("compare-100k.html");
  std::size_t bytes = 0;
  for (auto _ : state) {
    const report::Document page =
        report::compare_report(doc, r.est, r.val, r.fits, {"bench_report", "bench"});
    report::write_report(path, page);
    bytes = std::filesystem::file_size(path);
  }
  state.counters["bytes"] = static_cast<double>(bytes);
  state.counters["samples_per_record"] = static_cast<double>(kSamples);
}
BENCHMARK(BM_CompareReport100k)->Unit(benchmark::kMillisecond)->MinTime(2.0);

void BM_DiagnoseReport100k(benchmark::State& state) {
  const Records& r = records();
  report::DiagnoseFits fits;
  fits.baseline_estimation = r.fits[0].estimation;
  fits.baseline_validation = r.fits[0].validation;
  fits.final_estimation = r.fits[1].estimation;
  fits.final_validation = r.fits[1].validation;
  Json doc = {{"command", "diagnose"}, {"warnings", Json::array()}};
  doc["baseline"] = {{"model", {{"type", "lugre"}}}, {"validation", {{"rss_sss_percent", 1.0}}}};
  doc["final"] = {{"model", {{"type", "gms"}}}, {"validation", {{"rss_sss_percent", 0.1}}}};
  std::vector<report::FindingPanelInput> panels;
  for (const char* e : {"stribeck", "frictional-lag", "viscous"}) {
    doc["findings"].push_back({{"effect", e},
                               {"validation_before", 1.0},
                               {"validation_after", 0.5},
                               {"parameters", {{"viscous", 40.0}}}});
    panels.push_back({e, &r.val, fits.baseline_validation, fits.final_validation, "baseline",
                      "final", doc["findings"].back()});
  }
  doc["candidates"] = Json::array();
  const std::string path = output_path("diagnose-100k.html");
  std::size_t bytes = 0;
  for (auto _ : state) {
    const report::Document page =
        report::diagnose_report(doc, r.est, r.val, fits, panels, {"bench_report", "bench"});
    report::write_report(path, page);
    bytes = std::filesystem::file_size(path);
  }
  state.counters["bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_DiagnoseReport100k)->Unit(benchmark::kMillisecond)->MinTime(2.0);

void BM_ValidateReport100k(benchmark::State& state) {
  const Records& r = records();
  Json doc = {{"command", "validate"}, {"warnings", Json::array()}};
  doc["model"] = {{"type", "gms"}, {"parameters", {{"coulomb", 1.5}}}};
  doc["validation"] = {{"rss_sss_percent", 0.1}, {"noise", {{"floor_percent", 0.004}}}};
  const std::string path = output_path("validate-100k.html");
  std::size_t bytes = 0;
  for (auto _ : state) {
    const report::Document page = report::fit_report(
        doc, {{&r.val, "validation", r.fits[1].validation}}, {"bench_report", "bench"});
    report::write_report(path, page);
    bytes = std::filesystem::file_size(path);
  }
  state.counters["bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_ValidateReport100k)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace
