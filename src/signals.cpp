// Signal conditioning: see signals.hpp for the rules and estimators.
#include "friction/signals.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <limits>
#include <mutex>
#include <optional>
#include <random>
#include <sstream>
#include <utility>
#include <vector>

#include <Eigen/Dense>

#include "friction/error.hpp"
#include "friction/metrics.hpp"
#include "friction/record_fingerprint.hpp"
#include "friction/sample_derivatives.hpp"
#include "number_format.hpp"
#include "sample_statistics.hpp"

namespace friction {
namespace {

using statistics::median;

// 1.4826 * median absolute deviation: the standard deviation of normal data, robustly.
double robust_spread(const std::vector<double>& v) {
  if (v.empty()) return 0.0;
  const double m = median(v);
  std::vector<double> dev(v.size());
  std::transform(v.begin(), v.end(), dev.begin(), [m](double a) { return std::abs(a - m); });
  return 1.4826 * median(std::move(dev));
}

std::string number(double v) {
  return format_number(v, 6);
}

}  // namespace

const char* to_string(ForceSign s) noexcept {
  switch (s) {
    case ForceSign::positive:
      return "+1";
    case ForceSign::negative:
      return "-1";
    case ForceSign::automatic:
      break;
  }
  return "auto";
}

SamplingReport analyse_sampling(std::span<const double> time, double tolerance,
                                const std::string& source, long first_line) {
  const auto line = [first_line](std::size_t k) {
    return first_line > 0 ? first_line + static_cast<long>(k) : 0L;
  };
  FRICTION_CHECK(std::isfinite(tolerance) && tolerance >= 0.0,
                 "sampling tolerance must be finite and >= 0, got ", tolerance);
  if (time.size() < 2)
    throw DataError(
        source, 0, 0,
        "need at least 2 samples to analyse sampling, got " + std::to_string(time.size()));
  std::vector<double> dt(time.size() - 1);
  for (std::size_t k = 0; k < time.size(); ++k) {
    if (!std::isfinite(time[k]))
      throw DataError(source, line(k), 0, "time of sample " + std::to_string(k) + " is not finite");
    if (k == 0) continue;
    const double d = time[k] - time[k - 1];
    if (!(d > 0.0))
      throw DataError(source, line(k), 0,
                      "time " + number(time[k]) + " s is not greater than the previous " +
                          number(time[k - 1]) + " s: time must be strictly increasing");
    dt[k - 1] = d;
  }
  SamplingReport r;
  r.tolerance = tolerance;
  r.nominal_period = median(dt);
  const auto [lo, hi] = std::minmax_element(dt.begin(), dt.end());
  r.min_period = *lo;
  r.max_period = *hi;
  for (std::size_t i = 0; i < dt.size(); ++i)
    if (std::abs(dt[i] - r.nominal_period) > tolerance * r.nominal_period)
      r.gaps.push_back({i + 1, dt[i]});
  return r;
}

std::string describe_sampling(const SamplingReport& report, std::size_t intervals) {
  if (!report.irregular()) return {};
  // Group the gap lengths: sorted, a new group whenever the next length differs from the group's
  // first by more than the tolerance (so 10 ms +- float noise is one group).
  std::vector<double> sizes;
  sizes.reserve(report.gaps.size());
  for (const auto& g : report.gaps) sizes.push_back(g.dt);
  std::sort(sizes.begin(), sizes.end());
  struct Group {
    double first, sum;
    std::size_t count;
  };
  std::vector<Group> groups;
  const double tol = std::max(report.tolerance, 1e-9) * report.nominal_period;
  for (double s : sizes) {
    if (groups.empty() || s - groups.back().first > tol) groups.push_back({s, 0.0, 0});
    groups.back().sum += s;
    ++groups.back().count;
  }
  std::sort(groups.begin(), groups.end(),
            [](const Group& a, const Group& b) { return a.count > b.count; });
  std::ostringstream s;
  s << "irregular sampling: " << report.gaps.size() << " of " << intervals
    << " intervals differ from the nominal period " << number(report.nominal_period)
    << " s by more than " << number(100.0 * report.tolerance) << " % (";
  const std::size_t shown = std::min<std::size_t>(groups.size(), 6);
  for (std::size_t i = 0; i < shown; ++i) {
    if (i > 0) s << ", ";
    s << groups[i].count << " x " << number(groups[i].sum / static_cast<double>(groups[i].count))
      << " s";
  }
  if (shown < groups.size()) s << ", ...";
  s << "); samples kept as they are, the models step with each interval's own length";
  return s.str();
}

ForceSignEstimate estimate_force_sign(std::span<const double> time,
                                      std::span<const double> displacement,
                                      std::span<const double> force) {
  ForceSignEstimate e;
  const std::size_t n = std::min({time.size(), displacement.size(), force.size()});
  constexpr std::size_t h = 2;     // half-width of the centred difference
  constexpr std::size_t kMin = 5;  // sliding samples needed per direction used
  if (n < 2 * h + 1) return e;
  std::vector<double> v(n - 2 * h);
  for (std::size_t k = h; k + h < n; ++k)
    v[k - h] = (displacement[k + h] - displacement[k - h]) / (time[k + h] - time[k - h]);
  std::vector<double> speed(v.size());
  std::transform(v.begin(), v.end(), speed.begin(), [](double a) { return std::abs(a); });
  const double threshold = 0.2 * nearest_rank_quantile(std::move(speed), 0.98);
  e.sliding_velocity = threshold;
  if (!(threshold > 0.0)) return e;

  std::vector<double> up, down, signed_force;
  for (std::size_t i = 0; i < v.size(); ++i) {
    const double f = force[i + h];
    if (v[i] > threshold) {
      up.push_back(f);
      signed_force.push_back(f);
    } else if (v[i] < -threshold) {
      down.push_back(f);
      signed_force.push_back(-f);
    }
  }
  e.sliding_samples = signed_force.size();
  constexpr double kMedianEfficiency = 1.2533;  // sd(median) / sd(mean) for normal data
  if (up.size() >= kMin && down.size() >= kMin) {
    e.both_directions = true;
    const double su = robust_spread(up), sd = robust_spread(down);
    e.difference = median(up) - median(down);
    e.standard_error = kMedianEfficiency * std::sqrt(su * su / static_cast<double>(up.size()) +
                                                     sd * sd / static_cast<double>(down.size()));
  } else if (signed_force.size() >= kMin) {
    const double s = robust_spread(signed_force);
    e.difference = median(signed_force);
    e.standard_error = kMedianEfficiency * s / std::sqrt(static_cast<double>(signed_force.size()));
  } else {
    return e;
  }
  if (e.difference != 0.0 && std::abs(e.difference) > 4.0 * e.standard_error) {
    e.decided = true;
    e.sign = e.difference > 0.0 ? 1 : -1;
    return e;
  }
  // The medians' spread includes the force's own variation while sliding; the regression takes
  // the parts that vary it out (header comment).
  const SlidingForceRegression reg = sliding_force_regression(time, displacement, force);
  if (reg.samples > 0 && reg.coulomb != 0.0 && std::abs(reg.coulomb) > 4.0 * reg.coulomb_se) {
    e.difference = 2.0 * reg.coulomb;
    e.standard_error = 2.0 * reg.coulomb_se;
    e.decided = true;
    e.sign = reg.coulomb > 0.0 ? 1 : -1;
  }
  return e;
}

SlidingForceRegression sliding_force_regression(std::span<const double> time,
                                                std::span<const double> displacement,
                                                std::span<const double> force) {
  SlidingForceRegression out;
  const std::size_t n = std::min({time.size(), displacement.size(), force.size()});
  constexpr Eigen::Index p = 4;
  // Five sliding samples per coefficient at the least (and enough for sample_derivatives).
  if (n < 5 * static_cast<std::size_t>(p)) return out;
  SampleDerivatives d = sample_derivatives(time.first(n), displacement.first(n));
  std::vector<double> speed(n);
  for (std::size_t k = 0; k < n; ++k) speed[k] = std::abs(d.velocity[k]);
  const double threshold = 0.2 * nearest_rank_quantile(speed, 0.98);
  out.acceleration = std::move(d.acceleration);
  if (!(threshold > 0.0)) return out;
  std::vector<std::size_t> rows;
  for (std::size_t k = 0; k < n; ++k)
    if (speed[k] > threshold) rows.push_back(k);
  if (rows.size() < 5 * static_cast<std::size_t>(p)) return out;
  Eigen::MatrixXd a(static_cast<Eigen::Index>(rows.size()), p);
  Eigen::VectorXd f(a.rows());
  for (Eigen::Index i = 0; i < a.rows(); ++i) {
    const std::size_t k = rows[static_cast<std::size_t>(i)];
    a.row(i) << (d.velocity[k] > 0 ? 1.0 : -1.0), 1.0, d.velocity[k], out.acceleration[k];
    f(i) = force[k];
  }
  // Columns scaled to unit norm so that the rank decision does not depend on units.
  const Eigen::VectorXd scale = a.colwise().norm().transpose().cwiseMax(1e-300);
  const Eigen::MatrixXd as = a * scale.cwiseInverse().asDiagonal();
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(as);
  if (qr.rank() < p) return out;
  const Eigen::VectorXd c = qr.solve(f);
  const double dof = static_cast<double>(a.rows() - p);
  const double s2 = (f - as * c).squaredNorm() / dof;
  const Eigen::MatrixXd cov = s2 * (as.transpose() * as).inverse();
  const auto coefficient = [&](Eigen::Index j, double& value, double& se) {
    value = c(j) / scale(j);
    se = std::sqrt(std::max(cov(j, j), 0.0)) / scale(j);
  };
  coefficient(0, out.coulomb, out.coulomb_se);
  coefficient(1, out.offset, out.offset_se);
  coefficient(2, out.viscous, out.viscous_se);
  coefficient(3, out.mass, out.mass_se);
  out.samples = rows.size();
  return out;
}

std::optional<double> signal_quantum(std::span<const double> signal) {
  std::vector<double> d;
  d.reserve(signal.size());
  for (std::size_t k = 1; k < signal.size(); ++k) {
    const double s = std::abs(signal[k] - signal[k - 1]);
    if (s > 0.0 && std::isfinite(s)) d.push_back(s);
  }
  if (d.size() < 10) return std::nullopt;
  std::sort(d.begin(), d.end());
  // q0: the smallest step that recurs (clusters of steps equal to within 1e-6 relative, which
  // absorbs the binary representation of decimal data).
  const std::size_t support = std::max<std::size_t>(3, d.size() / 1000);
  double q0 = 0.0;
  for (std::size_t i = 0; i < d.size();) {
    std::size_t j = i;
    while (j < d.size() && d[j] - d[i] <= 1e-6 * d[i]) ++j;
    if (j - i >= support) {
      q0 = d[i + (j - i) / 2];
      break;
    }
    i = j;
  }
  if (!(q0 > 0.0)) return std::nullopt;
  for (int m = 1; m <= 64; ++m) {
    const double q = q0 / m;
    std::vector<double> unit;
    unit.reserve(d.size());
    for (double s : d) {
      const double r = s / q;
      const double nearest = std::round(r);
      if (nearest >= 1.0 && std::abs(r - nearest) <= 0.02) unit.push_back(s / nearest);
    }
    if (static_cast<double>(unit.size()) >= 0.9 * static_cast<double>(d.size())) {
      // The values must lie on the grid too: the increments of smooth motion at a nearly
      // constant speed are also (almost) all one step, but their sum drifts off any grid (a
      // ramp with a 0.2 % ripple passed for an encoder of one sample's travel, and the
      // derivative windows it chose cost the acceleration 5 % of its amplitude).
      const double quantum = median(std::move(unit));
      std::size_t on_grid = 0;
      for (double v : signal) {
        const double r = (v - signal[0]) / quantum;
        if (std::isfinite(r) && std::abs(r - std::round(r)) <= 0.02) ++on_grid;
      }
      if (static_cast<double>(on_grid) >= 0.9 * static_cast<double>(signal.size())) return quantum;
      return std::nullopt;
    }
  }
  return std::nullopt;
}

double noise_level(std::span<const double> signal) {
  if (signal.size() < 3) return 0.0;
  std::vector<double> d2(signal.size() - 2);
  for (std::size_t k = 1; k + 1 < signal.size(); ++k)
    d2[k - 1] = signal[k + 1] - 2.0 * signal[k] + signal[k - 1];
  return robust_spread(d2) / std::sqrt(6.0);
}

Resolution estimate_displacement_resolution(std::span<const double> displacement) {
  Resolution r;
  r.quantum = signal_quantum(displacement);
  r.noise = noise_level(displacement);
  r.value = std::max(r.quantum.value_or(0.0), r.noise);
  return r;
}

double estimate_force_noise(std::span<const double> force) {
  const double s = noise_level(force);
  if (s > 0.0) return s;
  const auto q = signal_quantum(force);
  return q ? *q / std::sqrt(12.0) : 0.0;
}

const Conditioning& condition_record(Record& record, const ConditioningOptions& options) {
  const std::size_t n = record.size();
  const std::string& src = record.source;
  const auto check_size = [&](const std::vector<double>& v, const char* what, bool optional) {
    if (v.size() != n && !(optional && v.empty()))
      throw DataError(src, 0, 0,
                      std::string(what) + " has " + std::to_string(v.size()) +
                          " samples but time has " + std::to_string(n));
  };
  check_size(record.displacement, "displacement", false);
  check_size(record.force, "force", true);
  check_size(record.normal, "normal force", true);
  const auto check_finite = [&](const std::vector<double>& v, const char* what) {
    for (std::size_t k = 0; k < v.size(); ++k)
      if (!std::isfinite(v[k]))
        throw DataError(src, record.line_of(k), 0,
                        std::string(what) + " of sample " + std::to_string(k) +
                            " is not finite: expected a finite number");
  };
  check_finite(record.displacement, "displacement");
  check_finite(record.force, "force");
  check_finite(record.normal, "normal force");

  Conditioning c;
  const SamplingReport sampling =
      analyse_sampling(record.time, options.period_tolerance, src, record.first_line);
  c.nominal_period = sampling.nominal_period;
  c.min_period = sampling.min_period;
  c.max_period = sampling.max_period;
  c.period_tolerance = sampling.tolerance;
  c.gaps = sampling.gaps;
  c.irregular = sampling.irregular();

  if (record.has_force()) {
    const ForceSignEstimate est =
        estimate_force_sign(record.time, record.displacement, record.force);
    c.sliding_samples = est.sliding_samples;
    c.sliding_velocity = est.sliding_velocity;
    if (options.force_sign == ForceSign::automatic) {
      c.force_sign_decided = est.decided;
      c.force_sign = est.decided ? est.sign : 1;
      if (!est.decided)
        c.warnings.push_back("force_sign: +1 kept: the sign of the force could not be detected (" +
                             (est.sliding_samples == 0 ? std::string("no sliding motion")
                                                       : "sliding force " + number(est.difference) +
                                                             " N is within the noise") +
                             "); set it with --force-sign if it opposes the motion");
      else if (c.force_sign < 0)
        c.warnings.push_back(
            "force_sign: -1: the recorded force opposes the motion while sliding (F*v < 0), as "
            "the force on the moving body does; it was flipped to the models' convention "
            "(--force-sign +1 keeps it as recorded)");
    } else {
      c.force_sign_given = true;
      c.force_sign = options.force_sign == ForceSign::negative ? -1 : 1;
      if (est.decided && est.sign != c.force_sign)
        c.warnings.push_back(std::string("force_sign: ") + to_string(options.force_sign) +
                             " as given, although the data suggest " +
                             (est.sign > 0 ? "+1" : "-1") +
                             " (F*v while sliding has the other sign)");
    }
    if (c.force_sign < 0)
      for (double& f : record.force) f = -f;
    c.force_noise = estimate_force_noise(record.force);
  }

  // Conditioning twice (a record conditioned, then sliced and conditioned again) starts from the
  // measured displacement, not from its estimate.
  if (!record.measured_displacement.empty()) {
    record.displacement = std::move(record.measured_displacement);
    record.measured_displacement.clear();
  }
  const Resolution res = estimate_displacement_resolution(record.displacement);
  c.displacement_resolution = res.value;
  c.displacement_quantised = res.quantum.has_value();
  // The displacement the models see (sample_derivatives.hpp): the local polynomial's value when
  // the rule's window is longer than three samples (a quadratic through three passes them).
  DerivativeWindows w;
  std::vector<double> estimate = displacement_the_models_see(record.time, record.displacement, &w);
  c.displacement_half_width = w.displacement_half_width;
  c.displacement_degree = w.displacement_degree;
  if (!estimate.empty()) {
    record.measured_displacement = std::move(record.displacement);
    record.displacement = std::move(estimate);
  }

  if (c.irregular) c.warnings.push_back(describe_sampling(sampling, n - 1));
  record.conditioning = std::move(c);
  return record.conditioning;
}

namespace {

// The displacement the models see with windows already chosen: empty when they pass the samples
// (a quadratic through three samples is the measured value itself), else the local polynomial's
// value at every t_k.  The record's conditioning and its replicas' (remeasured_replica) share it.
std::vector<double> displacement_with_windows(std::span<const double> time,
                                              std::span<const double> measured,
                                              const DerivativeWindows& w) {
  if (measured.size() < 16 || (w.displacement_half_width <= 1 && w.displacement_degree == 2))
    return {};
  std::vector<double> estimate(measured.size());
  apply_local_displacement<double>(time, measured, w, estimate);
  return estimate;
}

}  // namespace

std::vector<double> displacement_the_models_see(std::span<const double> time,
                                                std::span<const double> measured,
                                                DerivativeWindows* windows) {
  if (measured.size() < 16) return {};
  const DerivativeWindows w = choose_derivative_windows(time, measured);
  if (windows) *windows = w;
  return displacement_with_windows(time, measured, w);
}

namespace {

// The windows the rule chose on replicas of recent records (remeasured_replica).  A pure function
// of the record's time and displacement, the sensor the replica is measured with and the seed, so
// a hit gives what computing them again would.  A record is recognised by the fingerprint of its
// time and displacement (record_fingerprint.hpp): copies to compare cost 16 bytes a sample for
// each of the records remembered, and a diagnosis remembers two (the record and the motion its
// encoder's replicas are made from).
class ReplicaWindows {
 public:
  struct Key {
    std::uint64_t seed;
    double quantum;  // 0 without one
    double noise;
    bool operator==(const Key&) const = default;
  };
  struct Print {
    detail::RecordFingerprint fingerprint;
    std::size_t samples = 0;
    bool operator==(const Print&) const = default;
  };
  static Print print_of(std::span<const double> time, std::span<const double> displacement) {
    const auto x = [&](std::size_t k) { return displacement[k]; };
    return {detail::fingerprint_of(time, displacement.size(), x), displacement.size()};
  }
  std::optional<DerivativeWindows> find(const Print& p, const Key& key) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& e : entries_)
      if (e.print == p)
        for (const auto& [k, w] : e.windows)
          if (k == key) return w;
    return std::nullopt;
  }
  void remember(const Print& p, const Key& key, const DerivativeWindows& w) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto& e : entries_)
      if (e.print == p) {
        e.windows.emplace_back(key, w);
        return;
      }
    if (entries_.size() == kRecords) entries_.pop_back();
    entries_.push_front(Entry{p, {{key, w}}});
  }

 private:
  static constexpr std::size_t kRecords = 4;
  struct Entry {
    Print print;
    std::vector<std::pair<Key, DerivativeWindows>> windows;
  };
  std::mutex mutex_;
  std::deque<Entry> entries_;
};

ReplicaWindows& replica_windows() {
  static ReplicaWindows cache;
  return cache;
}

}  // namespace

namespace {

// A symmetric pentadiagonal matrix by its bands: a0[k] = A(k, k), a1[k] = A(k, k + 1),
// a2[k] = A(k, k + 2).
struct Pentadiagonal {
  std::vector<double> a0, a1, a2;
  // Row k of A x, x given by x(j).
  template <class X>
  double row(std::size_t k, const X& x) const {
    const std::size_t n = a0.size();
    double s = a0[k] * x(k);
    if (k + 1 < n) s += a1[k] * x(k + 1);
    if (k + 2 < n) s += a2[k] * x(k + 2);
    if (k >= 1) s += a1[k - 1] * x(k - 1);
    if (k >= 2) s += a2[k - 2] * x(k - 2);
    return s;
  }
};

// Solves (A with diagonal `diagonal`) x = rhs in place (x holds rhs on entry) for a positive
// definite pentadiagonal A by LDL^T: L unit lower with two subdiagonals (l1, l2), D in `diagonal`
// (overwritten), O(N), no fill-in.
void solve_pentadiagonal(const Pentadiagonal& a, std::vector<double>& diagonal,
                         std::vector<double>& l1, std::vector<double>& l2, std::vector<double>& x) {
  const std::size_t n = diagonal.size();
  for (std::size_t k = 0; k < n; ++k) {
    double d = diagonal[k];
    if (k >= 1) d -= l1[k - 1] * l1[k - 1] * diagonal[k - 1];
    if (k >= 2) d -= l2[k - 2] * l2[k - 2] * diagonal[k - 2];
    diagonal[k] = d;
    l1[k] = k + 1 < n ? (a.a1[k] - (k >= 1 ? l2[k - 1] * l1[k - 1] * diagonal[k - 1] : 0.0)) / d
                      : 0.0;
    l2[k] = k + 2 < n ? a.a2[k] / d : 0.0;
  }
  for (std::size_t k = 0; k < n; ++k) {
    double y = x[k];
    if (k >= 1) y -= l1[k - 1] * x[k - 1];
    if (k >= 2) y -= l2[k - 2] * x[k - 2];
    x[k] = y;
  }
  for (std::size_t k = 0; k < n; ++k) x[k] /= diagonal[k];
  for (std::size_t k = n; k-- > 0;) {
    if (k + 1 < n) x[k] -= l1[k] * x[k + 1];
    if (k + 2 < n) x[k] -= l2[k] * x[k + 2];
  }
}

}  // namespace

std::vector<double> smoothest_motion_within_quanta(std::span<const double> time,
                                                   std::span<const double> measured,
                                                   double quantum) {
  const std::size_t n = measured.size();
  FRICTION_CHECK(time.size() == n, "smoothest_motion_within_quanta: time and displacement differ "
                 "in length");
  FRICTION_CHECK(quantum > 0 && std::isfinite(quantum),
                 "smoothest_motion_within_quanta: the quantum must be positive, not ", quantum);
  if (n < 3) return std::vector<double>(measured.begin(), measured.end());
  // In units of q about the first reading, and of the median interval in time, so that the
  // barrier's schedule below means the same whatever the record's scales.
  std::vector<double> h(n - 1);
  for (std::size_t k = 0; k + 1 < n; ++k) h[k] = time[k + 1] - time[k];
  std::vector<double> sorted(h);
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(sorted.size() / 2),
                   sorted.end());
  const double ts = sorted[sorted.size() / 2];
  FRICTION_CHECK(ts > 0 && std::all_of(h.begin(), h.end(), [](double v) { return v > 0; }),
                 "smoothest_motion_within_quanta: time must increase");
  sorted = {};
  // The reading k in quanta.  Vectors of the record's length are what this costs (a diagnosis of
  // a long record calls it beside other work): eight of them, everything else formed on the fly.
  const double origin = measured[0];
  const auto m = [&](std::size_t k) { return (measured[k] - origin) / quantum; };
  // H = D^T D, row r of D the second divided difference at sample r + 1 times Ts^2.
  Pentadiagonal hessian{std::vector<double>(n), std::vector<double>(n), std::vector<double>(n)};
  for (std::size_t r = 0; r + 2 < n; ++r) {
    const double h0 = h[r] / ts, h1 = h[r + 1] / ts, c = 2.0 / (h0 + h1);
    const double d0 = c / h0, d1 = -c / h0 - c / h1, d2 = c / h1;
    hessian.a0[r] += d0 * d0;
    hessian.a0[r + 1] += d1 * d1;
    hessian.a0[r + 2] += d2 * d2;
    hessian.a1[r] += d0 * d1;
    hessian.a1[r + 1] += d1 * d2;
    hessian.a2[r] += d0 * d2;
  }
  h = {};
  // The log barrier: min 1/2 b^T H b - mu sum(log(b - m + 1/2) + log(m + 1/2 - b)) by damped
  // Newton steps (each one banded solve), mu from 1 down by tenths, each level centred until the
  // Newton decrement^2 is below 1e-2 N mu, until 2 N mu (the barrier's bound on the distance to
  // the constrained optimum in the objective) is below a thousandth of the objective.  Started
  // at the readings, the tubes' centres.  A fixed last weight (1e-6) was not enough: on a smooth
  // motion the objective itself is of that order times N, and the test below found the result
  // rougher than the true motion.
  std::vector<double> b(n), diagonal(n), l1(n), l2(n), step(n);
  for (std::size_t k = 0; k < n; ++k) b[k] = m(k);
  const auto at_b = [&](std::size_t j) { return b[j]; };
  // The barrier objective at b + t step.
  const auto barrier_objective = [&](double t, double mu) {
    const auto x = [&](std::size_t j) { return b[j] + t * step[j]; };
    double s = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const double xk = x(k);
      const double below = xk - (m(k) - 0.5), above = (m(k) + 0.5) - xk;
      if (!(below > 0 && above > 0)) return std::numeric_limits<double>::infinity();
      s += 0.5 * xk * hessian.row(k, x) - mu * (std::log(below) + std::log(above));
    }
    return s;
  };
  // Minus the barrier objective's gradient at b, entry k.
  const auto minus_gradient = [&](std::size_t k, double mu) {
    const double below = b[k] - (m(k) - 0.5), above = (m(k) + 0.5) - b[k];
    return -(hessian.row(k, at_b) - mu / below + mu / above);
  };
  constexpr int kMaxNewtonSteps = 100;  // per barrier level; 3-5 are usual
  constexpr int kMaxLevels = 30;
  const auto roughness = [&] {
    double s = 0;
    for (std::size_t k = 0; k < n; ++k) s += b[k] * hessian.row(k, at_b);
    return s;
  };
  double mu = 1.0;
  for (int level = 0; level < kMaxLevels; ++level, mu *= 0.1) {
    // The barrier's optimum is within 2 N mu of the constrained one in the objective: stop at a
    // thousandth of the objective itself.
    if (level > 0 && 2.0 * static_cast<double>(n) * mu < 1e-3 * roughness()) break;
    for (int it = 0; it < kMaxNewtonSteps; ++it) {
      for (std::size_t k = 0; k < n; ++k) {
        const double below = b[k] - (m(k) - 0.5), above = (m(k) + 0.5) - b[k];
        step[k] = minus_gradient(k, mu);  // the right-hand side, solved for in place
        diagonal[k] = hessian.a0[k] + mu / (below * below) + mu / (above * above);
      }
      solve_pentadiagonal(hessian, diagonal, l1, l2, step);
      double decrement = 0;
      for (std::size_t k = 0; k < n; ++k) decrement += minus_gradient(k, mu) * step[k];
      if (!(decrement >= 1e-2 * static_cast<double>(n) * mu)) break;
      // The longest step that stays inside every tube (99 % of the way to the nearest wall),
      // halved until the barrier objective falls by a quarter of the decrement's promise.
      double t = 1.0;
      for (std::size_t k = 0; k < n; ++k) {
        const double below = b[k] - (m(k) - 0.5), above = (m(k) + 0.5) - b[k];
        if (step[k] < 0) t = std::min(t, 0.99 * below / -step[k]);
        if (step[k] > 0) t = std::min(t, 0.99 * above / step[k]);
      }
      const double f0 = barrier_objective(0.0, mu);
      for (;;) {
        if (barrier_objective(t, mu) <= f0 - 0.25 * t * decrement || t < 1e-12) break;
        t *= 0.5;
      }
      if (t < 1e-12) break;
      for (std::size_t k = 0; k < n; ++k) b[k] += t * step[k];
    }
  }
  for (std::size_t k = 0; k < n; ++k) b[k] = origin + quantum * b[k];
  return b;
}

bool remeasured_replica(const Record& record, std::span<const double> motion, std::uint64_t seed,
                        Record& replica, const Resolution& res, DerivativeWindows* windows) {
  FRICTION_CHECK(motion.size() == record.size(), "remeasured_replica: a motion of ", motion.size(),
                 " samples for a record of ", record.size());
  if (!res.quantum && !(res.noise > 0)) return false;
  std::mt19937_64 rng(seed);
  replica.time = record.time;
  replica.force = record.force;
  replica.normal = record.normal;
  std::vector<double> x(motion.begin(), motion.end());
  if (res.quantum) {
    const double q = *res.quantum;
    const double u = std::uniform_real_distribution<double>(0.0, q)(rng);
    for (double& v : x) v = q * std::round((v + u) / q) - u;
  } else {
    std::normal_distribution<double> noise(0.0, res.noise);
    for (double& v : x) v += noise(rng);
  }
  const std::size_t n = x.size();
  DerivativeWindows w;
  if (n >= 16) {
    // What displacement_the_models_see does, with the rule's choice remembered.
    const ReplicaWindows::Key key{seed, res.quantum.value_or(0.0), res.noise};
    const ReplicaWindows::Print print = ReplicaWindows::print_of(record.time, motion);
    if (auto known = replica_windows().find(print, key)) {
      w = *known;
    } else {
      w = choose_derivative_windows(replica.time, x);
      replica_windows().remember(print, key, w);
    }
  } else {
    w = record_derivative_windows(replica.time, x);
  }
  if (windows) *windows = w;
  std::vector<double> estimate = displacement_with_windows(replica.time, x, w);
  if (estimate.empty()) {
    replica.displacement = std::move(x);
    replica.measured_displacement.clear();
  } else {
    replica.displacement = std::move(estimate);
    replica.measured_displacement = std::move(x);
  }
  return true;
}

bool remeasured_replica(const Record& record, std::uint64_t seed, Record& replica,
                        const Resolution& sensor, DerivativeWindows* windows) {
  return remeasured_replica(record, std::span<const double>(record.displacement), seed, replica,
                            sensor, windows);
}

bool remeasured_replica(const Record& record, std::uint64_t seed, Record& replica) {
  return remeasured_replica(record, seed, replica,
                            estimate_displacement_resolution(record.measured()));
}

}  // namespace friction
