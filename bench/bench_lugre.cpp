// Cost of the LuGre exact step per sample and of CVODES over a 10,000-sample record.
//
// The record (1 kHz, 10 s): 3 s of presliding sinusoids (2 Hz, 2..5 um), then 7 s of sliding
// sweeps (1 Hz, 3.2 mm, so +-20 mm/s).  Paper-like parameters: sigma1 = sqrt(sigma0), sigma2 = 0.5,
// Fc = 1, Fs = 1.5 N, vs = 1 mm/s, mu = 2; sigma0 = 1e5 and 1e6 N/m.  The CVODES benchmarks report
// `max_err_N`, the largest |F_cvodes - F_exact| over the record, and `steps_per_sample`.
#include <benchmark/benchmark.h>

#include <ceres/jet.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "friction/lugre.hpp"
#include "friction/lugre_cvodes.hpp"
#include "friction/simulate.hpp"

namespace {

using friction::CvodesMethod;
using friction::CvodesOptions;
using friction::LuGre;
using friction::LuGreParameters;
using friction::Motion;

constexpr std::size_t kSamples = 10000;

struct Record {
  std::vector<double> time, x;
};

const Record& record() {
  static const Record r = [] {
    Record rec;
    rec.time.resize(kSamples);
    rec.x.resize(kSamples);
    for (std::size_t k = 0; k < kSamples; ++k) {
      const double t = 1e-3 * static_cast<double>(k);
      rec.time[k] = t;
      rec.x[k] = t < 3.0 ? (2e-6 + 1e-6 * t) * std::sin(2 * M_PI * 2 * t)
                         : 3.2e-3 * std::sin(2 * M_PI * (t - 3.0));
    }
    return rec;
  }();
  return r;
}

LuGreParameters<double> parameters(double sigma0) {
  return {sigma0, std::sqrt(sigma0), 0.5, 1.0, 1.5, 1e-3, 2.0};
}

template <typename T>
std::vector<Motion<T>> motions() {
  const auto& r = record();
  std::vector<Motion<T>> m(kSamples, Motion<T>{T(0), T(0), T(0)});
  for (std::size_t k = 1; k < kSamples; ++k) {
    const double dt = r.time[k] - r.time[k - 1], dx = r.x[k] - r.x[k - 1];
    m[k] = Motion<T>{T(dx), T(dx / dt), T(dt)};
  }
  return m;
}

void BM_LuGreExactStep(benchmark::State& state) {
  LuGre<double> model(parameters(1e5));
  const auto m = motions<double>();
  for (auto _ : state) {
    model.reset();
    for (const auto& motion : m) benchmark::DoNotOptimize(model.step(motion));
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * kSamples));
}
BENCHMARK(BM_LuGreExactStep);

// With derivatives in all seven parameters (what autodiff through the exact step costs).
void BM_LuGreExactStepJet7(benchmark::State& state) {
  using Jet = ceres::Jet<double, 7>;
  const auto theta = parameters(1e5).to_array();
  std::array<Jet, 7> tj;
  for (int j = 0; j < 7; ++j) tj[j] = Jet(theta[j], j);
  LuGre<Jet> model(LuGreParameters<Jet>::from_array(tj));
  const auto m = motions<Jet>();
  for (auto _ : state) {
    model.reset();
    for (const auto& motion : m) benchmark::DoNotOptimize(model.step(motion));
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * kSamples));
}
BENCHMARK(BM_LuGreExactStepJet7);

// Args: method (0 Adams, 1 BDF), sensitivities (0/1), log10(sigma0).
void BM_LuGreCvodes(benchmark::State& state) {
  const auto& r = record();
  const auto p = parameters(std::pow(10.0, static_cast<double>(state.range(2))));
  CvodesOptions options;
  options.method = state.range(0) == 0 ? CvodesMethod::Adams : CvodesMethod::BDF;
  options.sensitivities = state.range(1) != 0;
  friction::LuGreCvodesResult result;
  for (auto _ : state) {
    result = friction::simulate_lugre_cvodes(p, r.time, r.x, options);
    benchmark::DoNotOptimize(result.force.data());
  }
  LuGre<double> model(p);
  const auto exact =
      friction::simulate(model, std::span<const double>(r.time), std::span<const double>(r.x));
  double err = 0;
  for (std::size_t k = 0; k < kSamples; ++k)
    err = std::max(err, std::abs(result.force[k] - exact[k]));
  state.counters["max_err_N"] = err;
  state.counters["steps_per_sample"] =
      static_cast<double>(result.statistics.steps) / static_cast<double>(kSamples);
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * kSamples));
  state.SetLabel(std::string(state.range(0) == 0 ? "Adams" : "BDF") +
                 (state.range(1) ? "+sens" : ""));
}
BENCHMARK(BM_LuGreCvodes)
    ->ArgsProduct({{0, 1}, {0, 1}, {5, 6}})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(1.0);

}  // namespace
