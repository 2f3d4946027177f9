// resimulate_record: one record of the discovery study's plan, simulated again with a part of
// its measurement changed, to tell which part of a record biases an estimate (run by hand).
//
//   resimulate_record SEED ID DIR [--no-encoder] [--no-noise] [--rate-factor K]
//                     [--exact-derivatives] [--independent-design] [--noise-seed S]
//                     [--encoder-phase P]
//
// writes DIR/estimation.csv, DIR/validation.csv, DIR/read-options.txt (the CLI options the files
// need) and DIR/truth.json, like the study's own record directory; the same system, motions and
// normal programs.  --no-encoder: the displacement unquantised; --no-noise: force noise of
// 1e-6 Fc, white (not zero: a fit's standard errors stay defined); --rate-factor K: K times the
// sampling rate over the same durations; --exact-derivatives: DIR/exact-estimation.csv and
// DIR/exact-validation.csv, the exact v(t_k) and a(t_k) [m/s, m/s^2] of each record;
// --noise-seed S: another realisation of the force noise (and of an analog sensor's), the same
// system and motions, for a Monte-Carlo look at an estimate's spread against its standard error;
// --encoder-phase P: P quanta (0 <= P < 1) added to the encoder's offset, the same motion read by
// an encoder mounted a fraction of a line further on (what the quantisation alone does to an
// estimate);
// --independent-design: the validation motion of a study run before 2026-11-29 (study_design.hpp,
// ValidationDesign).  It prints the
// true elements (k_i and Delta_i = alpha_i Fc / k_i, for a model file of the true system) and the
// validation record's floors: the noise's, the reachable one (the sampled true system on the
// recorded displacement, its speed-dependent terms fed the best fixed window's estimates), and
// the same fed the exact v and a (the sampled system's own error).  E.g. README, "The discovery
// study's coverage".
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>

#include "study_design.hpp"

int main(int argc, char** argv) {
  using namespace truth;
  if (argc < 4) {
    std::fprintf(stderr, "usage: %s SEED ID DIR [--no-encoder] [--no-noise] [--rate-factor K] "
                 "[--exact-derivatives] [--independent-design] [--noise-seed S] "
                 "[--encoder-phase P]\n",
                 argv[0]);
    return 2;
  }
  try {
    const std::uint64_t seed = std::strtoull(argv[1], nullptr, 0);
    const std::string id = argv[2];
    const std::filesystem::path dir = argv[3];
    bool encoder = true, noise = true, exact_derivatives = false;
    double rate_factor = 1;
    std::optional<std::uint64_t> noise_seed;
    double encoder_phase = 0;
    ValidationDesign validation = ValidationDesign::another_realisation;
    for (int i = 4; i < argc; ++i) {
      const std::string a = argv[i];
      if (a == "--no-encoder") {
        encoder = false;
      } else if (a == "--exact-derivatives") {
        exact_derivatives = true;
      } else if (a == "--independent-design") {
        validation = ValidationDesign::independent_design;
      } else if (a == "--no-noise") {
        noise = false;
      } else if (a == "--encoder-phase" && i + 1 < argc) {
        encoder_phase = std::strtod(argv[++i], nullptr);
        if (!(encoder_phase >= 0 && encoder_phase < 1))
          throw std::invalid_argument("--encoder-phase must be in [0, 1)");
      } else if (a == "--noise-seed" && i + 1 < argc) {
        noise_seed = std::strtoull(argv[++i], nullptr, 0);
      } else if (a == "--rate-factor" && i + 1 < argc) {
        rate_factor = std::strtod(argv[++i], nullptr);
        if (!(rate_factor >= 1)) throw std::invalid_argument("--rate-factor must be >= 1");
      } else {
        throw std::invalid_argument("unknown argument '" + a + "'");
      }
    }
    const std::optional<RecordSpec> spec = plan_record(seed, id, validation);
    if (!spec) {
      std::fprintf(stderr, "error: no record '%s' in the plan of seed %s\n", id.c_str(), argv[1]);
      return 1;
    }
    StudyRecord r = make_record(*spec);
    if (!encoder || !noise || rate_factor != 1 || noise_seed || encoder_phase != 0) {
      for (Measurement* m : {&r.estimation, &r.validation}) {
        m->x_offset += encoder_phase * m->quantum;
        if (noise_seed) m->noise_seed = splitmix(m->noise_seed ^ *noise_seed);
        if (!encoder) m->quantum = 0;
        if (!noise) m->noise_sigma = 1e-6 * r.system.coulomb, m->noise_phi = 0;
        m->sampling_rate *= rate_factor;
        m->samples = static_cast<std::size_t>(static_cast<double>(m->samples) * rate_factor);
      }
      simulate_traces(r);
    }
    std::filesystem::create_directories(dir);
    write_csv(r, true, (dir / "estimation.csv").string());
    write_csv(r, false, (dir / "validation.csv").string());
    std::ofstream(dir / "read-options.txt") << r.read_options() << "\n";
    write_truth(r, (dir / "truth.json").string());
    if (exact_derivatives)
      for (const auto& [name, t] : {std::pair{"exact-estimation.csv", &r.trace_estimation},
                                    std::pair{"exact-validation.csv", &r.trace_validation}}) {
        std::ofstream o(dir / name);
        o.precision(17);
        o << "velocity,acceleration\n";
        for (std::size_t k = 0; k < t->velocity.size(); ++k)
          o << t->velocity[k] << "," << t->acceleration[k] << "\n";
      }
    std::printf("%s\n", r.summary().c_str());
    std::printf("elements (k [N/m], Delta [m]):");
    for (std::size_t i = 0; i < r.system.elements.size(); ++i)
      std::printf(" %.17g %.17g", r.system.elements[i].stiffness, r.system.threshold(i));
    std::printf("\n");
    const Trace& t = r.trace_validation;
    const NormalProgram* nv = r.normal_validation ? &*r.normal_validation : nullptr;
    const Derivatives estimated = best_local_derivatives(t);
    const std::vector<double> reachable =
        reachable_force(r.system, t, nv, r.validation, &estimated);
    const std::vector<double> exact = reachable_force(r.system, t, nv, r.validation, nullptr);
    double noise_ss = 0, gap = 0, gap_exact = 0, total = 0;
    for (std::size_t k = 0; k < t.force.size(); ++k) {
      noise_ss += (t.force[k] - t.clean[k]) * (t.force[k] - t.clean[k]);
      gap += (t.force[k] - reachable[k]) * (t.force[k] - reachable[k]);
      gap_exact += (t.force[k] - exact[k]) * (t.force[k] - exact[k]);
      total += t.force[k] * t.force[k];
    }
    std::printf("validation floors: noise %.4g %%, reachable %.4g %%, with exact v and a %.4g %%\n",
                100 * noise_ss / total, 100 * gap / total, 100 * gap_exact / total);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
