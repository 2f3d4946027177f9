// Profiled starts of the extension pieces (extension_fit.hpp, effect_table.hpp: Profiles).
//
// A local fit is only as good as its start: the Stribeck level of a record with a peak 1.6 times
// its Coulomb level, started from a regression of the residual, stayed at the baseline's error
// (3.086 %) and ended at vs = 1.5e-9 m/s; an inertia started from a diluted regression ended at
// 141 kg for ~3400 kg.  So no nonlinear parameter starts from a guess: each is started at the best
// point of a grid over its physical range, and at every point the parameters in which the model is
// linear -- the stiffnesses (F = sum k_i delta_i) and the added terms (viscous, offset, mass) --
// are solved exactly, by bounded least squares on the operators' deflections and the added terms'
// signals.  The deflections come from the model itself (for_each_extended_step with unit
// stiffnesses), so the level effects, the asymmetry, the lag and the delay act on them exactly as
// in the fit that follows.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "friction/extension_fit.hpp"
#include "friction/identification.hpp"
#include "friction/metrics.hpp"
#include "friction/stribeck.hpp"
#include "slip_regression.hpp"

namespace friction {

namespace {

// The columns of one grid point: deflections of unit-stiffness operators (M), then the added
// terms the pieces hold, in the order viscous, offset, inertia.
struct Columns {
  Eigen::MatrixXd a;
  Eigen::VectorXd lo, hi;
  bool viscous = false, offset = false, inertia = false;
};

// The velocity stage of a profile's state (Extended::record_velocity_stage): the lag's velocity
// and the Stribeck factor of every sample, the same at each grid point of a piece that comes after
// them in the level.  On data/ they were half of a position-dependence profile once the state held
// a lag on a Stribeck curve (0.27-0.30 s for 384 points, against 0.13 s without them).
struct VelocityStage {
  std::vector<double> lagged, factor;
  bool recorded = false;
};

// `stage`: null, or the stage to replay once recorded (by this call when not yet).
void fill_columns(const Record& r, const std::vector<double>& thresholds,
                  const std::vector<double>& rho, double rho_level,
                  const ExtensionParameters<double>& ext, const DerivativeWindows& windows,
                  Columns& c, VelocityStage* stage = nullptr) {
  const std::size_t m = thresholds.size(), n = r.size();
  c.viscous = ext.viscous.has_value();
  c.offset = ext.offset.has_value();
  c.inertia = ext.inertia.has_value();
  const std::size_t p = m + c.viscous + c.offset + c.inertia;
  c.a.resize(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(p));
  c.lo = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(p));
  c.hi = Eigen::VectorXd::Constant(static_cast<Eigen::Index>(p),
                                   std::numeric_limits<double>::infinity());
  MaxwellSlipParameters<double> unit;
  unit.stiffness.assign(m, 1.0);
  unit.threshold = thresholds;
  Extended<MaxwellSlip<double>> model(MaxwellSlip<double>(unit), ext, 2);
  set_extended_slip_state(model, std::span<const double>(deflections_from_relative(unit, rho, ext)));
  // The deflections of the model the state comes from (relative to its first level), whatever
  // level the profiled piece starts the record with: every grid point starts from the same
  // operators (extensions.hpp, Initial state).
  model.set_initial_state_level(rho_level);
  if (stage && stage->recorded) {
    model.replay_velocity_stage(stage->lagged, stage->factor);
  } else if (stage) {
    stage->lagged.clear();
    stage->factor.clear();
    stage->lagged.reserve(n);
    stage->factor.reserve(n);
    model.record_velocity_stage(stage->lagged, stage->factor);
  }
  const bool lag = ext.frictional_lag.has_value();
  for_each_extended_step(
      model, std::span<const double>(r.time), std::span<const double>(r.displacement),
      std::span<const double>(r.normal), &windows,
      [&](std::size_t k, const ExtendedMotion<double>& ctx, double) {
        const auto row = static_cast<Eigen::Index>(k);
        const auto d = model.base().deflections();
        for (std::size_t i = 0; i < m; ++i) c.a(row, static_cast<Eigen::Index>(i)) = d[i];
        Eigen::Index j = static_cast<Eigen::Index>(m);
        if (c.viscous) c.a(row, j++) = lag ? model.lagged_velocity() : ctx.piece_velocity;
        if (c.offset) c.a(row, j++) = 1.0;
        if (c.inertia) c.a(row, j++) = ctx.acceleration;
      },
      std::span<const double>(r.measured_displacement));
  if (stage) stage->recorded = true;
  if (c.offset) {
    const Eigen::Index j = static_cast<Eigen::Index>(m + c.viscous);
    c.lo[j] = -std::numeric_limits<double>::infinity();
  }
}

// Starts of position-dependence from a fine scan of its wavelength.  The grid of profile_axes
// (16 wavelengths, log) is too coarse for a record whose travel holds many periods: across the
// travel T a relative error e of the wavelength shifts the far end's phase by 2 pi e T / lambda,
// so a grid point 10 % off a wavelength of T / 6 is a quarter period out of step at the far end
// and fits little of it (a study record: wavelength 2.8 um in 15.7 um of travel, the coarse
// profile's best point at 0.64 um, the fit 77x the noise floor).  Linearised in the amplitude, the
// effect is the base's force sensitivity to its level g(t) (here: the force of the operators at
// their slip limits) times (A / F0) sin(2 pi x / lambda + phi), i.e. g sin(theta) and g cos(theta)
// with linear coefficients.  So every wavelength of a grid fine enough to stay within an eighth
// of a period over the travel (relative step lambda / (8 T); at most 1000 points) costs one
// regression of the base's residual on those two signals, and the three best local maxima of
// the explained sum of squares, with their amplitude and phase, are evaluated as starts beside
// the coarse grid.
std::vector<PositionExtension<double>> position_scan(
    const Record& r, const MaxwellSlipParameters<double>& base, const std::vector<double>& rho,
    double rho_level, const ExtensionParameters<double>& ext, const DerivativeWindows& windows,
    const ProfileScales& s) {
  const double f0 = ext.reference_force, travel = s.travel;
  const double lo = 10 * s.sample_travel;
  if (!(f0 > 0) || !(lo > 0) || !(travel > lo)) return {};
  ExtensionParameters<double> flat = ext;
  flat.position_dependence->amplitude = 0.0;
  flat.position_dependence->wavelength = travel;
  flat.position_dependence->phase = 0.0;
  Columns c;
  fill_columns(r, base.threshold, rho, rho_level, flat, windows, c);
  const Eigen::Index n = c.a.rows();
  const Eigen::Map<const Eigen::VectorXd> f(r.force.data(), n);
  const Eigen::VectorXd z = detail::box_least_squares(c.a, f, c.lo, c.hi);
  const Eigen::VectorXd res = f - c.a * z;
  const std::size_t m = base.size();
  Eigen::VectorXd g = Eigen::VectorXd::Zero(n);
  std::vector<char> saturated(m, 0);
  for (Eigen::Index k = 1; k < n; ++k) {
    const double dx = r.displacement[static_cast<std::size_t>(k)] -
                      r.displacement[static_cast<std::size_t>(k - 1)];
    for (std::size_t i = 0; i < m; ++i) {
      const Eigen::Index col = static_cast<Eigen::Index>(i);
      // Clipped: its deflection did not follow the displacement (held at a limit that moved
      // with the level, or stopped at it).  At rest the operator keeps its state.
      if (dx != 0.0)
        saturated[i] = std::abs(c.a(k, col) - c.a(k - 1, col) - dx) > 1e-9 * std::abs(dx);
      if (saturated[i]) g(k) += z(col) * c.a(k, col);
    }
  }
  if (!(g.squaredNorm() > 0)) return {};
  constexpr std::size_t kMaxPoints = 1000;
  const double floor_step = std::pow(travel / lo, 1.0 / static_cast<double>(kMaxPoints));
  std::vector<double> grid;
  for (double l = lo; l <= travel; l *= std::max(1.0 + l / (8.0 * travel), floor_step))
    grid.push_back(l);
  struct Fit {
    double explained, alpha, beta;
  };
  std::vector<Fit> fits;
  Eigen::VectorXd a1(n), a2(n);
  for (double l : grid) {
    for (Eigen::Index k = 0; k < n; ++k) {
      const double theta = 2.0 * M_PI * r.displacement[static_cast<std::size_t>(k)] / l;
      a1(k) = g(k) * std::sin(theta);
      a2(k) = g(k) * std::cos(theta);
    }
    const double g11 = a1.squaredNorm(), g12 = a1.dot(a2), g22 = a2.squaredNorm();
    const double b1 = a1.dot(res), b2 = a2.dot(res);
    const double det = g11 * g22 - g12 * g12;
    if (!(det > 1e-12 * g11 * g22)) {
      fits.push_back({0.0, 0.0, 0.0});
      continue;
    }
    const double alpha = (g22 * b1 - g12 * b2) / det, beta = (g11 * b2 - g12 * b1) / det;
    fits.push_back({alpha * b1 + beta * b2, alpha, beta});
  }
  std::vector<std::size_t> peaks;
  for (std::size_t j = 0; j < fits.size(); ++j) {
    const bool left = j == 0 || fits[j].explained >= fits[j - 1].explained;
    const bool right = j + 1 == fits.size() || fits[j].explained > fits[j + 1].explained;
    if (left && right && fits[j].explained > 0) peaks.push_back(j);
  }
  std::sort(peaks.begin(), peaks.end(),
            [&](std::size_t a, std::size_t b) { return fits[a].explained > fits[b].explained; });
  std::vector<PositionExtension<double>> out;
  for (std::size_t q = 0; q < peaks.size() && q < 3; ++q) {
    const Fit& fit = fits[peaks[q]];
    PositionExtension<double> pd;
    pd.wavelength = grid[peaks[q]];
    // level = 1 + (A / F0) sin(theta + phi) = 1 + (A / F0) (cos phi sin theta + sin phi cos theta)
    pd.amplitude = std::min(f0 * std::hypot(fit.alpha, fit.beta), 0.5 * f0);
    pd.phase = std::atan2(fit.beta, fit.alpha);
    if (pd.phase < 0) pd.phase += 2.0 * M_PI;
    out.push_back(pd);
  }
  return out;
}

}  // namespace

ProfileScales profile_scales(const Record& r, const ExtendedSlipRun& run, double reference_force) {
  ProfileScales s;
  const std::size_t n = r.size();
  s.reference_force = reference_force;
  s.duration = record_duration(r);
  s.sample_period = n > 1 ? s.duration / static_cast<double>(n - 1) : 1.0;
  std::vector<double> sliding, moving, steps;
  for (std::size_t k = 1; k < n; ++k) {
    const double v = std::abs(run.velocity[k]),
                 dx = std::abs(r.displacement[k] - r.displacement[k - 1]);
    if (dx > 0) {
      moving.push_back(v);
      steps.push_back(dx);
    }
    if (run.sliding[k] && v > 0) sliding.push_back(v);
  }
  // The speeds while sliding, or while moving when they reach higher: "sliding" is every
  // operator at its bound, and a base with an operator that saturates only at the ends of the
  // travel (a threshold at the largest travel: a linear spring) flags only the slow ends of the
  // strokes (a study record: 1.0e-6 m/s against 3.1e-4 m/s moving, and the Stribeck profile
  // ended 100x below the true vs).
  const double moving_95 = nearest_rank_quantile(moving, 0.95);
  s.sliding_speed_95 =
      sliding.size() >= 20 ? std::max(nearest_rank_quantile(sliding, 0.95), moving_95) : moving_95;
  const double moving_50 = nearest_rank_quantile(moving, 0.5);
  s.sliding_speed_50 =
      sliding.size() >= 20 ? std::max(nearest_rank_quantile(sliding, 0.5), moving_50) : moving_50;
  s.sample_travel = nearest_rank_quantile(steps, 0.5);
  const auto [lo, hi] = std::minmax_element(r.displacement.begin(), r.displacement.end());
  s.travel = *hi - *lo;
  // Reversals with a hysteresis of three resolution steps (identification.hpp's detector).
  const double h = std::max(3 * displacement_resolution(r.measured()), 1e-4 * s.travel);
  const std::vector<std::size_t> turns = turning_points(r.displacement, h);
  // Between extremes only: the detector also returns the first and the last sample.
  s.reversal_interval = s.duration;
  s.longest_reversal_interval = 0;
  for (std::size_t i = 2; i + 1 < turns.size(); ++i) {
    const double interval = r.time[turns[i]] - r.time[turns[i - 1]];
    s.reversal_interval = std::min(s.reversal_interval, interval);
    s.longest_reversal_interval = std::max(s.longest_reversal_interval, interval);
  }
  if (!(s.longest_reversal_interval > 0)) s.longest_reversal_interval = s.duration;
  return s;
}

ProfiledStart profile_start(const Record& r, const MaxwellSlipParameters<double>& base,
                            const std::vector<double>& rho, double rho_level,
                            const ExtensionParameters<double>& ext, Effect profiled,
                            const DerivativeWindows& windows, const ProfileScales& scales,
                            bool told) {
  FRICTION_CHECK(r.has_force() && r.size() >= 3, "profile_start: the record needs force");
  ExtensionParameters<double> point = ext;
  if (!(point.reference_force > 0)) point.reference_force = base.sliding_force();
  if (point.normal_load && r.has_normal()) {
    const double mean =
        std::accumulate(r.normal.begin(), r.normal.end(), 0.0) / static_cast<double>(r.size());
    point.normal_load->friction_coefficient = point.reference_force / mean;
  }
  ProfileScales s = scales;
  s.reference_force = point.reference_force;
  const std::vector<ProfileAxis> axes = profile_axes(profiled, s);
  const Eigen::Map<const Eigen::VectorXd> f(r.force.data(), static_cast<Eigen::Index>(r.size()));

  ProfiledStart best;
  best.rss = std::numeric_limits<double>::infinity();
  Columns c;
  detail::BoxLeastSquaresStorage storage;
  std::string last_rejection;
  std::vector<double> scaled_thresholds;
  // The state's lag and Stribeck curve are the same at every grid point of a piece that neither
  // is nor moves the velocity they follow (the delay does).
  VelocityStage stage;
  const bool shared_stage = (point.frictional_lag || point.stribeck) &&
                            profiled != Effect::frictional_lag && profiled != Effect::stribeck &&
                            profiled != Effect::delay;
  // `scale` multiplies the base's thresholds (the told Stribeck pass below).
  auto evaluate = [&](const ExtensionParameters<double>& at_point, double scale = 1.0) {
    try {
      at_point.validate();
      scaled_thresholds = base.threshold;
      for (double& d : scaled_thresholds) d *= scale;
      fill_columns(r, scaled_thresholds, rho, rho_level, at_point, windows, c,
                   shared_stage ? &stage : nullptr);
      const Eigen::VectorXd z = detail::box_least_squares(c.a, f, c.lo, c.hi, nullptr, &storage);
      const double rss = (f - c.a * z).squaredNorm();
      ++best.points;
      if (rss < best.rss) {
        best.rss = rss;
        best.ext = at_point;
        best.base = base;
        best.base.threshold = scaled_thresholds;
        const std::size_t m = base.size();
        double largest = 0;
        for (std::size_t i = 0; i < m; ++i)
          largest = std::max(largest, z[static_cast<Eigen::Index>(i)]);
        // An operator the data want at zero keeps a negligible positive stiffness (it is fitted
        // in log k).
        for (std::size_t i = 0; i < m; ++i)
          best.base.stiffness[i] =
              std::max(z[static_cast<Eigen::Index>(i)], 1e-9 * std::max(largest, 1e-300));
        Eigen::Index j = static_cast<Eigen::Index>(m);
        if (c.viscous) best.ext.viscous->viscous = z[j++];
        if (c.offset) best.ext.offset->offset = z[j++];
        if (c.inertia) best.ext.inertia->mass = z[j++];
      }
    } catch (const InvalidParameter& e) {
      // A grid point outside a piece's domain (e.g. a level that vanishes): skipped.
      if (last_rejection.empty()) last_rejection = e.what();
    }
  };
  std::vector<std::size_t> at(axes.size(), 0);
  for (;;) {
    for (std::size_t a = 0; a < axes.size(); ++a)
      point.for_each_parameter([&](Effect e, std::string_view name, double& v) {
        if (e == profiled && name == axes[a].parameter) v = axes[a].values[at[a]];
      });
    evaluate(point);
    std::size_t a = 0;
    while (a < axes.size() && ++at[a] == axes[a].values.size()) at[a++] = 0;
    if (a == axes.size()) break;
  }
  // Only for a piece the user asked for (`identify --extension`): the diagnosis weighs a
  // candidate's gain against what the coarse grid's few hundred trials can find in noise and model
  // mismatch, and a thousand wavelengths more find more of it (on data/, a GMS record without any
  // position effect, the diagnosis with the scan named position-dependence beside its three true
  // effects).
  if (told && profiled == Effect::position_dependence && point.position_dependence) {
    std::vector<PositionExtension<double>> scanned;
    try {
      scanned = position_scan(r, base, rho, rho_level, point, windows, s);
    } catch (const InvalidParameter&) {
      // The base with the piece at zero amplitude outside another piece's domain: the coarse
      // grid's points stand alone.
    }
    for (const PositionExtension<double>& pd : scanned) {
      ExtensionParameters<double> q = point;
      *q.position_dependence = pd;
      evaluate(q);
    }
  }
  // Also only for a piece the user asked for: a Stribeck curve whose velocity lies above the
  // speeds the record reaches.  Its level falls by (Fs - Fc)(v/vs)^delta over them, and a base
  // fitted without it has taken the level at the record's typical speed into its thresholds: the
  // curve is then a small rise above that base at low speeds *and* a Coulomb level below it, which
  // the grid above (the base's own sliding force as the curve's floor) cannot hold.  On a study
  // record (vs 3.8 times the 95th-percentile sliding speed, Fs/Fc 1.5, noise-free) its best point
  // was the smallest vs and the fit ended 0.0039 % of the force away from the data where the true
  // system is exact.  So the curve is tried again with the base's thresholds scaled by
  // c = 1 / (1 + (Fs/F0 - 1) w(v_50)), which keeps the level the base sees at the median sliding
  // speed v_50 where it was, and with vs reaching 10 times the 95th-percentile speed (same
  // logarithmic spacing as the grid above).
  if (told && profiled == Effect::stribeck && point.stribeck) {
    const double f0 = point.reference_force, v50 = std::max(s.sliding_speed_50, 1e-300);
    const std::vector<double> velocities =
        table_detail::log_grid(0.01 * s.sliding_speed_95, 10 * s.sliding_speed_95, 13);
    std::vector<double> exponents, statics;
    for (const ProfileAxis& a : axes) {
      if (a.parameter == "stribeck_exponent") exponents = a.values;
      if (a.parameter == "static") statics = a.values;
    }
    for (double vs : velocities)
      for (double delta : exponents)
        for (double fs : statics) {
          ExtensionParameters<double> q = point;
          q.stribeck->stribeck_velocity = vs;
          q.stribeck->stribeck_exponent = delta;
          q.stribeck->static_force = fs;
          const double typical = 1.0 + (fs / f0 - 1.0) * stribeck_weight(v50, vs, delta);
          evaluate(q, 1.0 / typical);
          if (vs > s.sliding_speed_95 * (1 + 1e-9)) evaluate(q);  // beyond the grid above
        }
  }
  FRICTION_CHECK(std::isfinite(best.rss), "profile_start: no grid point of ", effect_name(profiled),
                 " gave a usable model (the first rejected: ", last_rejection, ")");
  return best;
}

}  // namespace friction
