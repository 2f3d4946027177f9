// NLR identification of the basic Maxwell Slip model (see include/friction/nlr.hpp).
#include "friction/nlr.hpp"

#include <ceres/ceres.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <limits>
#include <memory>
#include <sstream>

#include "bounded_levenberg_marquardt.hpp"
#include "bounded_solver.hpp"
#include "compressed_cost.hpp"
#include "friction/covariance_report.hpp"
#include "friction/initial_state.hpp"
#include "merged_column_gram.hpp"
#include "parallel_for.hpp"
#include "slip_regression.hpp"
#include "subnormals.hpp"

namespace friction {
namespace {

struct Data {
  std::span<const double> x;
  std::vector<double> turns;  // detail::turns_of(x), once: every evaluation steps through them
  std::span<const double> force;
  Eigen::VectorXd y;  // force / scale
  double scale = 1;   // rms of the force
  double sss = 0;     // sum of the squared force
  // RSS/SSS [%] below which a fit is at the noise floor: N sigma^2 plus three standard errors of
  // that chi-square (sqrt(2N) sigma^2), sigma from estimate_white_noise_sigma.  0: unknown.
  double floor_percent = 0;
  double sigma2 = 0;  // variance of that noise in units of the scaled force; 0: unknown
  detail::StickBreaking sb{1, 2};
  // The slip limits' factors per sample when the operators are fitted under a level (slip
  // regression.hpp, SlipLimits; identify_maxwell_slip_under_limits); null: the nominal box.
  const detail::SlipLimits* limits = nullptr;
  // The dictionary's operators (dictionary_operators): (threshold [m], stiffness [scaled]) of the
  // NNLS fit over a dense grid of thresholds, in increasing threshold; empty: not computed.
  std::vector<std::pair<double, double>> dictionary;
  double dictionary_ratio = 1;  // of neighbouring grid thresholds
};

// A fit's data: the motion and its turns, the force, its sum of squares and the force scaled by
// its rms (y left empty when the force is identically zero: the callers say what that means).
Data fit_data(std::span<const double> x, std::span<const double> force,
              const detail::SlipLimits* limits) {
  Data d;
  d.x = x;
  d.turns = detail::turns_of(x);
  d.force = force;
  d.limits = limits;
  const Eigen::Map<const Eigen::VectorXd> f(force.data(), static_cast<Eigen::Index>(force.size()));
  d.sss = f.squaredNorm();
  d.scale = std::sqrt(d.sss / static_cast<double>(force.size()));
  if (d.sss > 0.0) d.y = f / d.scale;
  return d;
}

struct VpValue {
  Eigen::VectorXd r;
  Eigen::VectorXd k;
  std::vector<int> at_bound;
};

// Storage reused from one evaluation to the next: an identification evaluates the same sizes
// hundreds of times, and fresh N x M matrices every time cost more in page faults than the
// arithmetic.
struct Workspace {
  detail::OperatorTrajectories traj;
  detail::Projector proj;
  detail::BoxLeastSquaresStorage nnls;
  Eigen::MatrixXd phi, a, w, dr, jd, jr, jac;
  VpValue v;
  // The point (s, rho) the contents belong to.  Ceres evaluates the cost at a trial point (in its
  // projected line search, then again as the candidate) and, when it accepts the step, the
  // Jacobian at that same point: with the trajectories' sensitivities computed eagerly (they cost
  // little more than the trajectories) the later requests only assemble what is missing.
  std::vector<double> point;
  bool has_sensitivities = false, has_jacobian = false, has_factor = false;
  bool eager = false;
  // The compressed Jacobian (compressed_jacobian): its factor and the small matrices and row blocks
  // it is built from; the sensitivities, decoded a block of rows at a time (block_dt, block_di) or,
  // for full_jacobian, whole (dt, di).
  Eigen::MatrixXd factor, gram_aug, gram_phi, cross_t, cross_i, coupling, block_in, block_j;
  Eigen::MatrixXd block_dt, block_di, dt, di;
};

enum class Jacobian { none, full, compressed };

// The Golub-Pereyra Jacobian of the projected residual w.r.t. (s, rho), N x 2M, into ws.jac.
void full_jacobian(const Data& d, std::span<const double> s, std::span<const double> rho,
                   const std::vector<double>& thr, Workspace& ws) {
  const auto& traj = ws.traj;
  const VpValue& v = ws.v;
  const Eigen::Index n = traj.delta.rows(), mi = traj.delta.cols();
  ws.dt.resize(n, mi);
  ws.di.resize(n, mi);
  traj.sensitivity_rows(0, n, ws.dt, ws.di);
  ws.jd.setZero(n, mi);
  ws.jr.setZero(n, mi);
  std::vector<Eigen::Index> free;
  for (Eigen::Index i = 0; i < mi; ++i)
    if (!v.at_bound[static_cast<std::size_t>(i)]) free.push_back(i);
  if (!free.empty()) {
    const Eigen::Index nf = static_cast<Eigen::Index>(free.size());
    if (nf == mi) {
      ws.proj.compute(traj.delta);
    } else {
      ws.phi.resize(n, nf);
      for (Eigen::Index f = 0; f < nf; ++f)
        ws.phi.col(f) = traj.delta.col(free[static_cast<std::size_t>(f)]);
      ws.proj.compute(ws.phi);
    }
    // Columns: d/dDelta_i then d/drho_i for every free operator, all projected at once.
    ws.a.resize(n, 2 * nf);
    ws.w.setZero(nf, 2 * nf);
    for (Eigen::Index f = 0; f < nf; ++f) {
      const Eigen::Index i = free[static_cast<std::size_t>(f)];
      const double ki = v.k(i), ri = rho[static_cast<std::size_t>(i)],
                   di = thr[static_cast<std::size_t>(i)];
      ws.a.col(f) = ws.dt.col(i) + ri * ws.di.col(i);
      ws.a.col(nf + f) = di * ws.di.col(i);
      ws.w(f, f) = ws.a.col(f).dot(v.r);
      ws.w(f, nf + f) = ws.a.col(nf + f).dot(v.r);
      ws.a.col(f) *= ki;
      ws.a.col(nf + f) *= ki;
    }
    ws.proj.derivatives_into(ws.a, ws.w, ws.dr);
    for (Eigen::Index f = 0; f < nf; ++f) {
      const Eigen::Index i = free[static_cast<std::size_t>(f)];
      ws.jd.col(i) = ws.dr.col(f);
      ws.jr.col(i) = ws.dr.col(nf + f);
    }
  }
  ws.jac.resize(n, 2 * mi);
  ws.jac.leftCols(mi).noalias() = ws.jd * d.sb.jacobian(s);
  ws.jac.rightCols(mi) = ws.jr;
  ws.dt.resize(0, 0);
  ws.di.resize(0, 0);
}

// The compressed Jacobian: F ((2M+1) x (2M+1)) with F^T F = [J r]^T [J r], J the Jacobian of
// full_jacobian, which stands for J and r in the solver's problem (VpProblem; compressed_cost.hpp
// says why Levenberg-Marquardt takes the same steps on it).
//
// J is built in row blocks and never stored whole.  With Phi_f the trajectories of the free
// operators (stiffness not at its bound 0), A the derivatives of Phi_f k along each parameter and
// W their products with r before the stiffness factor (the second Golub-Pereyra term), the
// projected derivative is
//     dr = Phi_f C - A,   C = (Phi_f^T Phi_f)^-1 (Phi_f^T A - W),
// and C needs only M x M products over the record.  A block of rows of J = dr T (T: the
// stick-breaking chain rule, and the free operators' columns put in place) is then the same rows
// of Phi times C T (M x 2M) less those of A through T; every entry carries the rounding of the
// difference Phi_f C - A, as the full Jacobian's do, and only the Gram matrix of [J r] is
// accumulated.
// When Phi_f^T Phi_f is ill-conditioned (the Projector's rule: reciprocal condition of its
// unit-diagonal scaling at most 1e-10) the full Jacobian, through the rank-revealing QR, is
// formed instead and compressed the same way.
void compressed_jacobian(const Data& d, std::span<const double> s, std::span<const double> rho,
                         const std::vector<double>& thr, Workspace& ws) {
  const auto& traj = ws.traj;
  const VpValue& v = ws.v;
  const Eigen::Index n = traj.delta.rows(), mi = traj.delta.cols(), p = 2 * mi;
  ws.gram_aug.setZero(p + 1, p + 1);
  std::vector<Eigen::Index> free;
  for (Eigen::Index i = 0; i < mi; ++i)
    if (!v.at_bound[static_cast<std::size_t>(i)]) free.push_back(i);
  const Eigen::Index nf = static_cast<Eigen::Index>(free.size());
  bool blocked = nf == 0;
  if (nf == 0) ws.gram_aug(p, p) = v.r.squaredNorm();
  if (nf > 0) {
    ws.gram_phi.setZero(mi, mi);
    ws.gram_phi.selfadjointView<Eigen::Lower>().rankUpdate(traj.delta.transpose());
    Eigen::MatrixXd g(nf, nf), unused_r;
    for (Eigen::Index a = 0; a < nf; ++a)
      for (Eigen::Index b = 0; b <= a; ++b)
        g(a, b) = ws.gram_phi(free[static_cast<std::size_t>(a)], free[static_cast<std::size_t>(b)]);
    // The unit-diagonal scaling and its Cholesky factor, trusted by the rule the bounded least
    // squares and the Projector use (compress_by_gram).
    Eigen::VectorXd sc, unused_b;
    Eigen::LLT<Eigen::MatrixXd> llt;
    blocked = detail::compress_by_gram(g, Eigen::VectorXd::Zero(nf), llt, sc, unused_r, unused_b);
    constexpr Eigen::Index kRows = 256;  // a block of A and of [J r] stays in cache
    ws.block_dt.resize(kRows, mi);
    ws.block_di.resize(kRows, mi);
    if (blocked) {
      // The sensitivities' products with the trajectories and the residual, a block of rows at a
      // time (the workspace keeps them compact: OperatorTrajectories::codes).
      ws.cross_t.setZero(mi, mi);
      ws.cross_i.setZero(mi, mi);
      // With the residual: the second Golub-Pereyra term's W before the stiffness factor.
      Eigen::VectorXd w_threshold = Eigen::VectorXd::Zero(mi);
      Eigen::VectorXd w_initial = Eigen::VectorXd::Zero(mi);
      for (Eigen::Index t0 = 0; t0 < n; t0 += kRows) {
        const Eigen::Index rows = std::min(kRows, n - t0);
        traj.sensitivity_rows(t0, rows, ws.block_dt, ws.block_di);
        const auto phi = traj.delta.middleRows(t0, rows);
        const auto bt = ws.block_dt.topRows(rows), bi = ws.block_di.topRows(rows);
        ws.cross_t.noalias() += phi.transpose() * bt;
        ws.cross_i.noalias() += phi.transpose() * bi;
        w_threshold.noalias() += bt.transpose() * v.r.segment(t0, rows);
        w_initial.noalias() += bi.transpose() * v.r.segment(t0, rows);
      }
      Eigen::MatrixXd c(nf, 2 * nf);  // Phi_f^T A - W, then C
      for (Eigen::Index f = 0; f < nf; ++f) {
        const Eigen::Index i = free[static_cast<std::size_t>(f)];
        const double ki = v.k(i), ri = rho[static_cast<std::size_t>(i)],
                     di = thr[static_cast<std::size_t>(i)];
        for (Eigen::Index h = 0; h < nf; ++h) {
          const Eigen::Index l = free[static_cast<std::size_t>(h)];
          c(h, f) = ki * (ws.cross_t(l, i) + ri * ws.cross_i(l, i));
          c(h, nf + f) = ki * di * ws.cross_i(l, i);
        }
        const double wi = w_initial(i);
        c(f, f) -= w_threshold(i) + ri * wi;
        c(f, nf + f) -= di * wi;
      }
      c = sc.cwiseInverse().asDiagonal() * c;
      llt.solveInPlace(c);
      c = sc.cwiseInverse().asDiagonal() * c;
      // J = Phi * coupling - [A_threshold * SBJ, A_initial]: the coupling C T (M x 2M) acts on
      // every operator's trajectory (rows of operators at their bound are 0), the stick-breaking
      // chain rule on the threshold derivatives.
      const Eigen::MatrixXd sbj = d.sb.jacobian(s);
      ws.coupling.setZero(mi, p);
      for (Eigen::Index f = 0; f < nf; ++f) {
        const Eigen::Index i = free[static_cast<std::size_t>(f)];
        for (Eigen::Index h = 0; h < nf; ++h) {
          const Eigen::Index l = free[static_cast<std::size_t>(h)];
          ws.coupling.row(l).head(mi) += c(h, f) * sbj.row(i);
          ws.coupling(l, mi + i) += c(h, nf + f);
        }
      }
      ws.block_in.resize(kRows, 2 * mi);
      ws.block_j.resize(kRows, p + 1);
      for (Eigen::Index t0 = 0; t0 < n; t0 += kRows) {
        const Eigen::Index rows = std::min(kRows, n - t0);
        auto in = ws.block_in.topRows(rows);
        traj.sensitivity_rows(t0, rows, ws.block_dt, ws.block_di);
        for (Eigen::Index i = 0; i < mi; ++i) {
          const double ki = v.k(i), ri = rho[static_cast<std::size_t>(i)],
                       di = thr[static_cast<std::size_t>(i)];
          in.col(i) = ki * (ws.block_dt.col(i).head(rows) + ri * ws.block_di.col(i).head(rows));
          in.col(mi + i) = (ki * di) * ws.block_di.col(i).head(rows);
        }
        auto jb = ws.block_j.topRows(rows);
        jb.leftCols(p).noalias() = traj.delta.middleRows(t0, rows) * ws.coupling;
        jb.leftCols(mi).noalias() -= in.leftCols(mi) * sbj.triangularView<Eigen::Lower>();
        jb.middleCols(mi, mi) -= in.rightCols(mi);
        jb.col(p) = v.r.segment(t0, rows);
        ws.gram_aug.selfadjointView<Eigen::Lower>().rankUpdate(jb.transpose());
      }
    }
  }
  if (!blocked) {
    full_jacobian(d, s, rho, thr, ws);
    ws.gram_aug.topLeftCorner(p, p).selfadjointView<Eigen::Lower>().rankUpdate(ws.jac.transpose());
    ws.gram_aug.row(p).head(p).noalias() = (ws.jac.transpose() * v.r).transpose();
    ws.gram_aug(p, p) = v.r.squaredNorm();
  }
  detail::normal_factor(ws.gram_aug, ws.factor);
}

// Projected residual and, on request, its exact Jacobian w.r.t. (s, rho): whole (ws.jac) or
// compressed (ws.factor).
const VpValue& vp_evaluate(const Data& d, std::span<const double> s, std::span<const double> rho,
                           Jacobian form, Workspace& ws) {
  const std::size_t m = s.size();
  const Eigen::Index mi = static_cast<Eigen::Index>(m);
  const std::vector<double> thr = d.sb.thresholds(s);
  auto& traj = ws.traj;
  VpValue& v = ws.v;
  const bool with_jacobian = form != Jacobian::none;
  const bool same_point =
      ws.point.size() == 2 * m && std::equal(s.begin(), s.end(), ws.point.begin()) &&
      std::equal(rho.begin(), rho.end(), ws.point.begin() + static_cast<std::ptrdiff_t>(m));
  if (!same_point || (with_jacobian && !ws.has_sensitivities)) {
    std::vector<double> init(m);
    for (std::size_t i = 0; i < m; ++i) init[i] = rho[i] * thr[i];
    const bool sensitivities = with_jacobian || ws.eager;
    if (sensitivities && !d.limits)
      detail::operator_trajectories_compact(thr, init, d.x, traj, d.turns);
    else
      detail::operator_trajectories(thr, init, d.x, sensitivities, traj, d.limits, d.turns);
    const Eigen::VectorXd lo = Eigen::VectorXd::Zero(mi);
    const Eigen::VectorXd hi =
        Eigen::VectorXd::Constant(mi, std::numeric_limits<double>::infinity());
    v.k = detail::box_least_squares(traj.delta, d.y, lo, hi, &v.at_bound, &ws.nnls);
    v.r = d.y;
    v.r.noalias() -= traj.delta * v.k;
    ws.point.assign(s.begin(), s.end());
    ws.point.insert(ws.point.end(), rho.begin(), rho.end());
    ws.has_sensitivities = sensitivities;
    ws.has_jacobian = ws.has_factor = false;
  }
  if (form == Jacobian::full && !ws.has_jacobian) {
    full_jacobian(d, s, rho, thr, ws);
    ws.has_jacobian = true;
  }
  if (form == Jacobian::compressed && !ws.has_factor) {
    compressed_jacobian(d, s, rho, thr, ws);
    ws.has_factor = true;
  }
  return v;
}

double percent_of(const Eigen::VectorXd& r) {
  return 100.0 * r.squaredNorm() / static_cast<double>(r.size());
}

// The variable-projection problem as bounded_levenberg_marquardt sees it: x = (s, rho), 2M + 1
// rows, the compressed Jacobian of compressed_jacobian (the same Levenberg-Marquardt steps as on
// the N projected residuals).  Its trial points cost one evaluation each, with the trajectories'
// sensitivities computed eagerly: most trials are accepted, and the Jacobian there then only
// assembles what is missing.
class VpProblem {
 public:
  VpProblem(const Data& d, std::size_t m) : d_(d), m_(m) { ws_.eager = true; }
  bool cost(std::span<const double> x, double& c) {
    const auto& v = vp_evaluate(d_, x.first(m_), x.subspan(m_, m_), Jacobian::none, ws_);
    c = 0.5 * v.r.squaredNorm();
    return std::isfinite(c);
  }
  bool linearise(std::span<const double> x, Eigen::MatrixXd& rows, Eigen::VectorXd& e) {
    vp_evaluate(d_, x.first(m_), x.subspan(m_, m_), Jacobian::compressed, ws_);
    const Eigen::Index p = static_cast<Eigen::Index>(2 * m_);
    rows = ws_.factor.leftCols(p);
    e = ws_.factor.col(p);
    return rows.allFinite() && e.allFinite();
  }

 private:
  const Data& d_;
  std::size_t m_;
  Workspace ws_;
};

class JointCost final : public ceres::CostFunction {
 public:
  enum Mode { StickBreaking, LogThreshold };
  JointCost(const Data& d, int m, Mode mode, std::vector<double> rho = {})
      : d_(d), m_(m), mode_(mode), rho_(std::move(rho)) {
    set_num_residuals(static_cast<int>(d.y.size()));
    mutable_parameter_block_sizes()->push_back(m);
    mutable_parameter_block_sizes()->push_back(m);
    if (mode == StickBreaking) mutable_parameter_block_sizes()->push_back(m);
  }
  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    const std::size_t m = static_cast<std::size_t>(m_);
    std::vector<double> thr(m), rho(m);
    if (mode_ == StickBreaking) {
      thr = d_.sb.thresholds({p[1], m});
      rho.assign(p[2], p[2] + m);
    } else {
      for (std::size_t i = 0; i < m; ++i) thr[i] = std::exp(p[1][i]);
      rho = rho_;
    }
    std::vector<double> init(m);
    for (std::size_t i = 0; i < m; ++i) init[i] = rho[i] * thr[i];
    detail::OperatorTrajectories traj;
    detail::operator_trajectories(thr, init, d_.x, jacobians != nullptr, traj, d_.limits,
                                  d_.turns);
    Eigen::VectorXd k(m_);
    for (int i = 0; i < m_; ++i) k(i) = std::exp(p[0][i]);
    const Eigen::Index n = traj.delta.rows();
    Eigen::Map<Eigen::VectorXd> res(residuals, n);
    res = d_.y - traj.delta * k;
    if (!res.allFinite()) return false;  // a trial step too far: Ceres shrinks the region
    if (!jacobians) return true;
    using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    Eigen::MatrixXd jk(n, m_), jd(n, m_), jr(n, m_);
    for (int i = 0; i < m_; ++i) {
      const auto ii = static_cast<std::size_t>(i);
      jk.col(i) = -k(i) * traj.delta.col(i);
      jd.col(i) = -k(i) * (traj.d_threshold.col(i) + rho[ii] * traj.d_initial.col(i));
      jr.col(i) = -k(i) * thr[ii] * traj.d_initial.col(i);
    }
    if (jacobians[0]) Eigen::Map<RowMajor>(jacobians[0], n, m_) = jk;
    if (mode_ == StickBreaking) {
      if (jacobians[1]) Eigen::Map<RowMajor>(jacobians[1], n, m_) = jd * d_.sb.jacobian({p[1], m});
      if (jacobians[2]) Eigen::Map<RowMajor>(jacobians[2], n, m_) = jr;
    } else if (jacobians[1]) {
      for (int i = 0; i < m_; ++i) jd.col(i) *= thr[static_cast<std::size_t>(i)];
      Eigen::Map<RowMajor>(jacobians[1], n, m_) = jd;
    }
    return true;
  }

 private:
  const Data& d_;
  int m_;
  Mode mode_;
  std::vector<double> rho_;
};

struct Fit {
  std::vector<double> s, rho;
  Eigen::VectorXd k;
  double percent = std::numeric_limits<double>::infinity();
  double start_percent = 0;
  bool converged = false;
  int iterations = 0;
  double seconds = 0;
  std::string message;
};

// Ceres' options for the joint solver (NlrSolver::Joint); the variable-projection search
// (bounded_levenberg_marquardt) takes its iteration budget and tolerances from them.
ceres::Solver::Options solver_options(const NlrOptions& o, std::size_t samples) {
  ceres::Solver::Options so;
  // QR, robust to the zero columns of inactive operators.  DENSE_NORMAL_CHOLESKY was 20-35 %
  // faster per iteration at N = 10^4, but inside diagnose its factorisation failed often enough
  // (148 times on data/) that Ceres' warnings filled the user's terminal.
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = o.max_iterations;
  // By default within about a tenth of a standard error of the minimum (bounded_solver.hpp; the
  // NLR round-trip study's fits 12 % faster than with 1e-8).
  so.function_tolerance = o.function_tolerance > 0.0 ? o.function_tolerance
                                                     : detail::resolved_function_tolerance(samples);
  so.gradient_tolerance = 1e-12;
  so.parameter_tolerance = 1e-10;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  detail::use_value_only_line_search(so);
  // Non-monotonic steps let LM cross the small ridges of this piecewise-smooth cost: on the
  // ten-operator benchmark record they halved the iterations and reached a lower minimum.
  so.use_nonmonotonic_steps = true;
  return so;
}

// Initial rho for thresholds: stiffnesses by NNLS from the virgin state, then the initial-state
// estimate for those parameters.
std::vector<double> start_rho(const Data& d, const std::vector<double>& thr) {
  const std::size_t m = thr.size();
  const Eigen::Index mi = static_cast<Eigen::Index>(m);
  // The trajectories (N x M) are freed before the initial-state estimate, which keeps its own.
  const Eigen::VectorXd k = [&] {
    detail::OperatorTrajectories traj;
    detail::operator_trajectories(thr, std::vector<double>(m, 0.0), d.x, false, traj, d.limits,
                                  d.turns);
    return detail::box_least_squares(
        traj.delta, d.y, Eigen::VectorXd::Zero(mi),
        Eigen::VectorXd::Constant(mi, std::numeric_limits<double>::infinity()));
  }();
  Eigen::MatrixXd filter = k;
  if (filter.norm() == 0.0) return std::vector<double>(m, 0.0);
  const auto init = estimate_initial_deflections(
      d.x, std::span<const double>(d.y.data(), static_cast<std::size_t>(d.y.size())), thr, filter,
      {}, InitialStateOptions::quick());
  std::vector<double> rho(m);
  for (std::size_t i = 0; i < m; ++i) rho[i] = std::clamp(init[i] / thr[i], -1.0, 1.0);
  return rho;
}

// `target` [RSS/SSS %]: the lowest cost already known to be reachable (detail::HopelessSearch,
// bounded_solver.hpp); infinity disables the stop.
Fit local_search(const Data& d, std::vector<double> s, std::vector<double> rho, const NlrOptions& o,
                 double target = std::numeric_limits<double>::infinity()) {
  const int m = static_cast<int>(s.size());
  for (double& v : s) v = std::clamp(v, 0.0, 1.0);
  Fit fit;
  const double n = static_cast<double>(d.y.size());
  detail::HopelessSearch hopeless(target * (1.0 + o.stall_tolerance) * n / 200.0,
                                  0.5 * d.sigma2, o.max_iterations);
  ceres::Solver::Options so = solver_options(o, d.x.size());
  std::vector<double> logk;
  ceres::Solver::Summary summary;
  if (o.solver == NlrSolver::VariableProjection) {
    const auto started = std::chrono::steady_clock::now();
    const std::size_t mm = static_cast<std::size_t>(m);
    std::vector<double> x(s), lower(2 * mm, 0.0), upper(2 * mm, 1.0);
    x.insert(x.end(), rho.begin(), rho.end());
    std::fill(lower.begin() + m, lower.end(), -1.0);
    detail::BoundedLmOptions lm;
    lm.max_iterations = o.max_iterations;
    lm.function_tolerance = so.function_tolerance;
    lm.gradient_tolerance = so.gradient_tolerance;
    lm.parameter_tolerance = so.parameter_tolerance;
    detail::BoundedLmSummary result;
    {
      // Scoped so that its workspace (the trajectories with their sensitivities) is freed before
      // the final evaluation: at N = 10^6 that is 24 M bytes per operator.
      VpProblem problem(d, mm);
      result = detail::bounded_levenberg_marquardt(
          problem, std::span<double>(x), lower, upper, lm,
          [&hopeless](int, double cost) { return hopeless.keep_going(cost); });
    }
    fit.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    fit.start_percent = 100.0 * 2.0 * result.initial_cost / n;
    fit.converged = result.termination == detail::BoundedLmTermination::converged;
    // The start and every trial step (Ceres' count left out a last trial that ended the search
    // on a tolerance).
    fit.iterations = result.iterations + 1;
    fit.message = result.message;
    s.assign(x.begin(), x.begin() + m);
    rho.assign(x.begin() + m, x.end());
  } else {
    // Owned here so that its cost's workspace is freed before the final evaluation.
    auto problem = std::make_unique<ceres::Problem>();
    {
      Workspace ws;
      const auto& v = vp_evaluate(d, s, rho, Jacobian::none, ws);
      const double kmax = std::max(v.k.maxCoeff(), 1e-300);
      for (int i = 0; i < m; ++i) logk.push_back(std::log(std::max(v.k(i), 1e-6 * kmax)));
    }
    problem->AddResidualBlock(new JointCost(d, m, JointCost::StickBreaking), nullptr, logk.data(),
                              s.data(), rho.data());
    for (int i = 0; i < m; ++i) {
      problem->SetParameterLowerBound(s.data(), i, 0.0);
      problem->SetParameterUpperBound(s.data(), i, 1.0);
      problem->SetParameterLowerBound(rho.data(), i, -1.0);
      problem->SetParameterUpperBound(rho.data(), i, 1.0);
    }
    so.callbacks.push_back(&hopeless);
    ceres::Solve(so, problem.get(), &summary);
    problem.reset();
    fit.seconds = summary.total_time_in_seconds;
    fit.start_percent = 100.0 * 2.0 * summary.initial_cost / n;
    fit.converged = summary.termination_type == ceres::CONVERGENCE;
    fit.iterations = static_cast<int>(summary.iterations.size());
    fit.message = summary.message;
  }
  if (hopeless.converged()) {
    fit.converged = true;
    fit.message =
        "converged: at its pace its remaining iterations would lower the RSS by less "
        "than the noise variance";
  }
  if (hopeless.stopped())
    fit.message = target <= d.floor_percent
                      ? "stopped: at its pace it could not reach the noise floor (the global "
                        "stage takes over)"
                      : "stopped: at its pace it could not reach the best minimum already found";
  fit.s = s;
  fit.rho = rho;
  // Report the concentrated cost (for the joint solver too, stiffnesses re-solved by NNLS: the
  // same number the selection compares).
  Workspace ws;
  const auto& v = vp_evaluate(d, s, rho, Jacobian::none, ws);
  fit.k = v.k;
  fit.percent = percent_of(v.r);
  if (o.solver == NlrSolver::Joint) {
    const double joint = 100.0 * 2.0 * summary.final_cost / n;
    if (joint < fit.percent) {  // keep the joint stiffnesses when they are better
      fit.percent = joint;
      fit.k.resize(m);
      for (int i = 0; i < m; ++i) fit.k(i) = std::exp(logk[static_cast<std::size_t>(i)]);
    }
  }
  return fit;
}

// The log entry of one local search from thresholds `start` (distinct left false).
StartLog start_log(const Data& d, std::string kind, std::vector<double> start, const Fit& f) {
  StartLog log;
  log.operators = f.s.size();
  log.kind = std::move(kind);
  log.start_thresholds = std::move(start);
  log.start_percent = f.start_percent;
  log.final_percent = f.percent;
  log.final_thresholds = d.sb.thresholds(f.s);
  log.iterations = f.iterations;
  log.seconds = f.seconds;
  return log;
}

// Levenberg-Marquardt moves rho only along its local descent, and a wrong initial state is then
// compensated by biased thresholds: on the round-trip study (studies.md 1) the best fit's
// concentrated cost was often 2-15 % above what the same thresholds gave with the initial state
// that estimate_initial_deflections (initial_state.hpp, the routine validation uses; `thorough`
// searches the initial state globally for fixed parameters) found for them, and those seeds
// carried the intervals' misses (NLR coverage 31-36 of 40 per parameter before, 36-40 after).  So
// the fit is re-polished from that initial state while it improves: quickly after every stage at a
// fixed M, and thoroughly once for the M that is returned (during the order selection only that
// one: the quick passes at every M made DNLRX's selection about 0.5 s slower on its benchmark
// record, where it selected the same model with them and without them).
//
// `at_best` (may be null) receives the last estimate [m] when it belongs to the fit returned in
// `best` (the usual end: the estimate at the polished fit's parameters no longer pays for another
// polish), and is cleared otherwise; the report's free run then takes it instead of repeating the
// same global search (on the multisine bench record a third of NLR's initial-state time).
void refine_initial_state(const Data& d, Fit& best, const NlrOptions& o, bool thorough,
                          IdentificationReport& rep, std::vector<double>* at_best = nullptr) {
  const std::size_t m = best.s.size();
  if (at_best) at_best->clear();
  for (int pass = 0; pass < 3; ++pass) {
    const std::vector<double> thr = d.sb.thresholds(best.s);
    if (best.k.size() != static_cast<Eigen::Index>(m) || best.k.norm() == 0.0) return;
    std::vector<double> guess(m);
    for (std::size_t i = 0; i < m; ++i) guess[i] = best.rho[i] * thr[i];
    const Eigen::MatrixXd filter = best.k;
    const auto init = estimate_initial_deflections(
        d.x, std::span<const double>(d.y.data(), static_cast<std::size_t>(d.y.size())), thr, filter,
        guess, thorough ? InitialStateOptions{} : InitialStateOptions::quick());
    if (at_best) *at_best = init;
    std::vector<double> rho(m);
    for (std::size_t i = 0; i < m; ++i) rho[i] = std::clamp(init[i] / thr[i], -1.0, 1.0);
    if (rho == best.rho) return;
    // Polish only from an initial state that is already better at the current thresholds by
    // more than one unit of log-likelihood (2 sigma^2 of RSS; d.floor_percent / N is about one
    // sigma^2 in these units): a smaller gain cannot move the parameters by a visible part of
    // their standard errors, and the polish costs a local search.
    // Its own workspace, freed before the local search allocates one (N x M trajectories: at 1M
    // samples and M = 4 the two together were identify's peak).
    const double gain = [&] {
      Workspace ws;
      return best.percent - percent_of(vp_evaluate(d, best.s, rho, Jacobian::none, ws).r);
    }();
    if (!(gain > 2.0 * d.floor_percent / static_cast<double>(d.y.size()))) return;
    const Fit f = local_search(d, best.s, rho, o, best.percent);
    rep.starts.push_back(start_log(d, thorough ? "initial-state" : "initial-state-quick", thr, f));
    ++rep.convergence.local_searches;
    if (!(f.percent < best.percent * (1.0 - 1e-6))) return;
    best = f;
    if (at_best) at_best->clear();
  }
}

std::vector<double> clamp_sorted(std::vector<double> t, double lo, double hi) {
  for (double& v : t) v = std::clamp(v, lo, hi);
  std::sort(t.begin(), t.end());
  return t;
}

// Sorted thresholds `t` with one more at the geometric middle of their largest log-gap, the range
// extended to a quarter of the smallest and four times the largest (within [lo, hi]).
std::vector<double> with_one_in_largest_gap(std::vector<double> t, double lo, double hi) {
  std::vector<double> ext;
  ext.push_back(std::max(lo, t.front() / 4.0));
  ext.insert(ext.end(), t.begin(), t.end());
  ext.push_back(std::min(hi, t.back() * 4.0));
  std::size_t gap = 0;
  double widest = 0;
  for (std::size_t i = 0; i + 1 < ext.size(); ++i)
    if (ext[i + 1] / ext[i] > widest) widest = ext[i + 1] / ext[i], gap = i;
  t.push_back(std::sqrt(ext[gap] * ext[gap + 1]));
  return clamp_sorted(std::move(t), lo, hi);
}

struct Scales {
  double q, travel, presliding;
};

// The global stage: moves of one threshold at a time.  The concentrated cost is piecewise smooth
// in the thresholds, with kinks where a threshold crosses one the data hold, and the local searches
// stop at them in two ways: (a) with an operator spent twice on one true threshold, or parked at
// the resolution, while another true threshold has none (a bench record: 10 operators where 8
// suffice, 5x the cost of the minimum); (b) with every threshold within a few % of the truth and
// the initial states wrong, the thresholds biased to compensate (the NLR round-trip study: 2-3x
// the noise floor).  Both are escaped by changing one threshold with the others held: (a) needs a
// jump across the range, (b) a small step that crosses a kink.  So every operator's threshold is
// profiled over a log grid of [q, L] (8 points per decade, from the virgin state: a true threshold
// lies within 15 % of a grid point, inside the basin a local search descends from) and over
// +-20 % of its own value in steps of 1 % (with its own initial state); the stiffnesses are
// re-solved at every point, so no start is needed.  The best move of all is polished jointly, and
// sweeps repeat while they improve.  Deterministic, and cheap (below): the random search over all
// M coordinates at once that it replaced (NLopt CRS2, 500 M evaluations per round) found these
// moves only by chance, at 3-5x the cost.
// The 0.999 quantile of a chi-square of 2 degrees of freedom: -2 ln(1e-3).
constexpr double kMoveSignificance = 13.815510557964274;

bool threshold_moves(
    const Data& d, Fit& best, const NlrOptions& o,
    const std::function<void(const std::string&, const std::vector<double>&, const Fit&)>& record) {
  const std::size_t m = best.s.size();
  const double decades = std::log10(d.sb.hi / d.sb.lo);
  const std::size_t g =
      std::max<std::size_t>(8, static_cast<std::size_t>(std::ceil(8.0 * decades)));
  // Candidates: (operator, threshold, initial deflection / threshold).  A sweep needs only Gram
  // matrices: with Phi the current trajectories (N x M) and C a block of candidate trajectories,
  // moving operator i to candidate j replaces row and column i of Phi^T Phi by Phi^T c_j and
  // c_j^T c_j.  One product Phi^T C per block, then an M x M problem per move.
  struct Candidate {
    std::size_t op;  // m: every operator
    double threshold, rho;
  };
  const Eigen::Index mi = static_cast<Eigen::Index>(m);
  const double yy = d.y.squaredNorm(), n = static_cast<double>(d.y.size());
  const Eigen::VectorXd lo = Eigen::VectorXd::Zero(mi);
  const Eigen::VectorXd hi = Eigen::VectorXd::Constant(mi, std::numeric_limits<double>::infinity());
  constexpr std::size_t kBlock = 4;  // candidates per block: N x 4 doubles of storage
  Workspace ws;
  detail::OperatorTrajectories cand;
  Eigen::MatrixXd gram(mi, mi), moved(mi, mi), cross;
  Eigen::VectorXd phi_y(mi), rhs(mi), z;
  bool improved = false;
  for (std::size_t sweep = 0; sweep < 4 * m + 4; ++sweep) {
    if (best.percent <= d.floor_percent) return improved;
    const std::vector<double> thr = d.sb.thresholds(best.s);
    std::vector<Candidate> cands;
    for (std::size_t j = 0; j < g; ++j)
      cands.push_back({m,
                       d.sb.lo * std::pow(d.sb.hi / d.sb.lo,
                                          (static_cast<double>(j) + 0.5) / static_cast<double>(g)),
                       0.0});
    for (std::size_t i = 0; i < m; ++i)
      for (int step = -20; step <= 20; ++step)
        if (step != 0) {
          const double t = thr[i] * (1.0 + 0.01 * step);
          if (t >= d.sb.lo && t <= d.sb.hi) cands.push_back({i, t, best.rho[i]});
        }
    vp_evaluate(d, best.s, best.rho, Jacobian::none, ws);
    const Eigen::MatrixXd& phi = ws.traj.delta;
    gram.setZero();
    gram.selfadjointView<Eigen::Lower>().rankUpdate(phi.transpose());
    phi_y.noalias() = phi.transpose() * d.y;
    double best_move = best.percent;
    std::size_t move_i = 0;
    Candidate move{0, 0.0, 0.0};
    for (std::size_t j0 = 0; j0 < cands.size(); j0 += kBlock) {
      const std::size_t b = std::min(kBlock, cands.size() - j0);
      std::vector<double> t(b), init(b);
      for (std::size_t jj = 0; jj < b; ++jj)
        t[jj] = cands[j0 + jj].threshold, init[jj] = cands[j0 + jj].rho * t[jj];
      detail::operator_trajectories(t, init, d.x, false, cand, d.limits, d.turns);
      cross.noalias() = phi.transpose() * cand.delta;
      const Eigen::VectorXd cc = cand.delta.colwise().squaredNorm().transpose();
      const Eigen::VectorXd cy = cand.delta.transpose() * d.y;
      for (std::size_t jj = 0; jj < b; ++jj) {
        const Candidate& c = cands[j0 + jj];
        for (Eigen::Index i = 0; i < mi; ++i) {
          if (c.op != m && c.op != static_cast<std::size_t>(i)) continue;
          moved = gram;
          rhs = phi_y;
          for (Eigen::Index l = 0; l < mi; ++l)
            if (l != i) {
              const double x = cross(l, static_cast<Eigen::Index>(jj));
              if (l > i)
                moved(l, i) = x;
              else
                moved(i, l) = x;
            }
          moved(i, i) = cc(static_cast<Eigen::Index>(jj));
          rhs(i) = cy(static_cast<Eigen::Index>(jj));
          double rss = 0;
          if (!detail::box_least_squares_gram(moved, rhs, yy, lo, hi, z, rss)) continue;
          const double v = 100.0 * rss / n;
          if (v < best_move) best_move = v, move_i = static_cast<std::size_t>(i), move = c;
        }
      }
    }
    // A move is taken only when its gain is visible above the noise: the RSS a re-placed threshold
    // (with its initial state) lowers by chance is a chi-square of 2 degrees of freedom in units
    // of sigma^2, above kMoveSignificance sigma^2 with probability 1e-3.  Smaller gains are what
    // any threshold wins from the noise's own kinks, and polishing them cost most of a fixed-M
    // fit (three 30-50 iteration searches on the envelope bench record for 0.4 % of the RSS, the
    // validation error unchanged).
    const double gain = (best.percent - best_move) * n / 100.0;
    if (!(best_move < best.percent * (1.0 - 1e-6)) || !(gain > kMoveSignificance * d.sigma2))
      return improved;
    std::vector<std::pair<double, double>> ops;
    for (std::size_t l = 0; l < m; ++l)
      ops.emplace_back(l == move_i ? move.threshold : thr[l], l == move_i ? move.rho : best.rho[l]);
    std::sort(ops.begin(), ops.end());
    std::vector<double> move_thr, move_rho;
    for (const auto& [a, r] : ops) move_thr.push_back(a), move_rho.push_back(r);
    const Fit f = local_search(d, d.sb.coordinates(move_thr), move_rho, o, best.percent);
    const double before = best.percent;
    record("moved", move_thr, f);
    if (!(best.percent < before * (1.0 - 1e-6))) return improved;
    improved = true;
  }
  return improved;
}

// The dictionary.  At fixed thresholds and initial states the force is linear in the stiffnesses,
// so a dense grid of thresholds over [q, L] (16 per decade) is one NNLS problem, and its solution
// is sparse: the grid points it keeps gather in runs around the thresholds the data hold.  Its
// clusters are then a start close to the global minimum for every M at once, from one pass over
// the record: the force-quantile and geometric starts it replaces only placed thresholds where the
// force or a log scale said, and a local search from them ended in whatever basin it started in
// (on the three bench records 3-10x above the minimum that the global stage then took 0.5-0.8 s
// to find).
//
// The initial state.  An operator forgets its initial deflection once the record's range has
// covered twice its threshold (it has then been pushed to a bound whatever it started from);
// before that its trajectory depends on it.  From the virgin state alone the operators that the
// record wipes out late are wrong over a long prefix, and the NNLS makes up for them with spurious
// clusters (a random system of a test: 3.1 % RSS/SSS, two true thresholds merged, a phantom one
// between).  So every grid threshold not wiped out at once has three columns, from the virgin
// state and from either bound: nonnegative combinations of them span what the initial state does
// (0.0035 % on that record, every cluster at a true threshold).  Their stiffnesses add up.
//
// The NNLS runs on the Gram matrix of [Phi y], accumulated in blocks of rows (the N x P matrix is
// never stored; at 10^6 samples every ceil(N / 65536)-th row only: the trajectories still run over
// every sample), compressed through the eigen-decomposition of its unit-diagonal scaling: adjacent
// grid points and the three starts of one threshold are nearly collinear, and the active set's
// column-pivoted QR of the free columns takes what the directions kept (eigenvalues above 1e-13 of
// the largest) can resolve.
//
// `added` (optional): signals a_j(t_k) fitted beside the grid's columns, their coefficients
// bounded below by `added_lower` (free where it is short) and returned in `added_coefficients`
// (in the force's units per unit of a_j); the dictionary's operators are then those of the force
// with them taken out (dictionary_added_coefficients).  `residual_variance`: the fit's residual
// variance per sample, in the force's units squared.
void dictionary_operators(Data& d, std::span<const std::vector<double>> added = {},
                          std::span<const double> added_lower = {},
                          std::vector<double>* added_coefficients = nullptr,
                          double* residual_variance = nullptr) {
  if (added_coefficients) added_coefficients->clear();
  const double decades = std::log10(d.sb.hi / d.sb.lo);
  const std::size_t g = static_cast<std::size_t>(std::ceil(16.0 * decades)) + 1;
  const std::size_t n = d.x.size();
  std::vector<double> thr(g);
  for (std::size_t j = 0; j < g; ++j)
    thr[j] =
        d.sb.lo * std::pow(d.sb.hi / d.sb.lo, static_cast<double>(j) / static_cast<double>(g - 1));
  // The first sample at which the range covers 2 thr[j] (n: never); thresholds increase, so the
  // indices do.
  std::vector<std::size_t> wiped(g, n);
  {
    double lo = d.x[0], hi = d.x[0];
    std::size_t j = 0;
    for (std::size_t t = 0; t < n && j < g; ++t) {
      lo = std::min(lo, d.x[t]), hi = std::max(hi, d.x[t]);
      while (j < g && hi - lo >= 2.0 * thr[j]) wiped[j++] = t;
    }
  }
  // Columns: (grid index, initial deflection / threshold).
  std::vector<std::pair<std::size_t, double>> cols;
  for (std::size_t j = 0; j < g; ++j) {
    cols.emplace_back(j, 0.0);
    if (wiped[j] > 1) cols.emplace_back(j, 1.0), cols.emplace_back(j, -1.0);
  }
  const std::size_t p_operators = cols.size(), p = p_operators + added.size();
  const Eigen::Index pi = static_cast<Eigen::Index>(p);
  const std::size_t stride = (n + 65535) / 65536;
  constexpr Eigen::Index kRows = 1024;
  Eigen::MatrixXd block(kRows, pi + 1);
  std::vector<double> z(p_operators);
  for (std::size_t c = 0; c < p_operators; ++c) z[c] = cols[c].second * thr[cols[c].first];
  // A threshold's three columns (virgin, started at either bound) are equal to the bit once its
  // trajectories have met (the range has covered twice the threshold: all three at the same
  // bound), and from then on they stay equal, the same recursion on the same input.  So a block
  // of rows holds only the columns not yet merged into their threshold's virgin column
  // (merged_column_gram.hpp; the block's Gram matrix had been the largest single cost of an NLR
  // fit on the strokes bench record).
  std::vector<Eigen::Index> virgin_of(p_operators);
  for (std::size_t c = 0; c < p_operators; ++c)
    virgin_of[c] = cols[c].second == 0.0 ? static_cast<Eigen::Index>(c) : virgin_of[c - 1];
  detail::MergedColumnGram merged_gram(pi + 1);
  const auto start_block = [&] {
    for (std::size_t c = 0; c < p_operators; ++c) {
      const Eigen::Index ci = static_cast<Eigen::Index>(c);
      if (!merged_gram.merged(ci) && cols[c].second != 0.0 &&
          z[c] == z[static_cast<std::size_t>(virgin_of[c])])
        merged_gram.merge(ci, virgin_of[c]);
    }
  };
  const auto add_block = [&](Eigen::Index rows) {
    const Eigen::Index held = static_cast<Eigen::Index>(merged_gram.held().size());
    merged_gram.add(block.topLeftCorner(rows, held));
  };
  Eigen::Index rows = 0;
  bool block_open = false;
  for (std::size_t t = 0; t < n; ++t) {
    const double dx = t > 0 ? d.x[t] - d.x[t - 1] : 0.0;
    const double turn = d.turns[t];
    const double up = d.limits ? d.limits->upper[t] : 1.0;
    const double down = d.limits ? d.limits->lower[t] : 1.0;
    const bool turned = d.limits && !d.limits->turn_upper.empty();
    const double up_turn = turned ? d.limits->turn_upper[t] : up;
    const double down_turn = turned ? d.limits->turn_lower[t] : down;
    for (std::size_t c = 0; c < p_operators; ++c) {
      const double a = thr[cols[c].first];
      if (turn != 0.0)  // motion.hpp, Turns between samples (and The level at the turn)
        z[c] = std::clamp(std::clamp(z[c] + turn, -down_turn * a, up_turn * a) + (dx - turn),
                          -down * a, up * a);
      else
        z[c] = std::clamp(z[c] + dx, -down * a, up * a);
    }
    if (t % stride != 0) continue;
    if (!block_open) start_block(), block_open = true;
    const std::vector<Eigen::Index>& held = merged_gram.held();
    for (std::size_t u = 0; u < held.size(); ++u) {
      const std::size_t c = static_cast<std::size_t>(held[u]);
      const Eigen::Index ui = static_cast<Eigen::Index>(u);
      if (c < p_operators)
        block(rows, ui) = z[c];
      else if (c < p)
        block(rows, ui) = added[c - p_operators][t];
      else
        block(rows, ui) = d.y(static_cast<Eigen::Index>(t));
    }
    if (++rows == kRows || t + stride >= n) {
      add_block(rows);
      rows = 0;
      block_open = false;
    }
  }
  if (rows > 0) add_block(rows);
  const Eigen::MatrixXd& gram = merged_gram.gram();
  Eigen::VectorXd scale(pi);
  for (Eigen::Index c = 0; c < pi; ++c) scale(c) = gram(c, c) > 0.0 ? std::sqrt(gram(c, c)) : 1.0;
  Eigen::MatrixXd scaled = gram.topLeftCorner(pi, pi).selfadjointView<Eigen::Lower>();
  scaled = scale.cwiseInverse().asDiagonal() * scaled * scale.cwiseInverse().asDiagonal();
  const Eigen::VectorXd atb = gram.row(pi).head(pi).transpose().cwiseQuotient(scale);
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(scaled);
  if (eig.info() != Eigen::Success) return;
  const Eigen::VectorXd& lambda = eig.eigenvalues();
  const double keep = 1e-13 * std::max(lambda.maxCoeff(), 0.0);
  Eigen::MatrixXd as = Eigen::MatrixXd::Zero(pi, pi);
  Eigen::VectorXd bs = Eigen::VectorXd::Zero(pi);
  for (Eigen::Index e = 0; e < pi; ++e)
    if (lambda(e) > keep) {
      as.row(e) = std::sqrt(lambda(e)) * eig.eigenvectors().col(e).transpose();
      bs(e) = eig.eigenvectors().col(e).dot(atb) / std::sqrt(lambda(e));
    }
  constexpr double kInf = std::numeric_limits<double>::infinity();
  Eigen::VectorXd lower = Eigen::VectorXd::Zero(pi);
  for (std::size_t j = 0; j < added.size(); ++j)
    lower(static_cast<Eigen::Index>(p_operators + j)) =
        j < added_lower.size() ? added_lower[j] / d.scale : -kInf;
  const Eigen::VectorXd k = detail::box_least_squares_reduced(
      as, bs, scale, std::sqrt(std::max(gram(pi, pi), 0.0)), lower,
      Eigen::VectorXd::Constant(pi, kInf), nullptr);
  if (added_coefficients) {
    added_coefficients->resize(added.size());
    for (std::size_t j = 0; j < added.size(); ++j)
      (*added_coefficients)[j] = k(static_cast<Eigen::Index>(p_operators + j)) * d.scale;
  }
  if (residual_variance) {
    // ||y - A k||^2 = y'y - 2 k'A'y + k'A'A k, over the rows accumulated.
    const Eigen::MatrixXd ata = gram.topLeftCorner(pi, pi).selfadjointView<Eigen::Lower>();
    const double rss = std::max(
        0.0, gram(pi, pi) - 2.0 * k.dot(gram.row(pi).head(pi).transpose()) + k.dot(ata * k));
    const double rows_used = static_cast<double>((n + stride - 1) / stride);
    *residual_variance =
        rss / std::max(1.0, rows_used - static_cast<double>(p)) * d.scale * d.scale;
  }
  std::vector<double> total(g, 0.0);
  for (std::size_t c = 0; c < p_operators; ++c)
    total[cols[c].first] += std::max(0.0, k(static_cast<Eigen::Index>(c)));
  d.dictionary.clear();
  d.dictionary_ratio = thr[1] / thr[0];
  for (std::size_t j = 0; j < g; ++j)
    if (total[j] > 0.0) d.dictionary.emplace_back(thr[j], total[j]);
}

// M thresholds from the dictionary.  A true threshold between two grid points is held by those
// two, sometimes a third: a run of adjacent grid points that spans at most three grid steps (a
// factor 1.54) is one operator from the start.  Two true thresholds a factor 1.8 apart often have
// kept grid points all the way between them, so the points of longer runs start as operators of
// their own (a test's random system lost one of two such thresholds when every run was one
// operator; with every grid point its own, a split pair around one threshold of the envelope bench
// record made its local search 5x longer).  While there are more operators than M, the neighbours
// whose merger changes the force least are merged: (k1, D1) and (k2, D2) merged into one of
// stiffness k1 + k2 and threshold (k1 D1 + k2 D2) / (k1 + k2) keep the initial slope and the
// sliding force of the pair, and differ from it only between the two thresholds, by at most
// k1 k2 |D2 - D1| / (k1 + k2): the merger's cost.  Points around one threshold, a grid step (15 %)
// apart, merge before distinct thresholds do.  An operator may also be dropped, at the cost of its
// sliding force k D: the NNLS keeps small ones that fit the noise (one at the encoder step, with
// 0.1 % of the force, took the place of a true threshold in another random system).  With fewer
// operators than M, thresholds go into the largest log-gaps (as the warm start of the order
// selection does).  `clusters` receives the number of operators before the mergers.  Empty when
// the dictionary is.
std::vector<double> dictionary_start(const Data& d, std::size_t m, double lo, double hi,
                                     std::size_t* clusters = nullptr) {
  if (clusters) *clusters = 0;
  if (d.dictionary.empty()) return {};
  struct Cluster {
    double k, kd;  // sum k, sum k * threshold
    double threshold() const { return kd / k; }
  };
  // Runs of adjacent grid points; a run spanning at most kRunSteps grid steps is one operator.
  constexpr double kRunSteps = 3;
  std::vector<Cluster> c;
  const auto& dict = d.dictionary;
  for (std::size_t a = 0; a < dict.size();) {
    std::size_t b = a + 1;
    while (b < dict.size() && dict[b].first <= dict[b - 1].first * d.dictionary_ratio * 1.0001) ++b;
    const bool one =
        dict[b - 1].first <= dict[a].first * std::pow(d.dictionary_ratio, kRunSteps) * 1.0001;
    for (std::size_t i = a; i < b; ++i) {
      const auto& [t, k] = dict[i];
      if (one && i > a)
        c.back().k += k, c.back().kd += k * t;
      else
        c.push_back({k, k * t});
    }
    a = b;
  }
  if (clusters) *clusters = c.size();
  while (c.size() > m) {
    std::size_t best = 0;
    bool drop = false;
    double cost = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < c.size(); ++i) {
      if (c[i].kd < cost) cost = c[i].kd, best = i, drop = true;
      if (i + 1 == c.size()) continue;
      const double v = c[i].k * c[i + 1].k / (c[i].k + c[i + 1].k) *
                       std::abs(c[i + 1].threshold() - c[i].threshold());
      if (v < cost) cost = v, best = i, drop = false;
    }
    if (!drop) c[best].k += c[best + 1].k, c[best].kd += c[best + 1].kd, ++best;
    c.erase(c.begin() + static_cast<std::ptrdiff_t>(best));
  }
  std::vector<double> thr;
  for (const Cluster& x : c) thr.push_back(x.threshold());
  thr = clamp_sorted(std::move(thr), lo, hi);
  while (thr.size() < m) thr = with_one_in_largest_gap(std::move(thr), lo, hi);
  return thr;
}

// Fit M operators from the automatic starts, with the global stage when they disagree.
Fit fit_operators(const Data& d, std::size_t m, const std::vector<double>* previous,
                  double previous_percent, const Scales& sc, const NlrOptions& o,
                  IdentificationReport& rep) {
  std::vector<std::pair<std::string, std::vector<double>>> starts;
  // The dictionary's clusters when it has any (all stiffnesses zero: a force no operator set
  // explains); otherwise two starts that place thresholds where the force and a log scale say.
  // In the order selection, once M exceeds the dictionary's clusters its start is those clusters
  // with thresholds in the largest gaps, which the warm start (the M - 1 minimum with one in the
  // largest gap) already is, from a better point (on data/ the same 49-iteration search three
  // times over).
  std::size_t clusters = 0;
  if (auto dict = dictionary_start(d, m, sc.q, sc.travel, &clusters); !dict.empty()) {
    if (clusters >= m || !previous || previous->empty())
      starts.emplace_back("dictionary", std::move(dict));
  } else {
    std::vector<double> quant(m);
    for (std::size_t j = 0; j < m; ++j)
      quant[j] = 0.5 * travel_at_force_fraction(
                           d.x, d.force, (static_cast<double>(j) + 0.5) / static_cast<double>(m));
    quant = clamp_sorted(quant, sc.q, sc.travel);
    starts.emplace_back("force-quantiles", quant);
    const double top = std::clamp(0.5 * sc.presliding, sc.q, sc.travel);
    const double bottom = std::min(quant.front(), top / 4.0);
    std::vector<double> geo(m);
    for (std::size_t j = 0; j < m; ++j)
      geo[j] = m == 1 ? std::sqrt(bottom * top)
                      : bottom * std::pow(top / bottom,
                                          static_cast<double>(j) / static_cast<double>(m - 1));
    starts.emplace_back("geometric", clamp_sorted(geo, sc.q, sc.travel));
  }
  if (previous && !previous->empty())  // first in the start log: the (M-1) minimum extended
    starts.insert(starts.begin(), {"warm", with_one_in_largest_gap(*previous, sc.q, sc.travel)});

  Fit best;
  std::vector<double> minima;
  auto record = [&](const std::string& kind, const std::vector<double>& thr0, const Fit& f) {
    StartLog log = start_log(d, kind, thr0, f);
    log.distinct = std::none_of(minima.begin(), minima.end(), [&](double v) {
      return std::abs(v - f.percent) <= o.stall_tolerance * std::max(v, f.percent);
    });
    if (log.distinct) minima.push_back(f.percent);
    rep.starts.push_back(std::move(log));
    ++rep.convergence.local_searches;
    if (f.percent < best.percent) best = f;
  };
  // An M-operator model contains every (M-1)-operator one (an extra operator with stiffness 0), so
  // the (M-1) minimum is reachable too: a start that cannot get below it is stopped.  Each start
  // is measured against that minimum only, not against another start of this M, so the starts
  // are independent and run concurrently (NlrOptions::threads), with the same result for any
  // thread count (in the order selection the warm and the dictionary start take about as long).
  std::vector<Fit> fits(starts.size());
  detail::parallel_for(starts.size(), o.threads, [&](std::size_t i) {
    const auto& [kind, thr] = starts[i];
    // The first start at a fixed M has no minimum to measure itself against; the global stage
    // that follows it (threshold moves) escapes the valleys this piecewise-smooth cost has, so a
    // start that at its pace cannot reach the noise floor is handed over to it rather than let
    // crawl (the multisine bench record's first start spent 80 of its 101 iterations gaining 1 %
    // in a basin 5x above the minimum the moves then found: the same model, 1.0 -> 0.8 s).  The
    // dictionary's start is not: it starts in the minimum's basin.
    const bool handed_over = o.operators > 0 && o.global_stage && kind != "dictionary";
    fits[i] = local_search(
        d, d.sb.coordinates(thr), start_rho(d, thr), o,
        handed_over && !std::isfinite(previous_percent) ? d.floor_percent : previous_percent);
  });
  for (std::size_t i = 0; i < starts.size(); ++i)
    record(starts[i].first, starts[i].second, fits[i]);
  if (o.operators > 0) refine_initial_state(d, best, o, false, rep);

  // A fit already at the noise floor cannot be improved beyond chance, so the (costly) global
  // stage is skipped even when another start stalled elsewhere.
  // Weak-operator relocation: a trapped fit often spends one operator on nothing (a threshold at
  // the resolution with a tiny stiffness, seed 9 of studies.md 1) while the others share the
  // work of one more.  The operator that carries the least of the sliding force (k_i Delta_i) is
  // moved into the largest log-gap of the others' thresholds (or beyond the largest) and the fit
  // re-polished from there when that start is already better; kept when the polish is better.
  // Skipped at the noise floor, and during the order selection, where the warm start from M - 1
  // (one threshold inserted in the largest gap) is the same move.
  auto relocate_weakest = [&]() {
    if (o.operators == 0 || m < 2 || best.percent <= d.floor_percent ||
        best.k.size() != static_cast<Eigen::Index>(m))
      return;
    const std::vector<double> thr = d.sb.thresholds(best.s);
    std::size_t weak = 0;
    for (std::size_t i = 1; i < m; ++i)
      if (best.k(static_cast<Eigen::Index>(i)) * thr[i] <
          best.k(static_cast<Eigen::Index>(weak)) * thr[weak])
        weak = i;
    std::vector<double> others;
    for (std::size_t i = 0; i < m; ++i)
      if (i != weak) others.push_back(thr[i]);
    others.push_back(std::min(sc.travel, others.back() * 4.0));
    std::vector<double> moved(others.begin(), others.end() - 1);
    std::size_t gap = 0;
    double widest = 0;
    for (std::size_t g = 0; g + 1 < others.size(); ++g)
      if (others[g + 1] / others[g] > widest) widest = others[g + 1] / others[g], gap = g;
    moved.push_back(std::sqrt(others[gap] * others[gap + 1]));
    moved = clamp_sorted(moved, sc.q, sc.travel);
    // Polished only from a start already better than the fit (stiffnesses re-solved, initial
    // state estimated): since the dictionary starts, the relocated start was 1.007-52 times the
    // fit's cost wherever it ran (the NLR round-trip study's 5 relocations, the strokes bench
    // record, data/ at M = 6), and none of the 7 polishes, 27 iterations on the strokes record
    // (a third of its fit), ended below the fit.
    const std::vector<double> rho = start_rho(d, moved);
    const double start = [&] {
      Workspace ws;
      return percent_of(vp_evaluate(d, d.sb.coordinates(moved), rho, Jacobian::none, ws).r);
    }();
    if (!(start < best.percent)) return;
    const Fit f = local_search(d, d.sb.coordinates(moved), rho, o, best.percent);
    record("relocated", moved, f);
  };
  relocate_weakest();
  if (o.operators > 0) refine_initial_state(d, best, o, false, rep);

  // The global stage runs whenever the best start is above the noise floor, at a fixed M and in
  // the order selection alike: starts that agree are no sign of the global minimum (on the strokes
  // bench record both old starts ended at twice the floor, and the moves halved it; on the
  // tribometer record the dictionary holds two clusters, so from M = 3 on the warm start is the
  // only one, and without the moves the selection ended at 0.4265 % with 7 operators instead of
  // 0.4205 % with 5).  A sweep costs Gram products only; its polishes run only for a move whose
  // gain is significant (threshold_moves), which at most M is none.
  if (o.global_stage && !(best.percent <= d.floor_percent)) {
    for (int round = 0; round < 3 && !(best.percent <= d.floor_percent); ++round) {
      const double before_round = best.percent;
      // Without a move the restart and the relocation below would repeat what the round before
      // (or the starts) already did from this same fit.
      if (!threshold_moves(d, best, o, record)) break;
      const std::vector<double> thr = d.sb.thresholds(best.s);
      record("restart", thr, local_search(d, best.s, start_rho(d, thr), o, best.percent));
      if (o.operators > 0) refine_initial_state(d, best, o, false, rep);
      relocate_weakest();
      if (o.operators > 0) refine_initial_state(d, best, o, false, rep);
      if (!(best.percent < before_round * (1.0 - o.stall_tolerance))) break;
    }
  }
  return best;
}

}  // namespace

std::vector<double> nlr_thresholds_from_coordinates(std::span<const double> s, double lower,
                                                    double upper) {
  FRICTION_CHECK(lower > 0.0 && upper > lower,
                 "nlr: threshold bounds must satisfy 0 < lower < upper");
  return detail::StickBreaking{lower, upper}.thresholds(s);
}

std::vector<double> nlr_coordinates_from_thresholds(std::span<const double> thresholds,
                                                    double lower, double upper) {
  FRICTION_CHECK(lower > 0.0 && upper > lower,
                 "nlr: threshold bounds must satisfy 0 < lower < upper");
  return detail::StickBreaking{lower, upper}.coordinates({thresholds.begin(), thresholds.end()});
}

void nlr_projected_residual(std::span<const double> x, std::span<const double> force, double lower,
                            double upper, std::span<const double> s, std::span<const double> rho,
                            Eigen::VectorXd& residual, Eigen::MatrixXd* jacobian,
                            Eigen::VectorXd* stiffness, Eigen::MatrixXd* compressed) {
  FRICTION_CHECK(x.size() == force.size() && !x.empty(), "nlr: lengths differ");
  FRICTION_CHECK(s.size() == rho.size() && !s.empty(), "nlr: s and rho sizes differ");
  FRICTION_CHECK(lower > 0.0 && upper > lower,
                 "nlr: threshold bounds must satisfy 0 < lower < upper");
  Data d = fit_data(x, force, nullptr);
  FRICTION_CHECK(d.scale > 0.0, "nlr: the force is identically zero");
  d.sb = detail::StickBreaking{lower, upper};
  Workspace ws;
  const auto& v = vp_evaluate(d, s, rho, jacobian ? Jacobian::full : Jacobian::none, ws);
  residual = v.r;
  if (jacobian) *jacobian = ws.jac;
  if (stiffness) *stiffness = v.k * d.scale;
  if (compressed) {
    vp_evaluate(d, s, rho, Jacobian::compressed, ws);
    *compressed = ws.factor;
  }
}

namespace {

NlrResult identify(std::span<const double> time, std::span<const double> x,
                   std::span<const double> force, const NlrOptions& o,
                   const detail::SlipLimits* limits) {
  const detail::SubnormalsFlushed subnormals_flushed;  // subnormals.hpp
  const auto clock_start = std::chrono::steady_clock::now();
  FRICTION_CHECK(time.size() == x.size() && x.size() == force.size(),
                 "identify_maxwell_slip: time, displacement and force lengths differ");
  FRICTION_CHECK(x.size() >= 20, "identify_maxwell_slip: ", x.size(),
                 " samples are too few (at least 20)");
  FRICTION_CHECK(o.operators > 0 || o.max_operators > 0,
                 "identify_maxwell_slip: max_operators must be >= 1");
  for (std::size_t k = 0; k < x.size(); ++k)
    FRICTION_CHECK(std::isfinite(x[k]) && std::isfinite(force[k]), "identify_maxwell_slip: sample ",
                   k, " is not finite");

  Data d = fit_data(x, force, limits);
  const double sss = d.sss;
  FRICTION_CHECK(sss > 0.0, "identify_maxwell_slip: the force is identically zero");
  const double n = static_cast<double>(x.size());

  NlrResult result;
  IdentificationReport& rep = result.report;
  Scales sc;
  sc.q = o.displacement_resolution > 0 ? o.displacement_resolution : displacement_resolution(x);
  sc.travel = largest_travel(x);
  FRICTION_CHECK(sc.travel > 2.0 * sc.q, "identify_maxwell_slip: the displacement hardly moves");
  sc.presliding = std::clamp(travel_at_force_fraction(x, force, 0.95), 2.0 * sc.q, 2.0 * sc.travel);
  rep.displacement_resolution = sc.q;
  rep.largest_travel = sc.travel;
  rep.presliding_travel = sc.presliding;
  d.sb = detail::StickBreaking{sc.q, sc.travel};
  dictionary_operators(d);
  {
    const double sigma = estimate_white_noise_sigma(force) / d.scale;
    d.floor_percent = 100.0 * sigma * sigma * (1.0 + 3.0 * std::sqrt(2.0 / n));
    d.sigma2 = sigma * sigma;
  }

  const std::size_t m_lo = o.operators > 0 ? o.operators : 1;
  const std::size_t m_hi = o.operators > 0 ? o.operators : o.max_operators;
  std::vector<Fit> fits;
  std::vector<double> previous;
  double previous_percent = std::numeric_limits<double>::infinity();
  double best_bic = std::numeric_limits<double>::infinity();
  std::size_t best_index = 0;
  for (std::size_t m = m_lo; m <= m_hi; ++m) {
    Fit fit =
        fit_operators(d, m, previous.empty() ? nullptr : &previous, previous_percent, sc, o, rep);
    previous = d.sb.thresholds(fit.s);
    previous_percent = fit.percent;
    SelectionRow row;
    row.operators = m;
    std::size_t active = 0;
    for (Eigen::Index i = 0; i < fit.k.size(); ++i) active += fit.k(i) > 0.0;
    row.parameters = 2 * active;
    row.rss_sss_percent = fit.percent;
    row.rss = fit.percent / 100.0 * sss;
    row.criterion = bayesian_information_criterion(row.rss, x.size(), row.parameters);
    // A larger M is selected only when it lowers the criterion by more than 1 (a likelihood ratio
    // of e^0.5, "not worth more than a bare mention" on Kass and Raftery's scale): the local
    // searches stop within a few hundredths of it (solver_options), and an M whose extra operator
    // went to stiffness 0 is the smaller model continued a few steps further, not a better one.
    if (row.criterion < best_bic - 1.0) best_bic = row.criterion, best_index = fits.size();
    rep.selection.push_back(row);
    fits.push_back(std::move(fit));
  }
  rep.selection[best_index].selected = true;
  // The thorough initial-state refinement, once, for the selected M (it is the costly one: a
  // global search of the initial state; the order comparison above does not need it).
  Fit& best = fits[best_index];
  std::vector<double> estimated;  // the thorough estimate at best's parameters, when it has one
  if (o.refine_initial_state) refine_initial_state(d, best, o, true, rep, &estimated);

  // The model: operators whose stiffness went to the bound 0 are removed.
  const std::vector<double> thr = d.sb.thresholds(best.s);
  std::vector<double> rho;
  auto& p = result.parameters;
  for (std::size_t i = 0; i < thr.size(); ++i) {
    const double k = best.k(static_cast<Eigen::Index>(i)) * d.scale;
    if (k > 0.0) {
      p.stiffness.push_back(k);
      p.threshold.push_back(thr[i]);
      rho.push_back(best.rho[i]);
    } else {
      std::ostringstream w;
      w << "operator with threshold " << thr[i] << " m got stiffness 0 (the data want it negative);"
        << " it was removed";
      rep.warnings.push_back(w.str());
    }
  }
  FRICTION_CHECK_AS(NumericalError, !p.threshold.empty(),
                    "identify_maxwell_slip: every stiffness went to zero");
  const std::size_t m = p.size();
  if (rep.selection[best_index].operators == m_hi && o.operators == 0 && m_hi > 1)
    rep.warnings.push_back("the criterion chose the largest M tried (" + std::to_string(m_hi) +
                           "); a larger max_operators may fit better");

  // Errors of the free run from the estimated initial state (the routine validation uses).
  std::vector<double> guess(m);
  for (std::size_t i = 0; i < m; ++i) guess[i] = rho[i] * p.threshold[i];
  if (limits) {
    // Under a level the fit's own initial state (the estimate below knows only the nominal box),
    // and the run under the same limits.
    rep.initial_deflections = guess;
    const auto tr = detail::operator_trajectories(p.threshold, guess, x, false, limits);
    const Eigen::Map<const Eigen::VectorXd> k(p.stiffness.data(), static_cast<Eigen::Index>(m));
    const Eigen::VectorXd fhat = tr.delta * k;
    rep.estimation_simulated.assign(fhat.data(), fhat.data() + fhat.size());
  } else {
    // The routine validation uses, on the scaled force as refine_initial_state runs it (the same
    // estimate, which that refinement usually has made already), unless the caller asked for no
    // initial-state search (DNLRX's order selection, which uses only the minima per M): then the
    // fit's own initial state.
    if (!estimated.empty() && m == thr.size()) {
      rep.initial_deflections = std::move(estimated);
    } else if (o.refine_initial_state) {
      Eigen::MatrixXd filter(static_cast<Eigen::Index>(m), 1);
      for (std::size_t i = 0; i < m; ++i)
        filter(static_cast<Eigen::Index>(i), 0) = p.stiffness[i] / d.scale;
      rep.initial_deflections = estimate_initial_deflections(
          x, std::span<const double>(d.y.data(), static_cast<std::size_t>(d.y.size())), p.threshold,
          filter, guess);
    } else {
      rep.initial_deflections = guess;
    }
    MaxwellSlip<double> model(p);
    model.reset(std::span<const double>(rep.initial_deflections));
    rep.estimation_simulated.resize(x.size());
    for (std::size_t k = 0; k < x.size(); ++k)
      rep.estimation_simulated[k] =
          model.step(Motion<double>{k > 0 ? x[k] - x[k - 1] : 0.0, 0.0, 0.0, 1.0, 0.0,
                                    turn_increment(x, k)});
  }
  rep.estimation = compute_errors(force, rep.estimation_simulated);
  rep.noise_sigma = estimate_white_noise_sigma(force);
  rep.noise_floor_percent = noise_floor_rss_sss_percent(force, rep.noise_sigma);
  rep.convergence.converged = best.converged;
  rep.convergence.iterations = best.iterations;
  rep.convergence.initial_cost = best.start_percent;
  rep.convergence.final_cost = best.percent;
  rep.convergence.message = best.message;
  if (!best.converged)
    rep.warnings.push_back("local search did not report convergence: " + best.message);

  // Parameters, standard errors, correlations.
  const Eigen::Index mi = static_cast<Eigen::Index>(m);
  for (std::size_t i = 0; i < m; ++i)
    rep.parameters.push_back({"stiffness[" + std::to_string(i + 1) + "]", "N/m", p.stiffness[i], 0,
                              p.stiffness[i], p.stiffness[i]});
  for (std::size_t i = 0; i < m; ++i)
    rep.parameters.push_back({"threshold[" + std::to_string(i + 1) + "]", "m", p.threshold[i], 0,
                              p.threshold[i], p.threshold[i]});
  rep.correlation = Eigen::MatrixXd::Identity(2 * mi, 2 * mi);
  if (o.covariance) {
    // Jacobian of the scaled force w.r.t. (log k, log Delta) and, as nuisance parameters, the
    // relative initial deflections rho_i = delta_i(0) / Delta_i: they are estimated from the same
    // record, and holding them at their estimate made the intervals of the thresholds they
    // correlate with too narrow (studies.md 1).  The marginal covariance of (log k, log Delta)
    // does not depend on how the nuisance is parameterised (rho or delta(0)).
    std::vector<double> init(m);
    for (std::size_t i = 0; i < m; ++i) init[i] = rep.initial_deflections[i];
    // J (N x 3M) goes in blocks of rows into its triangular factor R: the SVD of R is J's.
    const auto tr = detail::operator_trajectories(p.threshold, init, x, true, limits);
    const Eigen::Index nn = tr.delta.rows();
    detail::RowCompressor compressor(3 * mi);
    constexpr Eigen::Index kRows = 1024;
    Eigen::MatrixXd block(kRows, 3 * mi);
    for (Eigen::Index t0 = 0; t0 < nn; t0 += kRows) {
      const Eigen::Index rows = std::min(kRows, nn - t0);
      for (Eigen::Index i = 0; i < mi; ++i) {
        const double ki = p.stiffness[static_cast<std::size_t>(i)] / d.scale;
        const double di = p.threshold[static_cast<std::size_t>(i)];
        const double ri = init[static_cast<std::size_t>(i)] / di;
        block.col(i).head(rows) = ki * tr.delta.col(i).segment(t0, rows);
        block.col(mi + i).head(rows) =
            ki * di *
            (tr.d_threshold.col(i).segment(t0, rows) + ri * tr.d_initial.col(i).segment(t0, rows));
        block.col(2 * mi + i).head(rows) = ki * di * tr.d_initial.col(i).segment(t0, rows);
      }
      compressor.add(block.topRows(rows));
    }
    Eigen::MatrixXd c;
    const bool ok = detail::marginal_covariance(compressor.factor(), 2 * mi, c, 1e-7);
    const double dof = std::max(1.0, n - 3.0 * static_cast<double>(m));
    const double sigma2 = rep.estimation.rss / (d.scale * d.scale) / dof;
    const bool usable = ok && c.allFinite();
    if (usable) c *= sigma2;
    // Stiffnesses and thresholds are fitted through their logarithms: log-normal intervals.
    std::vector<CovarianceParameter> cp;
    for (std::size_t a = 0; a < 2 * m; ++a)
      cp.push_back({rep.parameters[a].name, rep.parameters[a].unit, rep.parameters[a].value,
                    Parametrisation::log, 1.0, static_cast<std::ptrdiff_t>(a)});
    CovarianceOptions co;
    co.correlation_limit = 0.99;
    const CovarianceReport cr = covariance_report(usable ? &c : nullptr, cp, co);
    cr.apply(rep.parameters);
    rep.correlation = cr.correlation;
    for (const IdentifiabilityWarning& w : cr.warnings) {
      const ParameterEstimate& est = rep.parameters[w.parameter];
      std::ostringstream t;
      switch (w.issue) {
        case IdentifiabilityIssue::wide_interval:
          t << est.name << ": 95 % interval [" << est.lower95 << ", " << est.upper95 << "] "
            << est.unit << " spans more than an order of magnitude (poorly identified)";
          break;
        case IdentifiabilityIssue::correlated:
          t << est.name << " and " << rep.parameters[w.other].name
            << " are correlated above 0.99 (near-singular)";
          break;
        case IdentifiabilityIssue::covariance_unavailable:
          t << "the parameter covariance is rank-deficient (some parameters are not identifiable "
               "from this record); standard errors are not available";
          break;
        default:
          continue;
      }
      rep.warnings.push_back(t.str());
    }
  }
  for (std::size_t i = 0; i < m; ++i) {
    if (p.threshold[i] <= sc.q * 1.01)
      rep.warnings.push_back("threshold[" + std::to_string(i + 1) +
                             "] is at the displacement resolution: the operator acts as a relay");
    if (p.threshold[i] >= sc.travel * 0.99)
      rep.warnings.push_back("threshold[" + std::to_string(i + 1) +
                             "] is at the largest travel: the operator acts as a linear spring");
  }
  rep.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return result;
}

}  // namespace

NlrResult identify_maxwell_slip(std::span<const double> time, std::span<const double> x,
                                std::span<const double> force, const NlrOptions& o) {
  return identify(time, x, force, o, nullptr);
}

namespace detail {

NlrResult identify_maxwell_slip_under_limits(std::span<const double> time,
                                             std::span<const double> x,
                                             std::span<const double> force,
                                             const NlrOptions& options, const SlipLimits& limits) {
  check_slip_limits(limits, x.size());
  return identify(time, x, force, options, &limits);
}

std::vector<double> dictionary_added_coefficients(std::span<const double> x,
                                                  std::span<const double> force,
                                                  std::span<const std::vector<double>> added,
                                                  std::span<const double> lower,
                                                  double displacement_resolution_hint,
                                                  const SlipLimits* limits,
                                                  double* residual_variance) {
  FRICTION_CHECK(x.size() == force.size() && x.size() >= 20,
                 "dictionary_added_coefficients: lengths differ or too few samples");
  for (const auto& a : added)
    FRICTION_CHECK(a.size() == x.size(),
                   "dictionary_added_coefficients: a signal's length differs");
  if (limits) check_slip_limits(*limits, x.size());
  Data d = fit_data(x, force, limits);
  const double q = displacement_resolution_hint > 0 ? displacement_resolution_hint
                                                    : displacement_resolution(x);
  const double travel = largest_travel(x);
  if (!(d.sss > 0.0) || !(travel > 2.0 * q)) return {};
  d.sb = StickBreaking{q, travel};
  std::vector<double> beta;
  dictionary_operators(d, added, lower, &beta, residual_variance);
  return beta;
}

}  // namespace detail

}  // namespace friction
