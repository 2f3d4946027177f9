// Pieces on a LuGre or DNLRX base: the pieces and the initial state with the base held, then
// everything refitted together (extension_identification.hpp, section 2).
#include <cmath>
#include <type_traits>

#include "extension_families.hpp"
#include "extension_steps.hpp"
#include "friction/effect_table.hpp"

namespace friction::extension_detail {

namespace {

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

double own_f0(const DnlrxParameters<double>& p) {
  return p.sliding_force();
}
double own_f0(const LuGreParameters<double>& p) {
  return p.coulomb;
}

// The pieces with the base held, then (refit_base) everything from there; the joint result is
// kept when it lowers the RSS.
template <class Family>
void identify_held(ExtensionIdentification& res, Family fam, const Record& r,
                   const std::vector<double>& base_simulated,
                   const std::vector<double>& start_state, const std::vector<Effect>& effects,
                   const ExtensionFitOptions& o) {
  using Base = std::decay_t<decltype(fam.template make<double>(nullptr, {}).base())>;
  fam.lag_state =
      std::find(effects.begin(), effects.end(), Effect::frictional_lag) != effects.end();
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

  // Standard errors and intervals of the free parameters at the optimum.
  const std::size_t nb = fam.base_count();
  const Box sb = state_box(fam, r);
  std::vector<char> free_state(f.state.size(), 1);
  for (std::size_t i = 0; i < f.state.size(); ++i)
    if (at_bound(f.state[i], sb.lower[i]) || at_bound(f.state[i], sb.upper[i])) free_state[i] = 0;
  const auto new_base = nb > 0 ? fam.parameters(f.base_theta.data()) : fam.p;
  const double f0_own = own_f0(new_base);
  const JointReport rep = report_joint_fit(r, fam, f.base_theta, f.ext, f.state, free_state, f0,
                                           own_reference_ratio(f.ext, f0_own));
  res.estimates = rep.pieces;
  res.base_parameters = rep.base;
  res.correlation_matrix = rep.correlation;
  note_rank_deficiency(res, rep.rank_deficient);
  res.model = AnyModel(Extended<Base>(Base(new_base), to_own_reference(f.ext, f0_own)));
  judge_evidence(res, effects, f0_own, o.evidence_sigmas);
}

}  // namespace

void identify_on_dnlrx(ExtensionIdentification& res, const DnlrxParameters<double>& base,
                       const Record& r, const std::vector<double>& base_simulated,
                       const std::vector<double>& base_initial, const std::vector<Effect>& effects,
                       const ExtensionFitOptions& o) {
  identify_held(res, DnlrxFamily{base}, r, base_simulated, state_from(base_initial, base.threshold),
                effects, o);
}

void identify_on_lugre(ExtensionIdentification& res, const LuGreParameters<double>& base,
                       const Record& r, const std::vector<double>& base_simulated,
                       const std::vector<double>& base_initial, const std::vector<Effect>& effects,
                       const ExtensionFitOptions& o) {
  const LuGreFamily fam{base, false};
  const double u = base_initial.empty() ? 0.0 : base_initial[0] / fam.zref();
  identify_held(res, fam, r, base_simulated, {u}, effects, o);
}

}  // namespace friction::extension_detail
