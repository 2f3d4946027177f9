// Identification with requested extension pieces (see extension_identification.hpp).
#include "friction/extension_identification.hpp"

#include <ceres/ceres.h>
#include <ceres/dynamic_autodiff_cost_function.h>

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <sstream>

#include "friction/diagnose.hpp"
#include "friction/dnlrx_identification.hpp"
#include "friction/extension_fit.hpp"
#include "friction/initial_state.hpp"
#include "friction/lg.hpp"
#include "friction/lugre.hpp"
#include "friction/nlr.hpp"

namespace friction {

namespace {

double sum_sq(const std::vector<double>& v) {
  double s = 0;
  for (double e : v) s += e * e;
  return s;
}

std::string fmt(double v, int precision = 4) {
  std::ostringstream s;
  s.precision(precision);
  s << v;
  return s.str();
}

double record_duration(const Record& r) {
  return std::max(r.time.back() - r.time.front(), 1e-12);
}

double largest_speed(const Record& r) {
  double vmax = 0;
  for (std::size_t k = 1; k < r.size(); ++k)
    vmax = std::max(
        vmax, std::abs(r.displacement[k] - r.displacement[k - 1]) / (r.time[k] - r.time[k - 1]));
  return std::max(vmax, 1e-12);
}

// ---------------------------------------------------------------------------------------------
// Model families: how to build Extended<Base<T>> from the parameter blocks and set its initial
// state.  Block 0 = [free base parameters (when the base is refitted), piece parameters], block 1
// = the initial state in relative units.  Each family also gives the box of its base parameters,
// which of them stay fixed, the base parameters of a block and their report entries.

struct Box {
  std::vector<double> lower, upper;
};

constexpr double kInf = std::numeric_limits<double>::infinity();

// Thresholds inside [q, L] as NLR and fit_extended_slip keep them (log units), widened to hold
// the start.
void threshold_box(Box& b, const Record& r, const std::vector<double>& thresholds) {
  const double q = displacement_resolution(r.displacement);
  const double big = std::max(largest_travel(r.displacement), q * 1.0001);
  for (double d : thresholds) {
    b.lower.push_back(std::log(std::min(q, d)));
    b.upper.push_back(std::log(std::max(big, d)));
  }
}

struct SlipFamily {
  MaxwellSlipParameters<double> p;
  bool free_base = false;  // block 0 starts with log k_i, log Delta_i
  std::size_t base_count() const { return free_base ? 2 * p.size() : 0; }
  std::size_t state_count() const { return p.size(); }
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
    std::vector<T> d(m);
    for (std::size_t i = 0; i < m; ++i)
      d[i] = s[i] * (free_base ? exp(theta[m + i]) : T(p.threshold[i]));
    model.base().reset(std::span<const T>(d));
  }
  std::vector<double> state_bounds() const { return {-1.0, 1.0}; }
};

// DNLRX: block 0's base part is [spring_filter (M (n+1)), input_filter (nx+1), log Delta (M)], the
// order of the DNLRX report.  Coefficients the identification dropped (rank deficiency, set to 0)
// stay 0.
struct DnlrxFamily {
  DnlrxParameters<double> p;
  bool free_base = false;
  std::size_t filter_count() const { return p.spring_filter.size() + p.input_filter.size(); }
  std::size_t base_count() const { return free_base ? filter_count() + p.size() : 0; }
  std::size_t state_count() const { return p.size(); }
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
    std::vector<T> d(p.size());
    for (std::size_t i = 0; i < p.size(); ++i)
      d[i] = s[i] * (free_base ? exp(theta[nf + i]) : T(p.threshold[i]));
    model.base().reset(std::span<const T>(d));
  }
  std::vector<double> state_bounds() const { return {-1.0, 1.0}; }
};

// LuGre: block 0's base part is the seven parameters in to_array order, natural units, boxed to
// their domain (sigma1, sigma2 >= 0; the others above a thousandth of their start, mu in
// [0.2, 10]).  A parameter the identification left at 0 (sigma1 or sigma2) stays 0.
struct LuGreFamily {
  LuGreParameters<double> p;
  bool free_base = false;
  double zref() const { return std::max(p.coulomb, p.static_force) / p.stiffness; }
  std::size_t base_count() const { return free_base ? LuGreParameters<double>::kSize : 0; }
  std::size_t state_count() const { return 1; }
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
  }
  // estimate_lugre_initial_state scans the same range.
  std::vector<double> state_bounds() const { return {-1.5, 1.5}; }
};

// Residuals (F - Fhat) * scale of the extended model's free run on the record.
template <class Family>
struct FamilyCost {
  const Record* record;
  Family family;
  ExtensionParameters<double> pieces;  // which pieces, and the reference force
  double scale;

  template <typename T>
  bool operator()(T const* const* p, T* residual) const {
    ExtensionParameters<T> ext = pieces.template cast<T>([](double v) { return T(v); });
    std::size_t j = family.base_count();
    ext.for_each_parameter([&](Effect, std::string_view, T& v) { v = p[0][j++]; });
    ext.reference_force = T(pieces.reference_force);
    try {
      auto model = family.template make<T>(p[0], std::move(ext));
      family.template set_state<T>(model, p[0], p[1]);
      extended_residuals(model, *record, scale, residual);
    } catch (const InvalidParameter&) {
      return false;
    }
    return true;
  }
};

template <class Family>
using FamilyCostFunction = ceres::DynamicAutoDiffCostFunction<FamilyCost<Family>, 16>;

template <class Family>
FamilyCostFunction<Family>* make_cost(const Record& r, const Family& family,
                                      const ExtensionParameters<double>& pieces, double scale,
                                      std::size_t theta_size) {
  auto* cost = new FamilyCostFunction<Family>(new FamilyCost<Family>{&r, family, pieces, scale});
  cost->AddParameterBlock(static_cast<int>(theta_size));
  cost->AddParameterBlock(static_cast<int>(family.state_count()));
  cost->SetNumResiduals(static_cast<int>(r.size()));
  return cost;
}

// Bounds of block 0: the family's base box (when refitted) and the pieces' boxes.
template <class Family>
Box theta_box(const Family& family, const ExtensionParameters<double>& pieces, double f0,
              const Record& r) {
  Box b;
  if (family.base_count() > 0) b = family.base_box(r);
  const double duration = record_duration(r), vmax = largest_speed(r);
  pieces.for_each_parameter([&](Effect e, std::string_view name, const double&) {
    const ExtensionBounds eb = extension_parameter_bounds(e, name, f0, duration, vmax);
    b.lower.push_back(eb.lower);
    b.upper.push_back(eb.upper);
  });
  return b;
}

std::vector<double> piece_values(const ExtensionParameters<double>& ext) {
  std::vector<double> v;
  ext.for_each_parameter([&](Effect, std::string_view, const double& x) { v.push_back(x); });
  return v;
}

void set_piece_values(ExtensionParameters<double>& ext, const double* v) {
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
  const std::vector<double> sb = family.state_bounds();
  for (double& s : state) s = std::clamp(s, sb[0], sb[1]);
  problem.AddResidualBlock(cost, nullptr, theta.data(), state.data());
  for (std::size_t i = 0; i < state.size(); ++i) {
    problem.SetParameterLowerBound(state.data(), static_cast<int>(i), sb[0]);
    problem.SetParameterUpperBound(state.data(), static_cast<int>(i), sb[1]);
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
  options.function_tolerance = 1e-7;
  options.parameter_tolerance = 1e-9;
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

// Free-run force of a family at given pieces and state (double).
template <class Family>
std::vector<double> family_run(const Record& r, const Family& family,
                               const ExtensionParameters<double>& ext, const double* theta_base,
                               const std::vector<double>& state) {
  auto model = family.template make<double>(theta_base, ext);
  family.template set_state<double>(model, theta_base, state.data());
  return simulate_extended(model, std::span<const double>(r.time),
                           std::span<const double>(r.displacement),
                           std::span<const double>(r.normal));
}

double rss_of(const Record& r, const std::vector<double>& f) {
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
  const std::vector<double> sb = family.state_bounds();
  std::vector<std::vector<double>> starts{plain, std::vector<double>(plain.size(), 0.0), plain};
  for (double& v : starts[2]) v *= 0.5;
  std::vector<double> best;
  double best_rss = std::numeric_limits<double>::infinity();
  for (auto s0 : starts) {
    for (double& s : s0) s = std::clamp(s, sb[0], sb[1]);
    const double rss0 = rss_of(r, family_run(r, family, ext, nullptr, s0));
    if (rss0 < best_rss) best_rss = rss0, best = s0;
    const FamilyFit f = fit_family(r, family, {}, ext, s0, /*fix_pieces=*/true, 30, f0);
    if (f.ok && f.rss < best_rss) best_rss = f.rss, best = f.state;
  }
  return best;
}

// ---------------------------------------------------------------------------------------------
// Covariance of the free parameters at an optimum (header comment, 3).

struct Covariance {
  std::vector<double> standard_error;  // per column of block 0 then block 1; 0: not available
  Eigen::MatrixXd correlation;         // of block 0's columns
  bool rank_deficient = false;
  bool ok = false;
};

template <class Family>
Covariance covariance_at(const Record& r, const Family& family,
                         const ExtensionParameters<double>& pieces, std::vector<double> theta,
                         std::vector<double> state, const std::vector<char>& free_theta,
                         const std::vector<char>& free_state) {
  Covariance out;
  const std::size_t n = r.size(), nt = theta.size(), ns = state.size();
  out.standard_error.assign(nt + ns, 0.0);
  out.correlation =
      Eigen::MatrixXd::Identity(static_cast<Eigen::Index>(nt), static_cast<Eigen::Index>(nt));
  std::unique_ptr<FamilyCostFunction<Family>> cost(make_cost(r, family, pieces, 1.0, nt));
  std::vector<double> residual(n);
  std::vector<double> j0(n * nt), j1(n * ns);
  const double* params[2] = {theta.data(), state.data()};
  double* jac[2] = {j0.data(), j1.data()};
  if (!cost->Evaluate(params, residual.data(), jac)) return out;
  std::vector<std::size_t> cols;  // free columns: 0..nt-1 block 0, nt.. block 1
  for (std::size_t c = 0; c < nt; ++c)
    if (free_theta[c]) cols.push_back(c);
  for (std::size_t c = 0; c < ns; ++c)
    if (free_state[c]) cols.push_back(nt + c);
  const std::size_t p = cols.size();
  if (p == 0 || n <= p) return out;
  Eigen::MatrixXd J(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(p));
  for (std::size_t k = 0; k < n; ++k)
    for (std::size_t q = 0; q < p; ++q) {
      const std::size_t c = cols[q];
      J(static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(q)) =
          c < nt ? j0[k * nt + c] : j1[k * ns + (c - nt)];
    }
  if (!J.allFinite()) return out;
  // Column scaling makes the condition number a property of the model, not of the units.
  Eigen::VectorXd d = J.colwise().norm().transpose();
  for (Eigen::Index q = 0; q < d.size(); ++q)
    if (!(d(q) > 0)) {
      out.rank_deficient = true;
      return out;
    }
  const Eigen::MatrixXd Js = J * d.cwiseInverse().asDiagonal();
  const Eigen::MatrixXd H = Js.transpose() * Js;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(H);
  const double emax = eig.eigenvalues().maxCoeff(), emin = eig.eigenvalues().minCoeff();
  if (!(emin > 1e-12 * emax)) {
    out.rank_deficient = true;
    return out;
  }
  const double s2 = sum_sq(residual) / static_cast<double>(n - p);
  const Eigen::MatrixXd Hinv = eig.eigenvectors() * eig.eigenvalues().cwiseInverse().asDiagonal() *
                               eig.eigenvectors().transpose();
  const Eigen::MatrixXd cov =
      s2 * d.cwiseInverse().asDiagonal() * Hinv * d.cwiseInverse().asDiagonal();
  for (std::size_t q = 0; q < p; ++q) {
    const double v = cov(static_cast<Eigen::Index>(q), static_cast<Eigen::Index>(q));
    out.standard_error[cols[q]] = v > 0 ? std::sqrt(v) : 0.0;
  }
  for (std::size_t a = 0; a < p; ++a)
    for (std::size_t b = 0; b < p; ++b) {
      if (cols[a] >= nt || cols[b] >= nt) continue;
      const double sa = out.standard_error[cols[a]], sb = out.standard_error[cols[b]];
      if (sa > 0 && sb > 0)
        out.correlation(static_cast<Eigen::Index>(cols[a]), static_cast<Eigen::Index>(cols[b])) =
            cov(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) / (sa * sb);
    }
  out.ok = true;
  return out;
}

bool at_bound(double v, double bound) {
  if (!std::isfinite(bound)) return false;
  return v == bound || std::abs(v - bound) <= 1e-6 * std::max(std::abs(bound), std::abs(v));
}

// ---------------------------------------------------------------------------------------------
// Starts for the held bases: regressions of the base's residual on each effect's signature.

// Velocity and acceleration of a record as simulate_extended computes them (no delay).
struct RecordSignals {
  std::vector<double> v, a;
};

RecordSignals record_signals(const Record& r) {
  const std::size_t n = r.size();
  FRICTION_CHECK(n >= 3, "identify: too few samples (", n, ") for extension pieces");
  RecordSignals s;
  s.v.assign(n, 0.0);
  s.a.assign(n, 0.0);
  for (std::size_t k = 1; k < n; ++k)
    s.v[k] = (r.displacement[k] - r.displacement[k - 1]) / (r.time[k] - r.time[k - 1]);
  for (std::size_t k = 1; k + 1 < n; ++k)
    s.a[k] = (s.v[k + 1] - s.v[k]) / (0.5 * (r.time[k + 1] - r.time[k - 1]));
  s.a.front() = s.a[1];
  s.a.back() = s.a[n - 2];
  return s;
}

// Starts of the pieces on a held base: the effect table's regressions on the base's residual.
ExtensionParameters<double> regression_start(const std::vector<Effect>& effects, const Record& r,
                                             const std::vector<double>& fhat, double f0) {
  const std::size_t n = r.size();
  const RecordSignals sig = record_signals(r);
  std::vector<double> e(n), t(n);
  for (std::size_t k = 0; k < n; ++k) {
    e[k] = r.force[k] - fhat[k];
    t[k] = r.time[k] - r.time.front();
  }
  const RegressionSignals signals{e, fhat,   sig.v,    sig.a, r.displacement,
                                  t, r.time, r.normal, f0,    record_duration(r)};
  ExtensionParameters<double> x;
  for (Effect eff : effects) {
    x.enable(eff);
    x.assign(eff, start_from_regression(eff, signals).values);
  }
  return x;
}

// ---------------------------------------------------------------------------------------------

bool scales_with_f0(Effect e, std::string_view name) {
  return find_parameter(e, name)->scales_with_reference_force;
}

// The main parameter of a piece and its null value (no effect); false when it has none
// (normal-load: mu only rescales the level).
bool main_parameter(Effect e, std::string_view* name, double f0, double* null_value) {
  const EffectInfo& info = effect_info(e);
  *name = info.main_parameter;
  *null_value = info.null_value == NullValue::reference_force ? f0 : 0.0;
  return info.null_value != NullValue::none;
}

// Order of a joint start: the velocity pieces before the lag that acts through them.
std::vector<Effect> velocity_pieces_first(std::vector<Effect> effects) {
  std::stable_partition(effects.begin(), effects.end(),
                        [](Effect e) { return e != Effect::frictional_lag; });
  return effects;
}

// Estimates (values, bounds, standard errors) of the pieces from the fitted theta (pieces part),
// the box of the fit and the covariance's standard errors; `ratio` converts to the own F0.
std::vector<ExtensionEstimate> make_estimates(const ExtensionParameters<double>& fitted_ref,
                                              const Box& box, std::size_t base_count,
                                              const Covariance& cov, double ratio) {
  std::vector<ExtensionEstimate> out;
  std::size_t j = 0;
  fitted_ref.for_each_parameter([&](Effect e, std::string_view name, const double& v) {
    const std::size_t c = base_count + j;
    ExtensionEstimate est;
    est.effect = e;
    est.name = std::string(name);
    est.unit = std::string(parameter_unit(name));
    const double s = scales_with_f0(e, name) ? ratio : 1.0;
    est.value = v * s;
    est.at_bound = at_bound(v, box.lower[c]) || at_bound(v, box.upper[c]);
    est.standard_error = cov.ok && !est.at_bound ? cov.standard_error[c] * s : 0.0;
    out.push_back(est);
    ++j;
  });
  return out;
}

// Warnings about the pieces: bounds and missing evidence (header comment, 3).
void judge_evidence(ExtensionIdentification& res, const std::vector<Effect>& effects, double f0,
                    double sigmas) {
  for (Effect e : effects) {
    std::string_view main;
    double null_value = 0;
    const bool testable = main_parameter(e, &main, f0, &null_value);
    bool no_evidence = false;
    for (const auto& est : res.estimates) {
      if (est.effect != e) continue;
      if (est.at_bound) {
        if (testable && est.name == main && at_bound(est.value, null_value))
          no_evidence = true;
        else
          res.warnings.push_back("extension " + std::string(effect_name(e)) + ": " + est.name +
                                 " = " + fmt(est.value) + " " + est.unit +
                                 " ends at a bound of the fit (not identified by this record)");
      }
      if (testable && est.name == main && !est.at_bound && est.standard_error > 0 &&
          std::abs(est.value - null_value) < sigmas * est.standard_error)
        no_evidence = true;
    }
    if (no_evidence) {
      res.without_evidence.push_back(e);
      res.warnings.push_back("the record gives no evidence of " + std::string(effect_name(e)) +
                             " (its fitted value is within " + fmt(sigmas, 2) +
                             " standard errors of none, or at the bound that means none)");
    }
  }
}

std::vector<double> state_from(const std::vector<double>& values,
                               const std::vector<double>& thresholds) {
  std::vector<double> s(thresholds.size(), 0.0);
  for (std::size_t i = 0; i < thresholds.size() && i < values.size(); ++i)
    s[i] = values[i] / thresholds[i];
  return s;
}

// Maxwell Slip: the base and all pieces refitted jointly (header comment, 1).
void identify_slip(ExtensionIdentification& res, const MaxwellSlipParameters<double>& base0,
                   const Record& r, const std::vector<double>& base_initial,
                   std::vector<Effect> effects, const ExtensionFitOptions& o) {
  const double f0ref = base0.sliding_force();
  ExtendedSlipFit cur;
  cur.base = base0;
  cur.rho = state_from(base_initial, base0.threshold);
  for (double& v : cur.rho) v = std::clamp(v, -1.0, 1.0);
  cur.ext.reference_force = f0ref;
  const bool has_velocity_piece =
      std::find(effects.begin(), effects.end(), Effect::viscous) != effects.end() ||
      std::find(effects.begin(), effects.end(), Effect::stribeck) != effects.end();
  if (std::find(effects.begin(), effects.end(), Effect::frictional_lag) != effects.end() &&
      !has_velocity_piece) {
    effects.push_back(Effect::viscous);
    res.warnings.push_back(
        "frictional-lag acts through a velocity-dependent piece: a viscous piece was added with "
        "it");
  }
  const auto fit_step = [&](const ExtensionParameters<double>& start, Effect e) {
    ExtendedSlipFit f = fit_extended_slip(r, cur.base, cur.rho, start, false, o.max_iterations);
    if (!f.ok)
      throw NumericalError("identify: the fit of the " + std::string(effect_name(e)) +
                           " extension found no usable solution");
    cur = std::move(f);
  };
  if (o.order == ExtensionOrder::joint) {
    const ResidualEvidence ev = analyse_residual(cur.base, cur.ext, r);
    ExtensionParameters<double> start = cur.ext;
    for (Effect e : velocity_pieces_first(effects)) {
      if (start.has(e)) continue;
      start = extension_start(e, start, ev, r, f0ref);
      res.order.push_back(e);
    }
    fit_step(start, effects.front());
  } else {
    std::vector<Effect> remaining = effects;
    while (!remaining.empty()) {
      const ResidualEvidence ev = analyse_residual(cur.base, cur.ext, r);
      auto pick = remaining.begin();
      for (const auto& w : ev.effects) {
        auto it = std::find(remaining.begin(), remaining.end(), w.effect);
        if (it != remaining.end()) {
          pick = it;
          break;
        }
      }
      const Effect e = *pick;
      remaining.erase(pick);
      if (cur.ext.has(e)) continue;  // a companion of an earlier piece
      const ExtensionParameters<double> start = extension_start(e, cur.ext, ev, r, f0ref);
      for (Effect added : kAllEffects)
        if (start.has(added) && !cur.ext.has(added)) res.order.push_back(added);
      fit_step(start, e);
    }
  }
  if (o.restart_base) {
    // The base was identified on a force that holds the effects, and the local refit may keep
    // its distortion.  Restart: NLR on the force with the fitted pieces taken out (added terms
    // subtracted, divided by the level), then the joint fit from there; the better one is kept.
    const RecordSignals sig = record_signals(r);
    Extended<MaxwellSlip<double>> model(MaxwellSlip<double>(cur.base), cur.ext, 2);
    model.base().reset(std::span<const double>(deflections_from_relative(cur.base, cur.rho)));
    std::vector<double> corrected(r.size());
    for (std::size_t k = 0; k < r.size(); ++k) {
      ExtendedMotion<double> c;
      c.x = r.displacement[k];
      c.dx = k > 0 ? r.displacement[k] - r.displacement[k - 1] : 0.0;
      c.velocity = sig.v[k];
      c.acceleration = sig.a[k];
      c.dt = k > 0 ? r.time[k] - r.time[k - 1] : 0.0;
      c.time = r.time[k] - r.time.front();
      if (r.has_normal()) c.normal = r.normal[k], c.has_normal = true;
      model.step_shifted(c);
      const double vl = cur.ext.frictional_lag ? model.lagged_velocity() : sig.v[k];
      double added = 0;
      if (cur.ext.viscous) added += cur.ext.viscous->viscous * vl;
      if (cur.ext.offset) added += cur.ext.offset->offset;
      if (cur.ext.inertia) added += cur.ext.inertia->mass * sig.a[k];
      corrected[k] = (r.force[k] - added) / std::max(model.level(), 0.05);
    }
    NlrOptions n;
    n.operators = o.operators;
    if (o.max_operators > 0) n.max_operators = o.max_operators;
    n.global_stage = o.global_stage;
    n.covariance = false;
    try {
      const NlrResult nr = identify_maxwell_slip(r.time, r.displacement, corrected, n);
      const ExtendedSlipFit g = fit_extended_slip(
          r, nr.parameters, state_from(nr.report.initial_deflections, nr.parameters.threshold),
          cur.ext, false, o.max_iterations);
      // M may differ (it is selected again on the corrected force): compare by BIC.
      const std::size_t pe = cur.ext.parameter_count();
      if (g.ok && bayesian_information_criterion(g.rss, r.size(), 2 * g.base.size() + pe) <
                      bayesian_information_criterion(cur.rss, r.size(), 2 * cur.base.size() + pe)) {
        cur = g;
        res.restarted = true;
      }
    } catch (const Error&) {
      // No restart: the first fit stands.
    }
  }
  res.fit_rss_sss_percent = 100.0 * cur.rss / sum_sq(r.force);

  // Covariance of theta = [log k, log Delta, pieces] and rho at the optimum.
  const std::size_t m = cur.base.size();
  SlipFamily fam{cur.base, true};
  std::vector<double> theta;
  for (double k : cur.base.stiffness) theta.push_back(std::log(k));
  for (double d : cur.base.threshold) theta.push_back(std::log(d));
  for (double v : piece_values(cur.ext)) theta.push_back(v);
  const Box box = theta_box(fam, cur.ext, f0ref, r);
  std::vector<char> free_theta(theta.size(), 1), free_state(m, 1);
  for (std::size_t c = 0; c < theta.size(); ++c)
    if (at_bound(theta[c], box.lower[c]) || at_bound(theta[c], box.upper[c])) free_theta[c] = 0;
  for (std::size_t i = 0; i < m; ++i)
    if (std::abs(cur.rho[i]) >= 1.0 - 1e-9) free_state[i] = 0;
  const Covariance cov = covariance_at(r, fam, cur.ext, theta, cur.rho, free_theta, free_state);
  if (cov.rank_deficient)
    res.warnings.push_back(
        "the joint fit's covariance is rank deficient (some parameters trade off against each "
        "other on this record): no standard errors are given");
  const double own_f0 = cur.base.sliding_force();
  const double ratio = own_reference_ratio(cur.ext, own_f0);
  res.estimates = make_estimates(cur.ext, box, 2 * m, cov, ratio);
  // The refitted base, with standard errors of k and Delta from those of their logarithms.
  for (std::size_t i = 0; i < 2 * m; ++i) {
    ParameterEstimate p;
    const bool stiff = i < m;
    const std::size_t idx = stiff ? i : i - m;
    p.name = (stiff ? "stiffness[" : "threshold[") + std::to_string(idx + 1) + "]";
    p.unit = stiff ? "N/m" : "m";
    p.value = stiff ? cur.base.stiffness[idx] : cur.base.threshold[idx];
    const double sl = cov.ok && free_theta[i] ? cov.standard_error[i] : 0.0;
    p.standard_error = p.value * sl;
    p.lower95 = p.value * std::exp(-1.96 * sl);
    p.upper95 = p.value * std::exp(1.96 * sl);
    res.base_parameters.push_back(p);
  }
  {
    const auto nt = static_cast<Eigen::Index>(theta.size());
    res.correlation_matrix = cov.correlation.topLeftCorner(nt, nt);
  }
  ExtensionParameters<double> own = to_own_reference(cur.ext, own_f0);
  res.model = AnyModel(Extended<MaxwellSlip<double>>(MaxwellSlip<double>(cur.base), own));
  judge_evidence(res, effects, own_f0, o.evidence_sigmas);
}

// Report entries of a refitted base from block 0's base part and its standard errors.
std::vector<ParameterEstimate> base_estimates(const DnlrxFamily& f, const std::vector<double>& th,
                                              const std::vector<double>& se) {
  std::vector<ParameterEstimate> out;
  const std::size_t taps = f.p.spring_taps(), ns = f.p.spring_filter.size();
  for (std::size_t c = 0; c < th.size(); ++c) {
    ParameterEstimate e;
    if (c < ns) {
      e.name =
          "spring_filter[" + std::to_string(c / taps + 1) + "," + std::to_string(c % taps) + "]";
      e.unit = "N/m";
    } else if (c < f.filter_count()) {
      e.name = "input_filter[" + std::to_string(c - ns) + "]";
      e.unit = "N/m";
    } else {
      e.name = "threshold[" + std::to_string(c - f.filter_count() + 1) + "]";
      e.unit = "m";
      e.value = std::exp(th[c]);
      e.standard_error = e.value * se[c];
      e.lower95 = e.value * std::exp(-1.96 * se[c]);
      e.upper95 = e.value * std::exp(1.96 * se[c]);
      out.push_back(e);
      continue;
    }
    e.value = th[c];
    e.standard_error = se[c];
    e.lower95 = th[c] - 1.96 * se[c];
    e.upper95 = th[c] + 1.96 * se[c];
    out.push_back(e);
  }
  return out;
}

std::vector<ParameterEstimate> base_estimates(const LuGreFamily&, const std::vector<double>& th,
                                              const std::vector<double>& se) {
  static constexpr std::array<const char*, 7> kUnits{"N/m", "N s/m", "N s/m", "N", "N", "m/s", "1"};
  std::vector<ParameterEstimate> out;
  for (std::size_t j = 0; j < th.size(); ++j)
    out.push_back({kLuGreParameterNames[j], kUnits[j], th[j], se[j], th[j] - 1.96 * se[j],
                   th[j] + 1.96 * se[j]});
  return out;
}

double own_f0(const DnlrxParameters<double>& p) {
  return p.sliding_force();
}
double own_f0(const LuGreParameters<double>& p) {
  return p.coulomb;
}

// LuGre / DNLRX (header comment, 2): the pieces and the initial state with the base held, then
// (refit_base) everything together from there.
template <class Family>
void identify_other(ExtensionIdentification& res, Family fam, const Record& r,
                    const std::vector<double>& base_simulated,
                    const std::vector<double>& start_state, const std::vector<Effect>& effects,
                    const ExtensionFitOptions& o) {
  using Base = std::decay_t<decltype(fam.template make<double>(nullptr, {}).base())>;
  const double f0 = own_f0(fam.p);
  FRICTION_CHECK(f0 > 0, "identify: the base's sliding force ", f0,
                 " N is not positive: its level cannot carry extension pieces");
  ExtensionParameters<double> start = regression_start(effects, r, base_simulated, f0);
  start.reference_force = f0;  // fixed while the base moves (as for Maxwell Slip)
  FamilyFit f = fit_family(r, fam, {}, start, start_state, false, o.max_iterations, f0);
  if (!f.ok)
    throw NumericalError("identify: the fit of the extension pieces found no usable solution");
  const std::string method = std::is_same_v<Family, LuGreFamily> ? "LG" : "DNLRX";
  res.base_held = true;
  if (o.refit_base) {
    Family joint = fam;
    joint.free_base = true;
    FamilyFit g =
        fit_family(r, joint, joint.base_theta(), f.ext, f.state, false, o.max_iterations, f0);
    if (g.ok && g.rss < f.rss) {
      f = std::move(g);
      fam = joint;
      res.base_held = false;
    } else {
      res.warnings.push_back("the joint refit of the " + method +
                             " base with the pieces did not improve on the fit with the base "
                             "held: the base keeps its " +
                             method + " estimate");
    }
  }
  if (res.base_held)
    res.warnings.push_back("the base parameters were held at their " + method +
                           " estimate; only the extension pieces and the initial state were "
                           "fitted");
  res.order = velocity_pieces_first(effects);
  res.fit_rss_sss_percent = 100.0 * f.rss / sum_sq(r.force);
  std::vector<double> theta = f.base_theta;
  for (double v : piece_values(f.ext)) theta.push_back(v);
  const std::size_t nb = fam.base_count();
  const Box box = theta_box(fam, f.ext, f0, r);
  std::vector<char> free_theta(theta.size(), 1), free_state(f.state.size(), 1);
  for (std::size_t c = 0; c < theta.size(); ++c)
    if (at_bound(theta[c], box.lower[c]) || at_bound(theta[c], box.upper[c])) free_theta[c] = 0;
  if (nb > 0)
    for (int h : fam.held(f.base_theta)) free_theta[static_cast<std::size_t>(h)] = 0;
  const std::vector<double> sb = fam.state_bounds();
  for (std::size_t i = 0; i < f.state.size(); ++i)
    if (at_bound(f.state[i], sb[0]) || at_bound(f.state[i], sb[1])) free_state[i] = 0;
  const Covariance cov = covariance_at(r, fam, f.ext, theta, f.state, free_theta, free_state);
  if (cov.rank_deficient)
    res.warnings.push_back(
        "the covariance of the fit is rank deficient (some parameters trade off against each "
        "other on this record): no standard errors are given");
  const auto new_base = nb > 0 ? fam.parameters(f.base_theta.data()) : fam.p;
  const double f0_own = own_f0(new_base);
  res.estimates = make_estimates(f.ext, box, nb, cov, own_reference_ratio(f.ext, f0_own));
  if (nb > 0) {
    std::vector<double> se(nb, 0.0);
    for (std::size_t c = 0; c < nb; ++c)
      se[c] = cov.ok && free_theta[c] ? cov.standard_error[c] : 0.0;
    res.base_parameters = base_estimates(fam, f.base_theta, se);
  }
  const auto nt = static_cast<Eigen::Index>(theta.size());
  res.correlation_matrix = cov.correlation.topLeftCorner(nt, nt);
  res.model = AnyModel(Extended<Base>(Base(new_base), to_own_reference(f.ext, f0_own)));
  judge_evidence(res, effects, f0_own, o.evidence_sigmas);
}

}  // namespace

// -----------------------------------------------------------------------------------------------

std::string extension_parameter_unit(std::string_view name) {
  return std::string(parameter_unit(name));
}

std::string extension_names() {
  return effect_names();
}

std::vector<Effect> parse_extension_list(const std::vector<std::string>& names) {
  std::vector<Effect> out;
  for (const auto& item : names) {
    std::size_t begin = 0;
    while (begin <= item.size()) {
      std::size_t end = item.find(',', begin);
      if (end == std::string::npos) end = item.size();
      std::string name = item.substr(begin, end - begin);
      name.erase(0, name.find_first_not_of(" \t"));
      name.erase(name.find_last_not_of(" \t") + 1);
      begin = end + 1;
      if (name.empty()) continue;
      const auto e = effect_from_name(name);
      if (!e)
        throw InvalidParameter("unknown extension '" + name + "' (expected one of " +
                               extension_names() + ")");
      if (std::find(out.begin(), out.end(), *e) == out.end()) out.push_back(*e);
    }
  }
  return out;
}

void check_extension_request(const std::string& type, const std::vector<Effect>& effects,
                             const Record& r) {
  const auto has = [&](Effect e) {
    return std::find(effects.begin(), effects.end(), e) != effects.end();
  };
  if (effects.empty()) return;
  FRICTION_CHECK(type == "maxwell-slip" || type == "lugre" || type == "dnlrx",
                 "identify: extensions can be identified on maxwell-slip, lugre and dnlrx, not ",
                 type);
  if (type == "lugre") {
    if (has(Effect::viscous))
      throw InvalidParameter(
          "identify: lugre already carries viscous friction in its base (sigma2 v, the "
          "'viscous' parameter); ask for viscous on maxwell-slip");
    if (has(Effect::stribeck))
      throw InvalidParameter(
          "identify: lugre already carries the Stribeck effect in its base (static, "
          "stribeck_velocity, stribeck_exponent); ask for stribeck on maxwell-slip");
    if (has(Effect::frictional_lag))
      throw InvalidParameter(
          "identify: frictional-lag acts through the viscous and Stribeck pieces, which lugre "
          "holds in its base (and its bristle dynamics already lag); ask for it on "
          "maxwell-slip");
  }
  if (type == "dnlrx") {
    if (has(Effect::viscous))
      throw InvalidParameter(
          "identify: dnlrx already carries viscous friction in its input filter (sum_j g_j "
          "dx(t-j) = (sum_j g_j) Ts v at constant speed; --input-order sets it); ask for "
          "viscous on maxwell-slip");
    if (has(Effect::frictional_lag) && !has(Effect::stribeck))
      throw InvalidParameter(
          "identify: on dnlrx frictional-lag needs the stribeck piece it acts through (the "
          "input filter is its own viscous lag); ask for stribeck,frictional-lag");
  }
  if (has(Effect::normal_load) && !r.has_normal())
    throw DataError(r.source, 0, 0,
                    "the normal-load extension needs a normal force column (normal, "
                    "normal_force or normal_force_n; --columns normal=NAME), and the record "
                    "has none");
}

ExtensionIdentification identify_extensions(const AnyModel& base, const Record& r,
                                            const std::vector<double>& base_simulated,
                                            const std::vector<double>& base_initial,
                                            const std::vector<Effect>& effects,
                                            const ExtensionFitOptions& o) {
  const auto started = std::chrono::steady_clock::now();
  FRICTION_CHECK(r.has_force(), r.source, ": the record has no force to identify from");
  FRICTION_CHECK(base.extensions().empty(), "identify_extensions: the base carries pieces already");
  FRICTION_CHECK(base_simulated.size() == r.size(),
                 "identify_extensions: the base's free run does not match the record");
  check_extension_request(base.type(), effects, r);
  ExtensionIdentification res{base};
  res.base_estimation_percent = 100.0 * rss_of(r, base_simulated) / sum_sq(r.force);
  if (effects.empty()) {
    res.model = base;
    res.simulated = base_simulated;
    res.estimation = compute_errors(r.force, base_simulated);
    res.initial_values = base_initial;
    return res;
  }
  std::visit(
      [&](const auto& ext) {
        using B = std::decay_t<decltype(ext.base())>;
        const auto& p = ext.base().parameters();
        if constexpr (std::is_same_v<B, MaxwellSlip<double>>) {
          identify_slip(res, p, r, base_initial, effects, o);
        } else if constexpr (std::is_same_v<B, Dnlrx<double>>) {
          identify_other(res, DnlrxFamily{p}, r, base_simulated,
                         state_from(base_initial, p.threshold), effects, o);
        } else if constexpr (std::is_same_v<B, LuGre<double>>) {
          const LuGreFamily fam{p, false};
          const double u = base_initial.empty() ? 0.0 : base_initial[0] / fam.zref();
          identify_other(res, fam, r, base_simulated, {u}, effects, o);
        } else {
          throw InvalidParameter("identify: extensions cannot be identified on " + base.type());
        }
      },
      base.variant());
  const ExtendedFreeRun run = free_run_extended(res.model, r);
  res.simulated = run.simulated;
  res.initial_values = run.initial;
  res.estimation = compute_errors(r.force, res.simulated);
  res.initial_state = {{"kind", "estimated"}, {"values", run.initial}, {"unit", "m"}};
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return res;
}

ExtendedFreeRun free_run_extended(const AnyModel& model, const Record& r) {
  FRICTION_CHECK(r.has_force(), r.source, ": the record has no force to estimate the state from");
  ExtendedFreeRun out;
  std::visit(
      [&](const auto& ext) {
        using B = std::decay_t<decltype(ext.base())>;
        const auto& p = ext.base().parameters();
        const ExtensionParameters<double>& pieces = ext.extensions();
        if constexpr (std::is_same_v<B, MaxwellSlip<double>>) {
          const SlipFamily fam{p, false};
          const std::vector<double> plain =
              estimate_initial_deflections(p, r.displacement, r.force);
          const std::vector<double> s = estimate_family_state(
              r, fam, pieces, state_from(plain, p.threshold), value_of(ext.reference_force()));
          out.simulated = family_run(r, fam, pieces, nullptr, s);
          out.initial = deflections_from_relative(p, s);
        } else if constexpr (std::is_same_v<B, Dnlrx<double>>) {
          const DnlrxFamily fam{p, false};
          const DnlrxFreeRun plain = free_run_dnlrx(p, r.time, r.displacement, r.force);
          const std::vector<double> s = estimate_family_state(
              r, fam, pieces, state_from(plain.initial_deflections, p.threshold),
              value_of(ext.reference_force()));
          out.simulated = family_run(r, fam, pieces, nullptr, s);
          for (std::size_t i = 0; i < s.size(); ++i) out.initial.push_back(s[i] * p.threshold[i]);
        } else if constexpr (std::is_same_v<B, LuGre<double>>) {
          const LuGreFamily fam{p, false};
          const double z0 = estimate_lugre_initial_state(p, r.time, r.displacement, r.force);
          const std::vector<double> s = estimate_family_state(r, fam, pieces, {z0 / fam.zref()},
                                                              value_of(ext.reference_force()));
          out.simulated = family_run(r, fam, pieces, nullptr, s);
          out.initial = {s[0] * fam.zref()};
        } else {
          throw InvalidParameter("free_run_extended: no initial-state estimator for " +
                                 model.type());
        }
      },
      model.variant());
  return out;
}

Json ExtensionIdentification::to_json() const {
  Json j;
  j["base"] = base_held ? "held" : "refitted jointly";
  Json ord = Json::array();
  for (Effect e : order) ord.push_back(std::string(effect_name(e)));
  j["order"] = ord;
  Json pieces = Json::object();
  for (const auto& est : estimates) {
    Json v = {{"value", est.value},
              {"unit", est.unit},
              {"standard_error", est.standard_error},
              {"at_bound", est.at_bound}};
    pieces[std::string(effect_name(est.effect))][est.name] = v;
  }
  j["pieces"] = pieces;
  Json none = Json::array();
  for (Effect e : without_evidence) none.push_back(std::string(effect_name(e)));
  j["no_evidence"] = none;
  j["estimation_before_percent"] = base_estimation_percent;
  j["estimation_after_percent"] = estimation.rss_sss_percent;
  j["fit_rss_sss_percent"] = fit_rss_sss_percent;
  if (!base_held) j["restarted"] = restarted;
  j["seconds"] = seconds;
  return j;
}

}  // namespace friction
