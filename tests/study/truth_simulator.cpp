// The independent simulator (see truth_simulator.hpp).
#include "truth_simulator.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <random>
#include <stdexcept>

namespace truth {

namespace {

class Envelope final : public Excitation {
 public:
  explicit Envelope(const EnvelopeProgram& p) : p_(p) {}
  double x(double t) const override { return p_.amplitude * e(t, 0) * c(t, 0); }
  double v(double t) const override {
    return p_.amplitude * (e(t, 1) * c(t, 0) + e(t, 0) * c(t, 1));
  }
  double a(double t) const override {
    return p_.amplitude * (e(t, 2) * c(t, 0) + 2 * e(t, 1) * c(t, 1) + e(t, 0) * c(t, 2));
  }
  std::string kind() const override { return "envelope"; }

 private:
  // The d-th derivative of the envelope and of the carrier.
  double e(double t, int d) const {
    const double w = 2 * std::numbers::pi * p_.fe, th = w * t + p_.psi, s = 1 - p_.e_min;
    if (d == 0) return p_.e_min + s * (1 - std::cos(th)) / 2;
    if (d == 1) return s * w * std::sin(th) / 2;
    return s * w * w * std::cos(th) / 2;
  }
  static double sin_d(double w, double th, int d) {
    if (d == 0) return std::sin(th);
    if (d == 1) return w * std::cos(th);
    return -w * w * std::sin(th);
  }
  double c(double t, int d) const {
    const double w1 = 2 * std::numbers::pi * p_.f1, w2 = 2 * std::numbers::pi * p_.f2;
    return p_.w1 * sin_d(w1, w1 * t, d) + p_.w2 * sin_d(w2, w2 * t + p_.chi, d);
  }
  EnvelopeProgram p_;
};

// Smooth velocity steps.  With z = (t - s_j)/w, step j contributes du_j H(z) to v,
// du_j w G(z) to x with G(z) = (z + ln cosh z + ln 2)/2 (0 long before the step, z long after)
// and du_j / (2 w) sech^2 z to a.  Steps far behind t (z > kFar) contribute du_j (t - s_j) to x
// and du_j to v, which prefix sums give at once; steps far ahead contribute nothing.
class Strokes final : public Excitation {
 public:
  explicit Strokes(const StrokeProgram& p) : w_(p.width) {
    if (p.velocity.size() != p.duration.size() || p.velocity.empty() || !(w_ > 0))
      throw std::invalid_argument("truth::make_strokes: bad program");
    double s = p.start, previous = 0;
    for (std::size_t j = 0; j < p.velocity.size(); ++j) {
      s_.push_back(s);
      du_.push_back(p.velocity[j] - previous);
      previous = p.velocity[j];
      s += p.duration[j];
    }
    sum_du_.assign(s_.size() + 1, 0.0);
    sum_du_s_.assign(s_.size() + 1, 0.0);
    for (std::size_t j = 0; j < s_.size(); ++j) {
      sum_du_[j + 1] = sum_du_[j] + du_[j];
      sum_du_s_[j + 1] = sum_du_s_[j] + du_[j] * s_[j];
    }
  }
  double x(double t) const override {
    const auto [past, near_end] = window(t);
    double x = t * sum_du_[past] - sum_du_s_[past];
    for (std::size_t j = past; j < near_end; ++j) {
      const double z = (t - s_[j]) / w_, az = std::abs(z);
      x += du_[j] * w_ * (z + az + std::log1p(std::exp(-2 * az))) / 2;
    }
    return x;
  }
  double v(double t) const override {
    const auto [past, near_end] = window(t);
    double v = sum_du_[past];
    for (std::size_t j = past; j < near_end; ++j)
      v += du_[j] * (1 + std::tanh((t - s_[j]) / w_)) / 2;
    return v;
  }
  double a(double t) const override {
    const auto [past, near_end] = window(t);
    double a = 0;
    for (std::size_t j = past; j < near_end; ++j) {
      const double th = std::tanh((t - s_[j]) / w_);
      a += du_[j] / (2 * w_) * (1 - th * th);
    }
    return a;
  }
  std::string kind() const override { return "strokes"; }

 private:
  static constexpr double kFar = 40;  // tanh(40) = 1 and sech^2(40) ~ 1e-34
  // [0, past): steps far behind t; [past, near_end): steps that still shape the motion at t.
  std::pair<std::size_t, std::size_t> window(double t) const {
    const auto past = std::lower_bound(s_.begin(), s_.end(), t - kFar * w_) - s_.begin();
    const auto near_end = std::upper_bound(s_.begin(), s_.end(), t + kFar * w_) - s_.begin();
    return {static_cast<std::size_t>(past), static_cast<std::size_t>(near_end)};
  }
  double w_;
  std::vector<double> s_, du_, sum_du_, sum_du_s_;
};

class Multisine final : public Excitation {
 public:
  explicit Multisine(const MultisineProgram& p) : p_(p) {
    if (p.amplitude.size() != p.frequency.size() || p.amplitude.size() != p.phase.size())
      throw std::invalid_argument("truth::make_multisine: bad program");
  }
  double x(double t) const override { return sum(t, 0); }
  double v(double t) const override { return sum(t, 1); }
  double a(double t) const override { return sum(t, 2); }
  std::string kind() const override { return "multisine"; }

 private:
  double sum(double t, int d) const {
    double s = 0;
    for (std::size_t j = 0; j < p_.amplitude.size(); ++j) {
      const double w = 2 * std::numbers::pi * p_.frequency[j], th = w * t + p_.phase[j];
      s += p_.amplitude[j] * (d == 0   ? std::sin(th)
                              : d == 1 ? w * std::cos(th)
                                       : -w * w * std::sin(th));
    }
    return s;
  }
  MultisineProgram p_;
};

}  // namespace

std::unique_ptr<Excitation> make_envelope(const EnvelopeProgram& p) {
  return std::make_unique<Envelope>(p);
}
std::unique_ptr<Excitation> make_strokes(const StrokeProgram& p) {
  return std::make_unique<Strokes>(p);
}
std::unique_ptr<Excitation> make_multisine(const MultisineProgram& p) {
  return std::make_unique<Multisine>(p);
}

double NormalProgram::at(double t) const {
  return mean * (1 + b1 * std::sin(2 * std::numbers::pi * f1 * t + p1) +
                 b2 * std::sin(2 * std::numbers::pi * f2 * t + p2));
}

// The level L of the header comment at motion instant tau (t = tau + D since the record's start).
static double slip_level(const System& sys, double tau, double delay, double x_abs, double v_felt,
                         const NormalProgram* normal) {
  const Effects& fx = sys.effects;
  double l = 1;
  if (fx.stribeck) {
    const auto& s = *fx.stribeck;
    l *= 1 + (s.static_force / sys.coulomb - 1) *
                 std::exp(-std::pow(std::abs(v_felt) / s.velocity, s.exponent));
  }
  if (fx.drift_rate) l *= 1 + *fx.drift_rate * std::max(tau + delay, 0.0);
  if (fx.position) {
    const auto& p = *fx.position;
    l *= 1 + p.relative_amplitude * std::sin(2 * std::numbers::pi * x_abs / p.wavelength + p.phase);
  }
  if (fx.normal_load) l *= normal->at(tau) / normal->mean;
  return l;
}

double System::threshold(std::size_t i) const {
  return elements.at(i).share * coulomb / elements.at(i).stiffness;
}

Trace simulate(const System& sys, const Excitation& motion, const NormalProgram* normal,
               const Measurement& m) {
  if (m.refine < 10) throw std::invalid_argument("truth::simulate: refine must be >= 10");
  if (sys.elements.empty() || !(sys.coulomb > 0))
    throw std::invalid_argument("truth::simulate: no elements or no Coulomb level");
  if (sys.effects.normal_load && !normal)
    throw std::invalid_argument("truth::simulate: normal load without a normal program");
  const Effects& fx = sys.effects;
  const double ts = 1.0 / m.sampling_rate, h = ts / m.refine;
  const double delay = fx.delay.value_or(0.0);
  const double asym = fx.asymmetry.value_or(0.0);
  const std::size_t n_el = sys.elements.size();

  auto level = [&](double tau, double x_abs, double v_felt) {
    return slip_level(sys, tau, delay, x_abs, v_felt, normal);
  };

  Trace out;
  const std::size_t n = m.samples;
  out.time.resize(n);
  out.position.resize(n);
  out.force.resize(n);
  out.clean.resize(n);
  out.velocity.resize(n);
  out.acceleration.resize(n);
  out.sliding.resize(n);
  out.felt_velocity.resize(n);
  out.motion_acceleration.resize(n);
  if (normal) out.normal.resize(n);

  // Fine grid tau_j = -delay + j h; sample k at j = k refine.  The warm-up starts from a virgin
  // state at the motion instant -warm_up (to within h), whatever the delay, so that records that
  // differ only in their delay share their history.
  if (!(m.warm_up >= ts)) throw std::invalid_argument("truth::simulate: warm_up below a sample");
  const long j0 = -static_cast<long>(std::ceil((m.warm_up - delay) / h - 1e-9));
  const long j_end = static_cast<long>(n - 1) * m.refine;
  std::vector<double> f(n_el, 0.0), lim_up(n_el), lim_lo(n_el);
  auto tau_of = [&](long j) { return -delay + static_cast<double>(j) * h; };
  double tau = tau_of(j0), x = motion.x(tau);
  double v_l = motion.v(tau);
  for (long j = j0;; ++j) {
    if (j >= 0 && j % m.refine == 0) {
      const std::size_t k = static_cast<std::size_t>(j / m.refine);
      double force = 0;
      bool all_at_limit = true;
      for (std::size_t i = 0; i < n_el; ++i) {
        force += f[i];
        const double tol = 1e-9 * (std::abs(lim_up[i]) + std::abs(lim_lo[i]));
        if (std::abs(f[i] - lim_up[i]) > tol && std::abs(f[i] - lim_lo[i]) > tol)
          all_at_limit = false;
      }
      if (fx.viscous) force += *fx.viscous * v_l;
      if (fx.mass) force += *fx.mass * motion.a(tau);
      if (fx.offset) force += *fx.offset;
      const double t_rec = static_cast<double>(k) * ts;
      out.time[k] = m.time_origin + t_rec;
      out.clean[k] = force;
      out.velocity[k] = motion.v(t_rec);
      out.acceleration[k] = motion.a(t_rec);
      out.position[k] = motion.x(t_rec) + m.x_offset;
      out.sliding[k] = all_at_limit;
      out.felt_velocity[k] = v_l;
      out.motion_acceleration[k] = motion.a(tau);
      out.element_force.insert(out.element_force.end(), f.begin(), f.end());
      if (normal) out.normal[k] = normal->at(t_rec);
    }
    if (j >= j_end) break;
    // One fine step tau -> tau + h.
    const double t1 = tau_of(j + 1);
    if (fx.lag_time) {
      const double tl = *fx.lag_time;
      auto rhs = [&](double t, double vl) { return (motion.v(t) - vl) / tl; };
      const double k1 = rhs(tau, v_l), k2 = rhs(tau + h / 2, v_l + h / 2 * k1),
                   k3 = rhs(tau + h / 2, v_l + h / 2 * k2), k4 = rhs(t1, v_l + h * k3);
      v_l += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    } else {
      v_l = motion.v(t1);
    }
    const double x1 = motion.x(t1), dx = x1 - x;
    const double l = sys.coulomb * level(t1, x1 + m.x_offset, v_l);
    for (std::size_t i = 0; i < n_el; ++i) {
      const double a_i = sys.elements[i].share * l;
      lim_up[i] = a_i * (1 + asym);
      lim_lo[i] = -a_i * (1 - asym);
      f[i] = std::clamp(f[i] + sys.elements[i].stiffness * dx, lim_lo[i], lim_up[i]);
    }
    tau = t1;
    x = x1;
  }

  std::mt19937_64 gen(m.noise_seed);
  std::normal_distribution<double> white(0.0, 1.0);
  for (double& xs : out.position) {
    if (m.position_noise > 0) xs += m.position_noise * white(gen);
    if (m.quantum > 0) xs = m.quantum * std::nearbyint(xs / m.quantum);
  }
  const double phi = m.noise_phi, innovation = std::sqrt(1 - phi * phi);
  double e = m.noise_sigma * white(gen);
  for (std::size_t k = 0; k < n; ++k) {
    if (k > 0) e = phi * e + innovation * m.noise_sigma * white(gen);
    out.force[k] = out.clean[k] + e;
  }
  return out;
}

namespace {

// Local quadratic fit over the 2m+1 samples around k (slid inside the record), differentiated at
// t_k: order 1 the velocity, 2 the acceleration.
double local_quadratic(const std::vector<double>& t, const std::vector<double>& x, std::size_t k,
                       std::size_t m, int order) {
  const std::size_t n = x.size(), w = std::min(2 * m + 1, n);
  std::size_t lo = k >= m ? k - m : 0;
  if (lo + w > n) lo = n - w;
  const double ts = (t[n - 1] - t[0]) / static_cast<double>(n - 1);
  double s[5] = {0, 0, 0, 0, 0}, r[3] = {0, 0, 0};
  for (std::size_t i = lo; i < lo + w; ++i) {
    const double tau = (t[i] - t[k]) / ts, y = x[i] - x[k];
    s[0] += 1, s[1] += tau, s[2] += tau * tau, s[3] += tau * tau * tau,
        s[4] += tau * tau * tau * tau;
    r[0] += y, r[1] += y * tau, r[2] += y * tau * tau;
  }
  // Cramer's rule on the 3 x 3 normal equations.
  auto det3 = [](double a, double b, double c, double d, double e, double f, double g, double h,
                 double i) {
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
  };
  const double d = det3(s[0], s[1], s[2], s[1], s[2], s[3], s[2], s[3], s[4]);
  if (order == 1) return det3(s[0], r[0], s[2], s[1], r[1], s[3], s[2], r[2], s[4]) / d / ts;
  return 2 * det3(s[0], s[1], r[0], s[1], s[2], r[1], s[2], s[3], r[2]) / d / (ts * ts);
}

double interpolate(const std::vector<double>& y, double s) {
  if (s <= 0) return y.front();
  const auto i = static_cast<std::size_t>(std::floor(s));
  if (i + 1 >= y.size()) return y.back();
  const double w = s - static_cast<double>(i);
  return (1 - w) * y[i] + w * y[i + 1];
}

}  // namespace

Derivatives best_local_derivatives(const Trace& t) {
  Derivatives best;
  const std::size_t n = t.position.size();
  double best_v = INFINITY, best_a = INFINITY;
  std::vector<double> v(n), a(n);
  for (std::size_t m = 1; m <= 40 && 2 * m + 1 <= n; ++m) {
    double ev = 0, ea = 0;
    for (std::size_t k = 0; k < n; ++k) {
      v[k] = local_quadratic(t.time, t.position, k, m, 1);
      a[k] = local_quadratic(t.time, t.position, k, m, 2);
      ev += (v[k] - t.velocity[k]) * (v[k] - t.velocity[k]);
      ea += (a[k] - t.acceleration[k]) * (a[k] - t.acceleration[k]);
    }
    if (ev < best_v) best_v = ev, best.v = v, best.velocity_window = static_cast<int>(m);
    if (ea < best_a) best_a = ea, best.a = a, best.acceleration_window = static_cast<int>(m);
  }
  return best;
}

std::vector<double> reachable_force(const System& sys, const Trace& t, const NormalProgram* normal,
                                    const Measurement& m, const Derivatives* estimated) {
  const Effects& fx = sys.effects;
  const double delay = fx.delay.value_or(0.0), asym = fx.asymmetry.value_or(0.0);
  const std::size_t n = t.position.size(), n_el = sys.elements.size();
  const double ts = 1.0 / m.sampling_rate;
  // The recorded displacement at t_k - D, linearly interpolated (held before the first sample).
  std::vector<double> x(n);
  for (std::size_t k = 0; k < n; ++k) {
    const double s = static_cast<double>(k) - delay / ts;
    if (s <= 0) {
      x[k] = t.position[0];
    } else {
      const auto i = static_cast<std::size_t>(std::floor(s));
      const double w = s - static_cast<double>(i);
      x[k] = i + 1 < n ? (1 - w) * t.position[i] + w * t.position[i + 1] : t.position[n - 1];
    }
  }
  const auto first = std::min(n - 1, static_cast<std::size_t>(std::ceil(delay / ts - 1e-9)));
  std::vector<double> f(t.element_force.begin() + static_cast<long>(first * n_el),
                        t.element_force.begin() + static_cast<long>((first + 1) * n_el));
  // The felt velocity and the acceleration at the motion instants: exact, or estimated from the
  // recorded displacement (shifted by the delay, and through the lag when there is one; the lag
  // starts from its true state).
  std::vector<double> felt = t.felt_velocity, accel = t.motion_acceleration;
  if (estimated) {
    const double tau_lag = fx.lag_time.value_or(0.0);
    double previous = 0;
    for (std::size_t k = first; k < n; ++k) {
      const double s = static_cast<double>(k) - delay / ts;
      const double v = interpolate(estimated->v, s);
      accel[k] = interpolate(estimated->a, s);
      if (tau_lag > 0 && k > first) {
        const double e = std::exp(-ts / tau_lag), slope_tau = (v - previous) * tau_lag / ts;
        felt[k] = v - slope_tau + (felt[k - 1] - previous + slope_tau) * e;
      } else if (!(tau_lag > 0)) {
        felt[k] = v;
      }
      previous = v;
    }
  }
  std::vector<double> out(n);
  for (std::size_t k = 0; k < n; ++k) {
    if (k < first) {
      out[k] = t.clean[k];
      continue;
    }
    if (k > first) {
      const double tau = static_cast<double>(k) * ts - delay;
      const double l = sys.coulomb * slip_level(sys, tau, delay, x[k], felt[k], normal);
      for (std::size_t i = 0; i < n_el; ++i) {
        const double a_i = sys.elements[i].share * l;
        f[i] = std::clamp(f[i] + sys.elements[i].stiffness * (x[k] - x[k - 1]), -a_i * (1 - asym),
                          a_i * (1 + asym));
      }
    }
    double force = 0;
    for (double fi : f) force += fi;
    if (fx.viscous) force += *fx.viscous * felt[k];
    if (fx.mass) force += *fx.mass * accel[k];
    if (fx.offset) force += *fx.offset;
    out[k] = force;
  }
  return out;
}

double rms_difference(const std::vector<double>& a, const std::vector<double>& b, bool scale_free) {
  if (a.size() != b.size() || a.empty())
    throw std::invalid_argument("truth::rms_difference: sizes differ");
  double c = 1;
  if (scale_free) {
    const double ab = std::inner_product(a.begin(), a.end(), b.begin(), 0.0);
    const double bb = std::inner_product(b.begin(), b.end(), b.begin(), 0.0);
    c = bb > 0 ? ab / bb : 0.0;
  }
  double s = 0;
  for (std::size_t k = 0; k < a.size(); ++k) s += (a[k] - c * b[k]) * (a[k] - c * b[k]);
  return std::sqrt(s / static_cast<double>(a.size()));
}

}  // namespace truth
