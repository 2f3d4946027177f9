// LuGre over a record with CVODES (see include/friction/lugre_cvodes.hpp for the method).
#include "friction/lugre_cvodes.hpp"

#include <ceres/jet.h>
#include <cvodes/cvodes.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <sstream>
#include <string>

#include "friction/error.hpp"
#include "friction/scalar.hpp"

namespace friction {
namespace {

// Jet directions: the seven parameters in to_array() order, then z0.
constexpr int kDirections = 8;
constexpr int kZ0 = 7;
using Jet = ceres::Jet<double, kDirections>;
using Jet1 = ceres::Jet<double, 1>;

// The sensitivities CVODES integrates: z depends on sigma0, Fc, Fs, vs, mu and z0 only.
constexpr int kSensitivities = 6;
constexpr std::array<int, kSensitivities> kSensitivityDirection{0, 3, 4, 5, 6, kZ0};

struct Problem {
  LuGreParameters<double> parameters;
  LuGreParameters<Jet> jet_parameters;  // unit derivative in each parameter's own direction
  double velocity = 0.0;
  double level = 1.0;
  std::string last_error;
};

int rhs(sunrealtype /*t*/, N_Vector y, N_Vector ydot, void* user_data) {
  const auto& pr = *static_cast<const Problem*>(user_data);
  const double z = N_VGetArrayPointer(y)[0];
  N_VGetArrayPointer(ydot)[0] = lugre_rhs(pr.parameters, z, pr.velocity, pr.level);
  return 0;
}

int jacobian(sunrealtype /*t*/, N_Vector y, N_Vector /*fy*/, SUNMatrix J, void* user_data,
             N_Vector /*tmp1*/, N_Vector /*tmp2*/, N_Vector /*tmp3*/) {
  const auto& pr = *static_cast<const Problem*>(user_data);
  const Jet1 z(N_VGetArrayPointer(y)[0], 0);
  const Jet1 f = lugre_rhs(pr.parameters.cast<Jet1>(), z, Jet1(pr.velocity), Jet1(pr.level));
  SM_ELEMENT_D(J, 0, 0) = f.v[0];
  return 0;
}

// z as a Jet whose derivative parts are the current sensitivities dz/dp.
Jet state_jet(double z, const N_Vector* yS) {
  Jet zj(z);
  for (int i = 0; i < kSensitivities; ++i)
    zj.v[kSensitivityDirection[i]] = N_VGetArrayPointer(yS[i])[0];
  return zj;
}

int sensitivity_rhs(int /*Ns*/, sunrealtype /*t*/, N_Vector y, N_Vector /*ydot*/, N_Vector* yS,
                    N_Vector* ySdot, void* user_data, N_Vector /*tmp1*/, N_Vector /*tmp2*/) {
  const auto& pr = *static_cast<const Problem*>(user_data);
  const Jet f = lugre_rhs(pr.jet_parameters, state_jet(N_VGetArrayPointer(y)[0], yS),
                          Jet(pr.velocity), Jet(pr.level));
  for (int i = 0; i < kSensitivities; ++i)
    N_VGetArrayPointer(ySdot[i])[0] = f.v[kSensitivityDirection[i]];
  return 0;
}

void record_error(int /*error_code*/, const char* module, const char* function, char* msg,
                  void* user_data) {
  auto& pr = *static_cast<Problem*>(user_data);
  pr.last_error = std::string(module ? module : "") + "/" + (function ? function : "") + ": " +
                  (msg ? msg : "");
}

void check(int flag, const char* call, double t, const Problem& pr) {
  if (flag >= 0) return;
  char* name = CVodeGetReturnFlagName(flag);
  std::ostringstream s;
  s << "CVODES " << call << " failed with " << (name ? name : "unknown flag") << " (" << flag
    << ") at t = " << t << " s";
  if (!pr.last_error.empty()) s << ": " << pr.last_error;
  std::free(name);
  throw NumericalError(s.str());
}

// Owners of the SUNDIALS objects, released in reverse order of creation.
struct ContextDeleter {
  void operator()(SUNContext ctx) const { SUNContext_Free(&ctx); }
};
struct VectorDeleter {
  void operator()(N_Vector v) const { N_VDestroy(v); }
};
struct MatrixDeleter {
  void operator()(SUNMatrix m) const { SUNMatDestroy(m); }
};
struct SolverDeleter {
  void operator()(SUNLinearSolver s) const { SUNLinSolFree(s); }
};
struct CvodeDeleter {
  void operator()(void* mem) const { CVodeFree(&mem); }
};
struct VectorArray {
  N_Vector* vectors = nullptr;
  int count = 0;
  ~VectorArray() {
    if (vectors) N_VDestroyVectorArray(vectors, count);
  }
};

struct Counters {
  long steps = 0, rhs = 0, sens_rhs = 0, error_tests = 0, iterations = 0;
};

Counters read_counters(void* mem, bool sensitivities) {
  Counters c;
  CVodeGetNumSteps(mem, &c.steps);
  CVodeGetNumRhsEvals(mem, &c.rhs);
  CVodeGetNumErrTestFails(mem, &c.error_tests);
  CVodeGetNumNonlinSolvIters(mem, &c.iterations);
  if (sensitivities) CVodeGetSensNumRhsEvals(mem, &c.sens_rhs);
  return c;
}

}  // namespace

LuGreCvodesResult simulate_lugre_cvodes(const LuGreParameters<double>& parameters,
                                        std::span<const double> time, std::span<const double> x,
                                        const CvodesOptions& options, double z0,
                                        std::span<const double> level,
                                        std::span<const double> velocity) {
  parameters.validate();
  const std::size_t n = time.size();
  FRICTION_CHECK(x.size() == n, "simulate_lugre_cvodes: time and displacement lengths differ (", n,
                 " and ", x.size(), ")");
  FRICTION_CHECK(level.empty() || level.size() == n,
                 "simulate_lugre_cvodes: level must be empty or as long as the record");
  FRICTION_CHECK(velocity.empty() || velocity.size() == n,
                 "simulate_lugre_cvodes: velocity must be empty or as long as the record");
  for (std::size_t k = 1; k < n; ++k)
    FRICTION_CHECK(time[k] > time[k - 1],
                   "simulate_lugre_cvodes: time must increase strictly (sample ", k, ")");
  for (std::size_t k = 0; k < level.size(); ++k)
    FRICTION_CHECK(std::isfinite(level[k]) && level[k] > 0.0, "simulate_lugre_cvodes: level[", k,
                   "] = ", level[k], " must be > 0");
  FRICTION_CHECK(std::isfinite(z0), "simulate_lugre_cvodes: initial state must be finite");
  FRICTION_CHECK(options.relative_tolerance > 0.0 && options.absolute_tolerance > 0.0,
                 "simulate_lugre_cvodes: tolerances must be > 0");
  FRICTION_CHECK(options.max_steps_per_sample > 0,
                 "simulate_lugre_cvodes: max_steps_per_sample must be > 0");

  LuGreCvodesResult result;
  result.force.resize(n);
  result.state.resize(n);
  const bool sens = options.sensitivities;
  if (sens) {
    result.jacobian.assign(n * LuGreParameters<double>::kSize, 0.0);
    result.initial_state_derivative.assign(n, 0.0);
  }
  if (n == 0) return result;

  Problem pr;
  pr.parameters = parameters;
  {
    const auto theta = parameters.to_array();
    std::array<Jet, LuGreParameters<double>::kSize> theta_j;
    for (std::size_t j = 0; j < theta.size(); ++j) theta_j[j] = Jet(theta[j], static_cast<int>(j));
    pr.jet_parameters = LuGreParameters<Jet>::from_array(theta_j, parameters.shape);
  }

  SUNContext raw_ctx = nullptr;
  if (SUNContext_Create(nullptr, &raw_ctx) != 0) throw NumericalError("SUNContext_Create failed");
  std::unique_ptr<_SUNContext, ContextDeleter> ctx(raw_ctx);

  std::unique_ptr<_generic_N_Vector, VectorDeleter> y(N_VNew_Serial(1, ctx.get()));
  if (!y) throw NumericalError("N_VNew_Serial failed");
  // Fused vector operations: CVODES then updates the six sensitivities with one call per
  // operation instead of one per vector (every vector here has one entry, so the calls are the
  // cost).  Measured on the strokes bench record: the check at LG's optimum 2-3 ms faster, the
  // Jacobian the same to the bit.
  N_VEnableFusedOps_Serial(y.get(), SUNTRUE);
  double* z = N_VGetArrayPointer(y.get());
  z[0] = z0;

  // Created before the CVODES memory so that CVodeFree runs first when they are released.
  std::unique_ptr<_generic_SUNMatrix, MatrixDeleter> matrix(SUNDenseMatrix(1, 1, ctx.get()));
  if (!matrix) throw NumericalError("SUNDenseMatrix failed");
  std::unique_ptr<_generic_SUNLinearSolver, SolverDeleter> solver(
      SUNLinSol_Dense(y.get(), matrix.get(), ctx.get()));
  if (!solver) throw NumericalError("SUNLinSol_Dense failed");
  VectorArray yS;
  if (sens) {
    yS.vectors = N_VCloneVectorArray(kSensitivities, y.get());
    if (!yS.vectors) throw NumericalError("N_VCloneVectorArray failed");
    yS.count = kSensitivities;
    for (int i = 0; i < kSensitivities; ++i) N_VConst(0.0, yS.vectors[i]);
    N_VGetArrayPointer(yS.vectors[kSensitivities - 1])[0] = 1.0;  // dz0/dz0
  }

  const int lmm = options.method == CvodesMethod::Adams ? CV_ADAMS : CV_BDF;
  std::unique_ptr<void, CvodeDeleter> mem(CVodeCreate(lmm, ctx.get()));
  if (!mem) throw NumericalError("CVodeCreate failed");
  void* cv = mem.get();
  check(CVodeSetErrHandlerFn(cv, record_error, &pr), "CVodeSetErrHandlerFn", time[0], pr);
  check(CVodeInit(cv, rhs, time[0], y.get()), "CVodeInit", time[0], pr);
  check(CVodeSetUserData(cv, &pr), "CVodeSetUserData", time[0], pr);
  check(CVodeSStolerances(cv, options.relative_tolerance,
                          options.absolute_tolerance / parameters.stiffness),
        "CVodeSStolerances", time[0], pr);
  check(CVodeSetMaxNumSteps(cv, options.max_steps_per_sample), "CVodeSetMaxNumSteps", time[0], pr);

  check(CVodeSetLinearSolver(cv, solver.get(), matrix.get()), "CVodeSetLinearSolver", time[0], pr);
  check(CVodeSetJacFn(cv, jacobian), "CVodeSetJacFn", time[0], pr);

  if (sens) {
    check(CVodeSensInit(cv, kSensitivities, CV_STAGGERED, sensitivity_rhs, yS.vectors),
          "CVodeSensInit", time[0], pr);
    std::array<double, kSensitivities> scale{};
    // Tolerance scales: dz/dp is of the order of z/p, and dz/dz0 of 1, so the parameter magnitude
    // (and the largest bristle deflection for z0) make the sensitivity tolerances commensurate.
    const auto theta = parameters.to_array();
    for (int i = 0; i + 1 < kSensitivities; ++i)
      scale[i] = std::abs(theta[kSensitivityDirection[i]]);
    scale[kSensitivities - 1] =
        std::max(parameters.coulomb, parameters.static_force) / parameters.stiffness;
    check(CVodeSetSensParams(cv, nullptr, scale.data(), nullptr), "CVodeSetSensParams", time[0],
          pr);
    check(CVodeSensEEtolerances(cv), "CVodeSensEEtolerances", time[0], pr);
    check(CVodeSetSensErrCon(cv, options.sensitivity_error_control ? SUNTRUE : SUNFALSE),
          "CVodeSetSensErrCon", time[0], pr);
  }

  // Sample k's output: eq. 2 at t_k with the interval velocity, on Jets for the derivatives.
  auto output = [&](std::size_t k, double v, double lev) {
    result.state[k] = z[0];
    if (!sens) {
      result.force[k] = lugre_force(parameters, z[0], v, lev);
      return;
    }
    const Jet f = lugre_force(pr.jet_parameters, state_jet(z[0], yS.vectors), Jet(v), Jet(lev));
    result.force[k] = f.a;
    double* row = result.jacobian.data() + LuGreParameters<double>::kSize * k;
    for (std::size_t j = 0; j < LuGreParameters<double>::kSize; ++j) row[j] = f.v[j];
    result.initial_state_derivative[k] = f.v[kZ0];
  };

  output(0, 0.0, level.empty() ? 1.0 : level[0]);
  CvodesStatistics& stats = result.statistics;
  auto velocity_of = [&](std::size_t k) {
    return velocity.empty() ? (x[k] - x[k - 1]) / (time[k] - time[k - 1]) : velocity[k];
  };
  auto level_of = [&](std::size_t k) { return level.empty() ? 1.0 : level[k]; };
  // The right-hand side jumps only where the velocity or the level changes, so the integrator is
  // re-initialised there and runs through a stretch of equal intervals (a stroke at constant
  // speed, an encoder's repeated count) in one go, each sample's state interpolated by CVODES.
  // Velocities from a displacement written in decimal differ in their last bits from sample to
  // sample of one stroke; a relative difference below a hundredth of the relative tolerance moves
  // z by less than that, so such intervals count as equal and are integrated at the stretch's
  // first velocity.
  const double same_velocity = 1e-2 * options.relative_tolerance;
  auto continues = [&](std::size_t k, double v, double lev) {
    return std::abs(velocity_of(k) - v) <= same_velocity * std::abs(v) && level_of(k) == lev;
  };
  std::size_t run_end = 0;  // last sample of the stretch being integrated; 0: none
  bool sensitivity_error_control = options.sensitivity_error_control;
  for (std::size_t k = 1; k < n; ++k) {
    const double v = velocity_of(k);
    const double lev = level_of(k);
    FRICTION_CHECK(std::isfinite(v), "simulate_lugre_cvodes: velocity of sample ", k,
                   " is not finite");
    if (v == 0.0) {
      run_end = 0;
    } else {
      const double t0 = time[k - 1], t1 = time[k];
      if (k > run_end) {
        run_end = k;
        while (run_end + 1 < n && continues(run_end + 1, v, lev)) ++run_end;
        pr.velocity = v;
        pr.level = lev;
        check(CVodeReInit(cv, t0, y.get()), "CVodeReInit", t0, pr);
        if (sens) check(CVodeSensReInit(cv, CV_STAGGERED, yS.vectors), "CVodeSensReInit", t0, pr);
        check(CVodeSetStopTime(cv, time[run_end]), "CVodeSetStopTime", t0, pr);
        ++stats.restarts;
        // Within one interval the steps chosen for z resolve the sensitivities too (header); across
        // a stretch the steps grow past the interval as z settles, and the sensitivities must
        // enter the error test: measured on the strokes bench record (936 stretches for 8,573
        // moving intervals), the Jacobian's relative error was 3e-3 without and 2.6e-5 with it
        // (2.2e-4 restarting at every sample).
        const bool error_control = options.sensitivity_error_control || run_end > k;
        if (sens && error_control != sensitivity_error_control)
          check(CVodeSetSensErrCon(cv, error_control ? SUNTRUE : SUNFALSE), "CVodeSetSensErrCon",
                t0, pr);
        sensitivity_error_control = error_control;
      }
      const Counters before = read_counters(cv, sens);
      sunrealtype reached = t0;
      check(CVode(cv, t1, y.get(), &reached, CV_NORMAL), "CVode", reached, pr);
      if (sens) check(CVodeGetSens(cv, &reached, yS.vectors), "CVodeGetSens", reached, pr);
      const Counters after = read_counters(cv, sens);
      stats.steps += after.steps - before.steps;
      stats.rhs_evaluations += after.rhs - before.rhs;
      stats.sensitivity_rhs_evaluations += after.sens_rhs - before.sens_rhs;
      stats.error_test_failures += after.error_tests - before.error_tests;
      stats.nonlinear_iterations += after.iterations - before.iterations;
      ++stats.intervals_integrated;
    }
    output(k, v, lev);
  }

  if (sens && options.log_parameters) {
    const auto theta = parameters.to_array();
    for (std::size_t k = 0; k < n; ++k)
      for (std::size_t j = 0; j < theta.size(); ++j)
        result.jacobian[LuGreParameters<double>::kSize * k + j] *= theta[j];
  }
  return result;
}

}  // namespace friction
