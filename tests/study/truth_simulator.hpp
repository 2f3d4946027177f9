// An independent simulator of friction experiments: the truth of the discovery study.
//
// It shares no code and no convention with the library.  It includes no friction/ header (the
// CMake target that builds it cannot see include/, and tests/CMakeLists.txt refuses to configure
// when one of its files names friction/); it has its own excitations, its own element model, its
// own integrator, its own noise and its own file writer.  What it simulates is a machine axis as a
// demanding user would meet it:
//
// Motion.  The displacement program x(t) is analytic, so velocity v(t) and acceleration a(t) are
// exact at any instant (in particular at the sample instants, which the study uses to judge
// differentiators).  Three families: an envelope (presliding loops growing into sliding and
// shrinking back), strokes at several constant speeds with rests and small presliding loops between
// them (the speed changes are smooth tanh steps whose integral is written in closed form), and a
// multisine (a decade of frequencies with random phases).
//
// Friction.  A GMS-like system of n elements (Al-Bender, Lampaert & Swevers 2005, in its limit of
// instantaneous slip): element i carries a force F_i; it sticks (dF_i = k_i dx) while
//     -alpha_i G_-(t) <= F_i <= alpha_i G_+(t),
// and slips along the limit it reaches.  G_+-(t) = Fc * L(t) * (1 +- asymmetry) is the element's
// slip level, where L(t) multiplies every level effect present:
//     Stribeck      g(|v_l|)/Fc = 1 + (Fs/Fc - 1) exp(-(|v_l|/vs)^q)
//     drift         1 + r t          (t since the record's start; 1 before it)
//     position      1 + rho sin(2 pi x / lambda + phi)   (x the absolute position)
//     normal load   N(t) / N0        (friction coefficient mu = Fc / N0)
// v_l is the velocity the speed-dependent parts feel: v itself, or, with frictional lag, the
// output of dv_l/dt = (v - v_l)/tau.  The recorded force is
//     F = sum_i F_i + sigma2 v_l + m a + c
// (viscous, inertia, offset).  With a delay D the force sampled at t_k is the one the motion at
// t_k - D produced; the displacement is sampled at t_k.
//
// Integration.  On a grid `refine` times finer than the sampling (>= 10), aligned with the motion
// instants t_k - D: each fine step moves every element by k_i (x(t+h) - x(t)) and clamps it to its
// limits at t + h (the exact update while x is monotone over the step and the level constant);
// v_l takes a classical Runge-Kutta step driven by the exact v(t).  The error comes from the
// reversals inside a step and from the level's change over a step; it falls as the grid is refined
// (test_truth_simulator shows it).
//
// Measurement.  The encoder quantises x + x_offset (plus white sensor noise, for an analog sensor)
// to multiples of `quantum`; the force gets
// stationary noise of standard deviation sigma, white or AR(1) with coefficient phi
// (e_k = phi e_{k-1} + sqrt(1 - phi^2) sigma w_k).  The normal force, when recorded, is exact.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace truth {

/// A displacement program with exact derivatives, defined for all t.
class Excitation {
 public:
  virtual ~Excitation() = default;
  virtual double x(double t) const = 0;
  virtual double v(double t) const = 0;
  virtual double a(double t) const = 0;
  virtual std::string kind() const = 0;
};

/// x = X e(t) c(t): the envelope e = e_min + (1 - e_min)(1 - cos(2 pi fe t + psi))/2 takes the
/// carrier c = w1 sin(2 pi f1 t) + w2 sin(2 pi f2 t + chi) from presliding loops into sliding and
/// back.
struct EnvelopeProgram {
  double amplitude = 1e-4, e_min = 0.05, fe = 0.2, psi = 0.0;
  double f1 = 1.0, f2 = 2.3, w1 = 0.7, w2 = 0.3, chi = 1.1;
};
std::unique_ptr<Excitation> make_envelope(const EnvelopeProgram& p);

/// A velocity that is a sum of smooth steps: v(t) = sum_j du_j H((t - s_j)/w), H = (1+tanh)/2,
/// starting from rest.  `pieces` are (velocity, duration) in order from `start`.
struct StrokeProgram {
  double start = 0;
  std::vector<double> velocity, duration;
  double width = 1e-3;  ///< w [s]
};
std::unique_ptr<Excitation> make_strokes(const StrokeProgram& p);

/// x = sum_j A_j sin(2 pi f_j t + phi_j).
struct MultisineProgram {
  std::vector<double> amplitude, frequency, phase;
};
std::unique_ptr<Excitation> make_multisine(const MultisineProgram& p);

/// A recorded normal force N(t) = N0 (1 + b1 sin(2 pi f1 t + p1) + b2 sin(2 pi f2 t + p2)).
struct NormalProgram {
  double mean = 1, b1 = 0, f1 = 0.1, p1 = 0, b2 = 0, f2 = 0.37, p2 = 0;
  double at(double t) const;
};

struct Element {
  double stiffness;  ///< k_i [N/m]
  double share;      ///< alpha_i; the shares sum to 1
};

/// The effects of methods.md section 7 in this simulator's own terms (see the header comment).
struct Effects {
  struct Stribeck {
    double static_force, velocity, exponent;  ///< Fs [N] (at the nominal level), vs [m/s], q
  };
  struct Position {
    double relative_amplitude, wavelength, phase;  ///< rho, lambda [m], phi [rad]
  };
  std::optional<double> viscous;  ///< sigma2 [N s/m]
  std::optional<Stribeck> stribeck;
  std::optional<double> lag_time;   ///< tau [s]
  std::optional<double> asymmetry;  ///< a
  std::optional<double> offset;     ///< c [N]
  std::optional<double> mass;       ///< m [kg]
  std::optional<Position> position;
  std::optional<double> drift_rate;  ///< r [1/s]
  std::optional<double> delay;       ///< D [s]
  bool normal_load = false;          ///< the level follows N(t)/N0
};

struct System {
  std::vector<Element> elements;
  double coulomb = 1;  ///< Fc [N]: the sliding force at the nominal level
  Effects effects;
  /// The threshold of element i, alpha_i Fc / k_i [m].
  double threshold(std::size_t i) const;
};

struct Measurement {
  double sampling_rate = 1000;  ///< [Hz]
  std::size_t samples = 4000;
  double warm_up = 1.0;       ///< [s] simulated before the first sample (from a virgin state)
  double time_origin = 0;     ///< t of the first sample as written [s]
  double quantum = 1e-8;      ///< encoder step [m]; 0: no quantisation
  double x_offset = 0;        ///< added to x before quantisation [m]
  double position_noise = 0;  ///< white noise on x before quantisation (analog sensor) [m]
  double noise_sigma = 0;     ///< [N]
  double noise_phi = 0;       ///< AR(1) coefficient, 0 = white
  int refine = 16;            ///< fine steps per sample, >= 10
  std::uint64_t noise_seed = 1;
};

/// One simulated record.  Times in the record run from 0 (the first sample); `time` adds
/// Measurement::time_origin.
struct Trace {
  std::vector<double> time;                 ///< [s] as written
  std::vector<double> position;             ///< quantised x + x_offset [m]
  std::vector<double> force;                ///< clean force + noise [N]
  std::vector<double> clean;                ///< the force without noise [N]
  std::vector<double> normal;               ///< N(t) [N] (empty without a normal program)
  std::vector<double> velocity;             ///< exact v(t_k) [m/s]
  std::vector<double> acceleration;         ///< exact a(t_k) [m/s^2]
  std::vector<bool> sliding;                ///< every element at a limit at t_k (motion instant)
  std::vector<double> felt_velocity;        ///< v_l at the motion instant t_k - D [m/s]
  std::vector<double> motion_acceleration;  ///< a(t_k - D) [m/s^2]
  std::vector<double> element_force;        ///< F_i at sample k, at [k * elements + i] [N]
};

/// Simulates `system` under `motion` (and `normal` when given) as `measurement` says.
Trace simulate(const System& system, const Excitation& motion, const NormalProgram* normal,
               const Measurement& measurement);

/// The force a perfect sampled model would give: the true system (effects, parameters and the
/// element forces at the first sample) stepped once per sample on the RECORDED displacement
/// (quantised, with the sensor's noise; shifted by the delay with linear interpolation, as a delay
/// model would), with the exact felt velocity and acceleration for the speed-dependent terms.
/// With a delay D the first ceil(D/Ts) samples would need displacement from before the record:
/// the replay starts from the true state at the first sample after them and returns the clean
/// force before it (a model estimates its initial state there; nothing is judged).
/// Its error against the recorded force is the floor a model driven by the measured
/// displacement can reach: force noise plus what the encoder's steps do to the elements.
std::vector<double> reachable_force(const System& system, const Trace& trace,
                                    const NormalProgram* normal, const Measurement& measurement,
                                    const struct Derivatives* estimated = nullptr);

/// Velocity and acceleration at the sample instants, estimated from the recorded displacement.
struct Derivatives {
  std::vector<double> v, a;
  int velocity_window = 0, acceleration_window = 0;  ///< half widths used
};

/// Local quadratic fits over 2m+1 samples (this simulator's own differentiator), with the half
/// widths that minimise the RMS error against the exact v(t_k), a(t_k) (an oracle: the best any
/// fixed window of this family does on this record).  With `estimated`, reachable_force uses these
/// instead of the exact values: a model must estimate them from the measured displacement too,
/// and where a large m a dominates, the exact acceleration would set a floor no model reaches.
Derivatives best_local_derivatives(const Trace& trace);

/// Root mean square of a - c b with c the least-squares scale (the part of a that a change of
/// level alone cannot explain).  `scale_free` false: RMS of a - b.
double rms_difference(const std::vector<double>& a, const std::vector<double>& b, bool scale_free);

}  // namespace truth
