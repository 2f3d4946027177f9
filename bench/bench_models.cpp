// Per-sample cost of the slip models on a realistic displacement record.
//
// The record: 10,000 samples at 1 kHz of a three-tone displacement (40, 12, 4 um at 0.7, 3.1 and
// 11 Hz), so the operators see presliding reversals with nonlocal memory as well as slides.  Each
// benchmark steps the model over the whole record per iteration; "items" are samples, so
// items_per_second is the inverse of the per-sample time, and `s_per_operator_sample` (Maxwell
// Slip) is the time per operator per sample.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstddef>
#include <vector>

#include "friction/dnlrx.hpp"
#include "friction/extensions.hpp"
#include "friction/gms.hpp"
#include "friction/maxwell_slip.hpp"
#include "friction/motion.hpp"
#include "friction/static_friction.hpp"

namespace {

constexpr std::size_t kSamples = 10000;
constexpr double kTs = 1e-3;

const std::vector<friction::Motion<double>>& record() {
  static const std::vector<friction::Motion<double>> motions = [] {
    std::vector<double> x(kSamples);
    for (std::size_t k = 0; k < kSamples; ++k) {
      const double t = kTs * static_cast<double>(k);
      x[k] = 40e-6 * std::sin(2 * M_PI * 0.7 * t) + 12e-6 * std::sin(2 * M_PI * 3.1 * t + 1.0) +
             4e-6 * std::sin(2 * M_PI * 11.0 * t + 2.0);
    }
    std::vector<friction::Motion<double>> m(kSamples, friction::Motion<double>{0, 0, 0});
    for (std::size_t k = 1; k < kSamples; ++k) {
      const double dx = x[k] - x[k - 1];
      m[k] = {dx, dx / kTs, kTs, 1.0};
    }
    return m;
  }();
  return motions;
}

// Thresholds log-spaced from 0.5 um to 30 um, stiffnesses falling with the threshold.
std::vector<double> thresholds(std::size_t m) {
  std::vector<double> d(m);
  for (std::size_t i = 0; i < m; ++i)
    d[i] = 0.5e-6 * std::pow(60.0, m > 1 ? static_cast<double>(i) / static_cast<double>(m - 1) : 0);
  return d;
}

friction::MaxwellSlipParameters<double> maxwell_slip(std::size_t m) {
  friction::MaxwellSlipParameters<double> p;
  p.threshold = thresholds(m);
  for (double d : p.threshold) p.stiffness.push_back(0.05 / (d * static_cast<double>(m)) + 1e3);
  return p;
}

template <class Model>
void run(benchmark::State& state, Model& model) {
  const auto& motions = record();
  for (auto _ : state) {
    model.reset();
    double sum = 0;
    for (const auto& m : motions) sum += model.step(m);
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) *
                          static_cast<std::int64_t>(motions.size()));
}

void BM_MaxwellSlip(benchmark::State& state) {
  const auto m = static_cast<std::size_t>(state.range(0));
  friction::MaxwellSlip<double> model(maxwell_slip(m));
  run(state, model);
  state.counters["s_per_operator_sample"] = benchmark::Counter(
      static_cast<double>(m * kSamples),
      benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_MaxwellSlip)->Arg(4)->Arg(10)->Arg(32);

void BM_Dnlrx(benchmark::State& state) {
  const auto m = static_cast<std::size_t>(state.range(0));
  const auto n = static_cast<std::size_t>(state.range(1));
  const auto nx = static_cast<std::size_t>(state.range(2));
  const auto ms = maxwell_slip(m);
  friction::DnlrxParameters<double> p;
  p.threshold = ms.threshold;
  p.spring_order = n;
  for (std::size_t i = 0; i < m; ++i)
    for (std::size_t j = 0; j <= n; ++j)
      p.spring_filter.push_back(ms.stiffness[i] / static_cast<double>(j + 1));
  for (std::size_t j = 0; j <= nx; ++j) p.input_filter.push_back(1e3 / static_cast<double>(j + 1));
  friction::Dnlrx<double> model(p);
  run(state, model);
}
BENCHMARK(BM_Dnlrx)->Args({10, 2, 2})->Args({4, 2, 2})->Args({32, 2, 2});

void BM_Gms(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto ms = maxwell_slip(n);
  friction::GmsParameters<double> p;
  p.stiffness = ms.stiffness;
  const double total = ms.sliding_force();
  for (std::size_t i = 0; i < n; ++i) p.share.push_back(ms.stiffness[i] * ms.threshold[i] / total);
  p.curve = {total, 1.3 * total, 1e-4, 2.0};
  p.attraction = 100.0;
  p.viscous = 50.0;
  friction::Gms<double> model(p);
  run(state, model);
}
BENCHMARK(BM_Gms)->Arg(4)->Arg(10);

void BM_StaticFriction(benchmark::State& state) {
  friction::StaticFriction<double> model({{0.4, 0.5, 1e-4, 2.0}, 50.0});
  run(state, model);
}
BENCHMARK(BM_StaticFriction);

// Maxwell Slip M = 10 with viscous, stribeck, asymmetry and offset pieces.
void BM_ExtendedMaxwellSlip(benchmark::State& state) {
  friction::ExtensionParameters<double> p;
  p.viscous = {{50.0}};
  p.stribeck = {{0.0, 1e-4, 2.0}};
  p.asymmetry = {{0.1}};
  p.offset = {{0.01}};
  friction::MaxwellSlip<double> base(maxwell_slip(10));
  p.stribeck->static_force = 1.3 * base.parameters().sliding_force();
  friction::Extended<friction::MaxwellSlip<double>> model(base, p);
  run(state, model);
}
BENCHMARK(BM_ExtendedMaxwellSlip);

}  // namespace
