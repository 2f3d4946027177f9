// DNLRX identification (see include/friction/dnlrx_identification.hpp).
#include "friction/dnlrx_identification.hpp"

#include <ceres/ceres.h>

#include <Eigen/SVD>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>

#include "friction/covariance_report.hpp"
#include "friction/initial_state.hpp"
#include "friction/simulate.hpp"
#include "bounded_solver.hpp"
#include "compressed_cost.hpp"
#include "parallel_for.hpp"
#include "slip_regression.hpp"
#include "subnormals.hpp"

namespace friction {
namespace {

struct Orders {
  std::size_t m, n, nx;
  Eigen::Index columns() const { return static_cast<Eigen::Index>(m * (n + 1) + nx + 1); }
  Eigen::Index spring_column(std::size_t i, std::size_t j) const {
    return static_cast<Eigen::Index>(i * (n + 1) + j);
  }
  Eigen::Index input_column(std::size_t j) const {
    return static_cast<Eigen::Index>(m * (n + 1) + j);
  }
};

std::string column_name(const Orders& o, Eigen::Index c) {
  const auto cu = static_cast<std::size_t>(c);
  if (cu < o.m * (o.n + 1))
    return "spring_filter[" + std::to_string(cu / (o.n + 1) + 1) + "," +
           std::to_string(cu % (o.n + 1)) + "]";
  return "input_filter[" + std::to_string(cu - o.m * (o.n + 1)) + "]";
}

struct Series {
  std::span<const double> x;
  Eigen::VectorXd y;   // force [N]
  Eigen::VectorXd dx;  // dx(0) = 0
  double scale = 1;    // rms force
};

Series make_series(std::span<const double> x, std::span<const double> force) {
  Series r;
  r.x = x;
  const Eigen::Index n = static_cast<Eigen::Index>(x.size());
  r.y = Eigen::Map<const Eigen::VectorXd>(force.data(), n);
  r.dx = Eigen::VectorXd::Zero(n);
  for (Eigen::Index t = 1; t < n; ++t)
    r.dx(t) = x[static_cast<std::size_t>(t)] - x[static_cast<std::size_t>(t - 1)];
  r.scale = std::sqrt(r.y.squaredNorm() / static_cast<double>(n));
  return r;
}

Eigen::MatrixXd regressors(const detail::OperatorTrajectories& tr, const Eigen::VectorXd& dx,
                           const Orders& o) {
  const Eigen::Index n = dx.size();
  Eigen::MatrixXd phi(n, o.columns());
  for (std::size_t i = 0; i < o.m; ++i)
    for (std::size_t j = 0; j <= o.n; ++j)
      phi.col(o.spring_column(i, j)) =
          detail::lagged(tr.delta.col(static_cast<Eigen::Index>(i)), static_cast<Eigen::Index>(j));
  for (std::size_t j = 0; j <= o.nx; ++j)
    phi.col(o.input_column(j)) = detail::lagged(dx, static_cast<Eigen::Index>(j));
  return phi;
}

Eigen::VectorXd input_part(const Series& r, const Orders& o, const Eigen::VectorXd& c) {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(r.dx.size());
  for (std::size_t j = 0; j <= o.nx; ++j)
    f += c(o.input_column(j)) * detail::lagged(r.dx, static_cast<Eigen::Index>(j));
  return f;
}

Eigen::MatrixXd spring_matrix(const Orders& o, const Eigen::VectorXd& c) {
  Eigen::MatrixXd th(static_cast<Eigen::Index>(o.m), static_cast<Eigen::Index>(o.n + 1));
  for (std::size_t i = 0; i < o.m; ++i)
    for (std::size_t j = 0; j <= o.n; ++j)
      th(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = c(o.spring_column(i, j));
  return th;
}

struct LinearFit {
  Eigen::VectorXd c;
  std::vector<double> init;
  double rss = std::numeric_limits<double>::infinity();
  std::size_t kept = 0;
  std::vector<Eigen::Index> dropped;
  std::vector<std::size_t> never_saturating;
};

// Linear least squares for fixed thresholds, alternating with the initial-state estimate.
LinearFit fit_linear(const Series& r, const std::vector<double>& thr, const Orders& o,
                     std::vector<double> init, double tol) {
  LinearFit fit;
  for (int round = 0; round < 3; ++round) {
    const auto tr = detail::operator_trajectories(thr, init, r.x, true);
    const Eigen::MatrixXd phi = regressors(tr, r.dx, o);
    // Operators that never saturate: their lags duplicate the input filter.
    std::vector<char> keep(static_cast<std::size_t>(o.columns()), 1);
    fit.never_saturating.clear();
    for (std::size_t i = 0; i < o.m; ++i)
      if (tr.d_initial.col(static_cast<Eigen::Index>(i)).minCoeff() > 0.5) {
        fit.never_saturating.push_back(i);
        for (std::size_t j = 1; j <= o.n; ++j)
          keep[static_cast<std::size_t>(o.spring_column(i, j))] = 0;
      }
    std::vector<Eigen::Index> cols;
    for (Eigen::Index c = 0; c < o.columns(); ++c)
      if (keep[static_cast<std::size_t>(c)]) cols.push_back(c);
    Eigen::MatrixXd pk(phi.rows(), static_cast<Eigen::Index>(cols.size()));
    for (std::size_t k = 0; k < cols.size(); ++k)
      pk.col(static_cast<Eigen::Index>(k)) = phi.col(cols[k]);
    const detail::Projector proj(pk, tol);
    const Eigen::VectorXd ck = proj.solve(r.y);
    fit.c = Eigen::VectorXd::Zero(o.columns());
    fit.dropped.clear();
    for (Eigen::Index c = 0; c < o.columns(); ++c)
      if (!keep[static_cast<std::size_t>(c)]) fit.dropped.push_back(c);
    for (std::size_t k = 0; k < cols.size(); ++k) {
      fit.c(cols[k]) = ck(static_cast<Eigen::Index>(k));
      if (proj.dropped(static_cast<Eigen::Index>(k))) fit.dropped.push_back(cols[k]);
    }
    std::sort(fit.dropped.begin(), fit.dropped.end());
    fit.kept = static_cast<std::size_t>(o.columns()) - fit.dropped.size();
    fit.rss = (r.y - phi * fit.c).squaredNorm();
    fit.init = init;
    if (round == 2) break;
    const Eigen::VectorXd target = r.y - input_part(r, o, fit.c);
    const std::vector<double> next = estimate_initial_deflections(
        r.x, std::span<const double>(target.data(), static_cast<std::size_t>(target.size())), thr,
        spring_matrix(o, fit.c), init, InitialStateOptions::quick());
    if (next == init) break;
    init = next;
  }
  return fit;
}

// Initial deflections for thresholds before any filter is known: NNLS stiffnesses from the virgin
// state, then the Maxwell Slip estimate.
std::vector<double> first_initial_state(const Series& r, const std::vector<double>& thr) {
  const std::size_t m = thr.size();
  const auto tr = detail::operator_trajectories(thr, std::vector<double>(m, 0.0), r.x, false);
  const Eigen::Index mi = static_cast<Eigen::Index>(m);
  const Eigen::VectorXd k = detail::box_least_squares(
      tr.delta, r.y, Eigen::VectorXd::Zero(mi),
      Eigen::VectorXd::Constant(mi, std::numeric_limits<double>::infinity()));
  if (k.norm() == 0.0) return std::vector<double>(m, 0.0);
  const Eigen::MatrixXd filter = k;
  return estimate_initial_deflections(
      r.x, std::span<const double>(r.y.data(), static_cast<std::size_t>(r.y.size())), thr, filter,
      {}, InitialStateOptions::quick());
}

// Variable projection over (s, rho) for fixed orders: residual (y - Phi c*) / scale.
class DnlrxVpCost final : public ceres::CostFunction {
 public:
  DnlrxVpCost(const Series& r, Orders o, detail::StickBreaking sb, double tol)
      : r_(r), o_(o), sb_(sb), tol_(tol) {
    set_num_residuals(static_cast<int>(r.y.size()));
    mutable_parameter_block_sizes()->push_back(static_cast<int>(o.m));
    mutable_parameter_block_sizes()->push_back(static_cast<int>(o.m));
  }
  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    const std::size_t m = o_.m;
    const Eigen::Index mi = static_cast<Eigen::Index>(m);
    // Ceres evaluates the cost at a trial point (its projected line search, then the candidate)
    // and the Jacobian at the same point once the step is accepted: the trajectories (with their
    // sensitivities, which cost little more), the projection and the residual are kept for the
    // last point, and a repeated request only assembles what is missing.
    const bool same = point_.size() == 2 * m && std::equal(p[0], p[0] + m, point_.begin()) &&
                      std::equal(p[1], p[1] + m, point_.begin() + static_cast<std::ptrdiff_t>(m));
    if (!same) {
      thr_ = sb_.thresholds({p[0], m});
      std::vector<double> init(m);
      for (std::size_t i = 0; i < m; ++i) init[i] = p[1][i] * thr_[i];
      detail::operator_trajectories(thr_, init, r_.x, true, tr_);
      phi_ = regressors(tr_, r_.dx, o_);
      proj_.compute(phi_, tol_);
      c_ = proj_.solve(r_.y);
      res_ = r_.y;
      res_.noalias() -= phi_ * c_;
      res_ /= r_.scale;
      point_.assign(p[0], p[0] + m);
      point_.insert(point_.end(), p[1], p[1] + m);
      has_jacobian_ = false;
    }
    Eigen::Map<Eigen::VectorXd>(residuals, res_.size()) = res_;
    if (!jacobians) return true;
    const Eigen::Index n = res_.size();
    if (!has_jacobian_) {
      // Columns d/dDelta_i (0..M-1) and d/drho_i (M..2M-1), projected at once.
      a_.setZero(n, 2 * mi);
      w_.setZero(o_.columns(), 2 * mi);
      for (std::size_t i = 0; i < m; ++i) {
        const Eigen::Index ii = static_cast<Eigen::Index>(i);
        for (int which = 0; which < 2; ++which) {
          const Eigen::Index col = ii + which * mi;
          if (which == 0)
            base_ = tr_.d_threshold.col(ii) + p[1][i] * tr_.d_initial.col(ii);
          else
            base_ = thr_[i] * tr_.d_initial.col(ii);
          base_ /= r_.scale;
          for (std::size_t j = 0; j <= o_.n; ++j) {
            // The lag-j copy of base (the record extended backwards with its first value).
            const Eigen::Index lag = static_cast<Eigen::Index>(j);
            const double cij = c_(o_.spring_column(i, j));
            double dot = 0.0;
            for (Eigen::Index t = 0; t < n; ++t) {
              const double l = base_(t >= lag ? t - lag : 0);
              a_(t, col) += cij * l;
              dot += l * res_(t);
            }
            w_(o_.spring_column(i, j), col) = dot * r_.scale;
          }
        }
      }
      proj_.derivatives_into(a_, w_, dr_);
      jd_.resize(n, mi);
      jd_.noalias() = dr_.leftCols(mi) * sb_.jacobian({p[0], m});
      has_jacobian_ = true;
    }
    using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    if (jacobians[0]) Eigen::Map<RowMajor>(jacobians[0], n, mi) = jd_;
    if (jacobians[1]) Eigen::Map<RowMajor>(jacobians[1], n, mi) = dr_.rightCols(mi);
    return true;
  }

 private:
  const Series& r_;
  Orders o_;
  detail::StickBreaking sb_;
  double tol_;
  // The last point and what was computed there (see Evaluate).
  mutable std::vector<double> point_, thr_;
  mutable bool has_jacobian_ = false;
  mutable detail::OperatorTrajectories tr_;
  mutable Eigen::MatrixXd phi_, a_, w_, dr_, jd_;
  mutable Eigen::VectorXd c_, res_, base_;
  mutable detail::Projector proj_;
};

struct Reoptimised {
  std::vector<double> thr, init;
  ceres::Solver::Summary summary;
};

// Thresholds (and initial deflections) re-optimised with the filters by variable projection.
Reoptimised reoptimise(const Series& r, const Orders& o, const detail::StickBreaking& sb,
                       const std::vector<double>& thr0, const std::vector<double>& init0,
                       double tol, int max_iterations) {
  std::vector<double> s = sb.coordinates(thr0), rho(o.m);
  for (std::size_t i = 0; i < o.m; ++i) rho[i] = std::clamp(init0[i] / thr0[i], -1.0, 1.0);
  ceres::Problem problem;
  problem.AddResidualBlock(new detail::CompressedCost(new DnlrxVpCost(r, o, sb, tol)), nullptr,
                           s.data(), rho.data());
  for (int i = 0; i < static_cast<int>(o.m); ++i) {
    problem.SetParameterLowerBound(s.data(), i, 0.0);
    problem.SetParameterUpperBound(s.data(), i, 1.0);
    problem.SetParameterLowerBound(rho.data(), i, -1.0);
    problem.SetParameterUpperBound(rho.data(), i, 1.0);
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.use_nonmonotonic_steps = true;
  so.max_num_iterations = max_iterations;
  so.function_tolerance = detail::resolved_function_tolerance(static_cast<std::size_t>(r.y.size()));
  so.parameter_tolerance = 1e-10;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  detail::use_value_only_line_search(so);
  Reoptimised out;
  ceres::Solve(so, &problem, &out.summary);
  out.thr = sb.thresholds(s);
  out.init.resize(o.m);
  for (std::size_t i = 0; i < o.m; ++i) out.init[i] = rho[i] * out.thr[i];
  return out;
}

// The model, its free run from the estimated initial state, and the uncertainty of its
// parameters: J = [Phi (kept columns), d Fhat / d log Delta].
void finish(std::span<const double> time, std::span<const double> x, std::span<const double> force,
            const Series& r, const Orders& o, const std::vector<double>& thr, const LinearFit& fit,
            bool covariance, DnlrxResult& result) {
  IdentificationReport& rep = result.report;
  const Eigen::Index n = r.y.size();
  auto& p = result.parameters;
  p.threshold = thr;
  p.spring_order = o.n;
  p.spring_filter.assign(fit.c.data(), fit.c.data() + o.m * (o.n + 1));
  p.input_filter.assign(fit.c.data() + o.m * (o.n + 1), fit.c.data() + o.columns());
  for (std::size_t i : fit.never_saturating)
    rep.warnings.push_back("operator " + std::to_string(i + 1) +
                           " never saturates on this record: its lagged deflections duplicate the "
                           "input filter and were dropped");
  for (Eigen::Index c : fit.dropped) {
    bool explained = false;
    for (std::size_t i : fit.never_saturating)
      explained |= static_cast<std::size_t>(c) < o.m * (o.n + 1) &&
                   static_cast<std::size_t>(c) / (o.n + 1) == i;
    if (!explained)
      rep.warnings.push_back(column_name(o, c) +
                             " is numerically dependent on the other regressors "
                             "(rank-revealing QR): dropped (set to 0)");
  }

  // Free run from the estimated initial state.
  {
    const Eigen::VectorXd target = r.y - input_part(r, o, fit.c);
    rep.initial_deflections =
        estimate_initial_deflections(x, std::span<const double>(target.data(), x.size()),
                                     p.threshold, spring_matrix(o, fit.c), fit.init);
    Dnlrx<double> model(p);
    model.reset(std::span<const double>(rep.initial_deflections));
    rep.estimation_simulated = simulate(model, time, x);
    rep.estimation = compute_errors(force, rep.estimation_simulated);
  }
  rep.noise_sigma = estimate_white_noise_sigma(force);
  rep.noise_floor_percent = noise_floor_rss_sss_percent(force, rep.noise_sigma);

  // Parameters and their uncertainty: J = [Phi (kept columns), d Fhat / d log Delta].
  const Eigen::Index pc = o.columns();
  const Eigen::Index mi = static_cast<Eigen::Index>(o.m);
  for (Eigen::Index c = 0; c < pc; ++c)
    rep.parameters.push_back({column_name(o, c), "N/m", fit.c(c), 0, fit.c(c), fit.c(c)});
  for (std::size_t i = 0; i < o.m; ++i)
    rep.parameters.push_back({"threshold[" + std::to_string(i + 1) + "]", "m", p.threshold[i], 0,
                              p.threshold[i], p.threshold[i]});
  rep.correlation = Eigen::MatrixXd::Identity(pc + mi, pc + mi);
  if (covariance) {
    const auto tr = detail::operator_trajectories(p.threshold, rep.initial_deflections, x, true);
    const Eigen::MatrixXd phi = regressors(tr, r.dx, o);
    std::vector<Eigen::Index> cols;
    for (Eigen::Index c = 0; c < pc; ++c)
      if (!std::binary_search(fit.dropped.begin(), fit.dropped.end(), c)) cols.push_back(c);
    for (Eigen::Index i = 0; i < mi; ++i) {
      if (std::find(fit.never_saturating.begin(), fit.never_saturating.end(),
                    static_cast<std::size_t>(i)) != fit.never_saturating.end()) {
        rep.warnings.push_back("threshold[" + std::to_string(i + 1) +
                               "] is not identifiable from this record (the operator never "
                               "saturates); it has no standard error");
        continue;
      }
      cols.push_back(pc + i);
    }
    Eigen::MatrixXd j(n, static_cast<Eigen::Index>(cols.size()));
    for (std::size_t k = 0; k < cols.size(); ++k) {
      const Eigen::Index c = cols[k];
      if (c < pc) {
        j.col(static_cast<Eigen::Index>(k)) = phi.col(c);
      } else {
        const std::size_t i = static_cast<std::size_t>(c - pc);
        const Eigen::VectorXd g = tr.d_threshold.col(c - pc);
        Eigen::VectorXd a = Eigen::VectorXd::Zero(n);
        for (std::size_t l = 0; l <= o.n; ++l)
          a += p.theta(i, l) * detail::lagged(g, static_cast<Eigen::Index>(l));
        j.col(static_cast<Eigen::Index>(k)) = a * p.threshold[i];
      }
    }
    // The initial deflections delta_i(0) are estimated from the same record: nuisance columns,
    // so that the covariance of the parameters above is the marginal one (holding them at their
    // estimate made the thresholds' intervals too narrow, studies.md 1).
    std::vector<Eigen::VectorXd> nuisance;
    for (Eigen::Index i = 0; i < mi; ++i) {
      if (std::find(fit.never_saturating.begin(), fit.never_saturating.end(),
                    static_cast<std::size_t>(i)) != fit.never_saturating.end())
        continue;
      const Eigen::VectorXd g = tr.d_initial.col(i);
      Eigen::VectorXd a = Eigen::VectorXd::Zero(n);
      for (std::size_t l = 0; l <= o.n; ++l)
        a += p.theta(static_cast<std::size_t>(i), l) *
             detail::lagged(g, static_cast<Eigen::Index>(l));
      if (a.norm() > 0.0) nuisance.push_back(std::move(a));
    }
    const Eigen::Index pj = j.cols();
    Eigen::MatrixXd jn(n, pj + static_cast<Eigen::Index>(nuisance.size()));
    jn.leftCols(pj) = j;
    for (std::size_t k = 0; k < nuisance.size(); ++k)
      jn.col(pj + static_cast<Eigen::Index>(k)) = nuisance[k];
    Eigen::MatrixXd cov;
    const double dof = std::max(1.0, static_cast<double>(n) - static_cast<double>(jn.cols()));
    const double sigma2 = rep.estimation.rss / dof;
    const bool usable = detail::marginal_covariance(jn, pj, cov, 1e-10);
    if (usable) cov *= sigma2;
    // Filters are fitted linearly (symmetric intervals), thresholds through log Delta.
    std::vector<CovarianceParameter> cp;
    for (const ParameterEstimate& e : rep.parameters)
      cp.push_back({e.name, e.unit, e.value, Parametrisation::linear, 1.0, -1});
    for (std::size_t a = 0; a < cols.size(); ++a) {
      auto& q = cp[static_cast<std::size_t>(cols[a])];
      q.column = static_cast<std::ptrdiff_t>(a);
      if (cols[a] >= pc) q.fitted = Parametrisation::log;
    }
    CovarianceOptions co;
    co.zero_test = true;
    const CovarianceReport cr = covariance_report(usable ? &cov : nullptr, cp, co);
    cr.apply(rep.parameters);
    rep.correlation = cr.correlation;
    for (const IdentifiabilityWarning& w : cr.warnings) {
      const std::string& name = rep.parameters[w.parameter].name;
      if (w.issue == IdentifiabilityIssue::not_significant)
        rep.warnings.push_back(name + ": not significantly different from 0 (|value| < 1.96 se)");
      else if (w.issue == IdentifiabilityIssue::wide_interval)
        rep.warnings.push_back(name + ": 95 % interval spans more than an order of magnitude");
      else if (w.issue == IdentifiabilityIssue::covariance_unavailable)
        rep.warnings.push_back(
            "the parameter covariance is rank-deficient; standard errors are not available");
    }
  }
}

}  // namespace

DnlrxFreeRun free_run_dnlrx(const DnlrxParameters<double>& p, std::span<const double> time,
                            std::span<const double> x, std::span<const double> force) {
  FRICTION_CHECK(time.size() == x.size() && x.size() == force.size() && !x.empty(),
                 "free_run_dnlrx: time, displacement and force lengths differ");
  p.validate();
  const Eigen::Index n = static_cast<Eigen::Index>(x.size());
  Eigen::VectorXd target(n);
  for (Eigen::Index t = 0; t < n; ++t) {
    double in = 0;
    for (std::size_t j = 0; j < p.input_taps(); ++j) {
      const Eigen::Index s = t - static_cast<Eigen::Index>(j);
      if (s >= 1)
        in += p.input_filter[j] *
              (x[static_cast<std::size_t>(s)] - x[static_cast<std::size_t>(s - 1)]);
    }
    target(t) = force[static_cast<std::size_t>(t)] - in;
  }
  Eigen::MatrixXd theta(static_cast<Eigen::Index>(p.size()),
                        static_cast<Eigen::Index>(p.spring_taps()));
  for (std::size_t i = 0; i < p.size(); ++i)
    for (std::size_t j = 0; j < p.spring_taps(); ++j)
      theta(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = p.theta(i, j);
  DnlrxFreeRun run;
  run.initial_deflections = estimate_initial_deflections(
      x, std::span<const double>(target.data(), x.size()), p.threshold, theta);
  Dnlrx<double> model(p);
  model.reset(std::span<const double>(run.initial_deflections));
  run.simulated = simulate(model, time, x);
  run.errors = compute_errors(force, run.simulated);
  return run;
}

DnlrxResult identify_dnlrx(std::span<const double> time, std::span<const double> x,
                           std::span<const double> force, const DnlrxOptions& opt) {
  const detail::SubnormalsFlushed subnormals_flushed;  // subnormals.hpp
  const auto clock_start = std::chrono::steady_clock::now();
  FRICTION_CHECK(time.size() == x.size() && x.size() == force.size(),
                 "identify_dnlrx: time, displacement and force lengths differ");
  FRICTION_CHECK(opt.operators > 0 || opt.max_operators > 0,
                 "identify_dnlrx: max_operators must be >= 1");
  FRICTION_CHECK(opt.rank_tolerance > 0.0 && opt.rank_tolerance < 1.0,
                 "identify_dnlrx: rank_tolerance must be in (0, 1)");

  // Thresholds for every M from NLR (which also validates the record).
  NlrOptions nlr = opt.nlr;
  nlr.operators = opt.operators;
  nlr.max_operators = opt.operators > 0 ? opt.operators : opt.max_operators;
  nlr.covariance = false;
  // In the order selection NLR's thorough initial-state refinement of its own selected M is
  // wasted here (DNLRX selects its own M, and its passes below refine the initial state of the
  // model it returns); at a fixed M it gives the passes a better start.
  nlr.refine_initial_state = opt.operators > 0;
  const std::size_t m_lo = opt.operators > 0 ? opt.operators : 1;
  const std::size_t m_hi = opt.operators > 0 ? opt.operators : opt.max_operators;

  DnlrxResult result;
  IdentificationReport& rep = result.report;
  // NLR's starts, for the thresholds of every M: those of the given report's order selection
  // (NLR's run with these options would log exactly the starts of M = m_lo..m_hi that it logged,
  // one local search each), or of DNLRX's own NLR run.
  const IdentificationReport* nlr_rep = opt.nlr_report;
  std::vector<StartLog> nlr_starts;
  if (nlr_rep) {
    for (const StartLog& s : nlr_rep->starts)
      if (s.operators >= m_lo && s.operators <= m_hi &&
          (nlr.refine_initial_state || s.kind != "initial-state"))
        nlr_starts.push_back(s);
    for (std::size_t m = m_lo; m <= m_hi && nlr_rep; ++m)
      if (std::none_of(nlr_starts.begin(), nlr_starts.end(),
                       [m](const StartLog& s) { return s.operators == m; }))
        nlr_rep = nullptr;
  }
  std::optional<NlrResult> own;
  int nlr_searches = static_cast<int>(nlr_starts.size());
  if (!nlr_rep) {
    own = identify_maxwell_slip(time, x, force, nlr);
    nlr_rep = &own->report;
    nlr_starts = own->report.starts;
    nlr_searches = own->report.convergence.local_searches;
  }
  rep.starts = nlr_starts;
  rep.displacement_resolution = nlr_rep->displacement_resolution;
  rep.largest_travel = nlr_rep->largest_travel;
  rep.presliding_travel = nlr_rep->presliding_travel;
  rep.convergence.local_searches = nlr_searches;

  const Series r = make_series(x, force);
  const Eigen::Index n = r.y.size();
  const double sss = r.y.squaredNorm();

  // Rank tolerance from the data: a unit-norm column whose part outside the span of the others
  // (its pivot in the column-pivoted QR) is below eta / sqrt(N), eta = noise sigma / rms(F), could
  // not be estimated to better than 100 % even if it carried a coefficient as large as the whole
  // force, so it is dropped.
  const double eta = estimate_white_noise_sigma(force) / r.scale;
  const double tol = std::max(opt.rank_tolerance, eta / std::sqrt(static_cast<double>(n)));
  const detail::StickBreaking sb{rep.displacement_resolution, rep.largest_travel};

  const std::size_t n_lo = opt.spring_order >= 0 ? static_cast<std::size_t>(opt.spring_order) : 0;
  const std::size_t n_hi = opt.spring_order >= 0 ? n_lo : opt.max_spring_order;
  const std::size_t x_lo = opt.input_order >= 0 ? static_cast<std::size_t>(opt.input_order) : 0;
  const std::size_t x_hi = opt.input_order >= 0 ? x_lo : opt.max_input_order;

  struct Candidate {
    Orders o;
    std::vector<double> thr;
    LinearFit fit;
  };
  // The operator counts are independent given NLR's thresholds: each M's re-optimisation and its
  // rows run on their own thread (DnlrxOptions::threads), and are merged below in the order of M,
  // so the result does not depend on the thread count.
  struct OperatorCount {
    std::optional<StartLog> log;  // the re-optimisation's
    std::vector<SelectionRow> rows;
    std::vector<Candidate> fits;  // one per row
  };
  std::vector<OperatorCount> per_m(m_hi - m_lo + 1);
  const auto fit_operator_count = [&](std::size_t k) {
    const std::size_t m = m_lo + k;
    OperatorCount& out = per_m[k];
    // The best local minimum NLR met with m operators.
    const StartLog* src = nullptr;
    for (const auto& s : nlr_starts)
      if (s.operators == m && (!src || s.final_percent < src->final_percent)) src = &s;
    if (!src) return;
    std::vector<double> thr = src->final_thresholds;
    std::vector<double> init0 = first_initial_state(r, thr);
    if (opt.thresholds == DnlrxThresholds::ReoptimisePerOperatorCount) {
      // With the smallest filters of the grid: what NLR's thresholds had to absorb (a viscous
      // term, a lag) is given to the filters before the orders are compared.
      const Orders o0{m, n_lo, x_lo};
      const LinearFit f0 = fit_linear(r, thr, o0, init0, tol);
      const Reoptimised ro = reoptimise(r, o0, sb, thr, f0.init, tol, opt.nlr.max_iterations);
      const LinearFit f1 = fit_linear(r, ro.thr, o0, ro.init, tol);
      StartLog log;
      log.operators = m;
      log.kind = "dnlrx-thresholds";
      log.start_thresholds = thr;
      log.start_percent = 100.0 * f0.rss / sss;
      log.final_percent = 100.0 * f1.rss / sss;
      log.final_thresholds = ro.thr;
      out.log = std::move(log);
      if (f1.rss < f0.rss) thr = ro.thr, init0 = f1.init;
    }
    for (std::size_t nn = n_lo; nn <= n_hi; ++nn)
      for (std::size_t nx = x_lo; nx <= x_hi; ++nx) {
        const Orders o{m, nn, nx};
        LinearFit fit = fit_linear(r, thr, o, init0, tol);
        SelectionRow row;
        row.operators = m;
        row.spring_order = nn;
        row.input_order = nx;
        row.parameters = fit.kept + m;
        row.rss = fit.rss;
        row.rss_sss_percent = 100.0 * fit.rss / sss;
        row.criterion = bayesian_information_criterion(fit.rss, x.size(), row.parameters);
        out.rows.push_back(row);
        out.fits.push_back(Candidate{o, thr, std::move(fit)});
      }
  };
  detail::parallel_for(per_m.size(), opt.threads, fit_operator_count);

  Candidate best{{1, 0, 0}, {}, {}};
  double best_bic = std::numeric_limits<double>::infinity();
  std::size_t best_row = 0;
  for (OperatorCount& c : per_m) {
    if (c.log) {
      rep.starts.push_back(std::move(*c.log));
      ++rep.convergence.local_searches;
    }
    for (std::size_t j = 0; j < c.rows.size(); ++j) {
      if (c.rows[j].criterion < best_bic) {
        best_bic = c.rows[j].criterion;
        best_row = rep.selection.size();
        best = std::move(c.fits[j]);
      }
      rep.selection.push_back(c.rows[j]);
    }
  }
  FRICTION_CHECK_AS(NumericalError, !rep.selection.empty(),
                    "identify_dnlrx: no order could be fitted");
  rep.selection[best_row].selected = true;
  const Orders o = best.o;

  // Thresholds re-optimised with the filters (variable projection) for the selected orders.
  rep.convergence.initial_cost = 100.0 * best.fit.rss / sss;
  rep.convergence.final_cost = rep.convergence.initial_cost;
  rep.convergence.converged = true;
  rep.convergence.message = "thresholds from NLR";
  // Passes: Levenberg-Marquardt moves the initial deflections only along its local descent, and a
  // wrong initial state is compensated by biased thresholds (the NLR round trip showed it,
  // nlr.hpp); so each pass starts from the initial state that the global estimate
  // (initial_state.hpp, default options) finds for the current thresholds and filters, and passes
  // repeat while they improve.
  for (int pass = 0; pass < 3 && opt.thresholds != DnlrxThresholds::Nlr; ++pass) {
    const Eigen::VectorXd target = r.y - input_part(r, o, best.fit.c);
    const std::vector<double> init = estimate_initial_deflections(
        r.x, std::span<const double>(target.data(), static_cast<std::size_t>(target.size())),
        best.thr, spring_matrix(o, best.fit.c), best.fit.init);
    // After the first pass, a new pass runs only when that initial state alone lowers the RSS by
    // more than one unit of log-likelihood (2 sigma^2): less cannot move the thresholds by a
    // visible part of their standard errors, and a pass costs a local search.
    if (pass > 0 && !(best.fit.rss - fit_linear(r, best.thr, o, init, tol).rss >
                      2.0 * eta * eta * sss / static_cast<double>(n)))
      break;
    const Reoptimised ro = reoptimise(r, o, sb, best.thr, init, tol, opt.nlr.max_iterations);
    ++rep.convergence.local_searches;
    LinearFit fit = fit_linear(r, ro.thr, o, ro.init, tol);
    StartLog log;
    log.operators = o.m;
    log.kind = "dnlrx-thresholds-selected";
    log.start_thresholds = best.thr;
    log.start_percent = 100.0 * best.fit.rss / sss;
    log.final_percent = 100.0 * fit.rss / sss;
    log.final_thresholds = ro.thr;
    rep.starts.push_back(log);
    rep.convergence.converged = ro.summary.termination_type == ceres::CONVERGENCE;
    rep.convergence.iterations = static_cast<int>(ro.summary.iterations.size());
    rep.convergence.message = ro.summary.message;
    rep.convergence.final_cost = 100.0 * best.fit.rss / sss;
    if (!(fit.rss < best.fit.rss * (1.0 - 1e-6))) break;
    best.thr = ro.thr;
    best.fit = std::move(fit);
    rep.convergence.final_cost = 100.0 * best.fit.rss / sss;
  }

  finish(time, x, force, r, o, best.thr, best.fit, opt.covariance, result);
  if (o.m == m_hi && opt.operators == 0 && m_hi > 1)
    rep.warnings.push_back("the criterion chose the largest M tried (" + std::to_string(m_hi) +
                           ")");
  rep.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return result;
}

DnlrxResult fit_dnlrx_filters(std::span<const double> time, std::span<const double> x,
                              std::span<const double> force, std::span<const double> thresholds,
                              std::size_t spring_order, std::size_t input_order,
                              double rank_tolerance) {
  const auto clock_start = std::chrono::steady_clock::now();
  FRICTION_CHECK(time.size() == x.size() && x.size() == force.size() && x.size() >= 2,
                 "fit_dnlrx_filters: time, displacement and force lengths differ");
  FRICTION_CHECK(!thresholds.empty(), "fit_dnlrx_filters: no thresholds");
  for (double d : thresholds)
    FRICTION_CHECK(std::isfinite(d) && d > 0.0, "fit_dnlrx_filters: threshold ", d, " must be > 0");
  FRICTION_CHECK(rank_tolerance > 0.0 && rank_tolerance < 1.0,
                 "fit_dnlrx_filters: rank_tolerance must be in (0, 1)");
  const Series r = make_series(x, force);
  const Eigen::Index n = r.y.size();
  const double sss = r.y.squaredNorm();
  FRICTION_CHECK(sss > 0.0, "fit_dnlrx_filters: the force is identically zero");
  const double eta = estimate_white_noise_sigma(force) / r.scale;
  const double tol = std::max(rank_tolerance, eta / std::sqrt(static_cast<double>(n)));
  const std::vector<double> thr(thresholds.begin(), thresholds.end());
  const Orders o{thr.size(), spring_order, input_order};
  const LinearFit fit = fit_linear(r, thr, o, first_initial_state(r, thr), tol);
  DnlrxResult result;
  IdentificationReport& rep = result.report;
  rep.displacement_resolution = displacement_resolution(x);
  rep.largest_travel = largest_travel(x);
  SelectionRow row;
  row.operators = o.m;
  row.spring_order = o.n;
  row.input_order = o.nx;
  row.parameters = fit.kept;
  row.rss = fit.rss;
  row.rss_sss_percent = 100.0 * fit.rss / sss;
  row.criterion = bayesian_information_criterion(fit.rss, x.size(), row.parameters);
  row.selected = true;
  rep.selection.push_back(row);
  rep.convergence.converged = true;
  rep.convergence.message = "linear least squares for fixed thresholds";
  rep.convergence.initial_cost = rep.convergence.final_cost = row.rss_sss_percent;
  finish(time, x, force, r, o, thr, fit, true, result);
  rep.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return result;
}

}  // namespace friction
