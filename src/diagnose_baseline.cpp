// The baseline stages of diagnose (diagnose.hpp, section 1): NLR and what one more operator buys;
// a LuGre baseline and its one candidate, nonlocal-memory.
#include <chrono>
#include <cmath>
#include <limits>

#include "diagnose_stages.hpp"
#include "friction/identification.hpp"
#include "friction/signals.hpp"
#include "parallel_for.hpp"
#include "sample_statistics.hpp"

namespace friction::diagnose_detail {

namespace {

// Rule (b), third part (section 4): what one more Maxwell Slip element buys on the estimation
// record.  The order selection's table holds M + 1 unless M is the largest M it tried (the cap of
// max_operators); then M + 1 is fitted here.
double one_more_operator(const Record& est, const IdentifiedModel& nlr, std::size_t m,
                         const DiagnoseOptions& o, std::vector<std::string>& warnings) {
  const SelectionRow* at = nullptr;
  const SelectionRow* next = nullptr;
  for (const auto& row : nlr.report.selection) {
    if (row.failed) continue;
    if (row.operators == m) at = &row;
    if (row.operators == m + 1) next = &row;
  }
  if (at && next) return std::max(at->rss - next->rss, 0.0);
  if (next) return 0.0;
  MethodOptions more = o.method;
  more.operators = m + 1;
  more.max_operators = 0;
  more.extensions = {};
  try {
    const IdentifiedModel bigger = identify_model("maxwell-slip", est, more);
    return std::max(nlr.report.estimation.rss - bigger.report.estimation.rss, 0.0);
  } catch (const std::exception& ex) {
    warnings.push_back("the reference fit with " + std::to_string(m + 1) + " operators failed (" +
                       ex.what() + "); rule (b) without it");
  }
  return 0.0;
}

// The model of `s` from `initial` on a record with its derivative windows `w`: the force at every
// sample, without the thread's filter cache (a replica's filter is not asked for again, and the
// validation record's would displace the estimation record's, which the fits that follow read).
std::vector<double> slip_force(const State& s, std::span<const double> initial, const Record& r,
                               const DerivativeWindows& w) {
  Extended<MaxwellSlip<double>> model(MaxwellSlip<double>(s.base), s.ext, 2);
  set_extended_slip_state(model, initial);
  std::vector<double> out(r.size());
  const detail::UncachedSteps uncached;
  for_each_extended_step(
      model, std::span<const double>(r.time), std::span<const double>(r.displacement),
      std::span<const double>(r.normal), &w,
      [&](std::size_t k, const ExtendedMotion<double>&, double force) { out[k] = force; },
      std::span<const double>(r.measured_displacement));
  return out;
}

// The record refined to four steps per sample (stepped_finely).  Made without a Record (no force,
// no conditioning): at 10^6 samples the fine record and the whole runs on it (force, regime,
// velocity, acceleration) were a quarter of the diagnosis's memory, and only the force at the
// record's own samples is read.
struct FineGrid {
  static constexpr std::size_t kSteps = 4;
  std::vector<double> time, x, normal;
};

FineGrid fine_grid(const Record& r) {
  const std::size_t n = r.size(), steps = FineGrid::kSteps;
  const std::size_t fine_n = steps * (n - 1) + 1;
  FineGrid g;
  g.time.reserve(fine_n);
  g.x.reserve(fine_n);
  if (!r.normal.empty()) g.normal.reserve(fine_n);
  for (std::size_t k = 0; k + 1 < n; ++k)
    for (std::size_t j = 0; j < steps; ++j) {
      const double w = static_cast<double>(j) / static_cast<double>(steps);
      const double t = r.time[k] + w * (r.time[k + 1] - r.time[k]);
      g.time.push_back(t);
      g.x.push_back(interpolate_displacement(std::span<const double>(r.time),
                                             std::span<const double>(r.displacement), k, t));
      if (!r.normal.empty()) g.normal.push_back((1 - w) * r.normal[k] + w * r.normal[k + 1]);
    }
  g.time.push_back(r.time.back());
  g.x.push_back(r.displacement.back());
  if (!r.normal.empty()) g.normal.push_back(r.normal.back());
  return g;
}

}  // namespace

DerivativeWindows fine_grid_windows(const Record& r) {
  if (r.size() < 2) return record_derivative_windows(r);
  const FineGrid g = fine_grid(r);
  return record_derivative_windows(std::span<const double>(g.time), std::span<const double>(g.x));
}

void warm_sensor_replica(const Record& r, std::size_t j) {
  if (r.size() < 8) return;
  Record replica;
  remeasured_replica(r, replica_seed(j), replica,
                     estimate_displacement_resolution(r.measured()), nullptr);
}

std::vector<double> stepped_finely(const State& s, std::span<const double> initial,
                                   const Record& r, const DerivativeWindows* fine_windows) {
  const std::size_t n = r.size(), steps = FineGrid::kSteps;
  const FineGrid g = fine_grid(r);
  const std::vector<double>& fine_time = g.time;
  const std::vector<double>& fine_x = g.x;
  const std::vector<double>& fine_normal = g.normal;
  Extended<MaxwellSlip<double>> model(MaxwellSlip<double>(s.base), s.ext, 2);
  set_extended_slip_state(model, initial);
  std::vector<double> out(n);
  const detail::UncachedSteps uncached;  // the filter of the fine grid is not asked for again
  for_each_extended_step(
      model, std::span<const double>(fine_time), std::span<const double>(fine_x),
      std::span<const double>(fine_normal), fine_windows,
      [&](std::size_t k, const ExtendedMotion<double>&, double force) {
        if (k % steps == 0) out[k / steps] = force;
      },
      std::span<const double>());
  return out;
}

double measurement_floor_rss(const State& s, const std::vector<double>& rho, const Record& r,
                             const DerivativeWindows& w, unsigned threads,
                             const DerivativeWindows* fine_windows) {
  if (r.size() < 8 || s.base.size() == 0) return 0.0;
  const std::vector<double> initial = deflections_from_relative(s.base, rho, s.ext);
  const std::vector<double> own = slip_force(s, initial, r, w);
  const auto squared_change = [&](const std::vector<double>& f) {
    double sum = 0;
    for (std::size_t k = 0; k < f.size(); ++k) sum += (f[k] - own[k]) * (f[k] - own[k]);
    return sum;
  };
  // The sensor's part.
  const Resolution sensor = estimate_displacement_resolution(r.measured());
  std::vector<double> sums(kSensorReplicas, 0.0);
  std::vector<char> made(kSensorReplicas, 0);
  // The stepping's part (below) as one more task beside the replicas: the slowest, first.
  double stepping_part = 0;
  std::vector<std::size_t> order{kSensorReplicas};
  for (std::size_t j = 0; j < kSensorReplicas; ++j) order.push_back(j);
  detail::parallel_for(kSensorReplicas + 1, threads, [&](std::size_t j) {
    if (j == kSensorReplicas) {
      stepping_part = squared_change(stepped_finely(s, initial, r, fine_windows));
      return;
    }
    Record replica;
    DerivativeWindows rw;
    if (!remeasured_replica(r, replica_seed(j), replica, sensor, &rw)) return;
    const double sum = squared_change(slip_force(s, initial, replica, rw));
    if (!std::isfinite(sum)) return;
    sums[j] = sum;
    made[j] = 1;
  }, order);
  double total = 0;
  std::size_t count = 0;
  for (std::size_t j = 0; j < kSensorReplicas; ++j)
    if (made[j]) total += sums[j], ++count;
  const double sensor_part = count > 0 ? total / static_cast<double>(count) : 0.0;
  return sensor_part + (std::isfinite(stepping_part) ? stepping_part : 0.0);
}

Baseline fit_baseline(const Record& est, const Record& val, const DiagnoseOptions& o) {
  const auto started = std::chrono::steady_clock::now();
  MethodOptions base = o.method;
  base.base_without_dominant_inertia = true;  // a dominant m·a is a finding, not a failure
  Baseline b{identify_model("maxwell-slip", est, base), {}, 0.0, {}, 0.0};
  b.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  const auto& ms = std::get<Extended<MaxwellSlip<double>>>(b.nlr.model.variant());
  State& s = b.state;
  s.base = ms.base().parameters();
  s.rho.resize(s.base.size());
  for (std::size_t i = 0; i < s.base.size(); ++i)
    s.rho[i] = i < b.nlr.report.initial_deflections.size()
                   ? b.nlr.report.initial_deflections[i] / s.base.threshold[i]
                   : 0.0;
  s.ext.reference_force = s.base.sliding_force();
  const ExtendedSlipRun run =
      run_extended_slip(s.base, s.ext, deflections_from_relative(s.base, s.rho, s.ext), est);
  s.rss = 0;
  for (std::size_t k = 0; k < est.size(); ++k)
    s.rss += (est.force[k] - run.force[k]) * (est.force[k] - run.force[k]);
  s.validation = extended_validation_percent(s.base, s.ext, val);
  for (const auto& w : b.nlr.report.warnings) b.warnings.push_back("baseline NLR: " + w);
  b.operator_drop = one_more_operator(est, b.nlr, s.base.size(), o, b.warnings);
  return b;
}

std::optional<Finding> fit_lugre_baseline(const Context& c, const Baseline& nlr, Diagnosis& dx) {
  const IdentifiedModel lg = identify_model("lugre", c.est, c.options.method);
  const Validation lv = validate_model(lg.model, c.val);
  dx.baseline_model = lg.model;
  dx.baseline_validation_percent = lv.errors.rss_sss_percent;
  dx.baseline_estimation_percent = lg.report.estimation.rss_sss_percent;
  dx.baseline_evidence.rss_sss_percent = lv.errors.rss_sss_percent;
  dx.baseline_evidence.noise_sigma = lv.noise_sigma;
  dx.baseline_evidence.noise_floor_percent = lv.noise_floor_percent;
  for (const auto& w : lg.report.warnings) dx.warnings.push_back("baseline LG: " + w);

  // The one candidate: Maxwell Slip elements (nonlocal memory), i.e. the NLR baseline.
  const State& ms = nlr.state;
  const double rss_lg = lg.report.estimation.rss;
  const std::size_t p_lg = lg.model.parameter_count(), p_ms = 2 * ms.base.size();
  const double dbic_full = bayesian_information_criterion(ms.rss, c.n, p_ms) -
                           bayesian_information_criterion(rss_lg, c.n, p_lg);
  CandidateFit cf;
  cf.nonlocal_memory = true;
  cf.base = ms.base;
  cf.estimation_rss = ms.rss;
  cf.estimation_percent = statistics::rss_sss_percent(c.est.force, ms.rss);
  cf.delta_bic = dbic_full;
  cf.verdict = accept(c, rss_lg, ms.rss, 0, lv.errors.rss_sss_percent, ms.validation);
  cf.required_drop = cf.verdict.required;
  cf.validation_percent = ms.validation;
  cf.earns_place = cf.verdict.earns_place() && dbic_full < 0;
  dx.first_round.push_back(cf);
  if (!cf.earns_place) return std::nullopt;

  Finding f;
  f.elements = ms.base.size();
  f.validation_before = lv.errors.rss_sss_percent;
  f.validation_after = ms.validation;
  f.estimation_before = dx.baseline_estimation_percent;
  f.estimation_after = cf.estimation_percent;
  f.delta_bic = dbic_full;
  return f;
}

}  // namespace friction::diagnose_detail
