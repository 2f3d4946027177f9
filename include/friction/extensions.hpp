// Extension terms of methods.md section 7, as pieces that wrap any base friction model.
//
// A record with no hidden effect is a Maxwell Slip system; each effect of section 7 is added on top
// of a base model (MaxwellSlip, Dnlrx, Gms, LuGre, StaticFriction, ...) by `Extended<Base>`, whose
// parameters `ExtensionParameters<T>` hold one optional piece per effect, named as in section 7
// (what each effect is -- its names, units, boxes, starts -- is the table of effect_table.hpp).
// Pieces are independent and compose: any subset may be enabled.
//
// Two kinds of pieces (section 7):
//   * level effects scale the base's slip forces through `Motion::level` (thresholds Delta_i in
//     Maxwell Slip and DNLRX, s(v) in LuGre, alpha_i g(v) in GMS, g(v) in the static curve).  An
//     added term would make the force jump at every reversal; a scaled slip force does not, because
//     in presliding the operators are inside their thresholds and do not feel the level.  The level
//     passed to the base is the product
//         L = level_in * L_stribeck * L_position * L_drift * L_normal
//     floored at kMinimumLevel so that the base never sees a non-positive slip force; the
//     asymmetry makes the slip forces depend on the direction (Motion::asymmetry);
//   * added terms (viscous, offset, inertia) are summed to the base's force.
//
// F0 is the reference force: the base's nominal sliding level (MaxwellSlip sum k_i Delta_i, DNLRX
// sum theta_{i,j} Delta_i, GMS / LuGre / static Fc), taken from the base's parameters unless
// `reference_force` is given.  The pieces, with v_l the (possibly lagged) velocity:
//
//   viscous              + sigma2 v_l                                    `viscous` [N s/m]
//   stribeck             L *= 1 + (Fs/F0 - 1) exp(-(|v_l|/vs)^q)         `static` [N] (the force
//                        at rest: Fs relative to the base's F0), `stribeck_velocity` [m/s],
//                        `stribeck_exponent` [-]; the curve g(v)/F0 of section 5 (stribeck.hpp)
//   frictional-lag       v_l follows v through a first-order lag, dv_l/dt = (v - v_l)/tau,
//                        `lag_time` tau [s]; it feeds the stribeck and viscous pieces (without one
//                        of them it has no effect).  Exact for v linear between the sample
//                        instants (a record's fitted derivative; slope s = (v_k - v_{k-1})/dt,
//                        e = exp(-dt/tau)): v_l,k = v_k - s tau + (v_l,k-1 - v_{k-1} + s tau) e,
//                        and for the causal step's constant interval velocity
//                        v_l,k = v_k + (v_l,k-1 - v_k) e.  The lag starts at
//                        the first sample's velocity plus an offset u = v_l(t_0) - v(t_0) (0
//                        unless set_initial_lag_offset sets it): a record cut from longer motion
//                        starts with the lag's memory of that motion, which a fit estimates with
//                        the other initial states (extension_fit.hpp)
//   asymmetry            slip limits (1 + a) in +x and (1 - a) in -x (Motion::asymmetry),
//                        `asymmetry` a = (F+ - F-)/(F+ + F-) in (-1, 1)
//   offset               + c                                             `offset` [N]
//   inertia              + m a                                           `mass` [kg]
//   position-dependence  L *= 1 + (A/F0) sin(2 pi x / lambda + phi)      `amplitude` A [N],
//                        `wavelength` lambda [m], `phase` phi [rad]; x is the absolute position
//   drift                L *= 1 + r t, t the time since the record's start  `relative_rate` [1/s]
//   delay                the force lags the displacement by D: the base and every piece see the
//                        motion at t - D (the normal force and time t are not shifted)  `delay` [s]
//   normal-load          L *= mu N(t) / F0, i.e. N(t)/N_ref with N_ref = F0/mu
//                        `friction_coefficient` mu = F0/N_ref [-]; factor 1 when no normal force
//
// Asymmetry: direction-dependent slip limits.  Each element slips at (1 + a) L its nominal slip
// force moving in +x and at (1 - a) L moving in -x: an asperity whose friction coefficient depends
// on the direction of slip.  For a Maxwell Slip operator that is the box
// [-(1 - a) L Delta_i, (1 + a) L Delta_i]: no jump at a reversal (the box does not move), and the
// sliding levels are (1 +- a) F0.  While L is constant the box is a G + [-G, G] (G = L Delta_i):
// the force is exactly a symmetric model plus the constant a L F0, in sliding, in presliding and
// at rest, so an asymmetry and an offset are the same force until the level changes (a Stribeck
// curve, a drift, a position term, a normal load) -- which is what effect_table.hpp names as the
// excitation that separates the two.  (An earlier form switched a symmetric level with a
// continuous direction indicator; it put presliding loops "centred" at zero force, which no
// physical asymmetry does, and fitted a record made with direction-dependent limits worse than an
// offset: 6.6 times the floor against 1.0 on the discovery study's records.)
//
// Initial state.  A base's initial state (e.g. Maxwell Slip's deflections, set through base())
// is given at level 1, relative to the nominal slip limits, and the first step after a reset scales
// it by the level of that step (bases with a `scale_state`; Maxwell Slip has one).  Why: a record
// that starts at rest after sliding, with a Stribeck curve, starts with its operators at
// Fs/F0 times their nominal limits; a state clamped to the nominal box cannot hold that force,
// and the free run paid for it for hundreds of samples (a discovery-study record: 90 % of the
// estimation RSS in its first 450 samples, the fit 22 times the floor).  Given relative to the
// limits the record starts with, the state's box is the feasible set at the first sample whatever
// the level (a Stribeck curve at rest, a position term, a normal load), and an estimator needs no
// bound that depends on the parameters.
//
// Differentiators: which velocity each part uses (sample_derivatives.hpp says why).  The base
// model steps with the increment dx_k and the interval velocity dx_k/dt_k (Maxwell Slip and DNLRX
// use only dx; LuGre's and GMS's exact steps are written for a constant velocity over the
// interval).  The pieces use a velocity and an acceleration at the sample instant t_k
// (ExtendedMotion::piece_velocity, acceleration): on a record, `simulate_extended` takes them from
// local quadratic fits whose windows the record's own spectrum decides (choose_derivative_windows;
// a delay's shifted record is differentiated by the same filters); per sample, `step(Motion)` --
// what a controller calls -- has only the past, so there the pieces use the backward difference
// v_k = dx_k / dt_k and the causal second difference a_k = (v_k - v_{k-1}) / ((dt_k + dt_{k-1})/2),
// half a sample and one sample late.  What that costs a controller: sigma2 (Ts/2) a from a viscous
// term and about m Ts j from an inertia term (j the jerk).
//
// Delay.  On a record the displacement at t_k - D is interpolated by the cubic through the four
// samples around it (linearly in the first and last interval), for either sign of D; outside the
// record it is extrapolated by the quadratic through the edge sample fitted to the samples there
// (EdgePolynomial); velocity and acceleration are then differentiated from the shifted record.  Per
// sample (causal, D >= 0 only; a negative delay is ignored there) a ring of the last
// `delay_capacity` samples (allocated at construction) interpolates x and the provided acceleration
// linearly (the cubic would need a sample that has not come yet when D is below two samples); a
// delay longer than the ring holds the oldest sample.  The two differ by about w (1 - w) Ts^2 a / 2
// in x (w the fraction of the interval).
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string_view>
#include <type_traits>
#include <tuple>
#include <utility>
#include <vector>

#include "friction/effect_table.hpp"
#include "friction/error.hpp"
#include "friction/model_concept.hpp"
#include "friction/motion.hpp"
#include "friction/record.hpp"
#include "friction/record_fingerprint.hpp"
#include "friction/sample_derivatives.hpp"
#include "friction/scalar.hpp"
#include "friction/stribeck.hpp"

namespace friction {

// The pieces' parameters.  Member names are methods.md section 7's (`static` -> static_force).

template <typename T>
struct ViscousExtension {
  T viscous{0};  ///< sigma2 [N s/m], >= 0
  auto fields() { return std::tie(viscous); }
  auto fields() const { return std::tie(viscous); }
};
template <typename T>
struct StribeckExtension {
  T static_force{0};          ///< "static": the force at rest [N], > 0 (vs the base's F0)
  T stribeck_velocity{1e-3};  ///< vs [m/s], > 0
  T stribeck_exponent{2.0};   ///< q [-], > 0
  auto fields() { return std::tie(static_force, stribeck_velocity, stribeck_exponent); }
  auto fields() const { return std::tie(static_force, stribeck_velocity, stribeck_exponent); }
};
template <typename T>
struct FrictionalLagExtension {
  T lag_time{0};  ///< tau [s], >= 0 (0: no lag)
  auto fields() { return std::tie(lag_time); }
  auto fields() const { return std::tie(lag_time); }
};
template <typename T>
struct AsymmetryExtension {
  T asymmetry{0};  ///< a = (F+ - F-)/(F+ + F-), in (-1, 1)
  auto fields() { return std::tie(asymmetry); }
  auto fields() const { return std::tie(asymmetry); }
};
template <typename T>
struct OffsetExtension {
  T offset{0};  ///< c [N]
  auto fields() { return std::tie(offset); }
  auto fields() const { return std::tie(offset); }
};
template <typename T>
struct InertiaExtension {
  T mass{0};  ///< m [kg], >= 0
  auto fields() { return std::tie(mass); }
  auto fields() const { return std::tie(mass); }
};
template <typename T>
struct PositionExtension {
  T amplitude{0};   ///< A [N], |A| < F0
  T wavelength{1};  ///< lambda [m], > 0
  T phase{0};       ///< phi [rad]
  auto fields() { return std::tie(amplitude, wavelength, phase); }
  auto fields() const { return std::tie(amplitude, wavelength, phase); }
};
template <typename T>
struct DriftExtension {
  T relative_rate{0};  ///< r [1/s]
  auto fields() { return std::tie(relative_rate); }
  auto fields() const { return std::tie(relative_rate); }
};
template <typename T>
struct DelayExtension {
  T delay{0};  ///< D [s], > 0 when the force lags the displacement
  auto fields() { return std::tie(delay); }
  auto fields() const { return std::tie(delay); }
};
template <typename T>
struct NormalLoadExtension {
  T friction_coefficient{1};  ///< mu = F0 / N_ref [-], > 0
  auto fields() { return std::tie(friction_coefficient); }
  auto fields() const { return std::tie(friction_coefficient); }
};

// Each piece lists its members (fields()) in the order of its parameters in the effect table.
namespace detail {
template <class Piece>
constexpr std::size_t field_count = std::tuple_size_v<decltype(std::declval<Piece&>().fields())>;
}  // namespace detail
static_assert(detail::field_count<ViscousExtension<double>> ==
              effect_info(Effect::viscous).parameters.size());
static_assert(detail::field_count<StribeckExtension<double>> ==
              effect_info(Effect::stribeck).parameters.size());
static_assert(detail::field_count<FrictionalLagExtension<double>> ==
              effect_info(Effect::frictional_lag).parameters.size());
static_assert(detail::field_count<AsymmetryExtension<double>> ==
              effect_info(Effect::asymmetry).parameters.size());
static_assert(detail::field_count<OffsetExtension<double>> ==
              effect_info(Effect::offset).parameters.size());
static_assert(detail::field_count<InertiaExtension<double>> ==
              effect_info(Effect::inertia).parameters.size());
static_assert(detail::field_count<PositionExtension<double>> ==
              effect_info(Effect::position_dependence).parameters.size());
static_assert(detail::field_count<DriftExtension<double>> ==
              effect_info(Effect::drift).parameters.size());
static_assert(detail::field_count<DelayExtension<double>> ==
              effect_info(Effect::delay).parameters.size());
static_assert(detail::field_count<NormalLoadExtension<double>> ==
              effect_info(Effect::normal_load).parameters.size());

/// The enabled extension pieces and their parameters.
template <typename T>
struct ExtensionParameters {
  std::optional<ViscousExtension<T>> viscous;
  std::optional<StribeckExtension<T>> stribeck;
  std::optional<FrictionalLagExtension<T>> frictional_lag;
  std::optional<AsymmetryExtension<T>> asymmetry;
  std::optional<OffsetExtension<T>> offset;
  std::optional<InertiaExtension<T>> inertia;
  std::optional<PositionExtension<T>> position_dependence;
  std::optional<DriftExtension<T>> drift;
  std::optional<DelayExtension<T>> delay;
  std::optional<NormalLoadExtension<T>> normal_load;
  /// F0 [N], the base's sliding level that `static`, `amplitude` and `friction_coefficient` refer
  /// to; 0 takes it from the base's parameters (see Extended).
  T reference_force{0};

  bool has(Effect e) const noexcept {
    bool on = false;
    visit_piece(*this, e, [&](const auto& piece) { on = piece.has_value(); });
    return on;
  }
  /// Enables a piece with its default parameters (no-op when already enabled).
  void enable(Effect e) {
    visit_piece(*this, e, [](auto& piece) {
      if (!piece) piece.emplace();
    });
  }
  void disable(Effect e) {
    visit_piece(*this, e, [](auto& piece) { piece.reset(); });
  }
  bool empty() const noexcept {
    for (Effect e : kAllEffects)
      if (has(e)) return false;
    return true;
  }

  /// Calls f(Effect, std::string_view name, T& value) for every parameter of every enabled piece,
  /// in the order of kAllEffects and then of the members; names are methods.md section 7's.
  template <class F>
  void for_each_parameter(F&& f) {
    for_each_parameter_impl(*this, f);
  }
  template <class F>
  void for_each_parameter(F&& f) const {
    for_each_parameter_impl(*this, f);
  }

  /// Sets the parameters of effect e's (enabled) piece from `values`, in the order of the effect
  /// table; values beyond the piece's parameters are ignored.
  void assign(Effect e, std::span<const T> values) {
    std::size_t i = 0;
    for_each_parameter([&](Effect pe, std::string_view, T& v) {
      if (pe == e && i < values.size()) v = values[i++];
    });
  }

  /// Number of parameters of the enabled pieces.
  std::size_t parameter_count() const {
    std::size_t n = 0;
    for_each_parameter([&](Effect, std::string_view, const T&) { ++n; });
    return n;
  }

  /// The same pieces with every value converted by `convert` (e.g. double -> Jet).
  template <typename U, class Convert>
  ExtensionParameters<U> cast(Convert&& convert) const {
    ExtensionParameters<U> out;
    for (Effect e : kAllEffects)
      if (has(e)) out.enable(e);
    std::vector<U*> targets;
    out.for_each_parameter([&](Effect, std::string_view, U& v) { targets.push_back(&v); });
    std::size_t k = 0;
    for_each_parameter([&](Effect, std::string_view, const T& v) { *targets[k++] = convert(v); });
    out.reference_force = convert(reference_force);
    return out;
  }

  /// Throws InvalidParameter for values outside each piece's domain (see the members).  Checks that
  /// need F0 (|amplitude| < F0) are made by Extended.
  void validate() const {
    auto finite = [](const T& v) { return std::isfinite(value_of(v)); };
    for_each_parameter([&](Effect e, std::string_view name, const T& v) {
      FRICTION_CHECK(finite(v), "extension ", effect_name(e), ": ", name, " is not finite");
    });
    const double f0 = value_of(reference_force);
    FRICTION_CHECK(std::isfinite(f0) && f0 >= 0.0, "extensions: reference_force = ", f0,
                   " N must be finite and >= 0 (0: the base's sliding force)");
    if (viscous)
      FRICTION_CHECK(value_of(viscous->viscous) >= 0.0,
                     "extension viscous: viscous = ", value_of(viscous->viscous),
                     " N s/m must be >= 0");
    if (stribeck) {
      FRICTION_CHECK(value_of(stribeck->static_force) > 0.0,
                     "extension stribeck: static = ", value_of(stribeck->static_force),
                     " N must be > 0");
      FRICTION_CHECK(value_of(stribeck->stribeck_velocity) > 0.0,
                     "extension stribeck: stribeck_velocity must be > 0");
      FRICTION_CHECK(value_of(stribeck->stribeck_exponent) > 0.0,
                     "extension stribeck: stribeck_exponent must be > 0");
    }
    if (frictional_lag)
      FRICTION_CHECK(value_of(frictional_lag->lag_time) >= 0.0,
                     "extension frictional-lag: lag_time = ", value_of(frictional_lag->lag_time),
                     " s must be >= 0");
    if (asymmetry)
      FRICTION_CHECK(std::abs(value_of(asymmetry->asymmetry)) < 1.0,
                     "extension asymmetry: asymmetry = ", value_of(asymmetry->asymmetry),
                     " must lie in (-1, 1)");
    if (inertia)
      FRICTION_CHECK(value_of(inertia->mass) >= 0.0,
                     "extension inertia: mass = ", value_of(inertia->mass), " kg must be >= 0");
    if (position_dependence)
      FRICTION_CHECK(value_of(position_dependence->wavelength) > 0.0,
                     "extension position-dependence: wavelength = ",
                     value_of(position_dependence->wavelength), " m must be > 0");
    if (normal_load)
      FRICTION_CHECK(value_of(normal_load->friction_coefficient) > 0.0,
                     "extension normal-load: friction_coefficient = ",
                     value_of(normal_load->friction_coefficient), " must be > 0");
  }

 private:
  // Every parameter of every enabled piece, named by the effect table (the members of a piece are
  // listed by its fields(), in the table's order).
  template <class Self, class F>
  static void for_each_parameter_impl(Self& s, F& f) {
    for (Effect e : kAllEffects)
      visit_piece(s, e, [&](auto& piece) {
        if (!piece) return;
        const auto names = effect_info(e).parameters;
        std::size_t i = 0;
        std::apply([&](auto&... member) { (f(e, names[i++].name, member), ...); }, piece->fields());
      });
  }
};

/// The per-sample context of an extended model: the motion over the interval (t_{k-1}, t_k].
template <typename T>
struct ExtendedMotion {
  T x{0};               ///< displacement at t_k [m] (absolute: position-dependence uses it)
  T dx{0};              ///< x_k - x_{k-1} [m]
  T velocity{0};        ///< [m/s], dx / dt: the interval velocity the base model steps with
  T piece_velocity{0};  ///< [m/s], the velocity the pieces use at t_k (see the header)
  /// piece_velocity is a value at the instant t_k, linear between samples (a record's fitted
  /// derivative); false: the interval's constant velocity (the causal step).  The lag's exact step
  /// differs between the two.
  bool piece_velocity_at_instant = false;
  T acceleration{0};  ///< [m/s^2]
  T dt{0};            ///< t_k - t_{k-1} [s]; 0 for the first sample
  double time = 0.0;  ///< t_k - t_0, time since the start [s]
  T normal{0};        ///< normal force N [N], when has_normal
  bool has_normal = false;
  T level{1};  ///< external slip-force scale factor, multiplied with the level pieces
  T turn{0};   ///< increment to an extremum inside the interval (Motion::turn); 0: none
};

namespace detail {
/// F0 of a base model: its parameters' sliding_force() if any, else their Coulomb level.
template <class Base>
auto base_sliding_force(const Base& base) -> typename Base::Scalar {
  using T = typename Base::Scalar;
  if constexpr (requires { base.parameters().sliding_force(); }) {
    return T(base.parameters().sliding_force());
  } else if constexpr (requires { base.parameters().coulomb; }) {
    return T(base.parameters().coulomb);
  } else {
    return T(0);
  }
}
}  // namespace detail

/// A base friction model with extension pieces; itself a FrictionModel.
template <class Base>
class Extended {
 public:
  using Scalar = typename Base::Scalar;
  using T = Scalar;
  using Parameters = ExtensionParameters<T>;

  /// Smallest level handed to the base (keeps slip forces positive, e.g. under a strong drift).
  static constexpr double kMinimumLevel = 1e-6;

  /// `delay_capacity`: samples kept for the per-sample delay (allocated only with a delay piece).
  Extended(Base base, Parameters extensions, std::size_t delay_capacity = 1024)
      : base_(std::move(base)), p_(std::move(extensions)) {
    static_assert(FrictionModel<Base>, "Extended<Base> needs a friction model as its base");
    p_.validate();
    f0_ =
        value_of(p_.reference_force) > 0.0 ? p_.reference_force : detail::base_sliding_force(base_);
    const bool needs_f0 = p_.stribeck || p_.asymmetry || p_.position_dependence || p_.normal_load;
    FRICTION_CHECK(!needs_f0 || value_of(f0_) > 0.0,
                   "extensions: the base has no positive sliding force; give reference_force");
    if (p_.position_dependence)
      FRICTION_CHECK(std::abs(value_of(p_.position_dependence->amplitude)) < value_of(f0_),
                     "extension position-dependence: |amplitude| = ",
                     std::abs(value_of(p_.position_dependence->amplitude)),
                     " N must be below the sliding force F0 = ", value_of(f0_), " N");
    if (p_.delay) {
      FRICTION_CHECK(delay_capacity >= 2, "extension delay: delay_capacity must be >= 2");
      ring_time_.assign(delay_capacity, 0.0);
      ring_x_.assign(delay_capacity, T(0));
      ring_a_.assign(delay_capacity, T(0));
    }
    reset_extension_state();
  }

  const Base& base() const noexcept { return base_; }
  Base& base() noexcept { return base_; }
  const Parameters& extensions() const noexcept { return p_; }
  /// The asymmetry piece's a (0 without one): what the base's initial state is clamped with.
  T asymmetry() const noexcept { return p_.asymmetry ? p_.asymmetry->asymmetry : T(0); }
  /// F0 [N] (see the header comment).
  const T& reference_force() const noexcept { return f0_; }

  /// Virgin base and extension states.
  void reset() {
    base_.reset();
    reset_extension_state();
  }

  /// The base's state set through base() is relative to the slip limits at `level` rather than at
  /// the first step's level (header: Initial state): the first step scales it by `level`, then
  /// clamps it to its own limits as every step does.  Until the next reset.
  void set_initial_state_level(const T& level) noexcept {
    initial_level_ = level;
    fixed_initial_level_ = true;
  }

  /// The frictional-lag piece's initial state: v_l at the first sample is that sample's velocity
  /// plus `offset` [m/s] (header: frictional-lag).  Why an offset rather than v_l itself: 0 is the
  /// lag in step with the motion, the natural start of an estimate, whatever the record's speed.
  /// Until the next reset.
  void set_initial_lag_offset(const T& offset) noexcept { initial_lag_offset_ = offset; }

  /// The velocity stage of the level, for a caller that runs the same pieces many times on one
  /// record with only pieces after that stage changed (the profiled starts, extension_fit.hpp):
  /// each step's lag velocity v_l and Stribeck factor 1 + (Fs/F0 - 1) w(v_l) are appended to
  /// `lagged` and `factor` (record), or read from them in order instead of computed (replay).
  /// They depend on the lag, the Stribeck curve, the lag's initial offset and the record's
  /// velocity only, so a replay on the same record with those the same gives the same force, bit
  /// for bit; a step beyond what was recorded computes them again.  The vectors must outlive the
  /// run (reserve a recording's: a step is noexcept); steps keep appending or reading across
  /// reset_extension_state, which restarts the count.
  /// Double only: a Jet's lanes are not recorded.
  void record_velocity_stage(std::vector<double>& lagged, std::vector<double>& factor) noexcept
    requires std::is_same_v<T, double>
  {
    stage_record_lagged_ = &lagged;
    stage_record_factor_ = &factor;
    stage_replay_lagged_ = {};
    stage_replay_factor_ = {};
  }
  void replay_velocity_stage(std::span<const double> lagged,
                             std::span<const double> factor) noexcept
    requires std::is_same_v<T, double>
  {
    stage_replay_lagged_ = lagged.first(std::min(lagged.size(), factor.size()));
    stage_replay_factor_ = factor.first(stage_replay_lagged_.size());
    stage_record_lagged_ = stage_record_factor_ = nullptr;
  }

  /// Extension states only (lag, direction, delay ring, accumulated x and t): keeps a base state
  /// set through base().
  void reset_extension_state() {
    lagged_velocity_ = T(0);
    lag_started_ = false;
    initial_lag_offset_ = T(0);
    previous_piece_velocity_ = T(0);
    level_ = T(1);
    turn_level_ = T(1);
    first_step_ = true;
    fixed_initial_level_ = false;
    x_ = T(0);
    time_ = 0.0;
    previous_velocity_ = T(0);
    previous_dt_ = 0.0;
    ring_count_ = 0;
    ring_head_ = 0;
    delayed_x_started_ = false;
    delayed_x_ = T(0);
    stage_step_ = 0;
  }

  /// The FrictionModel interface: builds the context from the increments (see the header).
  T step(const Motion<T>& m) noexcept {
    ExtendedMotion<T> c;
    const double dt = value_of(m.dt);
    x_ += m.dx;
    time_ += dt;
    c.x = x_;
    c.dx = m.dx;
    c.turn = m.turn;
    c.velocity = m.velocity;
    c.piece_velocity = m.velocity;  // causal: the backward difference
    c.dt = m.dt;
    c.time = time_;
    c.level = m.level;
    if (dt > 0.0) {
      if (previous_dt_ > 0.0)
        c.acceleration = (m.velocity - previous_velocity_) / (0.5 * (dt + previous_dt_));
      previous_velocity_ = m.velocity;
      previous_dt_ = dt;
    }
    return step(c);
  }

  /// One sample with the full context; applies the per-sample delay (D >= 0) first.
  T step(const ExtendedMotion<T>& c) noexcept {
    if (!p_.delay || ring_time_.empty()) return step_shifted(c);
    ExtendedMotion<T> d = c;
    push_ring(c.time, c.x, c.acceleration);
    const T shift = value_of(p_.delay->delay) > 0.0 ? p_.delay->delay : T(0);
    interpolate_ring(T(c.time) - shift, d.x, d.acceleration);
    if (!delayed_x_started_) {
      delayed_x_ = d.x;
      delayed_x_started_ = true;
    }
    d.dx = d.x - delayed_x_;
    d.turn = T(0);  // causal: the delayed displacement's next sample is not known yet
    delayed_x_ = d.x;
    d.velocity = value_of(c.dt) > 0.0 ? T(d.dx / c.dt) : T(0);
    d.piece_velocity = d.velocity;
    return step_shifted(d);
  }

  /// One sample whose context is already shifted by the delay (record-level simulation does it by
  /// interpolation): every piece but the delay.
  T step_shifted(const ExtendedMotion<T>& c) noexcept {
    using std::sin;
    T v = c.piece_velocity;
    T here(1);  // the Stribeck factor at v
    if (!replayed_velocity_stage(c, v, here)) computed_velocity_stage(c, v, here);

    // The level at t_k and, when the interval holds a turn, at the extremum (motion.hpp, The level
    // at the turn): there the motion stands still (the lagged velocity, when there is a lag, does
    // not: it is taken as at t_k) and the displacement is that of the extremum.
    const bool turns = value_of(c.turn) != 0.0;
    T level = c.level, at_turn = c.level;
    if (p_.stribeck) {
      level *= here;
      if (turns) at_turn *= p_.frictional_lag ? here : T(p_.stribeck->static_force / f0_);
    }
    if (p_.position_dependence) {
      const auto& pd = *p_.position_dependence;
      level *= T(1) + pd.amplitude / f0_ * sin(T(2.0 * M_PI) * c.x / pd.wavelength + pd.phase);
      if (turns) {
        const T x_turn = c.x - c.dx + c.turn;
        at_turn *=
            T(1) + pd.amplitude / f0_ * sin(T(2.0 * M_PI) * x_turn / pd.wavelength + pd.phase);
      }
    }
    if (p_.drift) {
      const T factor = T(1) + p_.drift->relative_rate * T(c.time);
      level *= factor;
      at_turn *= factor;
    }
    if (p_.normal_load && c.has_normal) {
      const T factor = p_.normal_load->friction_coefficient * c.normal / f0_;
      level *= factor;
      at_turn *= factor;
    }
    if (level < T(kMinimumLevel)) level = T(kMinimumLevel);
    if (at_turn < T(kMinimumLevel)) at_turn = T(kMinimumLevel);
    level_ = level;
    turn_level_ = turns ? at_turn : level;
    if (first_step_) {
      // The initial state is given at level 1 (header: Initial state).
      if constexpr (requires(Base & b, const T& l) { b.scale_state(l); })
        base_.scale_state(fixed_initial_level_ ? initial_level_ : level);
      first_step_ = false;
    }

    const T asymmetry = p_.asymmetry ? p_.asymmetry->asymmetry : T(0);
    const T base_force =
        base_.step(Motion<T>{c.dx, c.velocity, c.dt, level, asymmetry, c.turn, turn_level_});

    T force = base_force;
    if (p_.viscous) force += p_.viscous->viscous * v;
    if (p_.offset) force += p_.offset->offset;
    if (p_.inertia) force += p_.inertia->mass * c.acceleration;
    return force;
  }

  /// Level handed to the base at the last step.
  const T& level() const noexcept { return level_; }
  /// Level at the turn inside the last step's interval (motion.hpp, The level at the turn); the
  /// step's level when the interval holds no turn.
  const T& turn_level() const noexcept { return turn_level_; }
  /// Lagged velocity v_l of the frictional-lag piece after the last step (0 without that piece).
  const T& lagged_velocity() const noexcept { return lagged_velocity_; }

 private:
  void push_ring(double t, const T& x, const T& a) noexcept {
    const std::size_t cap = ring_time_.size();
    ring_head_ = ring_count_ == 0 ? 0 : (ring_head_ + 1 == cap ? 0 : ring_head_ + 1);
    ring_time_[ring_head_] = t;
    ring_x_[ring_head_] = x;
    ring_a_[ring_head_] = a;
    if (ring_count_ < cap) ++ring_count_;
  }

  // Linear interpolation of x and a at `target` over the ring, held at its ends.
  void interpolate_ring(const T& target, T& x, T& a) const noexcept {
    const std::size_t cap = ring_time_.size();
    const double tv = value_of(target);
    std::size_t newer = ring_head_;
    if (ring_time_[newer] <= tv) {
      x = ring_x_[newer];
      a = ring_a_[newer];
      return;
    }
    for (std::size_t j = 1; j < ring_count_; ++j) {
      const std::size_t older = newer == 0 ? cap - 1 : newer - 1;
      if (ring_time_[older] <= tv) {
        const T w = (target - ring_time_[older]) / (ring_time_[newer] - ring_time_[older]);
        x = ring_x_[older] + (ring_x_[newer] - ring_x_[older]) * w;
        a = ring_a_[older] + (ring_a_[newer] - ring_a_[older]) * w;
        return;
      }
      newer = older;
    }
    x = ring_x_[newer];  // older than the ring (or than the record): hold the oldest sample
    a = ring_a_[newer];
  }

  // The velocity stage of the next step, computed: the lag's velocity (from v, the pieces'
  // velocity, on entry) and the Stribeck factor at it, recorded when a recording is on.
  void computed_velocity_stage(const ExtendedMotion<T>& c, T& v, T& here) noexcept {
    const double dt = value_of(c.dt);
    if (p_.frictional_lag) {
      const T& tau = p_.frictional_lag->lag_time;
      if (value_of(tau) <= 0.0) {
        lagged_velocity_ = v;
        lag_started_ = true;
      } else if (!lag_started_) {
        lagged_velocity_ = v + initial_lag_offset_;
        lag_started_ = true;
      } else if (dt > 0.0 && c.piece_velocity_at_instant) {
        const T slope_tau = (v - previous_piece_velocity_) * tau / c.dt;
        lagged_velocity_ = v - slope_tau + (lagged_velocity_ - previous_piece_velocity_ +
                                            slope_tau) * lag_decay(c.dt, tau);
      } else if (dt > 0.0) {
        lagged_velocity_ = v + (lagged_velocity_ - v) * lag_decay(c.dt, tau);
      }
      previous_piece_velocity_ = v;
      v = lagged_velocity_;
    }
    if (p_.stribeck) {
      const auto& s = *p_.stribeck;
      here = T(1) + (s.static_force / f0_ - T(1)) *
                        stribeck_weight(v, s.stribeck_velocity, s.stribeck_exponent);
    }
    if constexpr (std::is_same_v<T, double>) {
      if (stage_record_lagged_) {
        stage_record_lagged_->push_back(v);
        stage_record_factor_->push_back(here);
      }
    }
  }

  // The velocity stage of the next step from a replay (replay_velocity_stage): v and the factor,
  // with the lag's state as the step would have left it.  False: none (left to compute).
  bool replayed_velocity_stage(const ExtendedMotion<T>& c, T& v, T& here) noexcept {
    if constexpr (std::is_same_v<T, double>) {
      if (stage_step_ < stage_replay_lagged_.size()) {
        v = stage_replay_lagged_[stage_step_];
        here = stage_replay_factor_[stage_step_];
        ++stage_step_;
        if (p_.frictional_lag) {
          lagged_velocity_ = v;
          lag_started_ = true;
          previous_piece_velocity_ = c.piece_velocity;
        }
        return true;
      }
    }
    return false;
  }

  // exp(-dt / tau) of the frictional lag over an interval dt.  The pieces are fixed for the
  // object's life (constructor) and a record's dt carries no derivative (motion.hpp), so the factor
  // is a function of dt's value alone: it is kept for the last dt, which on a uniformly sampled
  // record is every step's.  The exponential of each step was 2 % of a diagnosis of data/.
  T lag_decay(const T& dt, const T& tau) {
    using std::exp;
    if constexpr (requires { dt.v.isZero(); })
      if (!dt.v.isZero()) return exp(-dt / tau);  // a dt with derivatives: not cached
    const double d = value_of(dt);
    if (!(d == lag_decay_dt_)) {
      lag_decay_ = exp(-dt / tau);
      lag_decay_dt_ = d;
    }
    return lag_decay_;
  }

  Base base_;
  Parameters p_;
  T f0_{0};
  double lag_decay_dt_ = std::numeric_limits<double>::quiet_NaN();  // dt of lag_decay_
  T lag_decay_{0};
  // The velocity stage recorded or replayed (record_velocity_stage, replay_velocity_stage).
  std::vector<double>* stage_record_lagged_ = nullptr;
  std::vector<double>* stage_record_factor_ = nullptr;
  std::span<const double> stage_replay_lagged_, stage_replay_factor_;
  std::size_t stage_step_ = 0;
  // Extension states.
  T lagged_velocity_{0};
  bool lag_started_ = false;
  T initial_lag_offset_{0};
  T previous_piece_velocity_{0};
  T level_{1};
  T turn_level_{1};
  bool first_step_ = true;            // the next step scales the base's state by its level
  bool fixed_initial_level_ = false;  // ... or by initial_level_
  T initial_level_{1};
  // step(Motion) accumulators.
  T x_{0};
  double time_ = 0.0;
  T previous_velocity_{0};
  double previous_dt_ = 0.0;
  // Per-sample delay ring.
  std::vector<double> ring_time_;
  std::vector<T> ring_x_;
  std::vector<T> ring_a_;
  std::size_t ring_head_ = 0;
  std::size_t ring_count_ = 0;
  bool delayed_x_started_ = false;
  T delayed_x_{0};
};

namespace detail {
/// interpolate_displacement on samples given by `x(i)` of a record of n samples.
template <typename T, class Sample>
T interpolate_displacement_at(std::span<const double> time, const Sample& x, std::size_t n,
                           std::size_t j, const T& target) {
  if (j == 0 || j + 2 >= n) {
    const T w = (target - time[j]) / (time[j + 1] - time[j]);
    return x(j) + (x(j + 1) - x(j)) * w;
  }
  // Lagrange weights of the samples j-1 .. j+2 at the target time.
  const double t0 = time[j - 1], t1 = time[j], t2 = time[j + 1], t3 = time[j + 2];
  const T d0 = target - t0, d1 = target - t1, d2 = target - t2, d3 = target - t3;
  return x(j - 1) * (d1 * d2 * d3 / ((t0 - t1) * (t0 - t2) * (t0 - t3))) +
         x(j) * (d0 * d2 * d3 / ((t1 - t0) * (t1 - t2) * (t1 - t3))) +
         x(j + 1) * (d0 * d1 * d3 / ((t2 - t0) * (t2 - t1) * (t2 - t3))) +
         x(j + 2) * (d0 * d1 * d2 / ((t3 - t0) * (t3 - t1) * (t3 - t2)));
}
}  // namespace detail

/// The displacement at `target`, time[j] <= target < time[j + 1] (j + 1 < x.size()): the cubic
/// through samples j-1 .. j+2, linear in the first and last interval (delayed_displacement_into
/// says why cubic).
template <typename T>
T interpolate_displacement(std::span<const double> time, std::span<const T> x, std::size_t j,
                           const T& target) {
  return detail::interpolate_displacement_at<T>(
      time, [&](std::size_t i) -> const T& { return x[i]; }, x.size(), j, target);
}

/// The quadratic through the edge sample of a record (`front` or back) whose slope and curvature
/// fit the `length` samples at that edge by least squares, in u = t - t_edge:
/// x ~ x_edge + c[1] u + c[2] u^2.  Through the edge sample, so that the displacement stays
/// continuous in D where the target crosses it (a jump there is a jump in a fit's cost).  Two
/// samples: the line through them; one: the constant.
struct EdgePolynomial {
  double edge_time = 0;
  double reach = 0;  ///< how far outside the record it is used [s]: its own length
  std::array<double, 3> c{};
  template <typename T>
  T at(const T& t) const {
    // Beyond its own length the quadratic would be a guess: held at its value there.
    const double lo = edge_time - reach, hi = edge_time + reach;
    const T u = (value_of(t) < lo ? T(lo) : value_of(t) > hi ? T(hi) : t) - edge_time;
    return T(c[0]) + u * (T(c[1]) + u * T(c[2]));
  }
};

template <typename T>
EdgePolynomial edge_polynomial(std::span<const double> time, std::span<const T> x, bool front,
                               std::size_t length) {
  const std::size_t n = x.size();
  length = std::min(std::max<std::size_t>(length, 1), n);
  EdgePolynomial p;
  const std::size_t e = front ? 0 : n - 1;
  p.edge_time = time[e];
  p.c[0] = value_of(x[e]);
  if (length == 1) return p;
  p.reach = std::abs(time[front ? length - 1 : n - length] - p.edge_time);
  // Normal equations of (c1, c2) in u / reach (well scaled: |u| <= 1).
  double a11 = 0, a12 = 0, a22 = 0, b1 = 0, b2 = 0;
  for (std::size_t i = 1; i < length; ++i) {
    const std::size_t k = front ? i : n - 1 - i;
    const double u = (time[k] - p.edge_time) / p.reach, d = value_of(x[k]) - p.c[0];
    a11 += u * u, a12 += u * u * u, a22 += u * u * u * u;
    b1 += u * d, b2 += u * u * d;
  }
  double c1 = b1 / a11, c2 = 0;
  if (length >= 3) {
    const double det = a11 * a22 - a12 * a12;
    c1 = (b1 * a22 - b2 * a12) / det;
    c2 = (a11 * b2 - a12 * b1) / det;
  }
  p.c[1] = c1 / p.reach;
  p.c[2] = c2 / (p.reach * p.reach);
  return p;
}

/// delayed_displacement_into one sample at a time, k = 0, 1, ... in order (what a record
/// streamed through a short buffer uses).  `X`: the scalar of the displacement given (double, or
/// T itself); its samples become T where they are used.
template <typename T, typename X = T>
class DelayedDisplacement {
 public:
  DelayedDisplacement(std::span<const double> time, std::span<const X> x, const T& delay,
                      std::size_t edge_length)
      : time_(time), x_(x), delay_(delay), edge_length_(edge_length),
        // A delay of exactly 0 that carries derivatives still needs them (d x(t - D) / dD = -v):
        // a fit started at D = 0 saw a zero gradient and never left it (36 times the floor on a
        // record with D = 0.3 samples).
        shifted_(!(value_of(delay) == 0.0 && !has_derivative(delay))) {}

  /// Whether the displacement is shifted at all (false: x itself).
  bool shifted() const { return shifted_; }

  T at(std::size_t k) {
    if (!shifted_) return T(x_[k]);
    const std::size_t n = x_.size();
    const T target = T(time_[k]) - delay_;
    const double tv = value_of(target);
    if (tv <= time_.front()) {
      if (edge_length_ == 0) return T(x_.front());
      if (!first_) first_ = edge_polynomial(time_, x_, true, edge_length_);
      return first_->at(target);
    }
    if (tv >= time_.back()) {
      if (edge_length_ == 0) return T(x_.back());
      if (!last_) last_ = edge_polynomial(time_, x_, false, edge_length_);
      return last_->at(target);
    }
    while (j_ + 1 < n && time_[j_ + 1] <= tv) ++j_;  // time[j] <= target < time[j + 1]
    return detail::interpolate_displacement_at<T>(
        time_, [&](std::size_t i) { return T(x_[i]); }, n, j_, target);
  }

 private:
  std::span<const double> time_;
  std::span<const X> x_;
  T delay_;
  std::size_t edge_length_;
  bool shifted_;
  std::optional<EdgePolynomial> first_, last_;
  std::size_t j_ = 0;  // targets increase with k
};

/// The displacement at t_k - D, interpolated by the cubic through the four samples around it
/// (linearly in the first and last interval), and outside the record extrapolated by the quadratic
/// through the edge sample fitted to the `edge_length` samples there (header: Delay); x itself
/// when D = 0.  Why cubic: linear interpolation at the fraction w of an interval is short of x by
/// about w (1 - w) Ts^2 a / 2, a force error proportional to the acceleration that a fitted model
/// paid for with a spurious mass beside a delay (0.047 kg beside a 1.7 ms delay on a test record,
/// named as an inertia); the cubic's error is of order Ts^4.  Why extrapolated: the first D / Ts
/// forces of a record were made by motion before it; held at the first sample, the model's force
/// there stood still while the recorded one moved (validation RSS/SSS 0.0187 % against 0.0005 %
/// now on a noise-free record of the study's simulator with D = 3 samples).  `edge_length`: the
/// record's velocity window (2m + 1 samples, sample_derivatives.hpp), the estimator whose
/// polynomial at the edge this continues; 0 holds the edge sample.
template <typename T>
void delayed_displacement_into(std::span<const double> time, std::span<const T> x, const T& delay,
                               std::vector<T>& xs, std::size_t edge_length = 0) {
  const std::size_t n = x.size();
  DelayedDisplacement<T> shifted(time, x, delay, edge_length);
  if (!shifted.shifted()) {
    xs.assign(x.begin(), x.end());
    return;
  }
  xs.resize(n);
  for (std::size_t k = 0; k < n; ++k) xs[k] = shifted.at(k);
}

template <typename T>
std::vector<T> delayed_displacement(std::span<const double> time, std::span<const T> x,
                                    const T& delay, std::size_t edge_length = 0) {
  std::vector<T> xs;
  delayed_displacement_into(time, x, delay, xs, edge_length);
  return xs;
}

/// The derivative windows of a record: chosen on the displacement as measured, and applied to the
/// one the models see (sample_derivatives.hpp, "The displacement the models see").
inline DerivativeWindows record_derivative_windows(const Record& r) {
  return record_derivative_windows(r.time, r.measured());
}

/// The samples a delay's extrapolation fits at a record's edge: the velocity window, 2m + 1.
inline std::size_t delay_edge_length(const DerivativeWindows& w) {
  return 2 * w.velocity_half_width + 1;
}

/// The displacement a model's base sees on a record: x(t - D) under a delay, continued before the
/// record by the polynomial of its velocity window (delayed_displacement_into), else the record's
/// own.  Whatever is estimated for the base alone (its initial state, NLR's operators) is
/// estimated on this: on the record as recorded it would belong to motion D later.
inline std::vector<double> displacement_the_base_sees(const Record& r,
                                                      const ExtensionParameters<double>& ext,
                                                      const DerivativeWindows& windows) {
  std::vector<double> x;
  delayed_displacement_into(std::span<const double>(r.time),
                            std::span<const double>(r.displacement),
                            ext.delay ? ext.delay->delay : 0.0, x,
                            ext.delay ? delay_edge_length(windows) : 0);
  return x;
}

namespace detail {
/// The velocity and acceleration filtered from the last undelayed displacement that
/// for_each_extended_step stepped through on this thread, with the fingerprint of the time and
/// displacement they came from: a fit simulates the same record with the same displacement at
/// every evaluation, and filtering it anew cost a fourteenth of a diagnosis.  One per thread for
/// every scalar type (the numbers are doubles): 16 bytes per sample.  It kept copies of the time
/// and displacement to compare, 16 bytes a sample more per thread, held by every thread that ever
/// stepped a model (at 10^5 samples two of them were 7 % of a diagnosis' peak).
struct FilteredDisplacement {
  std::vector<double> velocity, acceleration;
  RecordFingerprint fingerprint;
  std::size_t samples = 0;
  DerivativeWindows windows;
  bool valid = false;
  bool busy = false;  // a step is filling or reading it (a visitor that stepped again would not)
};
inline FilteredDisplacement& filtered_displacement() {
  thread_local FilteredDisplacement cache;
  return cache;
}
/// While one lives, for_each_extended_step on this thread neither reads nor fills the cache: for
/// a one-off run on a grid of its own (a finer one, say), whose filter nobody asks for again and
/// whose length the cache's buffers would otherwise keep for the thread's lifetime.
class UncachedSteps {
 public:
  UncachedSteps() : was_(filtered_displacement().busy) { filtered_displacement().busy = true; }
  UncachedSteps(const UncachedSteps&) = delete;
  UncachedSteps& operator=(const UncachedSteps&) = delete;
  ~UncachedSteps() { filtered_displacement().busy = was_; }

 private:
  bool was_;
};
}  // namespace detail

/// Steps an extended model over a record, calling visit(k, context, force) after every sample
/// (the model's state, e.g. its base's deflections and its lagged velocity, is that of sample k
/// then).  What simulate_extended does; the profiles of extension_profile.cpp read the operators'
/// deflections through it, so that they see exactly the model they start.  `measured`: the
/// displacement as measured when `x` is its estimate (Record::measured_displacement; empty
/// otherwise): the pieces' velocity and acceleration come from it, with the windows chosen on it,
/// and the model's displacement from `x` (sample_derivatives.hpp, "The displacement the models
/// see").  `x` may be given in double for a model on Jets (its samples become Jets where used).
///
/// The record is streamed: the shifted displacement is made a sample at a time, a few windows
/// ahead of the sample stepped, into a ring of a few windows' length, so that nothing of the
/// record's length is allocated per call (a fit of 10^6 samples on ceres::Jet<double, 16> kept
/// five record-long buffers of 136 bytes a sample per thread and scalar type).
template <class Base, typename X, class Visit>
void for_each_extended_step(Extended<Base>& model, std::span<const double> time,
                            std::span<const X> x, std::span<const double> normal,
                            const DerivativeWindows* windows, Visit&& visit,
                            std::span<const double> measured = {}) {
  using T = typename Base::Scalar;
  static_assert(std::is_same_v<X, T> || std::is_same_v<X, double>,
                "for_each_extended_step: the displacement is in the model's scalar or in double");
  const std::size_t n = x.size();
  FRICTION_CHECK(time.size() == n, "simulate_extended: time and displacement differ in length");
  FRICTION_CHECK(normal.empty() || normal.size() == n,
                 "simulate_extended: the normal force must be empty or as long as the record");
  const auto& p = model.extensions();
  FRICTION_CHECK(!p.normal_load || !normal.empty(),
                 "simulate_extended: the normal-load extension needs a normal force record");
  FRICTION_CHECK(measured.empty() || measured.size() == n,
                 "simulate_extended: the measured displacement must be empty or as long as x");
  if (n == 0) return;
  // The pieces' velocity and acceleration at the sample instants (header: Differentiators), with
  // the record's windows; the base's interval velocity dx/dt.
  DerivativeWindows own;
  if (!windows) {
    std::vector<double> xd(n);
    for (std::size_t k = 0; k < n; ++k) xd[k] = measured.empty() ? value_of(x[k]) : measured[k];
    own = record_derivative_windows(time, xd);
    windows = &own;
  }
  const T delay = p.delay ? p.delay->delay : T(0);
  const std::size_t edge = delay_edge_length(*windows);
  DelayedDisplacement<T, X> shifted_x(time, x, delay, edge);  // what the model moves by
  std::optional<DelayedDisplacement<T, double>> shifted_measured;  // what is differentiated
  if (!measured.empty()) shifted_measured.emplace(time, measured, delay, edge);
  const bool shifted = shifted_x.shifted();
  // A displacement without derivative parts (every fit but a delay's) is filtered as doubles:
  // the same numbers at a sixteenth of a Jet<16>'s cost, which was a fifth of a diagnosis.
  bool jets = shifted && has_derivative(delay);
  if constexpr (!std::is_same_v<X, double>)
    if (measured.empty())
      jets = jets || std::any_of(x.begin(), x.end(), [](const X& s) { return has_derivative(s); });
  // The undelayed displacement's filter is reused from the last call on this thread when time,
  // displacement and windows are equal to the last element.
  detail::FilteredDisplacement* cache = nullptr;
  bool cached = false;
  struct Release {
    detail::FilteredDisplacement* c = nullptr;
    ~Release() {
      if (c) c->busy = false;
    }
  } release;
  if (!jets && !shifted && !detail::filtered_displacement().busy) {
    cache = release.c = &detail::filtered_displacement();
    cache->busy = true;
    const detail::RecordFingerprint print = detail::fingerprint_of(
        time, n, [&](std::size_t k) { return measured.empty() ? value_of(x[k]) : measured[k]; });
    cached = cache->valid && cache->samples == n && cache->windows == *windows &&
             cache->fingerprint == print;
    if (!cached) {
      cache->valid = false;  // until every sample is filtered
      cache->fingerprint = print;
      cache->samples = n;
      cache->velocity.resize(n), cache->acceleration.resize(n);
    }
  }
  LocalPolynomialWeights velocity_weights(time, *windows, 1),
      acceleration_weights(time, *windows, 2);
  // Sample k reads the shifted displacement at k - 2 .. k + 1 (increment, turn) and its windows
  // at most 2m on either side (windows at the record's ends are shifted inside it).
  const std::size_t reach =
      std::max({velocity_weights.reach(), acceleration_weights.reach(), std::size_t{2}});
  const std::size_t ring = std::bit_ceil(2 * reach + 4), mask = ring - 1;
  // Rings reused per thread and scalar type: a fit simulates the same record hundreds of times.
  thread_local std::vector<T> xs, ds;
  thread_local std::vector<double> dd;
  xs.resize(std::max(xs.size(), ring));
  if (jets) ds.resize(std::max(ds.size(), ring));
  if (!jets && !cached) dd.resize(std::max(dd.size(), ring));
  std::size_t produced = 0;
  auto produce = [&](std::size_t upto) {
    for (; produced < upto; ++produced) {
      const std::size_t i = produced & mask;
      xs[i] = shifted_x.at(produced);
      if (jets) {
        ds[i] = shifted_measured ? shifted_measured->at(produced) : xs[i];
      } else if (!cached) {
        dd[i] = shifted_measured ? value_of(shifted_measured->at(produced)) : value_of(xs[i]);
      }
    }
  };
  // A derivative at sample k from the ring of the samples it is taken of.
  auto filtered = [&](LocalPolynomialWeights& weights, const auto& values, std::size_t k) {
    using V = std::decay_t<decltype(values[0])>;
    if (weights.trivial()) return V(0);
    return weights.filter(k, V(0), [&](std::size_t i) -> const V& { return values[i & mask]; });
  };
  // Unshifted and filtered before (every evaluation of a fit but a delay's after the first): the
  // samples are read where they are, and nothing is made ahead.
  const bool direct = !shifted && cached;
  auto step_all = [&](const auto& xs_at) {
    for (std::size_t k = 0; k < n; ++k) {
      if (!direct) produce(std::min(n, k + reach + 2));
      T velocity(0), acceleration(0);
      if (cached) {
        velocity = T(cache->velocity[k]);
        acceleration = T(cache->acceleration[k]);
      } else if (jets) {
        velocity = filtered(velocity_weights, ds, k);
        acceleration = filtered(acceleration_weights, ds, k);
      } else {
        const double vk = filtered(velocity_weights, dd, k);
        const double ak = filtered(acceleration_weights, dd, k);
        if (cache) cache->velocity[k] = vk, cache->acceleration[k] = ak;
        velocity = T(vk);
        acceleration = T(ak);
      }
      ExtendedMotion<T> c;
      c.x = xs_at(k);
      c.dx = k > 0 ? T(xs_at(k) - xs_at(k - 1)) : T(0);
      c.turn = detail::turn_increment_at<T>(xs_at, n, k);
      c.velocity = k > 0 ? T(c.dx / (time[k] - time[k - 1])) : T(0);
      c.piece_velocity = velocity;
      c.piece_velocity_at_instant = true;
      c.acceleration = acceleration;
      c.dt = k > 0 ? T(time[k] - time[k - 1]) : T(0);
      c.time = time[k] - time.front();
      if (!normal.empty()) {
        c.normal = T(normal[k]);
        c.has_normal = true;
      }
      const T force = model.step_shifted(c);
      visit(k, c, force);
    }
  };
  if (direct) {
    step_all([&](std::size_t i) -> decltype(auto) {
      if constexpr (std::is_same_v<X, T>)
        return (x[i]);
      else
        return T(x[i]);
    });
  } else {
    step_all([&](std::size_t i) -> const T& { return xs[i & mask]; });
  }
  if (cache && !cached) {
    cache->windows = *windows;
    cache->valid = true;
  }
}

/// Simulates an extended model on a record, from whatever state it is in (reset() it first):
/// displacement `x` [m] at `time` [s], optional `normal` force [N] (empty: none; required by a
/// normal-load piece), force [N] written to `force`.  Delay by interpolation, the pieces' velocity
/// and acceleration at the sample instants by the record's derivative windows (computed here when
/// `windows` is null), as the header comment says.
template <class Base, typename T = typename Base::Scalar>
void simulate_extended(Extended<Base>& model, std::span<const double> time, std::span<const T> x,
                       std::span<const double> normal, std::span<T> force,
                       const DerivativeWindows* windows = nullptr,
                       std::span<const double> measured = {}) {
  FRICTION_CHECK(force.size() == x.size(),
                 "simulate_extended: time, displacement and force must have the same length");
  for_each_extended_step(
      model, time, x, normal, windows,
      [&](std::size_t k, const ExtendedMotion<T>&, const T& f) { force[k] = f; }, measured);
}

/// Convenience overload returning the simulated force.
template <class Base, typename T = typename Base::Scalar>
std::vector<T> simulate_extended(Extended<Base>& model, std::span<const double> time,
                                 std::span<const T> x, std::span<const double> normal = {},
                                 const DerivativeWindows* windows = nullptr,
                                 std::span<const double> measured = {}) {
  std::vector<T> force(x.size());
  simulate_extended(model, time, x, normal, std::span<T>(force), windows, measured);
  return force;
}

}  // namespace friction
