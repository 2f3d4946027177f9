// The effects of methods.md section 7, as one table: what each effect is, in one place.
//
// Everything the library knows about an effect -- its fixed name, its parameters (SI unit, the box
// they are fitted in as a rule over the record's scales, how they are fitted), whether it is an
// added term or a level effect, its signature in a residual, how a fit of it is started, the effect
// it is confused with under poor excitation and the excitation that separates the two, and the
// words a report uses -- is a row of kEffectTable or a function below that switches on Effect.  No
// other file switches on Effect: extensions.hpp computes the pieces, extension_fit.hpp fits them,
// diagnose.hpp decides which ones a record holds, and all of them read this table.  A change of how
// an effect is fitted (its box, its start, its parametrisation) is a change here.
//
// Kinds (methods.md 7).  Level effects (stribeck, asymmetry, position-dependence, drift,
// normal-load) scale the elements' slip forces; an added term would make the force jump at every
// reversal.  viscous, offset and inertia are added terms.  frictional-lag is a lag of the velocity
// that the viscous and Stribeck pieces see; delay shifts the motion that drives the model.
//
// Bounds.  A parameter's box is a rule over the record's scales (RecordScales: the reference force
// F0 of the level pieces, the record's duration T, its largest speed vmax), e.g. a
// stribeck_velocity between 1e-6 vmax and 10 vmax, a drift rate in [-0.9/T, 5/T] (the level stays
// positive over the record), a delay within T/10.  The rule is evaluated exactly as written in the
// row (factor times scale, or scale over factor), so the box is the same number wherever it is
// used.
//
// Residual signatures (evidence_signature).  The residual e = F - Fhat of a free run is regressed
// on each effect's signature beyond nuisance regressors that a refit of the thresholds absorbs
// anyway (a Coulomb level change d, the sliding direction); the share of e's sum of squares the
// signature explains ranks the candidates and its coefficient starts the fit:
//   offset 1;  viscous v while sliding (nuisance d);  asymmetry Fhat^2 / F0 (nuisance 1: the
//   level difference appears where the simulated force is large in either direction);  inertia a;
//   drift d F0 t (nuisance d);  delay dFhat/dt (the coefficient is the best shift of Fhat);
//   frictional-lag a while sliding (nuisance d and v while sliding);  stribeck
//   d exp(-(v/vs)^2) over a grid of vs (nuisance d);  position-dependence d sin, d cos(2 pi x / l)
//   over a grid of wavelengths l spanning the travel (nuisance d);  normal-load d N (nuisance d).
// The Stribeck signature is searched over vs on the 2-75 % quantiles of the sliding speeds and on
// a log grid from their 95 % quantile down by a factor 100 (stribeck_start_grid, the one grid of
// the library: diagnose and identify both start from it): on stroke records with rests, operators
// that stop at their thresholds count as sliding at |v| ~ 0, the low quantiles fall to ~1e-7 m/s,
// and a fit started there did not move (a Stribeck effect at 5.4 times the noise went unfound on
// one of six such records).  The grid points that start a fit (vs, and the wavelength and phase of
// the position term) are kept at 6 significant digits, the precision the evidence reports them
// with.
//
// Starts.  start_from_evidence starts a piece on a Maxwell Slip model from the evidence above
// (diagnose, and identify on a Maxwell Slip base).  start_from_regression starts a piece on a HELD
// LuGre or DNLRX base from plain regressions of that base's residual on each effect's variable
// (there is no regime from operator states to weigh by), with the same Stribeck grid.  Both return
// typed values (PieceStart), never text.  frictional-lag acts through a velocity piece: started on
// a model that has neither viscous nor Stribeck piece it brings a viscous companion.
//
// Ambiguity (methods.md 7).  offset and asymmetry while sliding, inertia and a position term under
// a single sinusoid, delay and frictional-lag, and viscous or Stribeck against a higher Coulomb
// level at a single speed: each row names its partner and the excitation that would separate them.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <initializer_list>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "friction/parametrisation.hpp"

namespace friction {

/// The extension pieces, one per effect of methods.md section 7 (`nonlocal-memory` is a number
/// of Maxwell Slip elements, not a piece).
enum class Effect {
  viscous,
  stribeck,
  frictional_lag,
  asymmetry,
  offset,
  inertia,
  position_dependence,
  drift,
  delay,
  normal_load,
};

inline constexpr std::size_t kEffectCount = 10;

inline constexpr std::array<Effect, kEffectCount> kAllEffects = {
    Effect::viscous, Effect::stribeck,   Effect::frictional_lag,      Effect::asymmetry,
    Effect::offset,  Effect::inertia,    Effect::position_dependence, Effect::drift,
    Effect::delay,   Effect::normal_load};

/// Order in which the residual evidence lists the signatures before ranking them (ties keep it).
inline constexpr std::array<Effect, kEffectCount> kEvidenceOrder = {
    Effect::offset,         Effect::viscous,  Effect::asymmetry,
    Effect::inertia,        Effect::drift,    Effect::delay,
    Effect::frictional_lag, Effect::stribeck, Effect::position_dependence,
    Effect::normal_load};

enum class EffectKind {
  added,         ///< a term summed to the base's force
  level,         ///< scales the elements' slip forces
  velocity_lag,  ///< lags the velocity the velocity pieces see
  time_shift,    ///< shifts the motion that drives the model
};

/// Scales of a record that a parameter's box refers to.
struct RecordScales {
  double reference_force = 0;  ///< F0 [N]
  double duration = 0;         ///< T [s]
  double largest_speed = 0;    ///< vmax [m/s]
};

/// One bound of a fitted parameter: a rule over the record's scales.
struct BoundRule {
  enum class Scale { constant, reference_force, largest_speed, duration_over, over_duration };
  Scale scale = Scale::constant;
  double factor = 0;
  /// constant: factor; reference_force / largest_speed: factor times it; duration_over: T /
  /// factor; over_duration: factor / T.
  constexpr double operator()(const RecordScales& s) const {
    switch (scale) {
      case Scale::constant:
        return factor;
      case Scale::reference_force:
        return factor * s.reference_force;
      case Scale::largest_speed:
        return factor * s.largest_speed;
      case Scale::duration_over:
        return s.duration / factor;
      case Scale::over_duration:
        return factor / s.duration;
    }
    return factor;
  }
};

namespace table_detail {
inline constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr BoundRule constant(double v) {
  return {BoundRule::Scale::constant, v};
}
constexpr BoundRule times_f0(double v) {
  return {BoundRule::Scale::reference_force, v};
}
constexpr BoundRule times_vmax(double v) {
  return {BoundRule::Scale::largest_speed, v};
}
constexpr BoundRule duration_over(double v) {
  return {BoundRule::Scale::duration_over, v};
}
constexpr BoundRule over_duration(double v) {
  return {BoundRule::Scale::over_duration, v};
}
}  // namespace table_detail

/// One parameter of a piece (methods.md 7 name, SI unit, box, parametrisation).
struct EffectParameter {
  std::string_view name;
  std::string_view unit;
  BoundRule lower;
  BoundRule upper;
  Parametrisation fitted = Parametrisation::linear;
  /// Expressed relative to the reference force F0 (converted when F0 changes).
  bool scales_with_reference_force = false;
};

/// The value of a piece's main parameter that means "no effect".
enum class NullValue {
  none,             ///< no null value (normal-load: mu only rescales the level)
  zero,             ///< 0
  reference_force,  ///< F0 (stribeck: static = F0 is a flat curve)
};

/// How the evidence reports the grid point a start came from.
enum class StartDetail { none, velocity, wavelength_phase, shift };

/// One row of the table.
struct EffectInfo {
  Effect effect;
  std::string_view name;  ///< methods.md 7
  EffectKind kind;
  std::span<const EffectParameter> parameters;  ///< in the order of the piece's members
  std::string_view main_parameter;  ///< what `--effect NAME=VALUE` sets; tested for evidence
  NullValue null_value;
  std::string_view in_the_data;   ///< methods.md 7, "in the data"
  std::string_view extension;     ///< how a finding extends the model
  std::optional<Effect> partner;  ///< confused with it under poor excitation
  /// viscous / Stribeck: confused with a higher Coulomb level when the speeds barely vary.
  bool ambiguous_with_coulomb_level = false;
  std::string_view separating_excitation;  ///< what separates it from its partner
  std::string_view would_establish;        ///< what an estimation record needs for it to act
  std::optional<Effect> reported_with;     ///< a companion reported with it (lag: viscous)
  bool needs_normal_force = false;
  StartDetail detail = StartDetail::none;
};

/// Name of the Coulomb-level alternative of the velocity pieces (a finding's `ambiguous_with`).
inline constexpr std::string_view kCoulombLevelAlternative = "a higher Coulomb level (thresholds)";

namespace table_detail {
using P = Parametrisation;
inline constexpr EffectParameter kViscous[] = {
    {"viscous", "N s/m", constant(0.0), constant(kInf), P::linear, false}};
inline constexpr EffectParameter kStribeck[] = {
    {"static", "N", times_f0(0.05), times_f0(20.0), P::linear, true},
    {"stribeck_velocity", "m/s", times_vmax(1e-6), times_vmax(10.0), P::linear, false},
    {"stribeck_exponent", "", constant(0.3), constant(5.0), P::linear, false}};
inline constexpr EffectParameter kLag[] = {
    {"lag_time", "s", constant(0.0), duration_over(4), P::linear, false}};
inline constexpr EffectParameter kAsymmetry[] = {
    {"asymmetry", "", constant(-0.9), constant(0.9), P::linear, false}};
inline constexpr EffectParameter kOffset[] = {
    {"offset", "N", constant(-kInf), constant(kInf), P::linear, false}};
inline constexpr EffectParameter kInertia[] = {
    {"mass", "kg", constant(0.0), constant(kInf), P::linear, false}};
inline constexpr EffectParameter kPosition[] = {
    {"amplitude", "N", times_f0(-0.9), times_f0(0.9), P::linear, true},
    {"wavelength", "m", constant(1e-12), constant(kInf), P::linear, false},
    {"phase", "rad", constant(-kInf), constant(kInf), P::linear, false}};
inline constexpr EffectParameter kDrift[] = {
    {"relative_rate", "1/s", over_duration(-0.9), over_duration(5.0), P::linear, false}};
inline constexpr EffectParameter kDelay[] = {
    {"delay", "s", duration_over(-10), duration_over(10), P::linear, false}};
inline constexpr EffectParameter kNormal[] = {
    {"friction_coefficient", "", constant(1e-12), constant(kInf), P::linear, true}};

inline constexpr std::string_view kSeveralSpeeds = "sliding at several constant speeds";
inline constexpr std::string_view kOffsetOrAsymmetry =
    "a change of the friction level along the record (a normal load that changes, sliding across "
    "a Stribeck curve's speeds): an asymmetry scales with the level, an offset does not; at a "
    "constant level the two are the same force, at rest and in presliding too";
inline constexpr std::string_view kInertiaOrPosition =
    "motion at several frequencies or amplitudes over the same travel (inertia follows the "
    "acceleration, a position term the position)";
inline constexpr std::string_view kDelayOrLag =
    "velocity steps while sliding and presliding reversals (a delay shifts presliding too, a "
    "frictional lag only acts while sliding)";
inline constexpr std::string_view kRestsAndBothDirections = "rests and sliding in both directions";
inline constexpr std::string_view kSpeedSteps = "sliding at several speeds, with speed steps";
}  // namespace table_detail

/// The table, in the order of the Effect enumeration.
inline constexpr std::array<EffectInfo, kEffectCount> kEffectTable = {{
    {Effect::viscous, "viscous", EffectKind::added, table_detail::kViscous, "viscous",
     NullValue::zero, "sliding friction grows with speed", "added viscous term sigma2 v",
     std::nullopt, true, table_detail::kSeveralSpeeds, table_detail::kSpeedSteps, std::nullopt,
     false, StartDetail::none},
    {Effect::stribeck, "stribeck", EffectKind::level, table_detail::kStribeck, "static",
     NullValue::reference_force, "sliding friction falls from a static peak as speed rises",
     "thresholds scaled by the Stribeck curve 1 + (Fs/F0 - 1) exp(-(|v|/vs)^q)", std::nullopt, true,
     table_detail::kSeveralSpeeds, table_detail::kSpeedSteps, std::nullopt, false,
     StartDetail::velocity},
    {Effect::frictional_lag, "frictional-lag", EffectKind::velocity_lag, table_detail::kLag,
     "lag_time", NullValue::zero,
     "friction lags velocity changes while sliding (loops in F against v)",
     "the velocity-dependent friction follows the velocity through a first-order lag",
     Effect::delay, false, table_detail::kDelayOrLag, table_detail::kSpeedSteps, Effect::viscous,
     false, StartDetail::none},
    {Effect::asymmetry, "asymmetry", EffectKind::level, table_detail::kAsymmetry, "asymmetry",
     NullValue::zero, "sliding levels differ by direction, presliding centred",
     "slip limits (1 + a) in +x and (1 - a) in -x (direction-dependent slip forces)",
     Effect::offset, false, table_detail::kOffsetOrAsymmetry, table_detail::kRestsAndBothDirections,
     std::nullopt, false, StartDetail::none},
    {Effect::offset, "offset", EffectKind::added, table_detail::kOffset, "offset", NullValue::zero,
     "a constant bias on every sample, at rest too", "added constant offset", Effect::asymmetry,
     false, table_detail::kOffsetOrAsymmetry, table_detail::kRestsAndBothDirections, std::nullopt,
     false, StartDetail::none},
    {Effect::inertia, "inertia", EffectKind::added, table_detail::kInertia, "mass", NullValue::zero,
     "the force contains m a (a drive force, not pure friction)", "added inertial term m a",
     Effect::position_dependence, false, table_detail::kInertiaOrPosition, "larger accelerations",
     std::nullopt, false, StartDetail::none},
    {Effect::position_dependence, "position-dependence", EffectKind::level, table_detail::kPosition,
     "amplitude", NullValue::zero, "friction varies along the travel",
     "thresholds scaled by 1 + (A/F0) sin(2 pi x / lambda + phi)", Effect::inertia, false,
     table_detail::kInertiaOrPosition, "several strokes over different positions", std::nullopt,
     false, StartDetail::wavelength_phase},
    {Effect::drift, "drift", EffectKind::level, table_detail::kDrift, "relative_rate",
     NullValue::zero, "the friction level changes slowly over the record",
     "thresholds scaled by 1 + r t", std::nullopt, false, "", "a longer record", std::nullopt,
     false, StartDetail::none},
    {Effect::delay, "delay", EffectKind::time_shift, table_detail::kDelay, "delay", NullValue::zero,
     "force and displacement shifted in time",
     "the model is driven by the displacement delayed by D", Effect::frictional_lag, false,
     table_detail::kDelayOrLag, "faster reversals", std::nullopt, false, StartDetail::shift},
    {Effect::normal_load, "normal-load", EffectKind::level, table_detail::kNormal,
     "friction_coefficient", NullValue::none,
     "friction follows a recorded normal force (needs that column)",
     "thresholds scaled by mu N(t) / F0 (friction proportional to the normal force)", std::nullopt,
     false, "", "changes of the normal load while it moves", std::nullopt, true, StartDetail::none},
}};

namespace table_detail {
constexpr bool rows_in_enum_order() {
  for (std::size_t i = 0; i < kEffectCount; ++i)
    if (static_cast<std::size_t>(kEffectTable[i].effect) != i ||
        kAllEffects[i] != kEffectTable[i].effect)
      return false;
  return true;
}
static_assert(rows_in_enum_order(), "kEffectTable must list the effects in enum order");
}  // namespace table_detail

constexpr const EffectInfo& effect_info(Effect e) noexcept {
  return kEffectTable[static_cast<std::size_t>(e)];
}

/// The fixed name of methods.md section 7 ("frictional-lag", "position-dependence", ...).
constexpr std::string_view effect_name(Effect e) noexcept {
  return effect_info(e).name;
}

/// The effect of a section 7 name; nullopt for unknown names (and for "nonlocal-memory").
constexpr std::optional<Effect> effect_from_name(std::string_view name) noexcept {
  for (const EffectInfo& row : kEffectTable)
    if (row.name == name) return row.effect;
  return std::nullopt;
}

/// True for the pieces that scale the slip forces (through Motion::level).
constexpr bool is_level_effect(Effect e) noexcept {
  return effect_info(e).kind == EffectKind::level;
}

/// The section 7 names, comma-separated, for messages.
inline std::string effect_names() {
  std::string s;
  for (const EffectInfo& row : kEffectTable) {
    if (!s.empty()) s += ", ";
    s += row.name;
  }
  return s;
}

/// A parameter of a piece by name; nullptr when the piece has no such parameter.
constexpr const EffectParameter* find_parameter(Effect e, std::string_view name) noexcept {
  for (const EffectParameter& p : effect_info(e).parameters)
    if (p.name == name) return &p;
  return nullptr;
}

/// SI unit of a piece parameter named as in methods.md 7 ("" when dimensionless or unknown).
constexpr std::string_view parameter_unit(std::string_view name) noexcept {
  for (const EffectInfo& row : kEffectTable)
    for (const EffectParameter& p : row.parameters)
      if (p.name == name) return p.unit;
  return "";
}

/// Calls f(piece) with the std::optional member of `pieces` (an ExtensionParameters) that holds
/// effect e's piece: the one map from Effect to the member.
template <class Pieces, class F>
void visit_piece(Pieces& pieces, Effect e, F&& f) {
  switch (e) {
    case Effect::viscous:
      f(pieces.viscous);
      return;
    case Effect::stribeck:
      f(pieces.stribeck);
      return;
    case Effect::frictional_lag:
      f(pieces.frictional_lag);
      return;
    case Effect::asymmetry:
      f(pieces.asymmetry);
      return;
    case Effect::offset:
      f(pieces.offset);
      return;
    case Effect::inertia:
      f(pieces.inertia);
      return;
    case Effect::position_dependence:
      f(pieces.position_dependence);
      return;
    case Effect::drift:
      f(pieces.drift);
      return;
    case Effect::delay:
      f(pieces.delay);
      return;
    case Effect::normal_load:
      f(pieces.normal_load);
      return;
  }
}

// ---------------------------------------------------------------------------------------------
// Residual signatures (see the header comment).

/// v rounded to `digits` significant decimal digits (the precision the evidence reports).
inline double to_significant_digits(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return std::strtod(buf, nullptr);
}

/// The per-sample signals of one record's residual analysis (all of the record's length, except
/// `normal`, which is empty without a normal force).
struct EvidenceSignals {
  std::span<const double> residual;      ///< e = F - Fhat [N]
  std::span<const double> simulated;     ///< Fhat [N]
  std::span<const double> velocity;      ///< [m/s]
  std::span<const double> acceleration;  ///< [m/s^2]
  std::span<const double> position;      ///< x [m]
  std::span<const double> time;          ///< since the record's start [s]
  std::span<const double> record_time;   ///< the record's own time stamps [s]
  std::span<const double> sliding;       ///< 1 sliding, 0 presliding (the model's operators)
  std::span<const double> direction;     ///< +1 / -1 sliding in +x / -x, 0 presliding
  std::span<const double> normal;        ///< N [N]
  double reference_force = 0;            ///< F0 [N]
};

/// Regressors of a signature: nuisance columns, then the effect's columns.
struct SignatureRegressors {
  std::vector<std::vector<double>> nuisance, effect;
};

/// The Stribeck start grid of vs from a record's sliding speeds (|v|, any order): the 2, 10, 25,
/// 50 and 75 % quantiles, then 8 points from the 95 % quantile down by a factor 100 (header
/// comment); empty without speeds.
inline std::vector<double> stribeck_start_grid(std::vector<double> speeds) {
  std::vector<double> grid;
  if (speeds.empty()) return grid;
  std::sort(speeds.begin(), speeds.end());
  const auto quantile = [&](double q) {
    return speeds[static_cast<std::size_t>(q * static_cast<double>(speeds.size() - 1))];
  };
  for (double q : {0.02, 0.1, 0.25, 0.5, 0.75}) grid.push_back(quantile(q));
  const double top = quantile(0.95);
  for (int g = 0; g < 8; ++g) grid.push_back(top * std::pow(0.01, g / 7.0));
  return grid;
}

/// The grid a signature is searched over: Stribeck vs (from the sliding speeds), position
/// wavelengths (travel / 10 to 4 travel, 28 points, travel = twice the largest travel), none for
/// the others.  `skip`: the record cannot show the signature at all (Stribeck without sliding).
struct SignatureGrid {
  bool gridded = false;
  bool skip = false;
  std::vector<double> values;
};

inline SignatureGrid evidence_grid(Effect e, const std::vector<double>& sliding_speeds,
                                   double travel) {
  SignatureGrid g;
  switch (e) {
    case Effect::stribeck:
      g.gridded = true;
      g.values = stribeck_start_grid(sliding_speeds);
      g.skip = g.values.empty();
      for (double& v : g.values) v = std::max(v, 1e-12);
      return g;
    case Effect::position_dependence:
      g.gridded = true;
      if (travel > 0)
        for (int k = 0; k < 28; ++k) g.values.push_back(travel / 10.0 * std::pow(40.0, k / 27.0));
      return g;
    case Effect::viscous:
    case Effect::frictional_lag:
    case Effect::asymmetry:
    case Effect::offset:
    case Effect::inertia:
    case Effect::drift:
    case Effect::delay:
    case Effect::normal_load:
      return g;
  }
  return g;
}

/// The regressors of effect e's signature on `s` at grid point `grid` (vs or a wavelength).
inline SignatureRegressors evidence_signature(Effect e, const EvidenceSignals& s, double grid) {
  constexpr double kPi = 3.14159265358979323846;
  const std::size_t n = s.residual.size();
  // The columns are moved into the result, not copied: each is as long as the record, and the
  // evidence stage builds dozens of these while other stages run beside it.
  const auto dir = [&s] { return std::vector<double>(s.direction.begin(), s.direction.end()); };
  std::vector<double> col(n, 0.0);
  SignatureRegressors r;
  switch (e) {
    case Effect::offset:
      r.effect.emplace_back(n, 1.0);
      return r;
    case Effect::viscous:
      for (std::size_t k = 0; k < n; ++k) col[k] = s.sliding[k] * s.velocity[k];
      r.nuisance.push_back(dir());
      r.effect.push_back(std::move(col));
      return r;
    case Effect::asymmetry:
      for (std::size_t k = 0; k < n; ++k)
        col[k] = s.reference_force > 0 ? s.simulated[k] * s.simulated[k] / s.reference_force : 0.0;
      r.nuisance.emplace_back(n, 1.0);
      r.effect.push_back(std::move(col));
      return r;
    case Effect::inertia:
      r.effect.emplace_back(s.acceleration.begin(), s.acceleration.end());
      return r;
    case Effect::drift:
      for (std::size_t k = 0; k < n; ++k) col[k] = s.direction[k] * s.reference_force * s.time[k];
      r.nuisance.push_back(dir());
      r.effect.push_back(std::move(col));
      return r;
    case Effect::delay:
      for (std::size_t k = 1; k + 1 < n; ++k)
        col[k] = (s.simulated[k + 1] - s.simulated[k - 1]) /
                 (s.record_time[k + 1] - s.record_time[k - 1]);
      r.effect.push_back(std::move(col));
      return r;
    case Effect::frictional_lag: {
      std::vector<double> v_s(n);
      for (std::size_t k = 0; k < n; ++k) {
        v_s[k] = s.sliding[k] * s.velocity[k];
        col[k] = s.sliding[k] * s.acceleration[k];
      }
      r.nuisance.push_back(dir());
      r.nuisance.push_back(std::move(v_s));
      r.effect.push_back(std::move(col));
      return r;
    }
    case Effect::stribeck:
      for (std::size_t k = 0; k < n; ++k)
        col[k] = s.direction[k] * std::exp(-(s.velocity[k] / grid) * (s.velocity[k] / grid));
      r.nuisance.push_back(dir());
      r.effect.push_back(std::move(col));
      return r;
    case Effect::position_dependence: {
      std::vector<double> c2(n);
      for (std::size_t k = 0; k < n; ++k) {
        col[k] = s.direction[k] * std::sin(2 * kPi * s.position[k] / grid);
        c2[k] = s.direction[k] * std::cos(2 * kPi * s.position[k] / grid);
      }
      r.nuisance.push_back(dir());
      r.effect.push_back(std::move(col));
      r.effect.push_back(std::move(c2));
      return r;
    }
    case Effect::normal_load:
      for (std::size_t k = 0; k < n; ++k) col[k] = s.direction[k] * s.normal[k];
      r.nuisance.push_back(dir());
      r.effect.push_back(std::move(col));
      return r;
  }
  return r;
}

/// What the evidence gives a fit of one effect to start from (typed; the report formats it).
struct EffectStart {
  double coefficient = 0;  ///< regression coefficient of the signature, SI (delay: the shift)
  double velocity = 0;     ///< stribeck: vs of the best grid point [m/s]
  double wavelength = 0;   ///< position-dependence: lambda of the best grid point [m]
  double phase = 0;        ///< position-dependence: phi [rad]
  double shift = 0;        ///< delay: the shift of Fhat that explains e best [s]
};

/// The typed start of effect e from the regression at its best grid point: `coefficients` of the
/// effect's regressors, `grid` the grid point, `best_shift` the delay's shift.
inline EffectStart evidence_start(Effect e, std::span<const double> coefficients, double grid,
                                  double best_shift) {
  EffectStart s;
  const double first = coefficients.empty() ? 0.0 : coefficients[0];
  switch (e) {
    case Effect::delay:
      s.coefficient = best_shift;
      s.shift = best_shift;
      return s;
    case Effect::stribeck:
      s.coefficient = first;
      s.velocity = to_significant_digits(grid, 6);
      return s;
    case Effect::position_dependence:
      if (coefficients.size() == 2) {
        s.coefficient = std::hypot(coefficients[0], coefficients[1]);
        s.phase = to_significant_digits(std::atan2(coefficients[1], coefficients[0]), 6);
      }
      s.wavelength = to_significant_digits(grid, 6);
      return s;
    case Effect::viscous:
    case Effect::frictional_lag:
    case Effect::asymmetry:
    case Effect::offset:
    case Effect::inertia:
    case Effect::drift:
    case Effect::normal_load:
      s.coefficient = first;
      return s;
  }
  return s;
}

// ---------------------------------------------------------------------------------------------
// Starts.

/// A piece's start values, in the order of its parameters in the table.
struct PieceStart {
  std::array<double, 3> values{};
  /// frictional-lag on a model without a velocity piece: the viscous companion's start [N s/m].
  std::optional<double> viscous_companion;
};

/// What start_from_evidence needs besides the effect's own evidence.
struct EvidenceStartContext {
  double reference_force = 0;       ///< F0 [N]
  double duration = 0;              ///< max(T, 1e-12) [s]
  double sample_period = 0;         ///< T / (N - 1) [s]
  double mean_normal_force = 0;     ///< mean N of the record [N] (NaN without one)
  double sliding_speed_max = 0;     ///< 95 % quantile of the sliding speeds [m/s]
  bool has_velocity_piece = false;  ///< the model already has a viscous or Stribeck piece
  double current_viscous = 0;       ///< its viscous coefficient (0 without one) [N s/m]
  double viscous_coefficient = 0;   ///< the viscous signature's coefficient [N s/m]
};

/// Start of effect e's piece on a Maxwell Slip model from its evidence `w` (null: none).
inline PieceStart start_from_evidence(Effect e, const EffectStart* w,
                                      const EvidenceStartContext& c) {
  // A coefficient that is not finite is no evidence (a degenerate regression).
  const double coef = w && std::isfinite(w->coefficient) ? w->coefficient : 0.0;
  const double f0 = c.reference_force;
  PieceStart p;
  auto& v = p.values;
  switch (e) {
    case Effect::viscous:
      v[0] = std::max(coef, 0.0);
      return p;
    case Effect::offset:
      v[0] = coef;
      return p;
    case Effect::inertia:
      v[0] = std::max(coef, 0.0);
      return p;
    case Effect::asymmetry:
      v[0] = std::clamp(coef, -0.8, 0.8);
      return p;
    case Effect::drift:
      v[0] = std::clamp(coef, -0.5 / c.duration, 2.0 / c.duration);
      return p;
    case Effect::delay:
      v[0] = coef;
      return p;
    case Effect::stribeck:
      v[0] = std::clamp(f0 + coef, 0.3 * f0, 5.0 * f0);
      v[1] = w ? std::max(w->velocity, 1e-12) : 1e-3;
      v[2] = 2.0;
      return p;
    case Effect::position_dependence:
      v[0] = std::clamp(coef, -0.5 * f0, 0.5 * f0);
      v[1] = w ? w->wavelength : 1.0;
      v[2] = w ? w->phase : 0.0;
      return p;
    case Effect::normal_load:
      v[0] = c.mean_normal_force > 0 ? f0 / c.mean_normal_force : 1.0;
      return p;
    case Effect::frictional_lag: {
      double sigma2 = c.current_viscous;
      if (!c.has_velocity_piece) {
        double companion =
            std::isfinite(c.viscous_coefficient) ? std::max(c.viscous_coefficient, 0.0) : 0.0;
        if (companion <= 0) companion = 0.05 * f0 / std::max(c.sliding_speed_max, 1e-12);
        p.viscous_companion = companion;
        sigma2 = companion;
      }
      const double ts = c.sample_period;
      v[0] = std::clamp(sigma2 > 0 ? -coef / sigma2 : 5 * ts, 2 * ts, c.duration / 20);
      return p;
    }
  }
  return p;
}

/// The signals of a held base's free run on its record (start_from_regression).
struct RegressionSignals {
  std::span<const double> residual;      ///< e = F - Fhat [N]
  std::span<const double> simulated;     ///< Fhat [N]
  std::span<const double> velocity;      ///< [m/s]
  std::span<const double> acceleration;  ///< [m/s^2]
  std::span<const double> displacement;  ///< x [m]
  std::span<const double> time;          ///< since the record's start [s]
  std::span<const double> record_time;   ///< the record's own time stamps [s]
  std::span<const double> normal;        ///< N [N] (empty without one)
  double reference_force = 0;            ///< F0 of the held base [N]
  double duration = 0;                   ///< max(T, 1e-12) [s]
};

/// Start of effect e's piece on a held LuGre or DNLRX base: regressions of its residual on each
/// effect's variable (header comment).
inline PieceStart start_from_regression(Effect e, const RegressionSignals& s) {
  constexpr double kPi = 3.14159265358979323846;
  const std::size_t n = s.residual.size();
  const auto& r = s.residual;
  const auto& fhat = s.simulated;
  const auto& v = s.velocity;
  const double f0 = s.reference_force, duration = s.duration;
  const auto coef = [&](const auto& col) {
    double num = 0, den = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const double c = col(k);
      num += c * r[k];
      den += c * c;
    }
    return den > 0 ? num / den : 0.0;
  };
  const auto explained2 = [&](const auto& c1, const auto& c2, double* b1, double* b2) {
    double s11 = 0, s12 = 0, s22 = 0, y1 = 0, y2 = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const double p = c1(k), q = c2(k);
      s11 += p * p, s12 += p * q, s22 += q * q, y1 += p * r[k], y2 += q * r[k];
    }
    const double det = s11 * s22 - s12 * s12;
    if (!(std::abs(det) > 0)) return *b1 = *b2 = 0.0;
    *b1 = (s22 * y1 - s12 * y2) / det;
    *b2 = (s11 * y2 - s12 * y1) / det;
    return *b1 * y1 + *b2 * y2;
  };
  PieceStart p;
  auto& x = p.values;
  switch (e) {
    case Effect::viscous:
      x[0] = std::max(coef([&](std::size_t k) { return v[k]; }), 0.0);
      return p;
    case Effect::offset:
      x[0] = coef([](std::size_t) { return 1.0; });
      return p;
    case Effect::inertia:
      x[0] = std::max(coef([&](std::size_t k) { return s.acceleration[k]; }), 0.0);
      return p;
    case Effect::asymmetry:
      x[0] = std::clamp(coef([&](std::size_t k) {
                          const double d = k ? std::clamp(fhat[k - 1] / f0, -1.0, 1.0) : 0.0;
                          return d * f0;
                        }),
                        -0.8, 0.8);
      return p;
    case Effect::drift:
      x[0] = std::clamp(coef([&](std::size_t k) { return fhat[k] * s.time[k]; }), -0.5 / duration,
                        2.0 / duration);
      return p;
    case Effect::delay:
      x[0] = std::clamp(coef([&](std::size_t k) {
                          if (k == 0 || k + 1 >= n) return 0.0;
                          return -(fhat[k + 1] - fhat[k - 1]) /
                                 (s.record_time[k + 1] - s.record_time[k - 1]);
                        }),
                        -duration / 20, duration / 20);
      return p;
    case Effect::stribeck: {
      std::vector<double> speeds;
      for (double u : v)
        if (u != 0) speeds.push_back(std::abs(u));
      double best = -1, best_vs = 1e-3, best_c = 0;
      for (double grid_vs : stribeck_start_grid(speeds)) {
        const double vs = std::max(grid_vs, 1e-12);
        const auto col = [&](std::size_t k) {
          const double w = std::exp(-(v[k] / vs) * (v[k] / vs));
          return v[k] > 0 ? w : (v[k] < 0 ? -w : 0.0);
        };
        const double c = coef(col);
        double den = 0;
        for (std::size_t k = 0; k < n; ++k) den += col(k) * col(k);
        if (c * c * den > best) best = c * c * den, best_vs = vs, best_c = c;
      }
      x[0] = std::clamp(f0 + best_c, 0.3 * f0, 5.0 * f0);
      x[1] = best_vs;
      x[2] = 2.0;
      return p;
    }
    case Effect::position_dependence: {
      const auto [lo, hi] = std::minmax_element(s.displacement.begin(), s.displacement.end());
      const double range = std::max(*hi - *lo, 1e-12);
      double best = -1, lambda = range, amp = 0, phase = 0;
      for (int g = 0; g < 25; ++g) {
        const double l = 2.0 * range * std::pow(1.0 / 128.0, g / 24.0);
        double b1 = 0, b2 = 0;
        const double ex = explained2(
            [&](std::size_t k) { return fhat[k] * std::sin(2 * kPi * s.displacement[k] / l); },
            [&](std::size_t k) { return fhat[k] * std::cos(2 * kPi * s.displacement[k] / l); }, &b1,
            &b2);
        if (ex > best)
          best = ex, lambda = l, amp = f0 * std::hypot(b1, b2), phase = std::atan2(b2, b1);
      }
      x[0] = std::clamp(amp, -0.5 * f0, 0.5 * f0);
      x[1] = lambda;
      x[2] = phase;
      return p;
    }
    case Effect::normal_load: {
      double sum = 0;
      for (double q : s.normal) sum += q;
      const double mean = sum / static_cast<double>(s.normal.size());
      x[0] = mean > 0 ? f0 / mean : 1.0;
      return p;
    }
    case Effect::frictional_lag:
      x[0] = 5 * (duration / static_cast<double>(n - 1));
      return p;
  }
  return p;
}

// ------------------------------------------------------------------------------------------------
// Profiles: where a fit of each piece starts (issue 7).  Every nonlinear parameter of a piece is
// started from the best point of a grid over its physical range, derived from the record; the
// stiffnesses and the added terms (viscous, offset, mass) are solved by bounded least squares at
// every point, so they need no start at all (extension_profile.cpp).  The ranges:
//   stribeck             velocity 1 % to 100 % of the 95th-percentile sliding speed (5 points,
//                        log), exponent 0.5-2.5 (3), static 1.05-2.6 F0 (3);
//   position-dependence  wavelength from 10 samples' travel to the whole travel (16, log; a third
//                        of it missed a wavelength of 0.35 travel on a study record), phase (8),
//                        amplitude 2-15 % of F0 (3);
//   drift                +-(0.02-0.6) per duration (8) and 0;
//   asymmetry            +-(0.05-0.3) (8);
//   delay                +-0.1 of the shortest interval between reversals (21, linear): a
//                        fraction of the duration would make the cost grow as N^2;
//   frictional-lag       half a sample to 0.3 of the shortest interval between reversals (10, log);
//   normal-load          none: its level is N(t)/N_mean and mu = F0 / N_mean is derived, because
//                        with the reference force held, (Delta, mu) and (2 Delta, mu/2) give the
//                        same forces -- mu is not identifiable as a free parameter;
//   viscous, offset, inertia  none (solved by projection).
// Each point costs a bounded least-squares solve on the whole record, and the fit from the best
// point does the rest.  The Stribeck grid had 9 x 5 x 6 points; the 45 above found the same fits
// in the discovery study (README, 7 December).  What a grid must keep is its ends: with the static
// axis ending at 2.0 F0, a study record of Fs = 3 Fc lost its position-dependence.  Nor may the
// phases go below 8: with 4, a study record (viscous+position-dependence, seed
// 8182649501330643343) started from a wrong wavelength and ended 9 standard errors from the true
// one, at 33 times the validation error.

/// The scales of a record the profiles' ranges follow from.
struct ProfileScales {
  double reference_force = 0;            ///< F0 [N]
  double sliding_speed_95 = 0;           ///< 95th percentile of |v| while sliding [m/s]
  double sliding_speed_50 = 0;           ///< median of the same speeds [m/s]
  double travel = 0;                     ///< max x - min x [m]
  double sample_travel = 0;              ///< median |dx| while moving [m]
  double reversal_interval = 0;          ///< shortest interval between two reversals [s]
  double longest_reversal_interval = 0;  ///< longest interval between two reversals [s]
  double duration = 0;                   ///< T [s]
  double sample_period = 0;              ///< Ts [s]
};

/// One axis of a profile: a parameter (methods.md 7 name) and its grid.
struct ProfileAxis {
  std::string_view parameter;
  std::vector<double> values;
};

namespace table_detail {
inline std::vector<double> log_grid(double lo, double hi, int n) {
  std::vector<double> g;
  if (!(lo > 0) || !(hi > lo)) return {lo > 0 ? lo : hi};
  for (int i = 0; i < n; ++i)
    g.push_back(lo * std::pow(hi / lo, n > 1 ? double(i) / (n - 1) : 0.0));
  return g;
}
inline std::vector<double> symmetric(std::initializer_list<double> magnitudes, double scale,
                                     bool with_zero) {
  std::vector<double> g;
  for (double m : magnitudes) {
    g.push_back(-m * scale);
    g.push_back(m * scale);
  }
  if (with_zero) g.push_back(0.0);
  std::sort(g.begin(), g.end());
  return g;
}
}  // namespace table_detail

/// The profile of effect e (its axes, whose product is the grid); empty when nothing is profiled.
inline std::vector<ProfileAxis> profile_axes(Effect e, const ProfileScales& s) {
  using table_detail::log_grid;
  using table_detail::symmetric;
  const double f0 = s.reference_force, gap = std::max(s.reversal_interval, 2 * s.sample_period);
  switch (e) {
    case Effect::stribeck: {
      std::vector<double> fs;
      for (double r : {1.05, 1.6, 2.6}) fs.push_back(r * f0);
      return {{"stribeck_velocity", log_grid(0.01 * s.sliding_speed_95, s.sliding_speed_95, 5)},
              {"stribeck_exponent", {0.5, 1.5, 2.5}},
              {"static", fs}};
    }
    case Effect::position_dependence: {
      std::vector<double> phase;
      for (int i = 0; i < 8; ++i) phase.push_back(2 * M_PI * i / 8);
      return {{"wavelength", log_grid(10 * s.sample_travel, s.travel, 16)},
              {"phase", phase},
              {"amplitude", {0.02 * f0, 0.06 * f0, 0.15 * f0}}};
    }
    case Effect::drift:
      return {{"relative_rate",
               symmetric({0.02, 0.06, 0.2, 0.6}, 1 / std::max(s.duration, 1e-12), true)}};
    case Effect::asymmetry:
      return {{"asymmetry", symmetric({0.05, 0.1, 0.2, 0.3}, 1.0, false)}};
    case Effect::delay: {
      std::vector<double> d;
      for (int i = -10; i <= 10; ++i) d.push_back(0.1 * gap * i / 10);
      return {{"delay", d}};
    }
    case Effect::frictional_lag:
      return {{"lag_time", log_grid(0.5 * s.sample_period, 0.3 * gap, 10)}};
    case Effect::viscous:
    case Effect::offset:
    case Effect::inertia:
    case Effect::normal_load:
      return {};
  }
  return {};
}

/// Parameters held at a derived value during a fit (normal-load's mu = F0 / N_mean; see above).
inline bool held_in_fit(Effect e, std::string_view parameter) {
  return e == Effect::normal_load && parameter == "friction_coefficient";
}

}  // namespace friction
