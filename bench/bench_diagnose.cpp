// Wall time of a whole diagnosis (baseline NLR, evidence, greedy candidate fits, backward pass) on
// a 10,000 + 10,000 sample pair at 1 kHz: a 4-operator Maxwell Slip system with a viscous term
// and white force noise.  Target: < 30 s on one core.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

#include "friction/diagnose.hpp"
#include "friction/simulate.hpp"

namespace {

friction::Record make_record(std::size_t n, double t0, unsigned seed) {
  friction::Record r;
  r.time.resize(n);
  r.displacement.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const double t = t0 + 1e-3 * static_cast<double>(k);
    r.time[k] = t;
    r.displacement[k] =
        60e-6 * (0.55 + 0.45 * std::sin(2 * M_PI * 0.23 * t)) *
        (0.7 * std::sin(2 * M_PI * 1.3 * t) + 0.3 * std::sin(2 * M_PI * 3.1 * t + 1.1));
  }
  friction::MaxwellSlip<double> m({{4e4, 3e4, 2e4, 1e4}, {1e-6, 3e-6, 7e-6, 15e-6}});
  r.force = friction::simulate(m, std::span<const double>(r.time),
                               std::span<const double>(r.displacement));
  std::mt19937 gen(seed);
  std::normal_distribution<double> noise(0.0, 2e-3);
  for (std::size_t k = 0; k < n; ++k) {
    const double v = k ? (r.displacement[k] - r.displacement[k - 1]) / 1e-3 : 0.0;
    r.force[k] += 40.0 * v + noise(gen);
  }
  return r;
}

void BM_Diagnose10k(benchmark::State& state) {
  const friction::Record est = make_record(10000, 0.0, 1);
  const friction::Record val = make_record(10000, 10.0, 2);
  std::size_t findings = 0;
  double baseline = 0;
  for (auto _ : state) {
    const friction::Diagnosis d = friction::diagnose(est, val);
    findings = d.findings.size();
    baseline = d.baseline_seconds;
    benchmark::DoNotOptimize(d.final_validation_percent);
  }
  state.counters["findings"] = static_cast<double>(findings);
  state.counters["baseline_s"] = baseline;
}
BENCHMARK(BM_Diagnose10k)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace
