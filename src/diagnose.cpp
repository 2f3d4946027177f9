// diagnose(): the stages of src/diagnose_stages.hpp in order (see diagnose.hpp for the method).
#include "friction/diagnose.hpp"

#include <algorithm>
#include <chrono>
#include <optional>
#include <thread>
#include <utility>

#include "diagnose_stages.hpp"
#include "friction/metrics.hpp"
#include "joint_fit_memo.hpp"
#include "parallel_for.hpp"
#include "position_origin.hpp"
#include "subnormals.hpp"

namespace friction {

namespace {

// The candidates the record can support (normal-load needs a normal force).
std::vector<Effect> applicable(const DiagnoseOptions& o, const Record& r) {
  std::vector<Effect> out;
  for (Effect e :
       (o.candidates.empty() ? std::vector<Effect>(kAllEffects.begin(), kAllEffects.end())
                             : o.candidates))
    if (!effect_info(e).needs_normal_force || r.has_normal()) out.push_back(e);
  return out;
}

// A first-round candidate that one more operator would beat: the baseline may be short of them.
void warn_if_short_of_operators(Diagnosis& dx) {
  for (const auto& c : dx.first_round)
    if (c.verdict.fitted && !c.verdict.drop_exceeds() && c.verdict.operator_limited) {
      dx.warnings.push_back(
          "one more Maxwell Slip operator lowers the estimation error more than " +
          std::string(effect_name(c.effect)) +
          " would: the baseline may be short of operators (raise max_operators)");
      return;
    }
}

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace

Diagnosis diagnose(const Record& est_as_recorded, const Record& val_as_recorded,
                   const DiagnoseOptions& options) {
  const detail::SubnormalsFlushed subnormals_flushed;  // subnormals.hpp
  // The diagnosis's thread count is every stage's, the baseline's order selection and the
  // restarts' included (MethodOptions::threads would otherwise mean one per core).
  DiagnoseOptions o = options;
  o.method.threads = o.threads;
  using namespace diagnose_detail;
  const auto started = std::chrono::steady_clock::now();
  FRICTION_CHECK(est_as_recorded.has_force() && val_as_recorded.has_force(),
                 "diagnose: both records need a force");
  FRICTION_CHECK(o.baseline == "maxwell-slip" || o.baseline == "lugre",
                 "diagnose: baseline must be maxwell-slip or lugre, not ", o.baseline);
  // A position-dependence candidate is fitted about the estimation record's first position, as
  // every candidate sees it: both records shifted by it, the phase carried back to the origin at
  // the end (position_origin.hpp).
  const std::vector<Effect> candidates = applicable(o, est_as_recorded);
  const double x_ref = std::find(candidates.begin(), candidates.end(),
                                 Effect::position_dependence) != candidates.end() &&
                               !est_as_recorded.displacement.empty()
                           ? est_as_recorded.displacement.front()
                           : 0.0;
  Record est_shifted, val_shifted;
  if (x_ref != 0.0) {
    est_shifted = detail::shifted_record(est_as_recorded, x_ref);
    val_shifted = detail::shifted_record(val_as_recorded, x_ref);
  }
  const Record& est = x_ref != 0.0 ? est_shifted : est_as_recorded;
  const Record& val = x_ref != 0.0 ? val_shifted : val_as_recorded;
  Diagnosis dx;
  const std::size_t n = est.size();
  const double sigma = estimate_white_noise_sigma(est.force);
  const double floor_rss = static_cast<double>(n) * sigma * sigma;

  // The baseline's fit runs one NLR fit at a time; beside it, what the floors below need of each
  // record that no model changes: its derivative windows, those of its refined grid
  // (stepped_finely), and those of its sensor's replicas (remembered by remeasured_replica).  On
  // data/ those were 0.24 s of work, the baseline's fit 0.24 s, on two threads one after the
  // other.
  const unsigned all_threads =
      o.threads ? o.threads : std::max(1u, std::thread::hardware_concurrency());
  std::optional<Baseline> fitted_baseline;
  DerivativeWindows windows_est, windows_val, fine_est, fine_val;
  {
    constexpr std::size_t kPerRecord = 2 + kSensorReplicas;
    // Without the floors, only the estimation record's windows (task 1).
    const std::size_t tasks = 1 + (o.measurement_floor ? 2 * kPerRecord : 1);
    detail::parallel_for(tasks, o.threads, [&](std::size_t t) {
      if (t == 0) {
        // One thread fewer for the baseline's own starts: the windows take the other, and the
        // diagnosis stays within its threads (and is no slower: 2.55 against 2.58 s, medians of
        // 5 on data/ in turn, two threads).
        DiagnoseOptions for_baseline = o;
        for_baseline.method.threads = std::max(1u, all_threads - 1);
        fitted_baseline.emplace(fit_baseline(est, val, for_baseline));
        return;
      }
      const bool on_est = (t - 1) % 2 == 0;
      const Record& r = on_est ? est : val;
      const std::size_t part = (t - 1) / 2;
      if (part == 0) {
        (on_est ? windows_est : windows_val) = record_derivative_windows(r);
      } else if (part == 1) {
        (on_est ? fine_est : fine_val) = fine_grid_windows(r);
      } else {
        warm_sensor_replica(r, part - 2);
      }
    });
  }
  const Baseline& b = *fitted_baseline;
  dx.baseline_seconds = b.seconds;
  dx.warnings = b.warnings;
  dx.operator_drop = b.operator_drop;
  // The floors of rule (c) (diagnose.hpp, section 4): besides the force noise's, what the
  // displacement's sampling does to the baseline's force on each record (the initial state on
  // the validation record estimated there, as the validation error's is).
  // The work on either record is independent of the other's: the two run concurrently, each
  // with half the threads for its replicas (the floors were 0.25 s of a diagnosis of data/ on two
  // threads, one after the other, 0.10 and 0.11 s, with 0.04 s of the validation record's initial
  // state before them).
  const bool nlr_baseline = o.baseline != "lugre";
  std::vector<double> rho_v;
  std::optional<ProfileScales> scales;
  const unsigned half = std::max(1u, all_threads / 2);
  detail::parallel_for(2, o.threads, [&](std::size_t record) {
    if (record == 0) {
      if (o.measurement_floor)
        dx.estimation_measurement_floor_percent =
            100.0 * measurement_floor_rss(b.state, b.state.rho, est, windows_est, half, &fine_est) /
            sum_of_squares(est.force);
      scales = profile_scales(
          est,
          run_extended_slip(b.state.base, b.state.ext,
                            deflections_from_relative(b.state.base, b.state.rho, b.state.ext), est),
          b.state.ext.reference_force);
      return;
    }
    rho_v = estimate_relative_deflections(b.state.base, b.state.ext, val, nullptr);
    if (o.measurement_floor)
      dx.validation_measurement_floor_percent =
          100.0 *
          measurement_floor_rss(b.state, rho_v, val, windows_val, half, &fine_val) /
          sum_of_squares(val.force);
    if (nlr_baseline) dx.baseline_evidence = gather_evidence(b.state.base, b.state.ext, val, rho_v);
  });
  extension_detail::JointFitMemo joint_fits(est);
  const Context c{
      est,
      val,
      o,
      n,
      sigma,
      floor_rss,
      b.state.ext.reference_force,
      b.operator_drop,
      std::max(b.state.rss - floor_rss, 0.0),
      dx.estimation_measurement_floor_percent / 100.0 * sum_of_squares(est.force),
      windows_est,
      *scales,
      noise_floor_rss_sss_percent(val.force, estimate_white_noise_sigma(val.force)),
      dx.validation_measurement_floor_percent,
      x_ref,
      &joint_fits,
      o.measurement_floor ? &fine_est : nullptr};

  if (o.baseline == "lugre") {
    std::optional<Finding> nonlocal = fit_lugre_baseline(c, b, dx);
    if (!nonlocal) {
      dx.final_model = dx.baseline_model;
      dx.final_validation_percent = dx.baseline_validation_percent;
      dx.final_estimation_percent = dx.baseline_estimation_percent;
      dx.seconds = seconds_since(started);
      return dx;
    }
    dx.findings.push_back(std::move(*nonlocal));
  } else {
    dx.baseline_model = b.nlr.model;
    dx.baseline_validation_percent = b.state.validation;
    dx.baseline_estimation_percent = 100.0 * b.state.rss / sum_of_squares(est.force);
  }

  Chain chain = forward_pass(c, b.state, candidates, dx.first_round);
  warn_if_short_of_operators(dx);
  chain = backward_pass(c, std::move(chain));
  polish_final(c, chain);
  dx.warnings.insert(dx.warnings.end(), chain.warnings.begin(), chain.warnings.end());
  report(c, chain, dx);
  for (CandidateFit& cand : dx.first_round) detail::phase_to_origin(cand.extensions, x_ref);
  dx.seconds = seconds_since(started);
  return dx;
}

}  // namespace friction
