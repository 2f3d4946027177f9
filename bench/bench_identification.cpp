// Identification timings on synthetic records (one core):
//   NLR with M = 10 on 10,000 samples (target < 1 s),
//   DNLRX with order selection on 10,000 samples (target < 3 s),
//   variable projection against joint optimisation of (k, Delta) for NLR (the measurement behind
//   the default NlrSolver::VariableProjection), and where DNLRX takes its thresholds from.
// Counters report the final estimation RSS/SSS % so that speed is never bought with accuracy.
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "../tests/identification_fixtures.hpp"
#include "friction/dnlrx_identification.hpp"
#include "friction/initial_state.hpp"
#include "friction/nlr.hpp"

namespace {

using namespace friction;

MaxwellSlipParameters<double> ten_operators() {
  MaxwellSlipParameters<double> p;
  for (int i = 0; i < 10; ++i) {
    p.threshold.push_back(0.5e-6 * std::pow(40.0, i / 9.0));  // 0.5 .. 20 um
    p.stiffness.push_back(4e4 * std::pow(0.7, i));
  }
  return p;
}

Record with_viscous(Record r, double viscous) {
  for (std::size_t k = 1; k < r.size(); ++k)
    r.force[k] +=
        viscous * (r.displacement[k] - r.displacement[k - 1]) / (r.time[k] - r.time[k - 1]);
  return r;
}

void BM_NlrTenOperators(benchmark::State& state) {
  const auto sys = ten_operators();
  const Record rec = testing::synthetic_record(sys, 10000, 40e-6, 0, 2e-3, 7,
                                               std::vector<double>(10, 0.0), nullptr);
  NlrOptions o;
  o.operators = 10;
  o.solver = state.range(0) == 0 ? NlrSolver::VariableProjection : NlrSolver::Joint;
  double percent = 0, floor = 0, starts = 0;
  for (auto _ : state) {
    const auto r = identify_maxwell_slip(rec.time, rec.displacement, rec.force, o);
    percent = r.report.estimation.rss_sss_percent;
    floor = r.report.noise_floor_percent;
    starts = static_cast<double>(r.report.starts.size());
  }
  state.counters["rss_sss_percent"] = percent;
  state.counters["noise_floor_percent"] = floor;
  state.counters["starts"] = starts;
  state.SetLabel(state.range(0) == 0 ? "variable projection" : "joint");
}
BENCHMARK(BM_NlrTenOperators)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->Iterations(1);

void BM_NlrFourOperatorsSolver(benchmark::State& state) {
  const auto sys = testing::four_operator_system();
  const Record rec = testing::synthetic_record(sys, 3000, 30e-6, 0, 2e-3, 11,
                                               {0.5e-6, -2e-6, 3e-6, -10e-6}, nullptr);
  NlrOptions o;
  o.operators = 4;
  o.global_stage = false;
  o.covariance = false;
  o.solver = state.range(0) == 0 ? NlrSolver::VariableProjection : NlrSolver::Joint;
  double percent = 0;
  for (auto _ : state) {
    const auto r = identify_maxwell_slip(rec.time, rec.displacement, rec.force, o);
    percent = r.report.estimation.rss_sss_percent;
    double best = 1e300, worst = 0;
    for (const auto& s : r.report.starts)
      best = std::min(best, s.final_percent), worst = std::max(worst, s.final_percent);
    state.counters["best_start_percent"] = best;
    state.counters["worst_start_percent"] = worst;
  }
  state.counters["rss_sss_percent"] = percent;
  state.SetLabel(state.range(0) == 0 ? "variable projection" : "joint");
}
BENCHMARK(BM_NlrFourOperatorsSolver)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->Iterations(3);

void BM_DnlrxSelection(benchmark::State& state) {
  const auto sys = testing::four_operator_system();
  const Record rec = with_viscous(testing::synthetic_record(sys, 10000, 30e-6, 0, 2e-3, 21,
                                                            {0.5e-6, -2e-6, 3e-6, -10e-6}, nullptr),
                                  150.0);
  const Record val = with_viscous(
      testing::synthetic_record(sys, 10000, 25e-6, 1, 2e-3, 22, {0, 1e-6, -4e-6, 8e-6}, nullptr),
      150.0);
  DnlrxOptions o;
  o.thresholds = static_cast<DnlrxThresholds>(state.range(0));
  double percent = 0, validation = 0, m = 0, n = 0, nx = 0;
  for (auto _ : state) {
    const auto r = identify_dnlrx(rec.time, rec.displacement, rec.force, o);
    percent = r.report.estimation.rss_sss_percent;
    validation =
        free_run_dnlrx(r.parameters, val.time, val.displacement, val.force).errors.rss_sss_percent;
    m = static_cast<double>(r.parameters.size());
    n = static_cast<double>(r.parameters.spring_order);
    nx = static_cast<double>(r.parameters.input_taps()) - 1;
  }
  state.counters["rss_sss_percent"] = percent;
  state.counters["validation_percent"] = validation;
  state.counters["M"] = m;
  state.counters["n"] = n;
  state.counters["nx"] = nx;
  const char* labels[] = {"thresholds from NLR", "re-optimised for the selected orders",
                          "re-optimised per M and for the selected orders"};
  state.SetLabel(labels[state.range(0)]);
}
BENCHMARK(BM_DnlrxSelection)->DenseRange(0, 2)->Unit(benchmark::kMillisecond)->Iterations(1);

void BM_InitialStateTenOperators(benchmark::State& state) {
  const auto sys = ten_operators();
  const Record rec = testing::synthetic_record(sys, 10000, 40e-6, 1, 2e-3, 9,
                                               std::vector<double>(10, 0.0), nullptr, 400);
  for (auto _ : state) {
    auto d = estimate_initial_deflections(sys, rec.displacement, rec.force);
    benchmark::DoNotOptimize(d);
  }
}
BENCHMARK(BM_InitialStateTenOperators)->Unit(benchmark::kMillisecond);

}  // namespace
