// Support for the method studies (test_method_studies.cpp): synthetic records of a known model
// with a known noise realisation, the truth of each method's parameters under the names its
// report uses, and per-parameter coverage counts.
//
// Every record is built the way an experiment would be: a displacement excitation from
// excitation.hpp, the model run from some initial state (the methods must estimate it), then
// white Gaussian force noise from friction::NormalSource.  The noise is kept, so the floor any
// model can reach on the record, RSS/SSS of the noise itself, is known exactly rather than
// estimated.
#pragma once

#include <cmath>
#include <cstdint>
#include <iomanip>
#include <map>
#include <ostream>
#include <random>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "friction/dnlrx.hpp"
#include "friction/excitation.hpp"
#include "friction/identification.hpp"
#include "friction/lugre.hpp"
#include "friction/maxwell_slip.hpp"
#include "friction/record.hpp"
#include "friction/simulate.hpp"

namespace friction::studies {

/// A synthetic record and the noise that was added to its force.
struct NoisyRecord {
  Record record;
  std::vector<double> noise;  ///< [N], record.force = noiseless force + noise
};

/// 100 * sum(e^2) / sum(f^2): RSS/SSS % of `e` relative to the force `f`.
inline double rss_sss_percent(std::span<const double> e, std::span<const double> f) {
  double a = 0, b = 0;
  for (std::size_t k = 0; k < e.size(); ++k) a += e[k] * e[k], b += f[k] * f[k];
  return 100.0 * a / b;
}

/// The noise floor of a record: RSS/SSS % of the noise that was added to it.
inline double noise_floor_percent(const NoisyRecord& r) {
  return rss_sss_percent(r.noise, r.record.force);
}

/// Runs `model` (already reset to its initial state) over the excitation and adds noise of
/// standard deviation `sigma` [N] drawn from NormalSource(seed).
template <class Model>
NoisyRecord noisy_record(Model& model, const Signal& excitation, double sigma, std::uint64_t seed,
                         const std::string& source) {
  NoisyRecord r;
  r.record.time = excitation.time;
  r.record.displacement = excitation.displacement;
  r.record.source = source;
  r.record.force = simulate(model, std::span<const double>(r.record.time),
                            std::span<const double>(r.record.displacement));
  NormalSource normal(seed);
  r.noise.resize(r.record.size());
  for (std::size_t k = 0; k < r.noise.size(); ++k) {
    r.noise[k] = sigma * normal();
    r.record.force[k] += r.noise[k];
  }
  return r;
}

/// Uniform deviate in [-1, 1) from a NormalSource's engine would couple the two streams; a
/// separate generator keeps the initial states independent of the noise.
class UniformSource {
 public:
  explicit UniformSource(std::uint64_t seed) : engine_(seed) {}
  double operator()() { return 2.0 * (static_cast<double>(engine_() >> 11) * 0x1.0p-53) - 1.0; }

 private:
  std::mt19937_64 engine_;
};

/// The true values under the names the reports use (nlr.cpp, dnlrx_identification.cpp, lg.cpp).
using Truth = std::map<std::string, double>;

inline Truth truth_of(const MaxwellSlipParameters<double>& p) {
  Truth t;
  for (std::size_t i = 0; i < p.size(); ++i) {
    t["stiffness[" + std::to_string(i + 1) + "]"] = p.stiffness[i];
    t["threshold[" + std::to_string(i + 1) + "]"] = p.threshold[i];
  }
  return t;
}

inline Truth truth_of(const DnlrxParameters<double>& p) {
  Truth t;
  for (std::size_t i = 0; i < p.size(); ++i) {
    t["threshold[" + std::to_string(i + 1) + "]"] = p.threshold[i];
    for (std::size_t j = 0; j < p.spring_taps(); ++j)
      t["spring_filter[" + std::to_string(i + 1) + "," + std::to_string(j) + "]"] = p.theta(i, j);
  }
  for (std::size_t j = 0; j < p.input_taps(); ++j)
    t["input_filter[" + std::to_string(j) + "]"] = p.input_filter[j];
  return t;
}

inline Truth truth_of(const LuGreParameters<double>& p) {
  Truth t;
  const auto theta = p.to_array();
  for (std::size_t j = 0; j < theta.size(); ++j) t[kLuGreParameterNames[j]] = theta[j];
  return t;
}

/// Per-parameter coverage of the reported 95 % intervals over a series of fits.
struct Coverage {
  struct Count {
    int inside = 0;     ///< fits whose interval contains the truth
    int no_error = 0;   ///< fits that reported no standard error (interval = the value)
    double sum_z = 0;   ///< sum of (estimate - truth) / standard_error, for the mean bias
    double sum_z2 = 0;  ///< and its spread (1 for calibrated intervals)
    int z_count = 0;
  };
  Truth truth;
  std::map<std::string, Count> counts;
  int fits = 0;
  std::vector<std::string> unmatched;  ///< reported names without a truth, or the reverse

  explicit Coverage(Truth t) : truth(std::move(t)) {
    for (const auto& [name, value] : truth) counts[name];
  }

  void add(const IdentificationReport& report) {
    ++fits;
    std::map<std::string, bool> seen;
    for (const auto& e : report.parameters) {
      const auto it = truth.find(e.name);
      if (it == truth.end()) {
        unmatched.push_back("reported but not true: " + e.name);
        continue;
      }
      seen[e.name] = true;
      auto& c = counts[e.name];
      const double v = it->second;
      // The interval as reported; a parameter without a standard error has lower = upper = value
      // and so contains the truth only by accident: it counts as a miss, not as a skip.
      if (e.lower95 <= v && v <= e.upper95) ++c.inside;
      if (e.standard_error > 0) {
        // Positive parameters get log-normal intervals (value * exp(+-1.96 se_log)), so the
        // standardised error is taken on the scale the interval was built on.
        const bool log_scale =
            e.value > 0 && v > 0 &&
            std::abs(std::sqrt(e.lower95 * e.upper95) - e.value) < 1e-6 * e.value;
        const double z = log_scale ? std::log(e.value / v) / std::log(e.upper95 / e.value) * 1.96
                                   : (e.value - v) / e.standard_error;
        c.sum_z += z, c.sum_z2 += z * z, ++c.z_count;
      } else {
        ++c.no_error;
      }
    }
    for (const auto& [name, value] : truth)
      if (!seen.count(name)) unmatched.push_back("true but not reported: " + name);
  }

  double fraction(const std::string& name) const {
    return fits == 0 ? 0.0 : static_cast<double>(counts.at(name).inside) / fits;
  }

  void print(std::ostream& os, const std::string& title) const {
    os << title << ": coverage of the reported 95 % intervals over " << fits << " fits\n";
    int inside = 0;
    for (const auto& [name, c] : counts) {
      const double mean = c.z_count ? c.sum_z / c.z_count : 0.0;
      const double rms = c.z_count ? std::sqrt(c.sum_z2 / c.z_count) : 0.0;
      os << "  " << std::left << std::setw(22) << name << std::right << std::setw(3) << c.inside
         << "/" << fits << "  true " << std::setw(11) << std::setprecision(5) << truth.at(name)
         << "  mean z " << std::setw(7) << std::setprecision(3) << mean << "  rms z "
         << std::setw(6) << rms;
      if (c.no_error) os << "  (no standard error in " << c.no_error << ")";
      os << "\n";
      inside += c.inside;
    }
    os << "  pooled " << inside << "/" << fits * static_cast<int>(counts.size()) << "\n";
  }
};

}  // namespace friction::studies
