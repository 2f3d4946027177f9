// The records of the discovery study (see study_design.hpp).
#include "study_design.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <numbers>
#include <random>
#include <sstream>
#include <stdexcept>
#include <variant>

namespace truth {

namespace {

constexpr double kMinimumSnr = 6.0;

class Rng {
 public:
  explicit Rng(std::uint64_t seed) : gen_(seed) {}
  double uniform(double a, double b) { return std::uniform_real_distribution<double>(a, b)(gen_); }
  double log_uniform(double a, double b) { return std::exp(uniform(std::log(a), std::log(b))); }
  int integer(int a, int b) { return std::uniform_int_distribution<int>(a, b)(gen_); }
  bool chance(double p) { return uniform(0, 1) < p; }
  double sign() { return chance(0.5) ? 1.0 : -1.0; }
  std::uint64_t seed() { return gen_(); }
  template <class V>
  void shuffle(V& v) {
    std::shuffle(v.begin(), v.end(), gen_);
  }
  template <class V>
  const typename V::value_type& pick(const V& v) {
    return v[static_cast<std::size_t>(integer(0, static_cast<int>(v.size()) - 1))];
  }

 private:
  std::mt19937_64 gen_;
};

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  const auto k = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

bool has(const std::vector<std::string>& v, const std::string& name) {
  return std::find(v.begin(), v.end(), name) != v.end();
}

// ------------------------------------------------------------------------------- excitations

// A stroke program's design: its speeds (relative to the slowest, laid out at u_min = 1), the
// stroke, the presliding loop, the rests, and the slowest speed u_min [m/s] that the first
// realisation's duration set.
struct StrokeDesign {
  std::vector<double> speeds;
  double stroke = 0, loop = 0, loop_speed = 0.5, rest = 0, u_min = 0;
};

struct MotionDraw {
  std::unique_ptr<Excitation> motion;
  bool rests = false;
  int distinct_speeds = 0;
  std::variant<EnvelopeProgram, StrokeDesign, MultisineProgram> design;
};

MotionDraw draw_envelope(Rng& rng, double travel, double duration, double max_threshold) {
  EnvelopeProgram p;
  p.amplitude = travel / 2;
  p.e_min = std::clamp(rng.uniform(0.2, 0.6) * max_threshold / p.amplitude, 0.005, 0.3);
  p.f1 = rng.uniform(12, 30) / duration;
  p.f2 = p.f1 * rng.uniform(1.7, 2.9);
  p.fe = rng.uniform(1.5, 3.0) / duration;
  p.psi = rng.uniform(0, 2 * std::numbers::pi);
  p.chi = rng.uniform(0, 2 * std::numbers::pi);
  p.w1 = rng.uniform(0.55, 0.8);
  p.w2 = 1 - p.w1;
  return {make_envelope(p), false, 10, p};
}

// Strokes of length S at n_s speeds (a decade or more apart) in shuffled rounds, directions
// alternating, each followed by a rest, a small presliding loop and another rest, from `start`.
// `rounds` rounds, or (rounds = 0) as many as it takes to cover `total` seconds at the design's
// u_min.  The pieces are laid out at u_min = 1 and scaled by the design's u_min.
StrokeProgram lay_out_strokes(Rng& rng, StrokeDesign& d, int rounds, double start, double total) {
  StrokeProgram p;
  p.start = start;
  double relative = 0;
  auto piece = [&](double v, double dur) {
    p.velocity.push_back(v);
    p.duration.push_back(dur);
    relative += dur;
  };
  double direction = rng.sign();
  piece(0.0, d.rest);
  for (int r = 0; rounds > 0 ? r < rounds : relative * (1 / d.u_min) < total; ++r) {
    rng.shuffle(d.speeds);
    for (double s : d.speeds) {
      piece(direction * s, d.stroke / s);
      piece(0.0, d.rest);
      piece(-direction * d.loop_speed, d.loop / d.loop_speed);
      piece(direction * d.loop_speed, d.loop / d.loop_speed);
      piece(0.0, d.rest);
      direction = -direction;
    }
  }
  if (rounds > 0) d.u_min = relative / total;  // [m/s]
  double shortest = 1e300;
  for (std::size_t j = 0; j < p.velocity.size(); ++j) {
    p.velocity[j] *= d.u_min;
    p.duration[j] /= d.u_min;
    shortest = std::min(shortest, p.duration[j]);
  }
  p.width = shortest / 8;
  return p;
}

MotionDraw draw_strokes(Rng& rng, double travel, double start, double total, double max_threshold) {
  StrokeDesign d;
  const int n_speeds = rng.integer(3, 6);
  const double span = std::pow(10.0, rng.uniform(0.8, 1.3));
  for (int j = 0; j < n_speeds; ++j)
    d.speeds.push_back(std::pow(span, static_cast<double>(j) / (n_speeds - 1)));
  d.stroke = travel * rng.uniform(0.6, 1.0);
  d.loop = std::min(rng.uniform(0.3, 0.8) * max_threshold, 0.2 * d.stroke);
  d.rest = rng.uniform(0.05, 0.15) * d.stroke;
  const int rounds = rng.integer(2, 4);
  const StrokeProgram p = lay_out_strokes(rng, d, rounds, start, total);
  return {make_strokes(p), true, n_speeds, d};
}

MotionDraw draw_multisine(Rng& rng, double travel, double duration) {
  MultisineProgram p;
  const int n = rng.integer(3, 6);
  const double f_lo = rng.uniform(3, 6) / duration;
  const double f_hi = f_lo * std::pow(10.0, rng.uniform(0.7, 1.2));
  const double tilt = rng.uniform(0.5, 1.0);
  double sum = 0;
  for (int j = 0; j < n; ++j) {
    const double f = rng.log_uniform(f_lo, f_hi);
    p.frequency.push_back(f);
    p.amplitude.push_back(std::pow(f / f_lo, -tilt));
    p.phase.push_back(rng.uniform(0, 2 * std::numbers::pi));
    sum += p.amplitude.back();
  }
  for (double& a : p.amplitude) a *= travel / 2 / sum;
  return {make_multisine(p), false, 10, p};
}

MotionDraw draw_motion(Family family, Rng& rng, double travel, const Measurement& m,
                       double max_threshold) {
  const double duration = static_cast<double>(m.samples) / m.sampling_rate;
  switch (family) {
    case Family::envelope:
      return draw_envelope(rng, travel, duration, max_threshold);
    case Family::multisine:
      return draw_multisine(rng, travel, duration);
    case Family::strokes:
      return draw_strokes(rng, travel, -m.warm_up, m.warm_up + duration * 1.02, max_threshold);
  }
  throw std::logic_error("draw_motion: unknown family");
}

// Another realisation of `first`'s design for measurement `m`: the multisine's amplitudes and
// frequencies with new phases, the envelope's carriers and envelope with new phases, the strokes'
// speeds, lengths, loops and rests in a new order, as many rounds as cover m's duration.  The
// motion's scales -- speeds, accelerations, amplitudes -- are the first realisation's.
MotionDraw draw_realisation(const MotionDraw& first, Rng& rng, const Measurement& m) {
  const double duration = static_cast<double>(m.samples) / m.sampling_rate;
  if (const auto* e = std::get_if<EnvelopeProgram>(&first.design)) {
    EnvelopeProgram p = *e;
    p.psi = rng.uniform(0, 2 * std::numbers::pi);
    p.chi = rng.uniform(0, 2 * std::numbers::pi);
    return {make_envelope(p), first.rests, first.distinct_speeds, p};
  }
  if (const auto* ms = std::get_if<MultisineProgram>(&first.design)) {
    MultisineProgram p = *ms;
    for (double& phase : p.phase) phase = rng.uniform(0, 2 * std::numbers::pi);
    return {make_multisine(p), first.rests, first.distinct_speeds, p};
  }
  StrokeDesign d = std::get<StrokeDesign>(first.design);
  const StrokeProgram p = lay_out_strokes(rng, d, 0, -m.warm_up, m.warm_up + duration * 1.02);
  return {make_strokes(p), first.rests, first.distinct_speeds, d};
}

NormalProgram draw_normal(Rng& rng, double mean, double duration) {
  NormalProgram n;
  n.mean = mean;
  n.b1 = rng.uniform(0.1, 0.4);
  n.f1 = rng.uniform(0.7, 2.5) / duration;
  n.p1 = rng.uniform(0, 2 * std::numbers::pi);
  n.b2 = n.b1 * rng.uniform(0.2, 0.6);
  n.f2 = n.f1 * rng.uniform(2.2, 4.1);
  n.p2 = rng.uniform(0, 2 * std::numbers::pi);
  return n;
}

// ------------------------------------------------------------------------------- magnitudes

// One injected effect's magnitude: how to read it from and write it into a system (and the
// normal programs), and its physical bounds.
struct Knob {
  std::string effect;
  std::function<double(const StudyRecord&)> get;
  std::function<void(StudyRecord&, double)> set;
  double lower, upper;  // of |magnitude|
  double snr;           // target contribution / noise
};

// The system without `effect` (the lag's partner stays).
System without(const System& s, const std::string& effect) {
  System o = s;
  Effects& e = o.effects;
  if (effect == "viscous") e.viscous.reset();
  if (effect == "stribeck") e.stribeck.reset();
  if (effect == "frictional-lag") e.lag_time.reset();
  if (effect == "asymmetry") e.asymmetry.reset();
  if (effect == "offset") e.offset.reset();
  if (effect == "inertia") e.mass.reset();
  if (effect == "position-dependence") e.position.reset();
  if (effect == "drift") e.drift_rate.reset();
  if (effect == "delay") e.delay.reset();
  if (effect == "normal-load") e.normal_load = false;
  return o;
}

std::vector<double> clean_validation(const StudyRecord& r, const System& s) {
  Measurement m = r.validation;
  m.noise_sigma = 0;
  const NormalProgram* n = r.normal_validation ? &*r.normal_validation : nullptr;
  return simulate(s, *r.motion_validation, n, m).clean;
}

double contribution_of(const StudyRecord& r, const std::string& effect) {
  return rms_difference(clean_validation(r, r.system),
                        clean_validation(r, without(r.system, effect)),
                        /*scale_free=*/true);
}

std::vector<Knob> knobs_for(StudyRecord& r, Rng& rng, double v95, double a95, double duration,
                            double ts) {
  const double fc = r.system.coulomb;
  std::vector<Knob> knobs;
  auto snr = [&](const std::string& e) {
    const bool strong = (e == "viscous" || e == "inertia") && rng.chance(0.3);
    return strong ? rng.log_uniform(60, 150) : rng.log_uniform(kMinimumSnr, 60);
  };
  Effects& fx = r.system.effects;
  for (const std::string& e : r.spec.effects) {
    if (e == "viscous") {
      fx.viscous = 0.1 * fc / v95;
      knobs.push_back({e, [](const StudyRecord& s) { return *s.system.effects.viscous; },
                       [](StudyRecord& s, double m) { s.system.effects.viscous = m; }, 0,
                       3 * fc / v95, snr(e)});
    } else if (e == "stribeck") {
      const double vs = r.median_sliding_speed * std::pow(10.0, rng.uniform(-1, 1));
      fx.stribeck = Effects::Stribeck{1.3 * fc, vs, rng.uniform(0.5, 2.5)};
      knobs.push_back({e,
                       [](const StudyRecord& s) {
                         return s.system.effects.stribeck->static_force / s.system.coulomb - 1;
                       },
                       [](StudyRecord& s, double m) {
                         s.system.effects.stribeck->static_force = (1 + m) * s.system.coulomb;
                       },
                       0.03, 2.0, snr(e)});
    } else if (e == "frictional-lag") {
      fx.lag_time = 3 * ts;
      knobs.push_back({e, [](const StudyRecord& s) { return *s.system.effects.lag_time; },
                       [](StudyRecord& s, double m) { s.system.effects.lag_time = m; }, 1.5 * ts,
                       std::min(25 * ts, 0.02 * duration), snr(e)});
    } else if (e == "asymmetry") {
      const double sign = rng.sign();
      fx.asymmetry = 0.05 * sign;
      knobs.push_back({e,
                       [](const StudyRecord& s) { return std::abs(*s.system.effects.asymmetry); },
                       [sign](StudyRecord& s, double m) { s.system.effects.asymmetry = sign * m; },
                       0.0, 0.3, snr(e)});
    } else if (e == "offset") {
      const double sign = rng.sign();
      fx.offset = 0.05 * fc * sign;
      knobs.push_back({e, [](const StudyRecord& s) { return std::abs(*s.system.effects.offset); },
                       [sign](StudyRecord& s, double m) { s.system.effects.offset = sign * m; },
                       0.0, 0.3 * fc, snr(e)});
    } else if (e == "inertia") {
      fx.mass = 0.1 * fc / a95;
      knobs.push_back({e, [](const StudyRecord& s) { return *s.system.effects.mass; },
                       [](StudyRecord& s, double m) { s.system.effects.mass = m; }, 0.0,
                       2 * fc / a95, snr(e)});
    } else if (e == "position-dependence") {
      const double lambda =
          std::max(r.travel * std::pow(10.0, rng.uniform(-1.2, -0.5)), 20 * v95 * ts);
      fx.position = Effects::Position{0.05, lambda, rng.uniform(0, 2 * std::numbers::pi)};
      knobs.push_back(
          {e, [](const StudyRecord& s) { return s.system.effects.position->relative_amplitude; },
           [](StudyRecord& s, double m) { s.system.effects.position->relative_amplitude = m; }, 0.0,
           0.3, snr(e)});
    } else if (e == "drift") {
      const double sign = rng.sign();
      fx.drift_rate = sign * 0.05 / duration;
      knobs.push_back({e,
                       [](const StudyRecord& s) { return std::abs(*s.system.effects.drift_rate); },
                       [sign](StudyRecord& s, double m) { s.system.effects.drift_rate = sign * m; },
                       0.0, 0.4 / duration, snr(e)});
    } else if (e == "delay") {
      fx.delay = 0.5 * ts;
      knobs.push_back({e, [](const StudyRecord& s) { return *s.system.effects.delay; },
                       [](StudyRecord& s, double m) { s.system.effects.delay = m; }, 0.2 * ts,
                       5 * ts, snr(e)});
    } else if (e == "normal-load") {
      fx.normal_load = true;
      knobs.push_back({e, [](const StudyRecord& s) { return s.normal_validation->b1; },
                       [](StudyRecord& s, double m) {
                         for (auto* n : {&s.normal_estimation, &s.normal_validation}) {
                           const double ratio = (*n)->b2 / (*n)->b1;
                           (*n)->b1 = m;
                           (*n)->b2 = ratio * m;
                         }
                       },
                       0.02, 0.5, snr(e)});
    } else {
      throw std::invalid_argument("truth::make_record: unknown effect '" + e + "'");
    }
  }
  return knobs;
}

// Sets every knob so that its effect contributes snr times the noise, within its bounds (three
// passes: the effects of a pair interact); then lowers the noise where a bound held a contribution
// below kMinimumSnr times it.
void calibrate(StudyRecord& r, std::vector<Knob>& knobs) {
  for (int pass = 0; pass < 3; ++pass) {
    for (Knob& k : knobs) {
      const double c = contribution_of(r, k.effect), m = k.get(r);
      const double target = k.snr * r.validation.noise_sigma;
      const double next = c > 0 ? m * target / c : k.upper;
      k.set(r, std::clamp(next, k.lower, k.upper));
    }
  }
  for (Knob& k : knobs) {
    const double c = contribution_of(r, k.effect);
    if (c < kMinimumSnr * r.validation.noise_sigma) r.validation.noise_sigma = c / kMinimumSnr;
  }
  r.estimation.noise_sigma = r.validation.noise_sigma;
}

// ------------------------------------------------------------------------------- files

FileFormat draw_format(Rng& rng, double travel, double fc, bool with_normal) {
  FileFormat f;
  if (travel >= 2e-4 && rng.chance(0.5)) {
    f.displacement_unit = "mm";
    f.displacement_factor = 1e-3;
  } else if (travel < 5e-5 && rng.chance(0.5)) {
    f.displacement_unit = "um";
    f.displacement_factor = 1e-6;
  }
  if (fc < 0.5 && rng.chance(0.5)) {
    f.force_unit = "mN";
    f.force_factor = 1e-3;
  } else if (fc > 200 && rng.chance(0.5)) {
    f.force_unit = "kN";
    f.force_factor = 1e3;
  }
  if (rng.chance(0.15)) {
    f.time_unit = "ms";
    f.time_factor = 1e-3;
  }
  if (rng.chance(1.0 / 6)) {
    f.names_need_columns_option = true;
    f.time_name = "clock";
    f.displacement_name = "enc_pos";
    f.force_name = "load_cell";
    f.normal_name = "fz";
  } else {
    std::vector<std::string> time = {"time", "t", "Time"}, disp = {"displacement", "position", "x"},
                             force = {"force", "friction", "F"};
    if (f.time_unit == "s") time.push_back("time_s");
    if (f.displacement_unit == "m") disp.push_back("position_m");
    if (f.force_unit == "N") force.push_back("friction_force_N");
    f.time_name = rng.pick(time);
    f.displacement_name = rng.pick(disp);
    f.force_name = rng.pick(force);
    f.normal_name =
        f.force_unit == "N"
            ? rng.pick(std::vector<std::string>{"normal", "normal_force", "normal_force_N"})
            : rng.pick(std::vector<std::string>{"normal", "normal_force"});
  }
  (void)with_normal;
  f.extra_column = rng.chance(0.3);
  f.reversed_order = rng.chance(0.3);
  f.force_sign = rng.chance(1.0 / 6) ? -1 : 1;
  return f;
}

// The noise floor and the reachable floor of a record's validation trace.
void set_floors(StudyRecord& r) {
  const Trace& t = r.trace_validation;
  const NormalProgram* nv = r.normal_validation ? &*r.normal_validation : nullptr;
  const Derivatives estimated = best_local_derivatives(t);
  const std::vector<double> reachable = reachable_force(r.system, t, nv, r.validation, &estimated);
  double noise = 0, gap = 0, total = 0;
  for (std::size_t k = 0; k < t.force.size(); ++k) {
    noise += (t.force[k] - t.clean[k]) * (t.force[k] - t.clean[k]);
    gap += (t.force[k] - reachable[k]) * (t.force[k] - reachable[k]);
    total += t.force[k] * t.force[k];
  }
  r.true_floor_percent = 100 * noise / total;
  r.reachable_floor_percent = 100 * gap / total;
}

}  // namespace

std::string family_name(Family f) {
  switch (f) {
    case Family::envelope:
      return "envelope";
    case Family::strokes:
      return "strokes";
    case Family::multisine:
      return "multisine";
  }
  return "?";
}

const std::vector<std::string>& injectable_effects() {
  static const std::vector<std::string> names = {
      "viscous", "stribeck",   "frictional-lag",      "asymmetry",
      "offset",  "inertia",    "position-dependence", "drift",
      "delay",   "normal-load"};
  return names;
}

void simulate_traces(StudyRecord& r) {
  const NormalProgram* ne = r.normal_estimation ? &*r.normal_estimation : nullptr;
  const NormalProgram* nv = r.normal_validation ? &*r.normal_validation : nullptr;
  r.trace_estimation = simulate(r.system, *r.motion_estimation, ne, r.estimation);
  r.trace_validation = simulate(r.system, *r.motion_validation, nv, r.validation);
}

StudyRecord make_record(const RecordSpec& spec) {
  for (const std::string& e : spec.effects)
    if (!has(injectable_effects(), e))
      throw std::invalid_argument("truth::make_record: unknown effect '" + e + "'");
  if (has(spec.effects, "frictional-lag") && !has(spec.effects, "viscous") &&
      !has(spec.effects, "stribeck"))
    throw std::invalid_argument("truth::make_record: frictional-lag needs viscous or stribeck");
  if (has(spec.effects, "delay") && has(spec.effects, "normal-load"))
    throw std::invalid_argument("truth::make_record: delay with normal-load is not simulated");

  Rng rng(spec.seed);
  StudyRecord r;
  r.spec = spec;
  r.expected = spec.effects;
  std::sort(r.expected.begin(), r.expected.end());
  for (const char* level : {"stribeck", "drift", "position-dependence", "normal-load"})
    r.level_varies = r.level_varies || has(spec.effects, level);

  // Scales and the system.
  const double fc = rng.log_uniform(3e-3, 1e3);
  r.travel = rng.log_uniform(5e-6, 2e-3);
  const double fs = rng.log_uniform(200, 5000);
  const double quantum = std::max(1e-9, r.travel * std::pow(10.0, rng.uniform(-4.5, -3.0)));
  const double max_threshold = r.travel * rng.uniform(0.05, 0.25);
  const double min_threshold =
      std::max(4 * quantum, max_threshold * std::pow(10.0, rng.uniform(-2.0, -1.0)));
  const int n_elements = rng.integer(3, 12);
  std::vector<double> thresholds, shares;
  for (int i = 0; i < n_elements; ++i) {
    thresholds.push_back(rng.log_uniform(min_threshold, max_threshold));
    shares.push_back(rng.uniform(0.3, 1.0));
  }
  std::sort(thresholds.begin(), thresholds.end());
  double share_sum = 0;
  for (double s : shares) share_sum += s;
  r.system.coulomb = fc;
  for (int i = 0; i < n_elements; ++i) {
    const double alpha = shares[static_cast<std::size_t>(i)] / share_sum;
    r.system.elements.push_back({alpha * fc / thresholds[static_cast<std::size_t>(i)], alpha});
  }

  // Measurements and motions.
  const double x_offset = rng.uniform(-0.1, 0.1);
  const double sigma = fc * std::pow(10.0, rng.uniform(-3.0, -1.7));
  const double phi = rng.chance(0.5) ? 0.0 : rng.uniform(0.3, 0.95);
  for (Measurement* m : {&r.estimation, &r.validation}) {
    m->sampling_rate = fs;
    m->samples = static_cast<std::size_t>(rng.integer(3000, 5000));
    const double duration = static_cast<double>(m->samples) / fs;
    m->warm_up = duration * rng.uniform(0.05, 0.15);
    m->time_origin = rng.chance(0.5) ? 0.0 : rng.uniform(0, 100);
    m->quantum = quantum;
    m->x_offset = x_offset;
    m->noise_sigma = sigma;
    m->noise_phi = phi;
    m->noise_seed = rng.seed();
  }
  MotionDraw est = draw_motion(spec.family, rng, r.travel, r.estimation, max_threshold);
  MotionDraw val = spec.validation == ValidationDesign::another_realisation
                       ? draw_realisation(est, rng, r.validation)
                       : draw_motion(spec.family, rng, r.travel, r.validation, max_threshold);
  r.motion_estimation = std::move(est.motion);
  r.motion_validation = std::move(val.motion);
  r.has_rests = est.rests && val.rests;
  r.distinct_speeds = std::min(est.distinct_speeds, val.distinct_speeds);

  const bool recorded_normal = has(spec.effects, "normal-load") || rng.chance(1.0 / 3);
  if (recorded_normal) {
    const double mu = rng.uniform(0.1, 0.8);
    const double duration_e = static_cast<double>(r.estimation.samples) / fs;
    const double duration_v = static_cast<double>(r.validation.samples) / fs;
    r.normal_estimation = draw_normal(rng, fc / mu, duration_e);
    r.normal_validation = draw_normal(rng, fc / mu, duration_v);
  }

  // Speeds of the plain system on the validation record, for the effects' shapes and bounds.
  const double duration =
      static_cast<double>(std::max(r.estimation.samples, r.validation.samples)) / fs;
  {
    Measurement m = r.validation;
    m.noise_sigma = 0;
    System plain = r.system;
    const Trace t = simulate(plain, *r.motion_validation, nullptr, m);
    std::vector<double> sliding, speeds, accelerations;
    for (std::size_t k = 0; k < t.velocity.size(); ++k) {
      speeds.push_back(std::abs(t.velocity[k]));
      accelerations.push_back(std::abs(t.acceleration[k]));
      if (t.sliding[k] && std::abs(t.velocity[k]) > 0) sliding.push_back(std::abs(t.velocity[k]));
    }
    r.median_sliding_speed = quantile(sliding.empty() ? speeds : sliding, 0.5);
    std::vector<Knob> knobs =
        knobs_for(r, rng, quantile(speeds, 0.95), quantile(accelerations, 0.95), duration, 1 / fs);
    calibrate(r, knobs);
  }

  // The records.
  simulate_traces(r);
  for (const std::string& e : spec.effects) r.contribution[e] = contribution_of(r, e);
  set_floors(r);

  // The truth, in SI and the library's names.
  const Effects& fx = r.system.effects;
  // A level in newtons is a level at some normal force.  The simulator's are at N0 (the normal
  // programs' mean parameter); methods.md 7 defines normal-load as level proportional to N(t),
  // and the library states its levels at the estimation record's mean normal force (effect_table:
  // level N(t)/N_mean), which differs from N0 by what the finite record averages of the
  // program's sines.  So the truth of a level in N is the simulator's scaled to that force
  // (without normal-load the scale is 1).
  double at_mean_normal = 1;
  if (fx.normal_load && !r.trace_estimation.normal.empty()) {
    double sum = 0;
    for (double v : r.trace_estimation.normal) sum += v;
    at_mean_normal =
        sum / static_cast<double>(r.trace_estimation.normal.size()) / r.normal_estimation->mean;
  }
  if (fx.viscous) r.truth.push_back({"viscous", "viscous", *fx.viscous, true});
  if (fx.stribeck) {
    r.truth.push_back({"stribeck", "static", fx.stribeck->static_force * at_mean_normal, false});
    r.truth.push_back({"stribeck", "stribeck_velocity", fx.stribeck->velocity, false});
    r.truth.push_back({"stribeck", "stribeck_exponent", fx.stribeck->exponent, false});
  }
  if (fx.lag_time) r.truth.push_back({"frictional-lag", "lag_time", *fx.lag_time, false});
  if (fx.asymmetry) r.truth.push_back({"asymmetry", "asymmetry", *fx.asymmetry, true});
  if (fx.offset) r.truth.push_back({"offset", "offset", *fx.offset, true});
  if (fx.mass) r.truth.push_back({"inertia", "mass", *fx.mass, true});
  if (fx.position) {
    r.truth.push_back({"position-dependence", "amplitude",
                       fx.position->relative_amplitude * fc * at_mean_normal, true});
    r.truth.push_back({"position-dependence", "wavelength", fx.position->wavelength, true});
  }
  if (fx.drift_rate) r.truth.push_back({"drift", "relative_rate", *fx.drift_rate, true});
  if (fx.delay) r.truth.push_back({"delay", "delay", *fx.delay, true});
  if (fx.normal_load)
    r.truth.push_back(
        {"normal-load", "friction_coefficient", fc / r.normal_validation->mean, true});

  r.format = draw_format(rng, r.travel, fc, recorded_normal);
  return r;
}

StudyRecord twin_without(const StudyRecord& r, const std::vector<std::string>& effects) {
  StudyRecord t;
  t.spec = r.spec;
  t.system = r.system;
  for (const std::string& e : effects) t.system = without(t.system, e);
  t.spec.effects.clear();
  for (const std::string& e : r.spec.effects)
    if (!has(effects, e)) t.spec.effects.push_back(e);
  t.expected = t.spec.effects;
  std::sort(t.expected.begin(), t.expected.end());
  t.estimation = r.estimation;
  t.validation = r.validation;
  t.motion_estimation = r.motion_estimation;
  t.motion_validation = r.motion_validation;
  t.normal_estimation = r.normal_estimation;
  t.normal_validation = r.normal_validation;
  simulate_traces(t);
  for (const TrueParameter& p : r.truth)
    if (!has(effects, p.effect)) t.truth.push_back(p);
  for (const auto& [e, c] : r.contribution)
    if (!has(effects, e)) t.contribution[e] = c;
  t.travel = r.travel;
  t.median_sliding_speed = r.median_sliding_speed;
  set_floors(t);
  t.format = r.format;
  t.has_presliding_reversals = r.has_presliding_reversals;
  t.has_rests = r.has_rests;
  t.both_directions = r.both_directions;
  t.distinct_speeds = r.distinct_speeds;
  for (const char* level : {"stribeck", "drift", "position-dependence", "normal-load"})
    t.level_varies = t.level_varies || has(t.spec.effects, level);
  return t;
}

std::string StudyRecord::read_options() const {
  std::vector<std::string> units;
  if (format.time_unit != "s") units.push_back("time=" + format.time_unit);
  if (format.displacement_unit != "m") units.push_back("displacement=" + format.displacement_unit);
  if (format.force_unit != "N") {
    units.push_back("force=" + format.force_unit);
    if (normal_validation) units.push_back("normal=" + format.force_unit);
  }
  std::string out;
  auto join = [](const std::vector<std::string>& v) {
    std::string s;
    for (const auto& x : v) s += (s.empty() ? "" : ",") + x;
    return s;
  };
  if (!units.empty()) out += " --units '" + join(units) + "'";
  if (format.names_need_columns_option) {
    std::vector<std::string> cols = {"time=" + format.time_name,
                                     "displacement=" + format.displacement_name,
                                     "force=" + format.force_name};
    if (normal_validation) cols.push_back("normal=" + format.normal_name);
    out += " --columns '" + join(cols) + "'";
  }
  return out;
}

std::string StudyRecord::summary() const {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "%s, %.0f Hz, %zu+%zu samples, %zu elements, Fc %.3g N, travel %.3g m, encoder "
                "%.2g m, noise %.2g N (phi %.2f), units %s/%s/%s%s%s",
                family_name(spec.family).c_str(), estimation.sampling_rate, estimation.samples,
                validation.samples, system.elements.size(), system.coulomb, travel,
                estimation.quantum, validation.noise_sigma, validation.noise_phi,
                format.time_unit.c_str(), format.displacement_unit.c_str(),
                format.force_unit.c_str(), format.force_sign < 0 ? ", force sign -1" : "",
                normal_validation ? ", normal force recorded" : "");
  return buf;
}

void write_csv(const StudyRecord& r, bool estimation, const std::string& path) {
  const Trace& t = estimation ? r.trace_estimation : r.trace_validation;
  const FileFormat& f = r.format;
  struct Column {
    std::string name;
    std::function<double(std::size_t)> value;
    int digits;
  };
  std::vector<Column> columns = {
      {f.time_name, [&](std::size_t k) { return t.time[k] / f.time_factor; }, 12},
      {f.displacement_name, [&](std::size_t k) { return t.position[k] / f.displacement_factor; },
       15},
      {f.force_name, [&](std::size_t k) { return f.force_sign * t.force[k] / f.force_factor; },
       10}};
  if (!t.normal.empty())
    columns.push_back(
        {f.normal_name, [&](std::size_t k) { return t.normal[k] / f.force_factor; }, 10});
  if (f.extra_column)
    columns.push_back(
        {"temperature_C",
         [&](std::size_t k) { return 21.5 + 0.3 * std::sin(static_cast<double>(k) * 1e-3); }, 5});
  if (f.reversed_order) std::reverse(columns.begin(), columns.end());
  std::ofstream out(path);
  if (!out) throw std::runtime_error("truth::write_csv: cannot write " + path);
  for (std::size_t c = 0; c < columns.size(); ++c) out << (c ? "," : "") << columns[c].name;
  out << "\n";
  char buf[64];
  for (std::size_t k = 0; k < t.time.size(); ++k) {
    for (std::size_t c = 0; c < columns.size(); ++c) {
      std::snprintf(buf, sizeof buf, "%.*g", columns[c].digits, columns[c].value(k));
      out << (c ? "," : "") << buf;
    }
    out << "\n";
  }
  if (!out) throw std::runtime_error("truth::write_csv: write failed for " + path);
}

std::uint64_t splitmix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

std::vector<RecordSpec> study_plan(std::uint64_t seed) {
  std::vector<RecordSpec> plan;
  std::mt19937_64 gen(splitmix(seed));
  auto family = [&] { return static_cast<Family>(std::uniform_int_distribution<int>(0, 2)(gen)); };
  auto add = [&](std::string id, std::vector<std::string> effects) {
    RecordSpec s;
    s.id = std::move(id);
    s.effects = std::move(effects);
    s.family = family();
    s.seed = splitmix(seed ^ splitmix(plan.size() + 1));
    plan.push_back(s);
  };
  std::vector<std::string> singles;
  for (const std::string& e : injectable_effects())
    if (e != "frictional-lag") singles.push_back(e);
  for (const std::string& e : singles)
    for (int i = 1; i <= 3; ++i) add(e + "-" + std::to_string(i), {e});
  add("frictional-lag+viscous-1", {"frictional-lag", "viscous"});
  add("frictional-lag+viscous-2", {"frictional-lag", "viscous"});
  add("frictional-lag+stribeck-1", {"frictional-lag", "stribeck"});
  add("frictional-lag+stribeck-2", {"frictional-lag", "stribeck"});
  std::vector<std::pair<std::string, std::string>> pairs;
  for (std::size_t i = 0; i < singles.size(); ++i)
    for (std::size_t j = i + 1; j < singles.size(); ++j)
      // Not simulated together: a delay with a normal load (whose channel would need a delay of
      // its own), and an offset with an asymmetry, which at a constant level are one offset
      // (pair_separated): no record could show both.
      if (!((singles[i] == "delay" && singles[j] == "normal-load") ||
            (singles[i] == "normal-load" && singles[j] == "delay") ||
            (singles[i] == "offset" && singles[j] == "asymmetry") ||
            (singles[i] == "asymmetry" && singles[j] == "offset")))
        pairs.emplace_back(singles[i], singles[j]);
  std::shuffle(pairs.begin(), pairs.end(), gen);
  for (int i = 0; i < 9; ++i)
    add(pairs[static_cast<std::size_t>(i)].first + "+" + pairs[static_cast<std::size_t>(i)].second,
        {pairs[static_cast<std::size_t>(i)].first, pairs[static_cast<std::size_t>(i)].second});
  for (int i = 1; i <= 22; ++i) {
    add((i < 10 ? "none-0" : "none-") + std::to_string(i), {});
  }
  return plan;
}

std::optional<RecordSpec> plan_record(std::uint64_t seed, const std::string& id,
                                      ValidationDesign validation) {
  for (RecordSpec& s : study_plan(seed))
    if (s.id == id) {
      s.validation = validation;
      return std::move(s);
    }
  return std::nullopt;
}

void write_truth(const StudyRecord& r, const std::string& path) {
  nlohmann::json t = nlohmann::json::array();
  for (const TrueParameter& p : r.truth)
    t.push_back({{"effect", p.effect}, {"name", p.name}, {"value", p.value}});
  std::ofstream out(path);
  out << nlohmann::json{{"summary", r.summary()}, {"parameters", t}}.dump(1) << "\n";
  if (!out) throw std::runtime_error("truth::write_truth: write failed for " + path);
}

}  // namespace truth
