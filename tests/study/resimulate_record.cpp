// resimulate_record: one record of the discovery study's plan, simulated again with a part of
// its measurement changed, to tell which part of a record biases an estimate (run by hand).
//
//   resimulate_record SEED ID DIR [--no-encoder] [--no-noise] [--rate-factor K]
//
// writes DIR/estimation.csv, DIR/validation.csv, DIR/read-options.txt (the CLI options the files
// need) and DIR/truth.json, like the study's own record directory; the same system, motions and
// normal programs.  --no-encoder: the displacement unquantised; --no-noise: force noise of
// 1e-6 Fc, white (not zero: a fit's standard errors stay defined); --rate-factor K: K times the
// sampling rate over the same durations.  E.g. README, "The discovery study's coverage".
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <string>

#include "study_design.hpp"

int main(int argc, char** argv) {
  using namespace truth;
  if (argc < 4) {
    std::fprintf(stderr, "usage: %s SEED ID DIR [--no-encoder] [--no-noise] [--rate-factor K]\n",
                 argv[0]);
    return 2;
  }
  try {
    const std::uint64_t seed = std::strtoull(argv[1], nullptr, 0);
    const std::string id = argv[2];
    const std::filesystem::path dir = argv[3];
    bool encoder = true, noise = true;
    double rate_factor = 1;
    for (int i = 4; i < argc; ++i) {
      const std::string a = argv[i];
      if (a == "--no-encoder") {
        encoder = false;
      } else if (a == "--no-noise") {
        noise = false;
      } else if (a == "--rate-factor" && i + 1 < argc) {
        rate_factor = std::strtod(argv[++i], nullptr);
        if (!(rate_factor >= 1)) throw std::invalid_argument("--rate-factor must be >= 1");
      } else {
        throw std::invalid_argument("unknown argument '" + a + "'");
      }
    }
    const std::optional<RecordSpec> spec = plan_record(seed, id);
    if (!spec) {
      std::fprintf(stderr, "error: no record '%s' in the plan of seed %s\n", id.c_str(), argv[1]);
      return 1;
    }
    StudyRecord r = make_record(*spec);
    if (!encoder || !noise || rate_factor != 1) {
      for (Measurement* m : {&r.estimation, &r.validation}) {
        if (!encoder) m->quantum = 0;
        if (!noise) m->noise_sigma = 1e-6 * r.system.coulomb, m->noise_phi = 0;
        m->sampling_rate *= rate_factor;
        m->samples = static_cast<std::size_t>(static_cast<double>(m->samples) * rate_factor);
      }
      const NormalProgram* ne = r.normal_estimation ? &*r.normal_estimation : nullptr;
      const NormalProgram* nv = r.normal_validation ? &*r.normal_validation : nullptr;
      r.trace_estimation = simulate(r.system, *r.motion_estimation, ne, r.estimation);
      r.trace_validation = simulate(r.system, *r.motion_validation, nv, r.validation);
    }
    std::filesystem::create_directories(dir);
    write_csv(r, true, (dir / "estimation.csv").string());
    write_csv(r, false, (dir / "validation.csv").string());
    std::ofstream(dir / "read-options.txt") << r.read_options() << "\n";
    write_truth(r, (dir / "truth.json").string());
    std::printf("%s\n", r.summary().c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
