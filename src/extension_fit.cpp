// Joint fit of Maxwell Slip and extension pieces (see extension_fit.hpp for the method).
#include "friction/extension_fit.hpp"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "friction/identification.hpp"
#include "friction/initial_state.hpp"
#include "friction/metrics.hpp"

#include "bounded_solver.hpp"
#include "compressed_cost.hpp"
#include "extension_steps.hpp"
#include "streamed_autodiff_cost.hpp"
#include "subnormals.hpp"

namespace friction {

// ---------------------------------------------------------------------------------------------
// Free run of an extended Maxwell Slip model in double, with the regime of every sample.  The
// context is built exactly as simulate_extended builds it (tests compare the two).

ExtendedSlipRun run_extended_slip(const MaxwellSlipParameters<double>& base,
                                  const ExtensionParameters<double>& ext,
                                  std::span<const double> initial, const Record& r) {
  const std::size_t n = r.size();
  Extended<MaxwellSlip<double>> model(MaxwellSlip<double>(base), ext, 2);
  set_extended_slip_state(model, initial);
  const double asymmetry = ext.asymmetry ? ext.asymmetry->asymmetry : 0.0;
  ExtendedSlipRun out;
  out.force.resize(n);
  out.sliding.resize(n);
  out.velocity.resize(n);
  out.acceleration.resize(n);
  for_each_extended_step(
      model, std::span<const double>(r.time), std::span<const double>(r.displacement),
      std::span<const double>(r.normal), nullptr,
      [&](std::size_t k, const ExtendedMotion<double>& c, double force) {
        out.force[k] = force;
        out.sliding[k] = model.base().sliding(model.level(), asymmetry) ? 1 : 0;
        out.velocity[k] = c.piece_velocity;
        out.acceleration[k] = c.acceleration;
      },
      std::span<const double>(r.measured_displacement));
  return out;
}

// ---------------------------------------------------------------------------------------------
// The cost: residuals of the extended model's free run, parameters in two blocks:
//   theta = [log k (M), log Delta (M), extension parameters in for_each_parameter order]
//   rho   = relative initial deflections (M), in [-1, 1], then the lag's offset u [m/s] with a
//           frictional-lag piece (extended_state_size)
// The extension template fixes which pieces are on and the reference force F0.

namespace {

struct ExtendedCost {
  const Record* record;
  std::size_t operators;
  ExtensionParameters<double> pieces;
  double scale;               // 1 / rms(F)
  DerivativeWindows windows;  // the record's, computed once

  // Hands residual k to visit(k, residual_k) in sample order (streamed_autodiff_cost.hpp).
  template <typename T, class Visit>
  bool operator()(T const* const* p, Visit&& visit) const {
    using std::exp;
    const std::size_t m = operators;
    MaxwellSlipParameters<T> mp;
    mp.stiffness.resize(m);
    mp.threshold.resize(m);
    for (std::size_t i = 0; i < m; ++i) {
      mp.stiffness[i] = exp(p[0][i]);
      mp.threshold[i] = exp(p[0][m + i]);
    }
    ExtensionParameters<T> ext = pieces.template cast<T>([](double v) { return T(v); });
    std::size_t j = 2 * m;
    ext.for_each_parameter([&](Effect, std::string_view, T& v) { v = p[0][j++]; });
    ext.reference_force = T(pieces.reference_force);
    try {
      Extended<MaxwellSlip<T>> model(MaxwellSlip<T>(std::move(mp)), std::move(ext), 2);
      std::vector<T> d(m);
      const T a = model.extensions().asymmetry ? model.extensions().asymmetry->asymmetry : T(0);
      for (std::size_t i = 0; i < m; ++i) d[i] = (p[1][i] + a) * exp(p[0][m + i]);
      model.base().reset(std::span<const T>(d), model.asymmetry());
      if (pieces.frictional_lag) model.set_initial_lag_offset(p[1][m]);
      visit_extended_residuals(model, *record, scale, windows, visit);
    } catch (const InvalidParameter&) {
      return false;  // outside the domain: Ceres rejects the step
    }
    return true;
  }
};

// The same Jacobian at a fraction of the cost, from the structure of the model.  Forward-mode
// differentiation of the whole model carries every parameter through every operator: 3M + E lanes
// (in passes of 16) on each of the M operators, although operator i depends only on its own
// (log k_i, log Delta_i, rho_i) and on what the pieces hand to the base.  And the pieces never see
// the base: the level (Stribeck, position, drift, normal load, through the lag), the shifted
// increment dx (delay), the asymmetry a and the added force (viscous, offset, inertia) follow from
// the record and the E piece parameters alone, and MaxwellSlip::step is a sum of independent
// operators (maxwell_slip.hpp, eqs. 4-5).  So:
//   1. the pieces run once over the record with Jets of the E piece parameters, on a base whose
//      one operator has stiffness 0 (it contributes nothing): the slip limits' factors
//      level (1 +- a), dx_k and the added force;
//   2. each operator runs alone with Jets of those E lanes plus its log Delta_i and rho_i, with the
//      limits and increments of pass 1.  Its force k_i delta_i is linear in k_i, so the log k_i
//      column is k_i delta_i, and the other lanes are k_i times delta_i's.
// About M (E + 2) lanes per sample instead of M (3M + E) rounded up to passes of 16: at M = 5 and
// one piece parameter 5 x 4 against 5 x 16.  The arithmetic of every lane is the one of the full
// model, so the Jacobian agrees with it to rounding (the test compares them).  It needs F0 given
// (a reference force > 0: otherwise F0 is the base's sliding force and couples all operators) and
// E + 2 <= 16; other fits keep the whole-model derivatives.
class StructuredSlipCost final : public ceres::CostFunction, public detail::RowStreamingCost {
 public:
  explicit StructuredSlipCost(ExtendedCost* functor)
      : functor_(functor),
        whole_(std::unique_ptr<ExtendedCost>(functor),
               {static_cast<int>(2 * functor->operators + pieces()),
                static_cast<int>(functor->operators + lag())},
               static_cast<int>(functor->record->size())) {
    *mutable_parameter_block_sizes() = whole_.parameter_block_sizes();
    set_num_residuals(whole_.num_residuals());
  }

  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    if (!jacobians || !structured()) return whole_.Evaluate(p, residuals, jacobians);
    const bool requested[2] = {jacobians[0] != nullptr, jacobians[1] != nullptr};
    const std::size_t cols = 2 * functor_->operators + pieces();
    const std::size_t states = functor_->operators + lag();
    return EvaluateRows(p, residuals, requested, [&](std::size_t k, const double* const* rows) {
      if (jacobians[0]) std::copy_n(rows[0], cols, jacobians[0] + k * cols);
      if (jacobians[1]) std::copy_n(rows[1], states, jacobians[1] + k * states);
    });
  }

  bool streams() const override { return structured() || whole_.streams(); }

  bool EvaluateRows(double const* const* p, double* residuals, const bool* requested,
                    const RowVisitor& visit) const override {
    if (!structured()) return whole_.EvaluateRows(p, residuals, requested, visit);
    if (!(*functor_)(p, [&](std::size_t k, double e) { residuals[k] = e; })) return false;
    const std::size_t e = pieces() + lag();
    if (e + 2 <= 4) return jacobian<4, 4>(p, requested, visit);
    if (e <= 4) return jacobian<4, 8>(p, requested, visit);
    if (e + 2 <= 8) return jacobian<8, 8>(p, requested, visit);
    if (e <= 8) return jacobian<8, 16>(p, requested, visit);
    return jacobian<16, 16>(p, requested, visit);
  }

  const ceres::CostFunction& whole_model() const { return whole_; }

  /// Whether Evaluate takes the structured path (see above).
  bool structured() const {
    return functor_->pieces.reference_force > 0 && pieces() + lag() + 2 <= 16;
  }

 private:
  std::size_t pieces() const {
    std::size_t e = 0;
    functor_->pieces.for_each_parameter([&](Effect, std::string_view, const double&) { ++e; });
    return e;
  }
  // 1 with the lag's initial offset in block 1 (after the M deflections), else 0.
  std::size_t lag() const { return functor_->pieces.frictional_lag ? 1 : 0; }

  // NF lanes for the pieces' pass (>= E, plus the lag's offset u when there is one: it is felt
  // only through the pieces), NO for an operator's (>= those + 2: its log Delta and rho; its log k
  // enters linearly and is differentiated by hand).  The operators step in lockstep with the
  // pieces, sample by sample, so that a row is complete when it is handed over and nothing of
  // length N is kept: the memory of an evaluation does not grow with the record.
  template <int NF, int NO>
  bool jacobian(double const* const* p, const bool* requested, const RowVisitor& visit) const {
    static_assert(NO >= NF, "an operator's Jets carry the pieces' lanes");
    using JF = ceres::Jet<double, NF>;
    using JO = ceres::Jet<double, NO>;
    using std::exp;
    const ExtendedCost& f = *functor_;
    const Record& r = *f.record;
    const std::size_t m = f.operators, e = pieces(), l = lag();
    const std::size_t cols = 2 * m + e, states = m + l;
    ExtensionParameters<JF> ext = f.pieces.template cast<JF>([](double v) { return JF(v); });
    std::size_t j = 0;
    ext.for_each_parameter([&](Effect, std::string_view, JF& v) {
      v = JF(p[0][2 * m + j], static_cast<int>(j));
      ++j;
    });
    ext.reference_force = JF(f.pieces.reference_force);
    auto lift = [](const JF& v) {
      JO out(v.a);
      out.v.template head<NF>() = v.v;
      return out;
    };
    std::vector<double> theta_row(cols), state_row(states);
    const double* rows[2] = {requested[0] ? theta_row.data() : nullptr,
                             requested[1] ? state_row.data() : nullptr};
    std::vector<JO> delta(m), limit(m);
    std::vector<double> stiffness(m);
    const int own = static_cast<int>(e + l);
    JO a(0);
    try {
      // The pieces over the record (with a base whose one operator has stiffness 0); the added
      // force starts the pieces' columns of each row.
      MaxwellSlipParameters<JF> silent;
      silent.stiffness = {JF(0)};
      silent.threshold = {JF(1)};
      Extended<MaxwellSlip<JF>> pieces_only(MaxwellSlip<JF>(std::move(silent), true),
                                            std::move(ext), 2);
      if (l) pieces_only.set_initial_lag_offset(JF(p[1][m], static_cast<int>(e)));
      const JF af = pieces_only.asymmetry();
      a = lift(af);
      for_each_extended_step(
          pieces_only, std::span<const double>(r.time), std::span<const double>(r.displacement),
          std::span<const double>(r.normal), &f.windows,
          [&](std::size_t k, const ExtendedMotion<JF>& c, const JF& added) {
            const JF& level = pieces_only.level();
            if (k == 0) {  // the state is given at level 1 (extensions.hpp: Initial state)
              const JO level0 = lift(level);
              for (std::size_t i = 0; i < m; ++i) {
                stiffness[i] = exp(p[0][i]);
                limit[i] = exp(JO(p[0][m + i], own));
                delta[i] = clamp(JO((JO(p[1][i], own + 1) + a) * limit[i]),
                                 JO(-(JO(1) - a) * limit[i]), JO((JO(1) + a) * limit[i]));
                delta[i] *= level0;
              }
            }
            const JO dx = lift(c.dx), turn = lift(c.turn);
            // The slip limits of maxwell_slip.hpp's step, hi = up limit_i and lo = -down limit_i.
            const JO up = lift(level * (JF(1) + af));
            const JO minus_down = -lift(level * (JF(1) - af));
            const JF& at_turn = pieces_only.turn_level();  // motion.hpp: The level at the turn
            const bool turned = turn.a != 0.0;              // motion.hpp, Turns between samples
            JO up_turn, minus_down_turn;
            if (turned) {
              up_turn = lift(at_turn * (JF(1) + af));
              minus_down_turn = -lift(at_turn * (JF(1) - af));
            }
            for (std::size_t q = 0; q < e; ++q) theta_row[2 * m + q] = -f.scale * added.v[q];
            if (l) state_row[m] = -f.scale * added.v[e];
            // Each operator (eqs. 4-5 of maxwell_slip.hpp, one operator; a limit's product formed
            // only when it binds, scalar.hpp: clamp_to_limits).
            for (std::size_t i = 0; i < m; ++i) {
              JO& d = delta[i];
              if (turned)
                d = clamp_to_limits(
                    JO(clamp_to_limits(JO(d + turn), minus_down_turn, up_turn, limit[i]) +
                       (dx - turn)),
                    minus_down, up, limit[i]);
              else
                d = clamp_to_limits(JO(d + dx), minus_down, up, limit[i]);
              const double g = -f.scale * stiffness[i];  // d residual / d delta
              for (std::size_t q = 0; q < e; ++q) theta_row[2 * m + q] += g * d.v[q];
              theta_row[i] = g * d.a;  // d(k delta) / d log k = k delta
              theta_row[m + i] = g * d.v[own];
              state_row[i] = g * d.v[own + 1];
              if (l) state_row[m] += g * d.v[e];
            }
            visit(k, rows);
          },
          std::span<const double>(r.measured_displacement));
    } catch (const InvalidParameter&) {
      return false;
    }
    return true;
  }

  ExtendedCost* functor_;  // owned by whole_
  detail::StreamedAutoDiffCost<ExtendedCost> whole_;
};

}  // namespace

ExtendedSlipJacobian extended_slip_jacobian(const Record& r,
                                            const MaxwellSlipParameters<double>& base,
                                            const std::vector<double>& rho,
                                            const ExtensionParameters<double>& ext,
                                            bool whole_model) {
  const std::size_t m = base.size(), n = r.size();
  const std::size_t states = extended_state_size(m, ext);
  FRICTION_CHECK(rho.size() == states, "extended_slip_jacobian: ", rho.size(),
                 " initial states for ", states, " (", m, " operators)");
  std::vector<double> theta;
  for (double k : base.stiffness) theta.push_back(std::log(k));
  for (double d : base.threshold) theta.push_back(std::log(d));
  ext.for_each_parameter([&](Effect, std::string_view, const double& v) { theta.push_back(v); });
  const double rms = std::sqrt(sum_of_squares(r.force) / static_cast<double>(n));
  StructuredSlipCost cost(
      new ExtendedCost{&r, m, ext, rms > 0 ? 1.0 / rms : 1.0, record_derivative_windows(r)});
  ExtendedSlipJacobian out;
  out.structured = !whole_model && cost.structured();
  out.residual.resize(static_cast<Eigen::Index>(n));
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> jt(n, theta.size()),
      jr(n, states);
  const double* p[] = {theta.data(), rho.data()};
  double* j[] = {jt.data(), jr.data()};
  out.ok = whole_model ? cost.whole_model().Evaluate(p, out.residual.data(), j)
                       : cost.Evaluate(p, out.residual.data(), j);
  out.theta = jt;
  out.rho = jr;
  return out;
}

// Box of each extension parameter during the fit: the effect table's rule over the record's scales.
ExtensionBounds extension_parameter_bounds(Effect e, std::string_view name, double f0,
                                           double duration, double vmax) {
  const double inf = std::numeric_limits<double>::infinity();
  const EffectParameter* p = find_parameter(e, name);
  if (!p) return {-inf, inf};
  const RecordScales scales{f0, duration, vmax};
  return {p->lower(scales), p->upper(scales)};
}

// Fits theta (and rho) from the given start; `fix_theta` estimates the initial state only.
ExtendedSlipFit fit_extended_slip(const Record& r, const MaxwellSlipParameters<double>& base0,
                                  const std::vector<double>& rho0,
                                  const ExtensionParameters<double>& ext0, bool fix_theta,
                                  int max_iterations) {
  return extension_detail::fit_extended_slip_within_reach(
      r, base0, rho0, ext0, fix_theta, max_iterations, std::numeric_limits<double>::infinity());
}

ExtendedSlipFit extension_detail::fit_extended_slip_within_reach(
    const Record& r, const MaxwellSlipParameters<double>& base0, const std::vector<double>& rho0,
    const ExtensionParameters<double>& ext0, bool fix_theta, int max_iterations,
    double target_rss, bool* stopped, bool settled_trust_region) {
  const detail::SubnormalsFlushed subnormals_flushed;  // subnormals.hpp
  const std::size_t m = base0.size();
  std::vector<double> theta;
  for (std::size_t i = 0; i < m; ++i) theta.push_back(std::log(base0.stiffness[i]));
  for (std::size_t i = 0; i < m; ++i) theta.push_back(std::log(base0.threshold[i]));
  std::vector<std::pair<Effect, std::string>> names;
  ext0.for_each_parameter([&](Effect e, std::string_view name, const double& v) {
    theta.push_back(v);
    names.emplace_back(e, std::string(name));
  });
  std::vector<double> rho(rho0);
  const std::size_t states = extended_state_size(m, ext0);
  rho.resize(states, 0.0);
  const double lag_bound = lag_offset_bound(r);
  for (std::size_t i = 0; i < states; ++i) {
    const double b = i < m ? 1.0 : lag_bound;
    rho[i] = std::clamp(rho[i], -b, b);
  }

  double rms = std::sqrt(sum_of_squares(r.force) / static_cast<double>(r.size()));
  auto* cost = new StructuredSlipCost(
      new ExtendedCost{&r, m, ext0, rms > 0 ? 1.0 / rms : 1.0, record_derivative_windows(r)});
  ceres::Problem problem;
  problem.AddResidualBlock(new detail::CompressedCost(cost), nullptr, theta.data(), rho.data());
  for (std::size_t i = 0; i < states; ++i) {
    const double b = i < m ? 1.0 : lag_bound;
    problem.SetParameterLowerBound(rho.data(), static_cast<int>(i), -b);
    problem.SetParameterUpperBound(rho.data(), static_cast<int>(i), b);
  }
  const double duration = record_duration(r);
  const double vmax = largest_interval_speed(r);
  const double f0 = ext0.reference_force > 0 ? ext0.reference_force : base0.sliding_force();
  for (std::size_t j = 0; j < names.size(); ++j) {
    const ExtensionBounds b = extension_parameter_bounds(names[j].first, names[j].second, f0,
                                                         duration, vmax);
    double& v = theta[2 * m + j];
    v = std::clamp(v, b.lower, b.upper);
    if (std::isfinite(b.lower))
      problem.SetParameterLowerBound(theta.data(), static_cast<int>(2 * m + j), b.lower);
    if (std::isfinite(b.upper))
      problem.SetParameterUpperBound(theta.data(), static_cast<int>(2 * m + j), b.upper);
  }
  // Thresholds inside [q, L] as NLR keeps them (nlr.hpp): an operator beyond the travel with a
  // large initial deflection would otherwise act as a free offset.
  {
    const double q = displacement_resolution(r.measured());
    const double big = std::max(largest_travel(r.displacement), q * 1.0001);
    for (std::size_t i = 0; i < m; ++i) {
      double& v = theta[m + i];
      const double lo = std::log(std::min(q, base0.threshold[i]));
      const double hi = std::log(std::max(big, base0.threshold[i]));
      v = std::clamp(v, lo, hi);
      problem.SetParameterLowerBound(theta.data(), static_cast<int>(m + i), lo);
      problem.SetParameterUpperBound(theta.data(), static_cast<int>(m + i), hi);
    }
  }
  if (fix_theta) {
    problem.SetParameterBlockConstant(theta.data());
  } else {
    // Parameters derived rather than fitted (effect_table.hpp: held_in_fit) stay where the start
    // put them.
    std::vector<int> held;
    for (std::size_t j = 0; j < names.size(); ++j)
      if (held_in_fit(names[j].first, names[j].second)) held.push_back(static_cast<int>(2 * m + j));
    if (!held.empty())
      problem.SetManifold(theta.data(),
                          new ceres::SubsetManifold(static_cast<int>(theta.size()), held));
  }

  ceres::Solver::Options options;
  options.minimizer_type = ceres::TRUST_REGION;
  options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = max_iterations;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  options.minimizer_progress_to_stdout = false;
  // 0.01 BIC units per step: far below any decision here.
  options.function_tolerance = detail::resolved_function_tolerance(r.size());
  options.parameter_tolerance = 1e-9;
  detail::use_value_only_line_search(options);
  // The cost is 0.5 RSS / rms^2.  No noise rule: a fit whose result is compared with others is
  // run to the same tolerance whatever its noise.
  const double residual_scale = rms > 0 ? 1.0 / rms : 1.0;
  detail::HopelessSearch hopeless(0.5 * target_rss * residual_scale * residual_scale, 0.0,
                                  max_iterations, settled_trust_region);
  if (std::isfinite(target_rss)) options.callbacks.push_back(&hopeless);
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  if (stopped) *stopped = hopeless.stopped();

  ExtendedSlipFit out;
  out.base.stiffness.resize(m);
  out.base.threshold.resize(m);
  for (std::size_t i = 0; i < m; ++i) {
    out.base.stiffness[i] = std::exp(theta[i]);
    out.base.threshold[i] = std::exp(theta[m + i]);
  }
  out.ext = ext0;
  std::size_t j = 2 * m;
  out.ext.for_each_parameter([&](Effect, std::string_view, double& v) { v = theta[j++]; });
  // The phase is fitted unbounded (a box would cut the circle): reported in [0, 2 pi), with a
  // positive amplitude (the same force; the tribometer's fit ended at 87.7 rad).
  if (auto& pd = out.ext.position_dependence) {
    if (pd->amplitude < 0) {
      pd->amplitude = -pd->amplitude;
      pd->phase += M_PI;
    }
    pd->phase -= 2 * M_PI * std::floor(pd->phase / (2 * M_PI));
  }
  for (std::size_t q = 0; q < names.size(); ++q) {
    if (held_in_fit(names[q].first, names[q].second)) continue;
    const ExtensionBounds b = extension_parameter_bounds(names[q].first, names[q].second, f0,
                                                         duration, vmax);
    const double v = theta[2 * m + q];
    auto on = [&](double edge) {
      return std::isfinite(edge) && std::abs(v - edge) <= 1e-9 * std::max(1.0, std::abs(edge));
    };
    if (on(b.lower) || on(b.upper)) out.at_bound.push_back(names[q]);
  }
  out.rho = rho;
  out.ok = summary.IsSolutionUsable();
  out.rss = out.ok ? 2.0 * summary.final_cost * rms * rms : std::numeric_limits<double>::infinity();
  return out;
}

double record_duration(const Record& r) {
  return std::max(r.time.back() - r.time.front(), 1e-12);
}

double largest_interval_speed(const Record& r) {
  double vmax = 0;
  for (std::size_t k = 1; k < r.size(); ++k)
    vmax = std::max(
        vmax, std::abs(r.displacement[k] - r.displacement[k - 1]) / (r.time[k] - r.time[k - 1]));
  return std::max(vmax, 1e-12);
}

double lag_offset_bound(const Record& r) { return 2.0 * largest_interval_speed(r); }

double own_reference_ratio(const ExtensionParameters<double>& ext, double own_f0) {
  return ext.reference_force > 0 ? own_f0 / ext.reference_force : 1.0;
}

ExtensionParameters<double> to_own_reference(const ExtensionParameters<double>& ext,
                                             double own_f0) {
  ExtensionParameters<double> out = ext;
  const double ratio = own_reference_ratio(ext, own_f0);
  out.reference_force = 0.0;
  out.for_each_parameter([&](Effect e, std::string_view name, double& v) {
    if (find_parameter(e, name)->scales_with_reference_force) v *= ratio;
  });
  return out;
}

std::vector<double> deflections_from_relative(const MaxwellSlipParameters<double>& base,
                                              const std::vector<double>& rho,
                                              const ExtensionParameters<double>& ext) {
  const double a = ext.asymmetry ? ext.asymmetry->asymmetry : 0.0;
  std::vector<double> d(base.size());
  for (std::size_t i = 0; i < base.size(); ++i) d[i] = (rho[i] + a) * base.threshold[i];
  if (ext.frictional_lag) d.push_back(rho.size() > base.size() ? rho[base.size()] : 0.0);
  return d;
}

double first_level(const MaxwellSlipParameters<double>& base,
                   const ExtensionParameters<double>& ext, const Record& r,
                   const DerivativeWindows* windows) {
  if (r.size() == 0 || !(ext.stribeck || ext.position_dependence || ext.drift || ext.normal_load))
    return 1.0;
  Extended<MaxwellSlip<double>> model(MaxwellSlip<double>(base), ext, 2);
  double level = 1.0;
  for_each_extended_step(
      model, std::span<const double>(r.time), std::span<const double>(r.displacement),
      std::span<const double>(r.normal), windows,
      [&](std::size_t k, const ExtendedMotion<double>&, double) {
        if (k == 0) level = model.level();
      },
      std::span<const double>(r.measured_displacement));
  return level;
}

std::vector<double> carried_state(const Record& r, const MaxwellSlipParameters<double>& from_base,
                                  const ExtensionParameters<double>& from_ext,
                                  const std::vector<double>& rho,
                                  const MaxwellSlipParameters<double>& to_base,
                                  const ExtensionParameters<double>& to_ext,
                                  const DerivativeWindows* windows) {
  const std::size_t m = to_base.size();
  FRICTION_CHECK(from_base.size() == m && rho.size() >= m, "carried_state: ", rho.size(),
                 " states of ", from_base.size(), " operators for ", m);
  const double from_level = first_level(from_base, from_ext, r, windows);
  const double to_level = first_level(to_base, to_ext, r, windows);
  const double a_from = from_ext.asymmetry ? from_ext.asymmetry->asymmetry : 0.0;
  const double a_to = to_ext.asymmetry ? to_ext.asymmetry->asymmetry : 0.0;
  std::vector<double> out(m);
  for (std::size_t i = 0; i < m; ++i) {
    const double d = (rho[i] + a_from) * from_level * from_base.threshold[i];
    out[i] = std::clamp(d / (to_level * to_base.threshold[i]) - a_to, -1.0, 1.0);
  }
  // The lag's offset carries over when both models have the lag (else it starts in step).
  if (to_ext.frictional_lag)
    out.push_back(from_ext.frictional_lag && rho.size() > m ? rho[m] : 0.0);
  return out;
}

// Initial state estimated from the record for fixed parameters: the plain Maxwell Slip estimate as
// a start, refined through the extended model.
std::vector<double> plain_relative_state(const MaxwellSlipParameters<double>& base,
                                         const ExtensionParameters<double>& ext, const Record& r) {
  // The force the plain operators should explain: the added terms and the asymmetry's shift of the
  // slip limits (a L0 F0, L0 the level the record starts with) removed.  Left in, an offset-like
  // part biases every operator's estimated deflection (an asymmetric model scored 2.7 % worse than
  // the offset model it equals, from its initial state alone).
  const DerivativeWindows windows = record_derivative_windows(r);
  const double level = first_level(base, ext, r, &windows);
  std::vector<double> f = r.force;
  if (ext.viscous || ext.offset || ext.inertia || ext.asymmetry) {
    std::vector<double> v(r.size()), a(r.size());
    apply_local_derivatives<double>(r.time, r.measured(), windows, v, a);
    // The shift moves operator i's box by a L0 Delta_i: its sum is a L0 times the base's own
    // sliding force, whatever reference force the level pieces use (extensions.hpp).
    const double f0 = base.sliding_force();
    for (std::size_t k = 0; k < r.size(); ++k) {
      if (ext.viscous) f[k] -= ext.viscous->viscous * v[k];
      if (ext.offset) f[k] -= ext.offset->offset;
      if (ext.inertia) f[k] -= ext.inertia->mass * a[k];
      if (ext.asymmetry) f[k] -= ext.asymmetry->asymmetry * level * f0;
    }
  }
  // Operators whose limits are those of the record's start, L0 Delta_i (the relative state is
  // relative to them: extensions.hpp, Initial state).
  MaxwellSlipParameters<double> at_start = base;
  for (double& d : at_start.threshold) d *= level;
  // With a delay the operators see the displacement at t - D (extensions.hpp), continued before
  // the record by its edge polynomial, and their state is estimated on that.  Estimated on the
  // record as recorded, it belonged to motion D later: on a record of the independent simulator
  // (D = 5 samples) the estimation error of the fitted model went 0.0591 -> 0.0510 % with this
  // (the floor 0.051 %), its validation 0.339 -> 0.303 % (README, "The initial state under a
  // delay": what is left there is a reversal before the record, which no state can carry).
  const std::vector<double> seen = displacement_the_base_sees(r, ext, windows);
  const std::vector<double> d = estimate_initial_deflections(at_start, seen, f);
  std::vector<double> rho(base.size());
  for (std::size_t i = 0; i < base.size(); ++i)
    rho[i] = std::clamp(d[i] / at_start.threshold[i], -1.0, 1.0);
  if (ext.frictional_lag) rho.push_back(0.0);  // in step with the motion
  return rho;
}

std::vector<double> estimate_relative_deflections(const MaxwellSlipParameters<double>& base,
                                                  const ExtensionParameters<double>& ext,
                                                  const Record& r, double* rss) {
  std::vector<double> rho = plain_relative_state(base, ext, r);
  ExtendedSlipFit f = fit_extended_slip(r, base, rho, ext, /*fix_theta=*/true, 30);
  // Guard: the refinement never makes it worse than its start.
  const ExtendedSlipRun start =
      run_extended_slip(base, ext, deflections_from_relative(base, rho, ext), r);
  double rss0 = 0;
  for (std::size_t k = 0; k < r.size(); ++k)
    rss0 += (r.force[k] - start.force[k]) * (r.force[k] - start.force[k]);
  if (!f.ok || f.rss > rss0) {
    if (rss) *rss = rss0;
    return rho;
  }
  if (rss) *rss = f.rss;
  return f.rho;
}
}  // namespace friction
