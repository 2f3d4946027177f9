// Writes the bench records of data/bench/ with the independent simulator (truth_simulator.hpp):
// three records of different character, 10 000 samples each, an estimation and a validation run:
//   envelope   presliding loops growing into sliding and shrinking back (two carriers);
//   strokes    strokes at five speeds over more than a decade, with rests and presliding loops;
//   multisine  five frequencies over a decade with random phases.
// The system is a GMS-like one with eight elements (not the Maxwell Slip model the methods fit),
// Fc 12 N, thresholds 0.2-25 um, a 10 nm encoder, white force noise of 0.25 % of Fc, 1 kHz.
// Usage: make_bench_records DIR   (writes DIR/<name>/est.csv and val.csv: time,displacement,force)
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <string>

#include "truth_simulator.hpp"

namespace {

truth::System bench_system() {
  truth::System s;
  s.coulomb = 12.0;
  const double thresholds[] = {0.2e-6, 0.5e-6, 1.1e-6, 2.4e-6, 4.5e-6, 8e-6, 14e-6, 25e-6};
  const double shares[] = {0.16, 0.14, 0.15, 0.12, 0.13, 0.1, 0.11, 0.09};
  for (int i = 0; i < 8; ++i)
    s.elements.push_back({shares[i] * s.coulomb / thresholds[i], shares[i]});
  return s;
}

std::unique_ptr<truth::Excitation> motion(const std::string& kind, int run, double duration) {
  std::mt19937_64 gen(1000 + static_cast<unsigned>(run));
  std::uniform_real_distribution<double> u(0, 1);
  if (kind == "envelope") {
    truth::EnvelopeProgram p;
    p.amplitude = 120e-6;
    p.e_min = 0.03;
    p.f1 = (18 + 6 * u(gen)) / duration;
    p.f2 = p.f1 * (2.1 + 0.5 * u(gen));
    p.fe = (2.5 + u(gen)) / duration;
    p.psi = 2 * std::numbers::pi * u(gen);
    return truth::make_envelope(p);
  }
  if (kind == "strokes") {
    truth::StrokeProgram p;
    p.start = -1;
    const double speeds[] = {5e-5, 1.2e-4, 3e-4, 7e-4, 1.6e-3};
    double direction = run ? -1 : 1;
    p.velocity.push_back(0);
    p.duration.push_back(0.2);
    for (int round = 0; round < 3; ++round)
      for (int j = 0; j < 5; ++j) {
        const double s = speeds[(j * 3 + round + run) % 5];
        for (auto [v, d] : {std::pair{direction * s, 150e-6 / s},
                            {0.0, 0.12},
                            {-direction * 2e-5, 3e-6 / 2e-5},
                            {direction * 2e-5, 3e-6 / 2e-5},
                            {0.0, 0.12}}) {
          p.velocity.push_back(v);
          p.duration.push_back(d);
        }
        direction = -direction;
      }
    p.velocity.push_back(0);
    p.duration.push_back(20);
    p.width = 4e-3;
    return truth::make_strokes(p);
  }
  truth::MultisineProgram p;
  for (int j = 0; j < 5; ++j) {
    const double f = (3.0 / duration) * std::pow(10.0, j / 4.0 + 0.1 * u(gen));
    p.frequency.push_back(f);
    p.amplitude.push_back(60e-6 / std::pow(f * duration / 3.0, 0.7));
    p.phase.push_back(2 * std::numbers::pi * u(gen));
  }
  return truth::make_multisine(p);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s DIR\n", argv[0]);
    return 2;
  }
  const truth::System system = bench_system();
  for (const std::string kind : {"envelope", "strokes", "multisine"}) {
    for (int run = 0; run < 2; ++run) {
      truth::Measurement m;
      m.sampling_rate = 1000;
      m.samples = 10000;
      m.warm_up = 1.0;
      m.quantum = 10e-9;
      m.noise_sigma = 0.0025 * system.coulomb;
      m.noise_seed = 77 + static_cast<unsigned>(run) + 10 * kind.size();
      const auto x = motion(kind, run, 10.0);
      const truth::Trace t = truth::simulate(system, *x, nullptr, m);
      const std::filesystem::path dir = std::filesystem::path(argv[1]) / kind;
      std::filesystem::create_directories(dir);
      std::ofstream out(dir / (run ? "val.csv" : "est.csv"));
      out << "time,displacement,force\n";
      char line[128];
      for (std::size_t k = 0; k < t.time.size(); ++k) {
        std::snprintf(line, sizeof line, "%.4f,%.9g,%.7g\n", t.time[k], t.position[k], t.force[k]);
        out << line;
      }
    }
  }
  return 0;
}
