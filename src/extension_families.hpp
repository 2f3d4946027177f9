// The model families an extension fit runs on (Maxwell Slip, DNLRX, LuGre bases), their cost,
// their fit and the covariance at an optimum: the machinery of extension_identification.hpp
// (sections 1, 2 and 4 of its header comment), private to the library.
//
// A family says how to build Extended<Base<T>> from two parameter blocks and set its initial
// state: block 0 = [free base parameters (when the base is refitted), piece parameters], block 1
// = the initial state in relative units.  Each family also gives the box of its base parameters,
// which of them stay fixed, and their report entries.  Everything here takes its inputs by const
// reference and returns values: fits of different candidates share nothing (the residual loop's
// buffers are per thread, extension_fit.hpp).
#pragma once

#include <ceres/ceres.h>

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "friction/covariance_report.hpp"
#include "friction/dnlrx.hpp"
#include "friction/extension_fit.hpp"
#include "friction/extensions.hpp"
#include "friction/identification.hpp"
#include "friction/lg.hpp"
#include "friction/lugre.hpp"
#include "friction/maxwell_slip.hpp"
#include "friction/metrics.hpp"
#include "friction/noise_colour.hpp"
#include "friction/record.hpp"
#include "friction/signals.hpp"

#include "bounded_solver.hpp"
#include "compressed_cost.hpp"
#include "streamed_autodiff_cost.hpp"

namespace friction::extension_detail {

inline double sum_sq(const std::vector<double>& v) {
  double s = 0;
  for (double e : v) s += e * e;
  return s;
}

inline bool at_bound(double v, double bound) {
  if (!std::isfinite(bound)) return false;
  return v == bound || std::abs(v - bound) <= 1e-6 * std::max(std::abs(bound), std::abs(v));
}

// ---------------------------------------------------------------------------------------------
// Model families: how to build Extended<Base<T>> from the parameter blocks and set its initial
// state.  Block 0 = [free base parameters (when the base is refitted), piece parameters], block 1
// = the initial state in relative units.  Each family also gives the box of its base parameters,
// which of them stay fixed, the base parameters of a block and their report entries.

struct Box {
  std::vector<double> lower, upper;
};

inline constexpr double kInf = std::numeric_limits<double>::infinity();

// Thresholds inside [q, L] as NLR and fit_extended_slip keep them (log units), widened to hold
// the start.
inline void threshold_box(Box& b, const Record& r, const std::vector<double>& thresholds) {
  const double q = displacement_resolution(r.measured());
  const double big = std::max(largest_travel(r.displacement), q * 1.0001);
  for (double d : thresholds) {
    b.lower.push_back(std::log(std::min(q, d)));
    b.upper.push_back(std::log(std::max(big, d)));
  }
}

struct SlipFamily {
  MaxwellSlipParameters<double> p;
  bool free_base = false;  // block 0 starts with log k_i, log Delta_i
  bool lag_state = false;  // block 1 ends with the lag's offset (extension_fit.hpp)
  std::size_t base_count() const { return free_base ? 2 * p.size() : 0; }
  std::size_t state_count() const { return p.size() + lag_state; }
  std::vector<double> base_theta() const {
    std::vector<double> t;
    for (double k : p.stiffness) t.push_back(std::log(k));
    for (double d : p.threshold) t.push_back(std::log(d));
    return t;
  }
  Box base_box(const Record& r) const {
    Box b;
    b.lower.assign(p.size(), -kInf);
    b.upper.assign(p.size(), kInf);
    threshold_box(b, r, p.threshold);
    return b;
  }
  std::vector<int> held(const std::vector<double>&) const { return {}; }
  // The columns (log k_i, log Delta_i) of the operators whose whole force is below what the record
  // resolves, k_i Delta_i < `resolution` (report_joint_fit).  A profile's bounded solve leaves an
  // operator it wants at zero stiffness with a negligible one (it is fitted in log k), and the
  // joint fit keeps it there.  Such an operator is at its zero-stiffness bound: its columns are
  // held in the covariance, as a piece's at a bound.  Left free, it traded off with an operator
  // of the same threshold, and F0's gradient, a negligible k_i Delta_i on its columns but not in
  // the covariance's scaled coordinates, failed the estimability test: a study record (discovery
  // study, seed 11377216255824524248, position-dependence+delay; k = 1.3e-9 of the largest) gave
  // the amplitude in newtons no standard error.
  std::vector<int> unresolved(const std::vector<double>& theta, double resolution) const {
    std::vector<int> u;
    if (!free_base) return u;
    const std::size_t m = p.size();
    for (std::size_t i = 0; i < m; ++i)
      if (std::exp(theta[i] + theta[m + i]) < resolution) {
        u.push_back(static_cast<int>(i));
        u.push_back(static_cast<int>(m + i));
      }
    return u;
  }
  // F0 of the base at block 0's base part (the fitted base's own, `p`, when it is held).
  double sliding_force(const double* theta) const {
    if (!free_base) return p.sliding_force();
    double f = 0;
    for (std::size_t i = 0; i < p.size(); ++i) f += std::exp(theta[i] + theta[p.size() + i]);
    return f;
  }
  template <typename T>
  Extended<MaxwellSlip<T>> make(const T* theta, ExtensionParameters<T> ext) const {
    using std::exp;
    const std::size_t m = p.size();
    MaxwellSlipParameters<T> mp;
    mp.stiffness.resize(m);
    mp.threshold.resize(m);
    for (std::size_t i = 0; i < m; ++i) {
      mp.stiffness[i] = free_base ? exp(theta[i]) : T(p.stiffness[i]);
      mp.threshold[i] = free_base ? exp(theta[m + i]) : T(p.threshold[i]);
    }
    return Extended<MaxwellSlip<T>>(MaxwellSlip<T>(std::move(mp)), std::move(ext), 2);
  }
  template <typename T>
  void set_state(Extended<MaxwellSlip<T>>& model, const T* theta, const T* s) const {
    using std::exp;
    const std::size_t m = p.size();
    // Relative to the centre of each operator's box, a Delta_i with an asymmetry a
    // (extensions.hpp).
    const T a = model.extensions().asymmetry ? model.extensions().asymmetry->asymmetry : T(0);
    std::vector<T> d(m);
    for (std::size_t i = 0; i < m; ++i)
      d[i] = (s[i] + a) * (free_base ? exp(theta[m + i]) : T(p.threshold[i]));
    model.base().reset(std::span<const T>(d), model.asymmetry());
    if (lag_state) model.set_initial_lag_offset(s[m]);
  }
  std::vector<double> state_bounds() const { return {-1.0, 1.0}; }
  // Report entries of block 0's base part, fitted as log k_i, log Delta_i; the values are those of
  // `p` (the family is built on the fitted parameters, whose logarithms are block 0).
  std::vector<CovarianceParameter> base_parameters(const std::vector<double>&) const {
    std::vector<CovarianceParameter> out;
    const std::size_t m = p.size();
    for (std::size_t i = 0; i < 2 * m; ++i) {
      const bool stiff = i < m;
      const std::size_t idx = stiff ? i : i - m;
      out.push_back({(stiff ? "stiffness[" : "threshold[") + std::to_string(idx + 1) + "]",
                     stiff ? "N/m" : "m", stiff ? p.stiffness[idx] : p.threshold[idx],
                     Parametrisation::log});
    }
    return out;
  }
};

// DNLRX: block 0's base part is [spring_filter (M (n+1)), input_filter (nx+1), log Delta (M)], the
// order of the DNLRX report.  Coefficients the identification dropped (rank deficiency, set to 0)
// stay 0.
struct DnlrxFamily {
  DnlrxParameters<double> p;
  bool free_base = false;
  bool lag_state = false;  // block 1 ends with the lag's offset (extension_fit.hpp)
  std::size_t filter_count() const { return p.spring_filter.size() + p.input_filter.size(); }
  std::size_t base_count() const { return free_base ? filter_count() + p.size() : 0; }
  std::size_t state_count() const { return p.size() + lag_state; }
  std::vector<double> base_theta() const {
    std::vector<double> t(p.spring_filter);
    t.insert(t.end(), p.input_filter.begin(), p.input_filter.end());
    for (double d : p.threshold) t.push_back(std::log(d));
    return t;
  }
  Box base_box(const Record& r) const {
    Box b;
    b.lower.assign(filter_count(), -kInf);
    b.upper.assign(filter_count(), kInf);
    threshold_box(b, r, p.threshold);
    return b;
  }
  // Its operators carry no stiffness of their own (the spring filter does).
  std::vector<int> unresolved(const std::vector<double>&, double) const { return {}; }
  std::vector<int> held(const std::vector<double>& theta) const {
    std::vector<int> h;
    for (std::size_t c = 0; c < filter_count(); ++c)
      if (theta[c] == 0.0) h.push_back(static_cast<int>(c));
    return h;
  }
  DnlrxParameters<double> parameters(const double* theta) const {
    DnlrxParameters<double> q = p;
    const std::size_t ns = p.spring_filter.size(), nf = filter_count();
    for (std::size_t c = 0; c < ns; ++c) q.spring_filter[c] = theta[c];
    for (std::size_t c = ns; c < nf; ++c) q.input_filter[c - ns] = theta[c];
    for (std::size_t i = 0; i < p.size(); ++i) q.threshold[i] = std::exp(theta[nf + i]);
    return q;
  }
  double sliding_force(const double* theta) const {
    return free_base ? parameters(theta).sliding_force() : p.sliding_force();
  }
  template <typename T>
  Extended<Dnlrx<T>> make(const T* theta, ExtensionParameters<T> ext) const {
    using std::exp;
    DnlrxParameters<T> q;
    q.spring_order = p.spring_order;
    const std::size_t ns = p.spring_filter.size(), nf = filter_count();
    // A coefficient the identification dropped (0) stays 0: its column is then zero.
    for (std::size_t c = 0; c < ns; ++c)
      q.spring_filter.push_back(free_base && p.spring_filter[c] != 0.0 ? theta[c]
                                                                       : T(p.spring_filter[c]));
    for (std::size_t c = ns; c < nf; ++c)
      q.input_filter.push_back(
          free_base && p.input_filter[c - ns] != 0.0 ? theta[c] : T(p.input_filter[c - ns]));
    for (std::size_t i = 0; i < p.size(); ++i)
      q.threshold.push_back(free_base ? exp(theta[nf + i]) : T(p.threshold[i]));
    return Extended<Dnlrx<T>>(Dnlrx<T>(std::move(q)), std::move(ext), 2);
  }
  template <typename T>
  void set_state(Extended<Dnlrx<T>>& model, const T* theta, const T* s) const {
    using std::exp;
    const std::size_t nf = filter_count();
    const T a = model.extensions().asymmetry ? model.extensions().asymmetry->asymmetry : T(0);
    std::vector<T> d(p.size());
    for (std::size_t i = 0; i < p.size(); ++i)
      d[i] = (s[i] + a) * (free_base ? exp(theta[nf + i]) : T(p.threshold[i]));
    model.base().reset(std::span<const T>(d), model.asymmetry());
    if (lag_state) model.set_initial_lag_offset(s[p.size()]);
  }
  std::vector<double> state_bounds() const { return {-1.0, 1.0}; }
  // Report entries of block 0's base part: the filters (N/m) and log Delta_i.
  std::vector<CovarianceParameter> base_parameters(const std::vector<double>& th) const {
    std::vector<CovarianceParameter> out;
    const std::size_t taps = p.spring_taps(), ns = p.spring_filter.size();
    for (std::size_t c = 0; c < th.size(); ++c) {
      if (c < ns)
        out.push_back(
            {"spring_filter[" + std::to_string(c / taps + 1) + "," + std::to_string(c % taps) + "]",
             "N/m", th[c]});
      else if (c < filter_count())
        out.push_back({"input_filter[" + std::to_string(c - ns) + "]", "N/m", th[c]});
      else
        out.push_back({"threshold[" + std::to_string(c - filter_count() + 1) + "]", "m",
                       std::exp(th[c]), Parametrisation::log});
    }
    return out;
  }
};

// LuGre: block 0's base part is the seven parameters in to_array order, natural units, boxed to
// their domain (sigma1, sigma2 >= 0; the others above a thousandth of their start, mu in
// [0.2, 10]).  A parameter the identification left at 0 (sigma1 or sigma2) stays 0.
struct LuGreFamily {
  LuGreParameters<double> p;
  bool free_base = false;
  bool lag_state = false;  // block 1 ends with the lag's offset (extension_fit.hpp)
  double zref() const { return std::max(p.coulomb, p.static_force) / p.stiffness; }
  std::size_t base_count() const { return free_base ? LuGreParameters<double>::kSize : 0; }
  std::size_t state_count() const { return 1 + lag_state; }
  std::vector<double> base_theta() const {
    const auto a = p.to_array();
    return std::vector<double>(a.begin(), a.end());
  }
  Box base_box(const Record&) const {
    Box b;
    const auto a = p.to_array();
    for (std::size_t j = 0; j < a.size(); ++j) {
      const bool nonnegative = j == 1 || j == 2;
      b.lower.push_back(nonnegative ? 0.0 : (j == 6 ? 0.2 : 1e-3 * a[j]));
      b.upper.push_back(j == 6 ? 10.0 : kInf);
    }
    return b;
  }
  std::vector<int> unresolved(const std::vector<double>&, double) const { return {}; }
  std::vector<int> held(const std::vector<double>& theta) const {
    std::vector<int> h;
    for (int j : {1, 2})
      if (theta[static_cast<std::size_t>(j)] == 0.0) h.push_back(j);
    return h;
  }
  LuGreParameters<double> parameters(const double* theta) const {
    LuGreParameters<double> q = p;
    q.stiffness = theta[0], q.micro_damping = theta[1], q.viscous = theta[2], q.coulomb = theta[3];
    q.static_force = theta[4], q.stribeck_velocity = theta[5], q.stribeck_exponent = theta[6];
    return q;
  }
  double sliding_force(const double* theta) const { return free_base ? theta[3] : p.coulomb; }
  template <typename T>
  Extended<LuGre<T>> make(const T* theta, ExtensionParameters<T> ext) const {
    LuGreParameters<T> q = p.template cast<T>();
    if (free_base) {
      // sigma1 or sigma2 left at 0 by the identification stays 0.
      q.stiffness = theta[0];
      q.micro_damping = p.micro_damping != 0.0 ? theta[1] : T(0);
      q.viscous = p.viscous != 0.0 ? theta[2] : T(0);
      q.coulomb = theta[3], q.static_force = theta[4], q.stribeck_velocity = theta[5];
      q.stribeck_exponent = theta[6];
    }
    return Extended<LuGre<T>>(LuGre<T>(std::move(q)), std::move(ext), 2);
  }
  template <typename T>
  void set_state(Extended<LuGre<T>>& model, const T*, const T* s) const {
    model.base().reset(T(s[0] * zref()));
    if (lag_state) model.set_initial_lag_offset(s[1]);
  }
  // estimate_lugre_initial_state scans the same range.
  std::vector<double> state_bounds() const { return {-1.5, 1.5}; }
  // Report entries of block 0's base part: the seven parameters in SI, fitted linearly.
  std::vector<CovarianceParameter> base_parameters(const std::vector<double>& th) const {
    static constexpr std::array<const char*, 7> kUnits{"N/m", "N s/m", "N s/m", "N",
                                                       "N",   "m/s",   "1"};
    std::vector<CovarianceParameter> out;
    for (std::size_t j = 0; j < th.size(); ++j)
      out.push_back({kLuGreParameterNames[j], kUnits[j], th[j]});
    return out;
  }
};

// The box of block 1: the base's states within the family's bounds, then the lag's offset
// within lag_offset_bound of the record.
template <class Family>
Box state_box(const Family& family, const Record& r) {
  const std::vector<double> sb = family.state_bounds();
  const std::size_t ns = family.state_count() - (family.lag_state ? 1 : 0);
  Box b{std::vector<double>(ns, sb[0]), std::vector<double>(ns, sb[1])};
  if (family.lag_state) {
    const double u = lag_offset_bound(r);
    b.lower.push_back(-u);
    b.upper.push_back(u);
  }
  return b;
}

// Residuals (F - Fhat) * scale of the extended model's free run on the record, handed over in
// sample order (streamed_autodiff_cost.hpp: no N x P Jacobian is kept).
template <class Family>
struct FamilyCost {
  const Record* record;
  Family family;
  ExtensionParameters<double> pieces;  // which pieces, and the reference force
  double scale;
  DerivativeWindows windows;  // the record's, computed once

  template <typename T, class Visit>
  bool operator()(T const* const* p, Visit&& visit) const {
    ExtensionParameters<T> ext = pieces.template cast<T>([](double v) { return T(v); });
    std::size_t j = family.base_count();
    ext.for_each_parameter([&](Effect, std::string_view, T& v) { v = p[0][j++]; });
    ext.reference_force = T(pieces.reference_force);
    try {
      auto model = family.template make<T>(p[0], std::move(ext));
      family.template set_state<T>(model, p[0], p[1]);
      visit_extended_residuals(model, *record, scale, windows, visit);
    } catch (const InvalidParameter&) {
      return false;
    }
    return true;
  }
};

template <class Family>
using FamilyCostFunction = detail::StreamedAutoDiffCost<FamilyCost<Family>>;

template <class Family>
FamilyCostFunction<Family>* make_cost(const Record& r, const Family& family,
                                      const ExtensionParameters<double>& pieces, double scale,
                                      std::size_t theta_size) {
  return new FamilyCostFunction<Family>(
      std::make_unique<FamilyCost<Family>>(
          FamilyCost<Family>{&r, family, pieces, scale, record_derivative_windows(r)}),
      {static_cast<int>(theta_size), static_cast<int>(family.state_count())},
      static_cast<int>(r.size()));
}

// Bounds of block 0: the family's base box (when refitted) and the pieces' boxes.
template <class Family>
Box theta_box(const Family& family, const ExtensionParameters<double>& pieces, double f0,
              const Record& r) {
  Box b;
  if (family.base_count() > 0) b = family.base_box(r);
  const double duration = record_duration(r), vmax = largest_interval_speed(r);
  pieces.for_each_parameter([&](Effect e, std::string_view name, const double&) {
    const ExtensionBounds eb = extension_parameter_bounds(e, name, f0, duration, vmax);
    b.lower.push_back(eb.lower);
    b.upper.push_back(eb.upper);
  });
  return b;
}

inline std::vector<double> piece_values(const ExtensionParameters<double>& ext) {
  std::vector<double> v;
  ext.for_each_parameter([&](Effect, std::string_view, const double& x) { v.push_back(x); });
  return v;
}

inline void set_piece_values(ExtensionParameters<double>& ext, const double* v) {
  std::size_t j = 0;
  ext.for_each_parameter([&](Effect, std::string_view, double& x) { x = v[j++]; });
}

// ---------------------------------------------------------------------------------------------
// Fit of a family: the pieces and the initial state, with the base parameters too when the family
// is refitted (base_theta0 then holds their start), or the initial state alone (fix_pieces).

struct FamilyFit {
  std::vector<double> base_theta;  // block 0's base part at the optimum (empty when held)
  ExtensionParameters<double> ext;
  std::vector<double> state;
  double rss = std::numeric_limits<double>::infinity();
  bool ok = false;
};

template <class Family>
FamilyFit fit_family(const Record& r, const Family& family, const std::vector<double>& base_theta0,
                     const ExtensionParameters<double>& ext0, std::vector<double> state0,
                     bool fix_pieces, int max_iterations, double f0) {
  const double rms = std::sqrt(sum_sq(r.force) / static_cast<double>(r.size()));
  const double scale = rms > 0 ? 1.0 / rms : 1.0;
  const std::size_t nb = family.base_count();
  FRICTION_CHECK(base_theta0.size() == nb, "fit_family: ", base_theta0.size(),
                 " base parameters for ", nb);
  std::vector<double> theta = base_theta0;
  const std::vector<double> pv = piece_values(ext0);
  theta.insert(theta.end(), pv.begin(), pv.end());
  const bool empty = theta.empty();
  if (empty) theta.push_back(0.0);  // Ceres needs a non-empty block
  const Box box = theta_box(family, ext0, f0, r);
  auto* cost = make_cost(r, family, ext0, scale, theta.size());
  ceres::Problem problem;
  std::vector<double> state = std::move(state0);
  state.resize(family.state_count(), 0.0);
  const Box sb = state_box(family, r);
  for (std::size_t i = 0; i < state.size(); ++i)
    state[i] = std::clamp(state[i], sb.lower[i], sb.upper[i]);
  problem.AddResidualBlock(new detail::CompressedCost(cost), nullptr, theta.data(), state.data());
  for (std::size_t i = 0; i < state.size(); ++i) {
    problem.SetParameterLowerBound(state.data(), static_cast<int>(i), sb.lower[i]);
    problem.SetParameterUpperBound(state.data(), static_cast<int>(i), sb.upper[i]);
  }
  std::vector<int> held = nb > 0 ? family.held(base_theta0) : std::vector<int>{};
  if (!empty) {
    for (std::size_t j = 0; j < box.lower.size(); ++j) {
      if (std::find(held.begin(), held.end(), static_cast<int>(j)) != held.end()) continue;
      theta[j] = std::clamp(theta[j], box.lower[j], box.upper[j]);
      if (std::isfinite(box.lower[j]))
        problem.SetParameterLowerBound(theta.data(), static_cast<int>(j), box.lower[j]);
      if (std::isfinite(box.upper[j]))
        problem.SetParameterUpperBound(theta.data(), static_cast<int>(j), box.upper[j]);
    }
  }
  // Held base entries have zero derivative (the family ignores them): they do not move.
  if (fix_pieces || empty) problem.SetParameterBlockConstant(theta.data());
  ceres::Solver::Options options;
  options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = max_iterations;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  options.function_tolerance = detail::resolved_function_tolerance(r.size());
  options.parameter_tolerance = 1e-9;
  detail::use_value_only_line_search(options);
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  FamilyFit out;
  out.ext = ext0;
  if (!empty) {
    out.base_theta.assign(theta.begin(), theta.begin() + static_cast<std::ptrdiff_t>(nb));
    set_piece_values(out.ext, theta.data() + nb);
  }
  out.state = state;
  out.ok = summary.IsSolutionUsable();
  if (out.ok) out.rss = 2.0 * summary.final_cost / (scale * scale);
  return out;
}

// Free-run force of a family at given pieces and state (double), on a record's signals.
template <class Family>
std::vector<double> family_run(std::span<const double> time, std::span<const double> displacement,
                               std::span<const double> normal,
                               std::span<const double> measured_displacement,
                               const Family& family, const ExtensionParameters<double>& ext,
                               const double* theta_base, const std::vector<double>& state,
                               const DerivativeWindows* windows) {
  auto model = family.template make<double>(theta_base, ext);
  family.template set_state<double>(model, theta_base, state.data());
  return simulate_extended(model, time, displacement, normal, windows, measured_displacement);
}

// The same on a record.
template <class Family>
std::vector<double> family_run(const Record& r, const Family& family,
                               const ExtensionParameters<double>& ext, const double* theta_base,
                               const std::vector<double>& state,
                               const DerivativeWindows* windows = nullptr) {
  return family_run(std::span<const double>(r.time), std::span<const double>(r.displacement),
                    std::span<const double>(r.normal),
                    std::span<const double>(r.measured_displacement), family, ext, theta_base,
                    state, windows);
}

inline double rss_of(const Record& r, const std::vector<double>& f) {
  double s = 0;
  for (std::size_t k = 0; k < r.size(); ++k) s += (r.force[k] - f[k]) * (r.force[k] - f[k]);
  return s;
}

// Initial state of a family with every parameter fixed: each start refined by Ceres (never worse
// than the start), the best kept.  Several starts because a state at its bound (an operator that
// saturates at once from the plain model's estimate) has no gradient to leave it by: the relaxed
// state (0) and halfway to the plain estimate are always tried as well.
template <class Family>
std::vector<double> estimate_family_state(const Record& r, const Family& family,
                                          const ExtensionParameters<double>& ext,
                                          const std::vector<double>& plain, double f0) {
  const Box sb = state_box(family, r);
  const std::size_t ns = family.state_count();
  std::vector<std::vector<double>> starts{plain, std::vector<double>(ns, 0.0), plain};
  for (double& v : starts[2]) v *= 0.5;
  std::vector<double> best;
  double best_rss = std::numeric_limits<double>::infinity();
  for (auto s0 : starts) {
    s0.resize(ns, 0.0);  // a lag's offset the plain estimate lacks starts in step (0)
    for (std::size_t i = 0; i < ns; ++i) s0[i] = std::clamp(s0[i], sb.lower[i], sb.upper[i]);
    const double rss0 = rss_of(r, family_run(r, family, ext, nullptr, s0));
    if (rss0 < best_rss) best_rss = rss0, best = s0;
    const FamilyFit f = fit_family(r, family, {}, ext, s0, /*fix_pieces=*/true, 30, f0);
    if (f.ok && f.rss < best_rss) best_rss = f.rss, best = f.state;
  }
  return best;
}

// ---------------------------------------------------------------------------------------------
// Covariance of the free parameters at an optimum (extension_identification.hpp, 3): the sandwich
// cov = s^2 (J^T J)^-1 (J^T R J) (J^T J)^-1 for a residual of AR(1) colour R (noise_colour.hpp;
// s^2 (J^T J)^-1, the Gauss-Newton form, when the residual is white), s^2 = RSS / (N - p), over
// the free columns of both blocks, J from automatic derivatives through the family's cost.  With
// coloured force noise the white form's intervals were 2-6 times too narrow (AR(1) at phi
// 0.8-0.95 on the discovery study's records).  Each variance is then raised to the block scores'
// where those are larger: what the model's structure misses leaks into the parameters as well as
// the noise (noise_colour.hpp, Misfit as well as noise).  Columns are scaled to unit norm before
// the rank test (reciprocal condition number below 1e-12: rank deficient), which makes it a
// property of the model, not of the units.

struct FreeCovariance {
  Eigen::MatrixXd covariance;        // over `columns`
  std::vector<std::size_t> columns;  // free columns: 0..nt-1 block 0, nt.. block 1
  bool rank_deficient = false;
  bool ok = false;
  // Per position in `columns`: estimable on this record (rank-deficient fits: see covariance_at).
  std::vector<char> estimable;
  ResidualColour colour;  // of the residual at the optimum
  // The directions the data do not see and no box bounds (unit-norm columns, in the column-scaled
  // coordinates theta_q * scale_q; those along which an initial state moves are in `covariance`
  // instead, covariance_at), and those scales.
  Eigen::MatrixXd null_directions;
  Eigen::VectorXd scale;
  // Position of block-0 column c in the covariance; -1 when it is not free or not computed.
  std::ptrdiff_t position_of(std::size_t c) const {
    if (!ok) return -1;
    const auto it = std::find(columns.begin(), columns.end(), c);
    return it == columns.end() ? -1 : it - columns.begin();
  }
  // Position of block-0 column c in the covariance; -1 when it is not free, not estimable or not
  // computed.
  std::ptrdiff_t column_of(std::size_t c) const {
    const std::ptrdiff_t q = position_of(c);
    return q >= 0 && estimable[static_cast<std::size_t>(q)] ? q : -1;
  }
  // Whether the linear function g^T theta (g over the covariance's columns) is estimable: g has no
  // part in the directions the data do not see (the test covariance_at applies to single
  // parameters).
  bool estimable_function(const Eigen::VectorXd& g) const {
    if (!ok) return false;
    const Eigen::VectorXd gs = g.cwiseQuotient(scale);
    if (null_directions.cols() == 0) return true;
    return (null_directions.transpose() * gs).squaredNorm() < 1e-6 * gs.squaredNorm();
  }
};

// The displacement's own error.  The models are driven by the measured displacement, the force
// came from the true one: an encoder's staircase moves a stiff operator by k q and a differentiated
// staircase puts noise into every velocity and acceleration term, and the least-squares estimate
// follows those errors (errors in the variables) where the force noise, which the sandwich
// above measures, does not reach.  On the discovery study's records that was most of what the
// intervals missed: without the encoder, eight of nine misses came within 1.7 standard errors
// (README, "The discovery study's coverage").  Measured here the way a second measurement of the
// same motion would show it: the record remeasured by its own sensor (signals.hpp,
// remeasured_replica: requantised with a random phase and conditioned as the record was), the
// model run again at the optimum, and the linearised response of the fit to the change of its
// force, d theta = (J^T J)^+ J^T dF, in the scaled coordinates of covariance_at.
// Its second moment over kInputReplicas replicas is added to the covariance (the part of those
// errors the residual already shows is counted twice: the intervals err on the wide side).
// Replicas are seeded by their index: the same record gives the same covariance.
inline constexpr std::size_t kInputReplicas = 24;
// Replicas whose force changes are held at once, each multiplied by the Jacobian's rows as they
// come (J^T dF, one pass of the Jacobian per group): 8 bytes a sample each.
inline constexpr std::size_t kReplicaGroup = 8;

// The rows of the Jacobian of both blocks (all nt + ns columns) in sample order, visit(k, row),
// with `residual` written up to k: from one pass of Jets when the cost streams, else (more than
// StreamedAutoDiffCost::kMaxLanes columns) from its N x P blocks.
template <class Family, class Visit>
bool for_each_jacobian_row(const FamilyCostFunction<Family>& cost, const double* const* params,
                           std::size_t nt, std::size_t ns, std::vector<double>& residual,
                           Visit&& visit) {
  const std::size_t n = residual.size();
  std::vector<double> row(nt + ns);
  if (cost.streams()) {
    const bool requested[2] = {true, true};
    return cost.EvaluateRows(params, residual.data(), requested,
                             [&](std::size_t k, const double* const* rows) {
                               std::copy_n(rows[0], nt, row.begin());
                               std::copy_n(rows[1], ns, row.begin() + static_cast<long>(nt));
                               visit(k, row);
                             });
  }
  std::vector<double> j0(n * nt), j1(n * ns);
  double* jac[2] = {j0.data(), j1.data()};
  if (!cost.Evaluate(params, residual.data(), jac)) return false;
  for (std::size_t k = 0; k < n; ++k) {
    std::copy_n(j0.begin() + static_cast<long>(k * nt), nt, row.begin());
    std::copy_n(j1.begin() + static_cast<long>(k * ns), ns, row.begin() + static_cast<long>(nt));
    visit(k, row);
  }
  return true;
}

// The motion an encoder's replicas requantise, smoothest_motion_within_quanta of the record's
// readings, remembered for the last record and quantum (by the fingerprint of its time and
// readings): a diagnosis asks for the covariance of many fits on one record.  Shared, not copied:
// 8 bytes a sample for the cache and every covariance in progress together.
inline std::shared_ptr<const std::vector<double>> replica_motion(const Record& r, double quantum) {
  struct Entry {
    detail::RecordFingerprint fingerprint;
    std::size_t samples = 0;
    double quantum = 0;
    std::shared_ptr<const std::vector<double>> motion;
  };
  static std::mutex mutex;
  static Entry last;
  const std::vector<double>& m = r.measured();
  const detail::RecordFingerprint print =
      detail::fingerprint_of(r.time, r.size(), [&](std::size_t k) { return m[k]; });
  {
    std::lock_guard<std::mutex> lock(mutex);
    if (last.samples == r.size() && last.quantum == quantum && last.fingerprint == print)
      return last.motion;
  }
  auto motion = std::make_shared<const std::vector<double>>(
      smoothest_motion_within_quanta(r.time, m, quantum));
  std::lock_guard<std::mutex> lock(mutex);
  last = Entry{print, r.size(), quantum, motion};
  return motion;
}

// The replicas' force changes dF (above), kReplicaGroup at a time, in the order of their seeds.
// With an encoder the replicas are made from the smoothest motion its readings allow (signals.hpp,
// smoothest_motion_within_quanta), and dF is taken against the model's force on that motion: the
// conditioned displacement keeps the staircase's plateaus where the motion is slow, and replicas
// of it carried about half the spread the encoder gives a fit (README, "The replicas' motion").
// Without one (an analog sensor's noise) they are made from the record's displacement, and dF is
// taken against the model's force on the record.
template <class Family>
class ReplicaForces {
 public:
  ReplicaForces(const Record& r, const Family& family, const ExtensionParameters<double>& pieces,
                const std::vector<double>& theta, const std::vector<double>& state,
                const std::vector<double>& residual)
      : r_(r), family_(family), pieces_(pieces), theta_(theta), state_(state),
        residual_(residual), sensor_(estimate_displacement_resolution(r.measured())) {
    if (!sensor_.quantum) return;
    motion_ = replica_motion(r, *sensor_.quantum);
    // The motion is the truth of its replicas: its force with the record's windows, which on a
    // smooth motion give its derivatives to their truncation error.
    const DerivativeWindows w = record_derivative_windows(r);
    try {
      motion_force_ = family_run(std::span<const double>(r.time), std::span<const double>(*motion_),
                                 std::span<const double>(r.normal), {}, family_, pieces_,
                                 theta_.data(), state_, &w);
    } catch (const InvalidParameter&) {
      motion_force_.clear();
    }
    if (!std::all_of(motion_force_.begin(), motion_force_.end(),
                     [](double f) { return std::isfinite(f); }))
      motion_force_.clear();
    if (motion_force_.empty()) motion_.reset();  // then made from the record, as without one
  }
  // The next group (empty when every replica was made or one could not be).
  const std::vector<std::vector<double>>& next() {
    group_.clear();
    while (!exhausted_ && next_ < kInputReplicas && group_.size() < kReplicaGroup) {
      const std::size_t j = next_++;
      const bool from_motion = !motion_force_.empty();
      if (!remeasured_replica(r_, from_motion ? *motion_ : r_.displacement,
                              replica_seed(j), replica_, sensor_, &windows_)) {
        exhausted_ = true;
        break;
      }
      std::vector<double> f;
      try {
        f = family_run(replica_, family_, pieces_, theta_.data(), state_, &windows_);
      } catch (const InvalidParameter&) {
        continue;
      }
      bool finite = true;
      for (std::size_t k = 0; k < f.size(); ++k) {
        // The model's force on the record itself is F - residual (the cost at scale 1).
        f[k] -= from_motion ? motion_force_[k] : r_.force[k] - residual_[k];
        finite = finite && std::isfinite(f[k]);
      }
      if (finite) group_.push_back(std::move(f));
    }
    return group_;
  }

 private:
  const Record& r_;
  const Family& family_;
  const ExtensionParameters<double>& pieces_;
  const std::vector<double>& theta_;
  const std::vector<double>& state_;
  const std::vector<double>& residual_;
  Resolution sensor_;
  DerivativeWindows windows_;  // the replica's, as its conditioning chose them
  // The encoder's replicas' motion, when there is one (at the record's time stamps).
  std::shared_ptr<const std::vector<double>> motion_;
  std::vector<double> motion_force_;  // the model's force on it (empty: replicas of the record)
  Record replica_;
  std::vector<std::vector<double>> group_;
  std::size_t next_ = 0;
  bool exhausted_ = false;
};

// The Jacobian is never stored: its rows are visited (for_each_jacobian_row) as the model runs
// and what the covariance needs is gathered from them on all nt + ns columns, unscaled: J^T J, the
// AR(1)-coloured Gram matrix, the block scores and the replicas' J^T dF.  The free columns the
// force feels and their unit-norm scales S follow from J^T J, and each of these is taken to the
// scaled columns J S afterwards (each is linear or bilinear in the rows).  At 10^6 samples the
// N x p Jacobian with its copies was the diagnosis's peak.
template <class Family>
FreeCovariance covariance_at(const Record& r, const Family& family,
                             const ExtensionParameters<double>& pieces, std::vector<double> theta,
                             std::vector<double> state, const std::vector<char>& free_theta,
                             const std::vector<char>& free_state, const Box& theta_bounds,
                             const Box& state_bounds) {
  FreeCovariance out;
  const std::size_t n = r.size(), nt = theta.size(), ns = state.size(), np = nt + ns;
  std::unique_ptr<FamilyCostFunction<Family>> cost(make_cost(r, family, pieces, 1.0, nt));
  std::vector<double> residual(n);
  const double* params[2] = {theta.data(), state.data()};
  // The residual first, on doubles (the Jets' values to the bit): its colour sets up the
  // accumulators, and the replicas' force changes are taken from the model's force.
  if (!cost->Evaluate(params, residual.data(), nullptr)) return out;
  if (!std::all_of(residual.begin(), residual.end(), [](double e) { return std::isfinite(e); }))
    return out;
  const ResidualColour colour = residual_colour(residual);
  ColouredGram coloured(np, colour.phi);
  BlockScores all_scores(np, score_block_length(n, colour));
  ReplicaForces<Family> replicas(r, family, pieces, theta, state, residual);
  std::vector<Eigen::VectorXd> replica_scores;  // J^T dF of each replica used
  for (bool first = true;; first = false) {
    const std::vector<std::vector<double>>& group = replicas.next();
    if (!first && group.empty()) break;
    std::vector<Eigen::VectorXd> g(group.size(), Eigen::VectorXd::Zero(static_cast<long>(np)));
    const bool ok =
        for_each_jacobian_row(*cost, params, nt, ns, residual,
                              [&](std::size_t k, const std::vector<double>& row) {
                                if (first) {
                                  coloured.add(row);
                                  all_scores.add(row, residual[k]);
                                }
                                const Eigen::Map<const Eigen::VectorXd> j(
                                    row.data(), static_cast<Eigen::Index>(np));
                                for (std::size_t i = 0; i < group.size(); ++i)
                                  g[i].noalias() += group[i][k] * j;
                              });
    if (!ok) return out;
    for (Eigen::VectorXd& v : g) replica_scores.push_back(std::move(v));
  }
  const Eigen::MatrixXd& gram = coloured.gram();
  // A parameter the force does not feel is not estimated by the record, and it is left out
  // rather than scaled up: an operator whose stiffness went to ~0 (1e-9 N/m beside 1e5) has
  // columns of ~1e-14 N, which the unit-norm scaling below would turn into full columns of their
  // shape; on one study record (DiscoveryStudy.APieceBesideAnOperatorTheForceDoesNotFeelHas...)
  // they then formed a null direction with the asymmetry's column, and the asymmetry, estimated
  // to three digits, was reported "not estimable".  Negligible: a step of one in the parameter
  // (an e-fold for the log-parametrised ones, one SI unit for the others) moves the RSS by less
  // than 1e-12 of the residual's variance, i.e. its standard error alone would exceed 1e6 of
  // those steps.
  const double negligible = 1e-12 * sum_sq(residual) / static_cast<double>(n);
  const auto felt = [&](std::size_t c) {
    const auto i = static_cast<Eigen::Index>(c);
    return gram(i, i) >= negligible;
  };
  std::vector<std::size_t>& cols = out.columns;
  for (std::size_t c = 0; c < nt; ++c)
    if (free_theta[c] && felt(c)) cols.push_back(c);
  for (std::size_t c = 0; c < ns; ++c)
    if (free_state[c] && felt(nt + c)) cols.push_back(nt + c);
  const std::size_t p = cols.size();
  if (p == 0 || n <= p) return out;
  // Columns scaled to unit norm (a column without any effect keeps scale 1 and stays zero): the
  // scaled Jacobian is Js = J S, S the chosen columns times 1 / d.  Taken by indexing, not by
  // products with S: a column left out (not free, not felt) may hold non-finite derivatives,
  // and 0 times those is not 0.
  Eigen::VectorXd d(static_cast<Eigen::Index>(p)), inv_d(static_cast<Eigen::Index>(p));
  std::vector<Eigen::Index> at(p);
  for (std::size_t q = 0; q < p; ++q) {
    const auto qi = static_cast<Eigen::Index>(q);
    at[q] = static_cast<Eigen::Index>(cols[q]);
    d(qi) = std::sqrt(gram(at[q], at[q]));
    if (!(d(qi) > 0)) d(qi) = 1.0;
    inv_d(qi) = 1.0 / d(qi);
  }
  const auto scaled_vector = [&](const Eigen::VectorXd& v) {
    Eigen::VectorXd out_v(d.size());
    for (Eigen::Index q = 0; q < d.size(); ++q)
      out_v(q) = inv_d(q) * v(at[static_cast<std::size_t>(q)]);
    return out_v;
  };
  const auto scaled_matrix = [&](const Eigen::MatrixXd& m) {
    Eigen::MatrixXd out_m(d.size(), d.size());
    for (Eigen::Index q = 0; q < d.size(); ++q)
      for (Eigen::Index u = 0; u < d.size(); ++u)
        out_m(q, u) = inv_d(q) * m(at[static_cast<std::size_t>(q)], at[static_cast<std::size_t>(u)]) *
                      inv_d(u);
    return out_m;
  };
  const Eigen::MatrixXd H = scaled_matrix(gram);
  if (!H.allFinite()) return out;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(H);
  const double emax = eig.eigenvalues().maxCoeff();
  if (!(emax > 0)) return out;
  // A rank-deficient fit (operators that trade off against each other, a piece that imitates the
  // base) still determines every parameter that has no part in the directions the data do not
  // see: for such a parameter the pseudo-inverse gives its variance exactly, whatever the others
  // do (the estimable functions of a linear model).  Parameter q is estimable when its unit vector
  // lies outside the null space, sum over null eigenvectors of v_q^2 < 1e-6; the others get no
  // standard error.
  //
  // A null direction along which an initial state moves is bounded all the same: the state lies
  // in its box (an operator's deflection within its threshold), and the record cannot put the
  // truth outside it.  The common case is an operator that never slips in the record: its force is
  // k (delta0 + x - x0), whose constant part k delta0 an offset imitates exactly, so the offset is
  // known only to within the force range that operator's initial deflection can take.  Along such
  // a direction v the fit is free over the segment t in [t_lo, t_hi] on which every parameter and
  // state stays in its box; with the truth anywhere on it and the estimate at t = 0, the error's
  // second moment is (t_lo^2 + t_lo t_hi + t_hi^2) / 3, added as that times v v^T.  The parameters
  // then get the standard error their box leaves them, wide where the record says little.  Null
  // directions among the model parameters alone (operators that trade stiffness for threshold)
  // stay unbounded: their boxes are the physical ranges of a search, not knowledge.
  const Eigen::VectorXd& ev = eig.eigenvalues();
  Eigen::VectorXd inverse = Eigen::VectorXd::Zero(ev.size());
  out.estimable.assign(p, 1);
  Eigen::VectorXd leverage = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(p));
  Eigen::MatrixXd bounded = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(p),
                                                  static_cast<Eigen::Index>(p));
  // The segment along v (unit, scaled coordinates) on which every entry stays in its box.
  const auto segment_second_moment = [&](const Eigen::VectorXd& v) {
    double lo = -kInf, hi = kInf;
    for (std::size_t q = 0; q < p; ++q) {
      const auto qi = static_cast<Eigen::Index>(q);
      if (std::abs(v(qi)) < 1e-9) continue;
      const std::size_t c = cols[q];
      const double step = v(qi) / d(qi);  // parameter change per unit t
      const double x = c < nt ? theta[c] : state[c - nt];
      const double l = c < nt ? theta_bounds.lower[c] : state_bounds.lower[c - nt];
      const double u = c < nt ? theta_bounds.upper[c] : state_bounds.upper[c - nt];
      const double a = (l - x) / step, b = (u - x) / step;
      lo = std::max(lo, std::min(a, b));
      hi = std::min(hi, std::max(a, b));
    }
    if (!std::isfinite(lo) || !std::isfinite(hi)) return -1.0;
    lo = std::min(lo, 0.0);
    hi = std::max(hi, 0.0);
    return (lo * lo + lo * hi + hi * hi) / 3.0;
  };
  std::vector<Eigen::Index> null_eigen;
  for (Eigen::Index e = 0; e < ev.size(); ++e) {
    if (ev(e) > 1e-12 * emax)
      inverse(e) = 1.0 / ev(e);
    else
      null_eigen.push_back(e);
  }
  // The null space's eigenvectors are any orthonormal basis of it, so a direction among the model
  // parameters alone and one that moves a state come mixed.  They are separated by the singular
  // vectors of the null basis' state rows: those with a state part (singular value above 1e-3, a
  // squared share above the 1e-6 of the estimability test) are bounded by the boxes, the rest are
  // not.
  Eigen::MatrixXd null_basis(static_cast<Eigen::Index>(p),
                             static_cast<Eigen::Index>(null_eigen.size()));
  for (std::size_t j = 0; j < null_eigen.size(); ++j)
    null_basis.col(static_cast<Eigen::Index>(j)) = eig.eigenvectors().col(null_eigen[j]);
  std::vector<Eigen::VectorXd> unbounded;
  if (!null_eigen.empty()) {
    out.rank_deficient = true;
    Eigen::MatrixXd state_rows = Eigen::MatrixXd::Zero(null_basis.rows(), null_basis.cols());
    for (std::size_t q = 0; q < p; ++q)
      if (cols[q] >= nt)
        state_rows.row(static_cast<Eigen::Index>(q)) = null_basis.row(static_cast<Eigen::Index>(q));
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(state_rows, Eigen::ComputeFullV);
    const Eigen::VectorXd& sv = svd.singularValues();
    for (Eigen::Index j = 0; j < null_basis.cols(); ++j) {
      const Eigen::VectorXd v = null_basis * svd.matrixV().col(j);
      const double t2 = j < sv.size() && sv(j) > 1e-3 ? segment_second_moment(v) : -1.0;
      if (t2 >= 0)
        bounded.noalias() += t2 * v * v.transpose();
      else
        unbounded.push_back(v);
    }
  }
  for (const Eigen::VectorXd& v : unbounded) leverage += v.cwiseAbs2();
  for (std::size_t q = 0; q < p; ++q)
    if (leverage(static_cast<Eigen::Index>(q)) >= 1e-6) out.estimable[q] = 0;
  // The degrees of freedom the fit used: its rank, not its column count.
  const auto rank = static_cast<std::size_t>((inverse.array() > 0).count());
  const double s2 = sum_sq(residual) / static_cast<double>(n - rank);
  const Eigen::MatrixXd Hinv =
      eig.eigenvectors() * inverse.asDiagonal() * eig.eigenvectors().transpose();
  out.colour = colour;
  // The larger of the AR(1) sandwich and the block scores' (noise_colour.hpp: misfit as well as
  // noise), both of the scaled columns.
  Eigen::MatrixXd scaled = sandwich_covariance(Hinv, scaled_matrix(coloured.coloured()), s2);
  const BlockScores scores = all_scores.selected(at, inv_d);
  if (scores.blocks() >= kMinimumScoreBlocks)
    scaled = larger_variances(scaled, block_sandwich_covariance(Hinv, scores, n, rank));
  // The displacement's own error: the second moment of the replicas' responses Hinv Js^T dF.
  if (!replica_scores.empty()) {
    Eigen::MatrixXd second = Eigen::MatrixXd::Zero(d.size(), d.size());
    for (const Eigen::VectorXd& g : replica_scores) {
      const Eigen::VectorXd gs = scaled_vector(g);
      second.noalias() += gs * gs.transpose();
    }
    second /= static_cast<double>(replica_scores.size());
    scaled += Hinv * second * Hinv;
  }
  scaled += bounded;
  out.covariance = d.cwiseInverse().asDiagonal() * scaled * d.cwiseInverse().asDiagonal();
  out.scale = d;
  out.null_directions.resize(static_cast<Eigen::Index>(p),
                             static_cast<Eigen::Index>(unbounded.size()));
  for (std::size_t j = 0; j < unbounded.size(); ++j)
    out.null_directions.col(static_cast<Eigen::Index>(j)) = unbounded[j];
  out.ok = true;
  return out;
}

// The gradient of the base's F0 over the covariance's columns: zero where the base was held or a
// base parameter is not free (held at a bound adds no variance, as for every other parameter).
// Central differences in block 0's base part, whatever the family's parametrisation.
template <class Family>
Eigen::VectorXd sliding_force_gradient(const Family& family, std::vector<double> base_theta,
                                       const FreeCovariance& cov) {
  Eigen::VectorXd g = Eigen::VectorXd::Zero(cov.covariance.rows());
  for (std::size_t c = 0; c < family.base_count(); ++c) {
    const std::ptrdiff_t q = cov.position_of(c);
    if (q < 0) continue;
    const double x = base_theta[c], h = 1e-6 * std::max(1.0, std::abs(x));
    base_theta[c] = x + h;
    const double up = family.sliding_force(base_theta.data());
    base_theta[c] = x - h;
    const double down = family.sliding_force(base_theta.data());
    base_theta[c] = x;
    g[q] = (up - down) / (2 * h);
  }
  return g;
}

// Standard errors of the pieces that are stated in the model's own F0 (effect table:
// `scales_with_reference_force`) when the base was refitted with them.  The fit holds the
// reference force fixed and scales by it, so a piece's value in the saved model is
// v F0(theta) / F_ref: it moves with the base's F0 as well as with v, and taking F0 as known made
// the intervals too narrow wherever F0 is uncertain (a position dependence's amplitude beside a
// Stribeck curve three times the Coulomb level: 6 % off with a standard error of 1.2 %, 4.8
// standard errors, on a study record).  By the delta method over both, with the gradient's
// estimability checked as for every other function of the parameters.
//  - normal-load's mu = F0 / N_mean has no column of its own (effect_table.hpp: it is not
//    identifiable beside the thresholds) and its variance is F0's alone;
//  - `static` and `amplitude` are v F0 / F_ref with v a column of the fit.
// Nothing when the base was held (F0 is then the held base's, without variance: the piece's own
// column is all there is), the covariance is missing or the function is not estimable.
template <class Family>
void reference_scaled_standard_error(const Family& family, const std::vector<double>& base_theta,
                                     const FreeCovariance& cov, std::ptrdiff_t own_column,
                                     double ratio, ExtensionEstimate& est) {
  const bool derived = held_in_fit(est.effect, est.name);
  // A derived parameter has no column, so covariance_report left it without a standard error.
  if (!cov.ok || family.base_count() == 0 || (!derived && own_column < 0)) return;
  const double f0 = family.sliding_force(base_theta.data());
  if (!(f0 > 0)) return;
  Eigen::VectorXd g = sliding_force_gradient(family, base_theta, cov) * (est.value / f0);
  if (!derived) g[own_column] += ratio;
  est.available = false;
  est.standard_error = 0;
  if (!cov.estimable_function(g)) return;
  est.standard_error = std::sqrt(std::max(g.dot(cov.covariance * g), 0.0));
  est.lower95 = est.value - 1.959964 * est.standard_error;
  est.upper95 = est.value + 1.959964 * est.standard_error;
  est.available = true;
}

// The report of a joint fit: every block-0 parameter (the base's when it was refitted, then the
// pieces) through covariance_report, in the parametrisation it was fitted in (extension pieces
// linearly; `ratio` converts F0-relative pieces to the model's own F0, extension_fit.hpp).
struct JointReport {
  std::vector<ExtensionEstimate> pieces;
  std::vector<ParameterEstimate> base;  // empty when the base was held
  Eigen::MatrixXd correlation;          // of [base, pieces]
  bool rank_deficient = false;
};

template <class Family>
JointReport report_joint_fit(const Record& r, const Family& family,
                             const std::vector<double>& base_theta,
                             const ExtensionParameters<double>& ext,
                             const std::vector<double>& state, const std::vector<char>& free_state,
                             double f0, double ratio) {
  const std::size_t nb = family.base_count();
  std::vector<double> theta = base_theta;
  for (double v : piece_values(ext)) theta.push_back(v);
  const Box box = theta_box(family, ext, f0, r);
  std::vector<char> free_theta(theta.size(), 1);
  for (std::size_t c = 0; c < theta.size(); ++c)
    if (at_bound(theta[c], box.lower[c]) || at_bound(theta[c], box.upper[c])) free_theta[c] = 0;
  if (nb > 0) {
    for (int h : family.held(base_theta)) free_theta[static_cast<std::size_t>(h)] = 0;
    // What the record resolves: a column of norm below the noise's sigma changes the fit's RSS by
    // less than one sample's noise variance; an operator's force column has norm at most
    // k_i Delta_i sqrt(N).
    const double resolution =
        estimate_white_noise_sigma(r.force) / std::sqrt(static_cast<double>(r.size()));
    for (int h : family.unresolved(base_theta, resolution))
      free_theta[static_cast<std::size_t>(h)] = 0;
  }
  {  // derived parameters (effect_table.hpp, held_in_fit) have no column of their own
    std::size_t c = nb;
    ext.for_each_parameter([&](Effect e, std::string_view name, const double&) {
      if (held_in_fit(e, name)) free_theta[c] = 0;
      ++c;
    });
  }
  const FreeCovariance cov = covariance_at(r, family, ext, theta, state, free_theta, free_state,
                                           box, state_box(family, r));

  std::vector<CovarianceParameter> cp;
  if (nb > 0) cp = family.base_parameters(base_theta);
  std::vector<Effect> effects;
  ext.for_each_parameter([&](Effect e, std::string_view name, const double& v) {
    const double s = find_parameter(e, name)->scales_with_reference_force ? ratio : 1.0;
    CovarianceParameter q{std::string(name), std::string(parameter_unit(name)), v * s,
                          find_parameter(e, name)->fitted, s};
    cp.push_back(q);
    effects.push_back(e);
  });
  for (std::size_t c = 0; c < cp.size(); ++c) {
    cp[c].column = free_theta[c] ? cov.column_of(c) : -1;
    cp[c].at_bound = c >= nb && !free_theta[c];
  }
  const CovarianceReport report = covariance_report(cov.ok ? &cov.covariance : nullptr, cp);
  JointReport out;
  out.rank_deficient = cov.rank_deficient;
  out.correlation = report.correlation;
  for (std::size_t c = 0; c < cp.size(); ++c) {
    const ParameterUncertainty& u = report.parameters[c];
    if (c < nb) {
      out.base.push_back(
          {cp[c].name, cp[c].unit, cp[c].value, u.standard_error, u.lower95, u.upper95});
      continue;
    }
    ExtensionEstimate est;
    est.effect = effects[c - nb];
    est.name = cp[c].name;
    est.unit = cp[c].unit;
    est.value = cp[c].value;
    est.standard_error = u.standard_error;
    est.at_bound = cp[c].at_bound;
    est.lower95 = u.lower95;
    est.upper95 = u.upper95;
    est.available = u.available;
    if (held_in_fit(est.effect, est.name)) est.at_bound = false;
    if (find_parameter(est.effect, est.name)->scales_with_reference_force && !est.at_bound)
      reference_scaled_standard_error(family, base_theta, cov, cp[c].column, ratio, est);
    out.pieces.push_back(est);
  }
  return out;
}

}  // namespace friction::extension_detail
