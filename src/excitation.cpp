#include "friction/excitation.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "friction/error.hpp"

namespace friction {

ExcitationKind parse_excitation_kind(const std::string& name) {
  if (name == "presliding") return ExcitationKind::Presliding;
  if (name == "strokes") return ExcitationKind::Strokes;
  if (name == "multisine") return ExcitationKind::Multisine;
  if (name == "combined") return ExcitationKind::Combined;
  throw InvalidParameter("unknown excitation '" + name +
                         "' (expected presliding, strokes, multisine or combined)");
}

std::string to_string(ExcitationKind kind) {
  switch (kind) {
    case ExcitationKind::Presliding:
      return "presliding";
    case ExcitationKind::Strokes:
      return "strokes";
    case ExcitationKind::Multisine:
      return "multisine";
    case ExcitationKind::Combined:
      return "combined";
  }
  return "?";
}

void ExcitationOptions::validate() const {
  FRICTION_CHECK(std::isfinite(rate) && rate > 0, "excitation: rate must be > 0 Hz, got ", rate);
  FRICTION_CHECK(presliding_amplitude > 0, "excitation: presliding amplitude must be > 0 m");
  FRICTION_CHECK(presliding_frequency > 0 && presliding_frequency < rate / 4,
                 "excitation: presliding frequency must be in (0, rate/4)");
  FRICTION_CHECK(presliding_cycles >= 1, "excitation: at least one presliding cycle");
  FRICTION_CHECK(presliding_decay > 0 && presliding_decay < 1,
                 "excitation: presliding decay must be in (0, 1)");
  FRICTION_CHECK(stroke > 0, "excitation: stroke must be > 0 m");
  FRICTION_CHECK(!speeds.empty(), "excitation: at least one stroke speed");
  for (double v : speeds) FRICTION_CHECK(v > 0, "excitation: stroke speeds must be > 0 m/s");
  FRICTION_CHECK(dwell >= 0 && reversal_time > 0, "excitation: dwell >= 0 s, reversal time > 0 s");
  FRICTION_CHECK(multisine_amplitude > 0 && multisine_components >= 1 &&
                     multisine_min_frequency > 0 &&
                     multisine_max_frequency >= multisine_min_frequency &&
                     multisine_max_frequency < rate / 4 && multisine_duration > 0,
                 "excitation: multisine needs amplitude > 0, 0 < fmin <= fmax < rate/4, "
                 "duration > 0 and at least one component");
}

namespace {

constexpr double kPi = std::numbers::pi;

// Appends samples while integrating a velocity profile; keeps the sample clock continuous.
class Builder {
 public:
  explicit Builder(double rate) : ts_(1.0 / rate) {
    s_.time.push_back(0.0);
    s_.displacement.push_back(0.0);
  }
  double x() const { return s_.displacement.back(); }

  // Velocity as a function of time since the segment start, for `duration` seconds.
  template <class F>
  void velocity_segment(double duration, F velocity) {
    const long n = std::lround(duration / ts_);
    for (long k = 1; k <= n; ++k) {
      // Midpoint rule per sample: exact for the piecewise-polynomial profiles used here to O(ts^3).
      const double tm = (static_cast<double>(k) - 0.5) * ts_;
      push(x() + velocity(tm) * ts_);
    }
  }
  // Displacement as a function of time since the segment start (relative to the current x).
  template <class F>
  void displacement_segment(double duration, F displacement) {
    const double x0 = x();
    const long n = std::lround(duration / ts_);
    for (long k = 1; k <= n; ++k) push(x0 + displacement(static_cast<double>(k) * ts_));
  }
  Signal take() { return std::move(s_); }

 private:
  void push(double x) {
    s_.time.push_back(static_cast<double>(s_.time.size()) * ts_);
    s_.displacement.push_back(x);
  }
  double ts_;
  Signal s_;
};

// Raised-cosine change of speed from v0 to v1 over `tr` seconds.
double ramp(double t, double tr, double v0, double v1) {
  const double u = std::clamp(t / tr, 0.0, 1.0);
  return v0 + (v1 - v0) * 0.5 * (1.0 - std::cos(kPi * u));
}

// One stroke of length `length` (signed) at peak speed v: accelerate, cruise, decelerate, dwell.
void stroke(Builder& b, double length, double v, double tr, double dwell) {
  const double dir = length > 0 ? 1.0 : -1.0;
  const double distance = std::abs(length);
  // Each ramp covers v*tr/2; if the stroke is too short to cruise, lower the peak speed.
  double peak = v;
  if (peak * tr > distance) peak = distance / tr;
  const double cruise = (distance - peak * tr) / peak;
  b.velocity_segment(tr, [&](double t) { return dir * ramp(t, tr, 0.0, peak); });
  b.velocity_segment(cruise, [&](double) { return dir * peak; });
  b.velocity_segment(tr, [&](double t) { return dir * ramp(t, tr, peak, 0.0); });
  b.velocity_segment(dwell, [](double) { return 0.0; });
}

void strokes(Builder& b, const ExcitationOptions& o) {
  // Start at the centre: half a stroke out, then full strokes back and forth at each speed.
  const double half = 0.5 * o.stroke;
  stroke(b, half, o.speeds.front(), o.reversal_time, o.dwell);
  for (double v : o.speeds) {
    stroke(b, -o.stroke, v, o.reversal_time, o.dwell);
    stroke(b, o.stroke, v, o.reversal_time, o.dwell);
  }
  stroke(b, -half, o.speeds.front(), o.reversal_time, o.dwell);
}

// Moves from the current position to `target` along a half cosine lasting `duration`.
void half_cosine_to(Builder& b, double target, double duration) {
  const double distance = target - b.x();
  b.displacement_segment(
      duration, [&](double t) { return distance * 0.5 * (1 - std::cos(kPi * t / duration)); });
}

void presliding(Builder& b, const ExcitationOptions& o) {
  // Reversal points alternate about the start and shrink by sqrt(decay) at every reversal (by
  // `decay` per cycle), so each new pair of reversals nests inside the previous one.
  const double centre = b.x();
  const double half_period = 0.5 / o.presliding_frequency;
  const double shrink = std::sqrt(o.presliding_decay);
  double amplitude = o.presliding_amplitude;
  half_cosine_to(b, centre + amplitude, 0.5 * half_period);
  for (int r = 0; r < 2 * o.presliding_cycles; ++r) {
    amplitude *= shrink;
    half_cosine_to(b, centre + (r % 2 == 0 ? -amplitude : amplitude), half_period);
  }
  half_cosine_to(b, centre, 0.5 * half_period);
}

void multisine(Builder& b, const ExcitationOptions& o, std::uint64_t seed) {
  const int n = o.multisine_components;
  std::vector<double> freq(n), phase(n);
  const double lo = std::log(o.multisine_min_frequency);
  const double hi = std::log(o.multisine_max_frequency);
  std::mt19937_64 engine(seed);
  for (int i = 0; i < n; ++i) {
    freq[i] = std::exp(n == 1 ? lo : lo + (hi - lo) * i / (n - 1));
    // Schroeder phases keep the crest factor low; a seeded offset varies the realisation.
    const double u = static_cast<double>(engine() >> 11) * 0x1.0p-53;
    phase[i] = -kPi * i * (i + 1) / n + 2 * kPi * u;
  }
  // Components weighted 1/f so that velocity is spread evenly over the band; taper in and out.
  auto raw = [&](double t) {
    double s = 0;
    for (int i = 0; i < n; ++i) s += std::sin(2 * kPi * freq[i] * t + phase[i]) / freq[i];
    return s;
  };
  const double duration = o.multisine_duration;
  double peak = 0;
  for (double t = 0; t < duration; t += 1e-3 / o.multisine_max_frequency)
    peak = std::max(peak, std::abs(raw(t) - raw(0)));
  const double scale = o.multisine_amplitude / peak;
  const double taper = std::min(0.1 * duration, 1.0 / o.multisine_min_frequency);
  b.displacement_segment(duration, [&](double t) {
    double w = 1.0;
    if (t < taper) w = 0.5 * (1 - std::cos(kPi * t / taper));
    if (t > duration - taper) w = 0.5 * (1 - std::cos(kPi * (duration - t) / taper));
    return w * scale * (raw(t) - raw(0));
  });
}

}  // namespace

Signal make_excitation(const ExcitationOptions& o) {
  o.validate();
  Builder b(o.rate);
  switch (o.kind) {
    case ExcitationKind::Presliding: {
      // Slide once to set a well-defined state, then the nested presliding loops.
      stroke(b, 0.5 * o.stroke, o.speeds.front(), o.reversal_time, o.dwell);
      presliding(b, o);
      break;
    }
    case ExcitationKind::Strokes:
      strokes(b, o);
      break;
    case ExcitationKind::Multisine:
      multisine(b, o, o.seed);
      break;
    case ExcitationKind::Combined:
      strokes(b, o);
      stroke(b, 0.5 * o.stroke, o.speeds.front(), o.reversal_time, o.dwell);
      presliding(b, o);
      break;
  }
  return b.take();
}

double NormalSource::operator()() {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  // Box-Muller on two uniforms in (0, 1].
  const double u1 = (static_cast<double>(engine_() >> 11) + 1.0) * 0x1.0p-53;
  const double u2 = static_cast<double>(engine_() >> 11) * 0x1.0p-53;
  const double r = std::sqrt(-2.0 * std::log(u1));
  spare_ = r * std::sin(2 * kPi * u2);
  has_spare_ = true;
  return r * std::cos(2 * kPi * u2);
}

void add_white_noise(std::vector<double>& signal, double sigma, NormalSource& source) {
  FRICTION_CHECK(std::isfinite(sigma) && sigma >= 0, "noise standard deviation must be >= 0");
  if (sigma == 0) return;
  for (double& s : signal) s += sigma * source();
}

void quantise(std::vector<double>& signal, double resolution) {
  FRICTION_CHECK(std::isfinite(resolution) && resolution >= 0, "resolution must be >= 0 m");
  if (resolution == 0) return;
  for (double& s : signal) s = resolution * std::round(s / resolution);
}

}  // namespace friction
