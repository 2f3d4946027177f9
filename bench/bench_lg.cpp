// LG identification of the LuGre model on a 10,000-sample record, one core (target: under 5 s).
//
// The record (1 kHz, 10 s): a third of presliding sinusoids at 3 Hz whose amplitude decays from
// 40 um to 3 um, then sinusoidal strokes growing from 0.2 to 3 mm and 1 to 2.5 Hz (sliding up to
// ~45 mm/s), generated with the exact step from paper-like parameters (sigma0 = 1e5 N/m,
// sigma1 = sqrt(sigma0), sigma2 = 0.4 N s/m, Fc = 1 N, Fs = 1.5 N, vs = 1 mm/s, mu = 2) and an
// initial state z0 = -0.4 Fs / sigma0, plus white force noise of 0.01 N.
// BM_IdentifyLuGre argument: the local stage's iterations with 0 = CVODES Jacobians with Adams,
// 1 = exact-step autodiff Jacobians (the default; one CVODES run checks the optimum),
// 2 = CVODES Jacobians with BDF.  Counters: the stage times [s], the number of Jacobians of the
// local stage and its check, RSS/SSS % and the noise floor.
// BM_LgJacobian: one residual-and-Jacobian evaluation of LgCostFunction at the generating
// parameters, 0 = CVODES sensitivities (Adams), 1 = exact-step autodiff.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "friction/lg.hpp"
#include "friction/simulate.hpp"

namespace {

using namespace friction;

struct Record {
  std::vector<double> time, x, force;
};

const Record& record() {
  static const Record r = [] {
    constexpr std::size_t n = 10000, n1 = n / 3;
    Record rec;
    rec.time.resize(n);
    rec.x.resize(n);
    const double t1 = static_cast<double>(n1) * 1e-3, t_end = static_cast<double>(n) * 1e-3;
    double phase = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
      const double t = 1e-3 * static_cast<double>(k);
      rec.time[k] = t;
      if (k < n1) {
        rec.x[k] = 40e-6 * std::pow(3.0 / 40.0, t / t1) * std::sin(2 * M_PI * 3.0 * t);
      } else {
        const double u = (t - t1) / (t_end - t1);
        phase += 2 * M_PI * (1.0 + 1.5 * u) * 1e-3;
        rec.x[k] = (0.2e-3 + 2.8e-3 * u) * std::sin(phase);
      }
    }
    const LuGreParameters<double> p{1e5, std::sqrt(1e5), 0.4, 1.0, 1.5, 1e-3, 2.0};
    LuGre<double> model(p);
    model.reset(-0.4 * 1.5 / 1e5);
    rec.force = simulate(model, std::span<const double>(rec.time), std::span<const double>(rec.x));
    std::mt19937 gen(7);
    std::normal_distribution<double> noise(0.0, 0.01);
    for (double& f : rec.force) f += noise(gen);
    return rec;
  }();
  return r;
}

void BM_IdentifyLuGre(benchmark::State& state) {
  const auto& r = record();
  LgOptions o;
  o.jacobian = state.range(0) == 1 ? LgJacobian::ExactStep : LgJacobian::Cvodes;
  o.cvodes_check = state.range(0) == 1;
  if (state.range(0) == 2) o.cvodes.method = CvodesMethod::BDF;
  LgResult result;
  for (auto _ : state) {
    result = identify_lugre(r.time, r.x, r.force, o);
    benchmark::DoNotOptimize(result.parameters.stiffness);
  }
  state.counters["start_s"] = result.timings.start;
  state.counters["global_s"] = result.timings.global;
  state.counters["local_s"] = result.timings.local;
  state.counters["report_s"] = result.timings.report;
  state.counters["jacobians"] = result.timings.jacobian_evaluations;
  state.counters["rss_pct"] = result.report.estimation.rss_sss_percent;
  state.counters["floor_pct"] = result.report.noise_floor_percent;
  const char* labels[] = {"cvodes-adams-jacobian", "exact-step-jacobian+cvodes-check",
                          "cvodes-bdf-jacobian"};
  state.SetLabel(labels[state.range(0)]);
}
BENCHMARK(BM_IdentifyLuGre)->Arg(0)->Arg(1)->Arg(2)->Iterations(2)->Unit(benchmark::kSecond);

void BM_LgJacobian(benchmark::State& state) {
  const auto& r = record();
  const LuGreParameters<double> p{1e5, std::sqrt(1e5), 0.4, 1.0, 1.5, 1e-3, 2.0};
  const std::size_t n = r.x.size();
  const LgCostFunction cost(r.time, r.x, r.force, 1.0, 1.5 / 1e5, StribeckShape::Rational,
                            state.range(0) == 1 ? LgJacobian::ExactStep : LgJacobian::Cvodes,
                            lg_default_cvodes());
  std::vector<double> log_theta, residuals(n), jacobian(n * LuGreParameters<double>::kSize),
      state_jacobian(n);
  for (double v : p.to_array()) log_theta.push_back(std::log(v));
  double u = -0.4;
  const double* blocks[2] = {log_theta.data(), &u};
  double* jacobians[2] = {jacobian.data(), state_jacobian.data()};
  for (auto _ : state) {
    const bool ok = cost.Evaluate(blocks, residuals.data(), jacobians);
    benchmark::DoNotOptimize(ok);
    log_theta[0] += 1e-12;  // a new point each time: no memo
  }
  state.SetLabel(state.range(0) == 1 ? "exact-step" : "cvodes-adams");
}
BENCHMARK(BM_LgJacobian)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
