// Displacement excitations of the kind a real friction identification experiment uses.
//
// * presliding: sinusoids whose amplitude falls geometrically cycle after cycle, starting from a
//   sliding stroke's end.  Every reversal point is nested inside the previous one, which is what
//   exercises nonlocal memory: a model without it (LuGre) cannot follow the inner loops.
// * strokes: back-and-forth strokes at several constant speeds with smooth (raised-cosine)
//   reversals and a short dwell at each end, so sliding friction is seen at every speed in both
//   directions and each reversal passes through presliding.
// * multisine: a Schroeder-phased sum of sinusoids, log-spaced in frequency, so velocity and
//   acceleration are rich (good for inertia, lag and delay).
// * combined: strokes followed by presliding loops: one experiment that visits both regimes, the
//   single-record setting of Rizos & Fassois.
//
// Everything is deterministic for a given seed: the generator is std::mt19937_64, whose sequence
// the standard fixes, and normal deviates come from our own Box-Muller transform rather than
// std::normal_distribution, whose algorithm differs between standard libraries.
#pragma once

#include <cstdint>
#include <random>
#include <string>
#include <vector>

namespace friction {

enum class ExcitationKind { Presliding, Strokes, Multisine, Combined };

/// Parses "presliding", "strokes", "multisine", "combined"; throws InvalidParameter otherwise.
ExcitationKind parse_excitation_kind(const std::string& name);
std::string to_string(ExcitationKind kind);

struct ExcitationOptions {
  ExcitationKind kind = ExcitationKind::Combined;
  double rate = 1000.0;                 ///< sampling rate [Hz]
  double presliding_amplitude = 20e-6;  ///< largest presliding amplitude [m]
  double presliding_frequency = 2.0;    ///< presliding sinusoid frequency [Hz]
  int presliding_cycles = 8;            ///< cycles of decreasing amplitude
  double presliding_decay = 0.75;       ///< amplitude ratio of successive cycles, in (0, 1)
  double stroke = 1e-3;                 ///< stroke length, end to end [m]
  std::vector<double> speeds{2e-4, 5e-4, 1e-3, 2e-3, 5e-3};  ///< stroke speeds [m/s]
  double dwell = 0.05;                                       ///< rest at each stroke end [s]
  double reversal_time = 0.02;           ///< duration of each raised-cosine speed change [s]
  double multisine_amplitude = 0.5e-3;   ///< peak displacement of the multisine [m]
  double multisine_min_frequency = 0.2;  ///< [Hz]
  double multisine_max_frequency = 10;   ///< [Hz]
  int multisine_components = 16;
  double multisine_duration = 10.0;  ///< [s]
  std::uint64_t seed = 1;            ///< phases of the multisine
  void validate() const;
};

struct Signal {
  std::vector<double> time;          ///< [s]
  std::vector<double> displacement;  ///< [m]
};

/// Displacement samples of the chosen excitation, starting at x = 0, t = 0.
Signal make_excitation(const ExcitationOptions& options);

/// Deterministic normal deviates (Box-Muller on mt19937_64).
class NormalSource {
 public:
  explicit NormalSource(std::uint64_t seed) : engine_(seed) {}
  double operator()();  ///< standard normal deviate

 private:
  std::mt19937_64 engine_;
  double spare_ = 0.0;
  bool has_spare_ = false;
};

/// Adds white Gaussian noise of standard deviation `sigma` to `signal` in place.
void add_white_noise(std::vector<double>& signal, double sigma, NormalSource& source);

/// Rounds `signal` to multiples of `resolution` (an encoder's quantisation), in place.
void quantise(std::vector<double>& signal, double resolution);

}  // namespace friction
