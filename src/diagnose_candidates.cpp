// The candidate stages of diagnose (diagnose.hpp, sections 3 and 4): a candidate's fit on top of
// the current model, the acceptance rule as a Verdict, the greedy forward pass and the backward
// pass.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>
#include <numeric>
#include <optional>

#include "diagnose_stages.hpp"
#include "extension_steps.hpp"
#include "friction/identification.hpp"
#include "friction/metrics.hpp"
#include "friction/noise_colour.hpp"
#include "parallel_for.hpp"
#include "sample_statistics.hpp"

namespace friction::diagnose_detail {

namespace {

// The diagnosis restarts its base on the force divided by the level, not under the level as
// `identify --extension` does (ExtensionFitOptions::base_under_level).  Under the level its chain
// on data/ (a GMS record: Stribeck, the GMS lag, viscous) fitted closer to the floor (final
// validation 0.0125 % -> 0.0074 %) and then took a fourth finding, an inertia of 0.13 kg with a
// validation gain of 1.06, which the record does not contain: a piece taking up the remaining
// misfit of a Maxwell Slip base on GMS data, which the acceptance rules let through once the
// chain before it fits better.  Until the rules guard against that, the diagnosis keeps the
// restart that names what the records hold.
constexpr bool kDiagnoseBaseUnderLevel = false;

double bic(double rss, std::size_t n, std::size_t p) {
  return bayesian_information_criterion(rss, n, p);
}

// 99.9 % quantile of chi-square with p degrees of freedom: what p parameters fitted to white
// noise of unit variance buy, with a margin for the tail.
double chi2_999(std::size_t p) {
  static const double table[] = {10.83, 13.82, 16.27, 18.47, 20.52, 22.46, 24.32, 26.12};
  if (p == 0) return 0.0;
  if (p <= 8) return table[p - 1];
  return 26.12 + 1.8 * static_cast<double>(p - 8);
}

// The numbers a model's pieces fit: their parameters and, with a frictional lag, the lag's initial
// offset, which the fit estimates on the record beside them (extension_fit.hpp,
// extended_state_size) and which a lag candidate can spend on the record's first samples.
std::size_t fitted_numbers(const ExtensionParameters<double>& ext) {
  return ext.parameter_count() + (ext.frictional_lag ? 1 : 0);
}

std::size_t extra_parameters(const ExtensionParameters<double>& with,
                             const ExtensionParameters<double>& without) {
  return fitted_numbers(with) - fitted_numbers(without);
}

// What one more operator would drop the RSS by at a model with estimation RSS rss0: the
// baseline's figure scaled by the share of the baseline's misfit (RSS above the noise floor) that
// is left (section 4; unscaled, the baseline's figure turned down a real viscous term after a
// normal-load piece had removed 99 % of the misfit, test_diagnose_pairs).
double operator_reference(const Context& c, double rss0) {
  if (!c.options.operator_reference || !(c.baseline_excess > 0.0)) return 0.0;
  return c.operator_drop * std::min(1.0, std::max(rss0 - c.floor_rss, 0.0) / c.baseline_excess);
}

// A state takes a fit's model, its estimation RSS, its edges and the validation error given.
void take_fit(State& s, const ExtendedSlipFit& f, double validation) {
  s.base = f.base;
  s.rho = f.rho;
  s.ext = f.ext;
  s.rss = f.rss;
  s.validation = validation;
  s.at_bound = f.at_bound;
}

// One candidate fitted on top of `s` from the start its evidence gives; validated only when
// rules (a) and (b) pass.
// Candidate t's fit taken as the state after s (before any restart).
State state_after(const State& s, const Tried& t) {
  State next;
  next.base = t.result.base;
  next.rho = t.result.rho;
  next.ext = t.result.ext;
  next.rss = t.fit.estimation_rss;
  next.validation = t.fit.validation_percent;
  next.order = s.order;
  next.order.push_back(t.fit.effect);
  next.at_bound = t.result.at_bound;
  return next;
}

// The rules (section 4) for a candidate fitted on top of s, `extra` fitted numbers beyond s's.
void judge_candidate(const Context& c, const State& s, Effect e, std::size_t extra, Tried& t) {
  if (!t.result.ok) {
    t.fit.verdict.fitted = false;
    return;
  }
  const double phi = residual_phi(c, t.result.base, t.result.ext, t.result.rho);
  t.fit.extensions = t.result.ext;
  t.fit.base = t.result.base;
  t.fit.extra_parameters = extra;
  t.fit.estimation_rss = t.result.rss;
  t.fit.estimation_percent = statistics::rss_sss_percent(c.est.force, t.result.rss);
  // The validation record is only consulted (rule c) when rules a and b pass.
  t.fit.validation_percent = std::numeric_limits<double>::quiet_NaN();
  if (accept(c, s.rss, t.result.rss, t.fit.extra_parameters, s.validation, s.validation - 1.0, phi)
          .passes_estimation_rules())
    t.fit.validation_percent = extended_validation_percent(t.result.base, t.result.ext, c.val);
  t.fit.verdict = accept(c, s.rss, t.result.rss, t.fit.extra_parameters, s.validation,
                         t.fit.validation_percent, phi);
  t.fit.verdict.stopped_short = t.stopped;
  for (const auto& [effect, name] : t.result.at_bound)
    if (effect == e) t.fit.verdict.at_bound = name;
  t.fit.earns_place = t.fit.verdict.earns_place();
  t.fit.delta_bic = t.fit.verdict.delta_bic;
  t.fit.required_drop = t.fit.verdict.required;
}

// The three parts of the drop rule (b) asks (accept) of a candidate with p extra numbers on a
// model at rss0, the noise part at the white-noise variance.  Coloured noise and a larger
// residual variance only raise the noise part, so `least()` is the least drop the rule can ask.
struct RuleBParts {
  double white_noise, share, reference;
  double least() const { return std::max({white_noise, share, reference}); }
};
RuleBParts rule_b_parts(const Context& c, double rss0, std::size_t p) {
  return {chi2_999(p) * (c.sigma * c.sigma),
          c.options.min_excess_share * std::max(rss0 - c.floor_rss, 0.0),
          operator_reference(c, rss0)};
}

// The largest estimation RSS with which a candidate with p extra numbers on s could pass rules
// (a) and (b) (header comment of diagnose.hpp, section 3): below RSS0 minus the least drop, and
// below RSS0 exp(-p ln N / N), where BIC on all N samples falls (on fewer effective samples,
// coloured noise, it asks more).
double candidate_target(const Context& c, const State& s, std::size_t p) {
  if (!c.options.stop_hopeless_candidates) return std::numeric_limits<double>::infinity();
  const double n = static_cast<double>(c.n);
  const double bic_bound = s.rss * std::exp(-static_cast<double>(p) * std::log(n) / n);
  return std::min(bic_bound, s.rss - rule_b_parts(c, s.rss, p).least());
}

// Effect e's joint fit on top of s (no verdict yet); false when it threw (t says why).
// `threads`: the candidate's own fits (from its profile, and again from the profile of each piece
// accepted on an edge) are independent, and run on this many threads when the candidate runs
// alone (lag_on_stribeck); compared in a fixed order, so the result does not depend on it.
bool fit_candidate_only(const Context& c, const State& s, Effect e, const ResidualEvidence& ev,
                        Tried& t, unsigned threads = 1) {
  const ExtensionParameters<double> start = extension_start(e, s.ext, ev, c.est, c.f0ref);
  t.fit.effect = e;
  try {
    // The evidence chose the candidate; the profile, not the evidence's regression, starts it.
    // The state carried as the same deflections at the first sample (extensions.hpp, Initial
    // state): the candidate may change the level the record starts with.
    const double level = first_level(s.base, s.ext, c.est, &c.windows);
    const ProfiledStart p =
        profile_start(c.est, s.base, s.rho, level, start, e, c.windows, c.scales);
    // A piece accepted on an edge (forward_pass) was fitted without what this candidate adds: its
    // own profile, with the candidate beside it, may find the basin the edge hid (a Stribeck
    // curve alone ran to exponent 5; with the viscous term and the lag its minimum is near 2).
    std::vector<Effect> edges;
    for (const auto& [edge_effect, name] : s.at_bound)
      if (edge_effect != e && s.ext.has(edge_effect)) edges.push_back(edge_effect);
    std::vector<ExtendedSlipFit> fits(1 + edges.size());
    std::vector<char> stopped(fits.size(), 0);
    detail::parallel_for(fits.size(), threads, [&](std::size_t i) {
      const ProfiledStart q =
          i == 0 ? p
                 : profile_start(c.est, p.base, s.rho, level, p.ext, edges[i - 1], c.windows,
                                 c.scales);
      bool stopped_early = false;
      fits[i] = extension_detail::fit_extended_slip_within_reach(
          c.est, q.base, carried_state(c.est, s.base, s.ext, s.rho, q.base, q.ext, &c.windows),
          q.ext, false, c.options.max_iterations,
          candidate_target(c, s, extra_parameters(q.ext, s.ext)), &stopped_early, true);
      stopped[i] = stopped_early;
    });
    std::size_t chosen = 0;
    for (std::size_t i = 1; i < fits.size(); ++i)
      if (fits[i].ok && (!fits[chosen].ok || fits[i].rss < fits[chosen].rss)) chosen = i;
    t.result = std::move(fits[chosen]);
    t.stopped = stopped[chosen] != 0;
  } catch (const std::exception& ex) {
    t.fit.verdict.fitted = false;
    t.fit.verdict.failure = ex.what();
    return false;
  }
  return true;
}

Tried fit_candidate(const Context& c, const State& s, Effect e, const ResidualEvidence& ev) {
  Tried t;
  const auto t_start = std::chrono::steady_clock::now();
  if (fit_candidate_only(c, s, e, ev, t))
    judge_candidate(c, s, e, extra_parameters(t.result.ext, s.ext), t);
  t.fit.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return t;
}

// A frictional lag on the Stribeck curve (header comment of diagnose.hpp, Nested candidates).  A
// lag candidate on a model without a velocity piece brings a viscous companion; when the record's
// velocity-dependent friction is a Stribeck curve behind a long lag, neither that pair nor the
// curve alone describes it (the curve follows the speed at once and misses the validation
// record's reversals), and each one-at-a-time round turned both down.  So when the round's
// Stribeck candidate passes the estimation rules on its own and no nested check turned it down,
// the lag is also fitted on top of that curve, and the lag candidate with the lower BIC against s
// is the round's.  (Without the nested gate, a curve that falls before the record slides came
// back as a lag's companion: a false lag on seed 8675309's `stribeck+inertia`.)  (Discovery
// study seed 424242, `frictional-lag+stribeck-2`: Fs = 3 Fc, lag 18 ms; the curve alone 4.09 ->
// 4.11 % on validation, named nothing.)
Tried lag_on_stribeck(const Context& c, const State& s, const Tried& stribeck) {
  const State on = state_after(s, stribeck);
  Tried t;
  const auto t_start = std::chrono::steady_clock::now();
  if (fit_candidate_only(c, on, Effect::frictional_lag,
                         gather_evidence(on.base, on.ext, c.est, on.rho), t, c.options.threads))
    judge_candidate(c, s, Effect::frictional_lag, extra_parameters(t.result.ext, s.ext), t);
  t.fit.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return t;
}

// The 5 % quantile of the speed while the fitted model slides on the estimation record.  Sliding
// is judged without the operators whose whole sliding force k D is below the force noise: they
// cannot make sliding and presliding differ visibly, and one of them at a large threshold (a
// baseline of a test's Stribeck record had k D = 5e-5 N against sigma = 2e-3 N, at 2.7x the
// largest other threshold) would put the start of sliding at speeds the true curve has long
// fallen from.
double lowest_sliding_speed(const Context& c, const ExtendedSlipFit& f) {
  MaxwellSlipParameters<double> base;
  std::vector<double> rho;
  for (std::size_t i = 0; i < f.base.size(); ++i)
    if (f.base.stiffness[i] * f.base.threshold[i] >= c.sigma) {
      base.stiffness.push_back(f.base.stiffness[i]);
      base.threshold.push_back(f.base.threshold[i]);
      rho.push_back(f.rho[i]);
    }
  if (base.size() == 0) base = f.base, rho = f.rho;
  else if (f.rho.size() > f.base.size()) rho.push_back(f.rho[f.base.size()]);  // the lag's offset
  const ExtendedSlipRun run =
      run_extended_slip(base, f.ext, deflections_from_relative(base, rho, f.ext), c.est);
  std::vector<double> speeds;
  for (std::size_t k = 0; k < run.velocity.size(); ++k)
    if (run.sliding[k] && run.velocity[k] != 0.0) speeds.push_back(std::abs(run.velocity[k]));
  return nearest_rank_quantile(std::move(speeds), 0.05);
}

// The time shift that stepping the model once per sample imitates (diagnose.hpp, Nested
// candidates): the model of `s` run on the record refined to four steps per sample
// (stepped_finely) against the same model run per sample; D is the least-squares shift with
// F_fine(t) ~ F_sample(t + D).
double stepping_shift(const Context& c, const State& s) {
  const Record& r = c.est;
  const std::size_t n = r.size();
  if (n < 8) return 0.0;
  const std::vector<double> initial = deflections_from_relative(s.base, s.rho, s.ext);
  const std::vector<double> coarse = run_extended_slip(s.base, s.ext, initial, r).force;
  const std::vector<double> refined = stepped_finely(s, initial, r, c.fine_windows_est);
  double num = 0, den = 0;
  for (std::size_t k = 1; k + 1 < n; ++k) {
    const double slope = (coarse[k + 1] - coarse[k - 1]) / (r.time[k + 1] - r.time[k - 1]);
    num += (refined[k] - coarse[k]) * slope;
    den += slope * slope;
  }
  return den > 0 ? num / den : 0.0;
}

// Nested candidates (diagnose.hpp): a velocity lag that ends at (almost) no lag is its velocity
// piece, and a lag fitted with its own companion must beat the companion alone (BIC); a Stribeck
// curve must fall where the record slides.
void check_nested(const Context& c, const State& s, std::vector<Tried>& round) {
  const double ts = (c.est.time.back() - c.est.time.front()) / static_cast<double>(c.n - 1);
  const auto curve_fallen_before_sliding = [&](const ExtendedSlipFit& f) {
    const auto& curve = *f.ext.stribeck;
    const double v05 = lowest_sliding_speed(c, f);
    const double remaining =
        std::exp(-std::pow(v05 / curve.stribeck_velocity, curve.stribeck_exponent));
    return std::abs(curve.static_force - f.ext.reference_force) * remaining < c.sigma;
  };
  for (auto& t : round) {
    if (t.fit.effect == Effect::stribeck && t.fit.verdict.earns_place_but_for_an_edge() &&
        t.result.ext.stribeck) {
      if (curve_fallen_before_sliding(t.result)) {
        t.fit.earns_place = false;
        t.fit.verdict.nested = Verdict::Nested::drop_below_sliding;
      }
      continue;
    }
    if (t.fit.effect == Effect::delay && t.fit.verdict.earns_place_but_for_an_edge() &&
        t.result.ext.delay) {
      // A model stepped per sample imitates the shift -D_step; what the fit adds beyond it must
      // exceed it to be a delay of the record.
      const double artefact = -stepping_shift(c, s);
      if (std::abs(t.result.ext.delay->delay - artefact) <= std::abs(artefact)) {
        t.fit.earns_place = false;
        t.fit.verdict.nested = Verdict::Nested::delay_within_stepping;
      }
      continue;
    }
    const EffectInfo& info = effect_info(t.fit.effect);
    if (info.kind != EffectKind::velocity_lag || !t.fit.earns_place) continue;
    // A lag fitted on a Stribeck curve brings the curve: the curve's rule holds for it too.
    if (t.result.ext.stribeck && !s.ext.stribeck && curve_fallen_before_sliding(t.result)) {
      t.fit.earns_place = false;
      t.fit.verdict.nested = Verdict::Nested::drop_below_sliding;
      continue;
    }
    // Its companion: the round's candidate of the velocity piece it came with (viscous, or the
    // Stribeck curve it was fitted on).
    const Tried* companion = nullptr;
    for (const auto& u : round)
      if (u.fit.effect != t.fit.effect && u.result.ok && !s.ext.has(u.fit.effect) &&
          t.result.ext.has(u.fit.effect))
        companion = &u;
    if (t.result.ext.frictional_lag->lag_time < ts) {
      t.fit.earns_place = false;
      t.fit.verdict.nested = Verdict::Nested::lag_below_one_sample;
    } else if (companion && !s.ext.has(companion->fit.effect) &&
               bic(t.fit.estimation_rss, c.n, t.fit.extra_parameters) >=
                   bic(companion->fit.estimation_rss, c.n, companion->fit.extra_parameters)) {
      t.fit.earns_place = false;
      t.fit.verdict.nested = Verdict::Nested::no_better_than_viscous;
    }
  }
}

// The state after accepting t.  The candidate's fit started from the operators of a model that
// was identified on a force holding the effect (the baseline's M was chosen by BIC with the
// effect's misfit in it), and a local refit from there can keep that distortion (identify's
// restart, extension_identification.hpp section 1): an offset fitted from the baseline of an
// asymmetric record stopped at an RSS 16 % above what the same model reached from the asymmetry's
// solution.  So the accepted model gets the restart too: NLR with its order selected again on the
// force without the pieces, the joint fit from that base, kept when its BIC is lower.
State accepted(const Context& c, const State& s, const Tried& t) {
  State next = state_after(s, t);
  ExtensionFitOptions o;
  o.max_iterations = c.options.max_iterations;
  o.max_operators = c.options.method.max_operators;
  o.global_stage = false;
  o.grow_operators = false;
  o.base_under_level = kDiagnoseBaseUnderLevel;
  o.threads = c.options.threads;  // the forward pass waits for the restart
  bool restarted = false;
  const ExtendedSlipFit g =
      extension_detail::restart_base(c.est, t.result, o, restarted, false, c.joint_fits);
  if (restarted) {
    take_fit(next, g, extended_validation_percent(g.base, g.ext, c.val));
  }
  return next;
}

// A piece of `s` that no finding named: the companion a velocity lag came with.
bool is_companion(const State& s, Effect e) {
  return s.ext.has(e) && std::find(s.order.begin(), s.order.end(), e) == s.order.end();
}

// The pieces of `full` without effect e (and without a companion that came with it only).
ExtensionParameters<double> without_piece(const State& full, Effect e) {
  ExtensionParameters<double> without = full.ext;
  without.disable(e);
  if (effect_info(e).kind == EffectKind::velocity_lag)
    for (Effect x : kAllEffects)
      if (x != e && is_companion(full, x)) without.disable(x);
  return without;
}

// The chain recomputed for the pieces of `full`, in its order, from the baseline `first`.
std::vector<State> rebuild_chain(const Context& c, const State& first, const State& full) {
  std::vector<State> states{first};
  for (std::size_t i = 0; i < full.order.size(); ++i) {
    ExtensionParameters<double> sub = full.ext;
    for (Effect e : kAllEffects) {
      bool keep = false;
      for (std::size_t j = 0; j <= i; ++j)
        keep = keep || full.order[j] == e ||
               (effect_info(full.order[j]).kind == EffectKind::velocity_lag &&
                is_companion(full, e));
      if (!keep) sub.disable(e);
    }
    const bool last = i + 1 == full.order.size();
    const ExtendedSlipFit f =
        last ? ExtendedSlipFit{full.base, full.rho, full.ext, full.rss, true, full.at_bound}
             : fit_extended_slip(
                   c.est, full.base,
                   carried_state(c.est, full.base, full.ext, full.rho, full.base, sub, &c.windows),
                   sub, false, c.options.max_iterations);
    State st;
    take_fit(st, f, last ? full.validation : extended_validation_percent(f.base, f.ext, c.val));
    st.order.assign(full.order.begin(), full.order.begin() + static_cast<std::ptrdiff_t>(i + 1));
    states.push_back(st);
  }
  return states;
}

}  // namespace

// Rules (a) and (b) with coloured noise (section 4).  A residual whose lag-one correlation is phi
// carries about N (1 - phi)/(1 + phi) independent samples, and p parameters fitted to it buy
// chi2_p (1 + phi)/(1 - phi) times its variance, not chi2_p times: with the white rules, AR(1)
// force noise at phi 0.8-0.95 let a delay or a viscous term into records that had none.  The
// colour and the variance are those of the candidate's residual (its noise once the candidate
// explains the rest; a larger variance where it does not, which only asks more of it), never less
// than the white-noise estimate; a phi within 3 sampling errors of 0 gives the white rules.
Verdict accept(const Context& c, double rss0, double rss1, std::size_t p, double val0, double val1,
               double phi) {
  const DiagnoseOptions& o = c.options;
  // A lag-one correlation within 3 sampling errors of zero is white noise.
  if (phi < 3 / std::sqrt(static_cast<double>(c.n))) phi = 0;
  const double inflation = (1 + phi) / (1 - phi);
  const double n_eff = std::max(static_cast<double>(c.n) / inflation, static_cast<double>(p) + 2);
  const double variance = std::max(c.sigma * c.sigma, rss1 / static_cast<double>(c.n));
  const RuleBParts parts = rule_b_parts(c, rss0, p);
  const double noise = phi > 0 ? chi2_999(p) * (variance * inflation) : parts.white_noise;
  const double share = parts.share, reference = parts.reference;
  Verdict v;
  v.residual_colour = phi;
  // BIC on the effective number of samples: n_eff ln(RSS1 / RSS0) + p ln(n_eff).
  v.delta_bic = n_eff * std::log(rss1 / rss0) + static_cast<double>(p) * std::log(n_eff);
  v.required = std::max({noise, share, reference});
  v.drop = rss0 - rss1;
  v.operator_limited =
      reference > 0.0 && v.required == reference && v.drop > std::max(noise, share);
  // The noise's RSS over N samples is N sigma^2 with standard deviation sqrt(2 N) sigma^2: a
  // model within three of them of the estimation record's floor (the noise's, and what the
  // displacement's sampling puts into its force) leaves nothing there that a drop could show to
  // be an effect rather than the noise and the sampling, which a piece with a free parameter
  // then fits instead (the judgement polish_final makes on the floor of the noise alone).
  v.estimation_at_floor = c.estimation_at_floor(rss0);
  v.validation_before = val0;
  v.validation_after = val1;
  // The required fall is a share of what lies above the force noise's floor; whether anything is
  // left to explain at all is judged against the floor with the displacement's sampling in it
  // too (c.validation_measurement_percent, an estimate good to its order of magnitude: it
  // decides that nothing is left, it does not scale the gain asked for).
  const double floor = c.validation_floor_with_sampling();
  v.validation_required =
      val0 - o.min_excess_share * std::max(val0 - c.validation_floor_percent, 0.0);
  v.validation = std::isnan(val1)                 ? Verdict::Validation::not_evaluated
                 : val0 <= floor                  ? Verdict::Validation::at_floor
                 : val1 < v.validation_required   ? Verdict::Validation::falls
                                                  : Verdict::Validation::does_not_fall;
  // At the floor the required fall is the floor itself (reported as such).
  if (v.validation == Verdict::Validation::at_floor) v.validation_required = floor;
  return v;
}

Tried fit_one_candidate(const Context& c, const State& s, Effect e) {
  return fit_candidate(c, s, e, gather_evidence(s.base, s.ext, c.est, s.rho));
}

std::vector<Tried> fit_candidates(const Context& c, const State& s,
                                  const std::vector<Effect>& pool) {
  const ResidualEvidence ev = gather_evidence(s.base, s.ext, c.est, s.rho);
  std::vector<Effect> todo;
  for (Effect e : pool)
    if (!s.ext.has(e)) todo.push_back(e);
  std::vector<Tried> out(todo.size());
  // Slowest first (the lag, Stribeck and position fits take 10-20 times the others), so that a
  // thread is not left with one long fit at the end.
  std::vector<std::size_t> queue(todo.size());
  std::iota(queue.begin(), queue.end(), std::size_t{0});
  std::stable_sort(queue.begin(), queue.end(), [&](std::size_t a, std::size_t b) {
    return profile_axes(todo[a], c.scales).size() > profile_axes(todo[b], c.scales).size();
  });
  detail::parallel_for(
      todo.size(), c.options.threads,
      [&](std::size_t i) { out[i] = fit_candidate(c, s, todo[i], ev); }, queue);
  check_nested(c, s, out);
  // The lag on the round's Stribeck curve (lag_on_stribeck), when the curve passes rules (a) and
  // (b) and no nested check turned it down; then the checks again, for that lag (each check
  // depends on its candidate's fit only, so the others keep their verdicts).  Not on a model that
  // validates at the floor: there no candidate passes rule (c), so the round accepts nothing
  // whichever lag it holds, and this fit, the slowest of a round (1.0 of the 2.4 s of a
  // single-thread diagnosis of data/bench/strokes, whose baseline is at the floor), would only
  // change which of two turned-down lags the document shows.
  if (!s.ext.viscous && !s.ext.stribeck && s.validation > c.validation_floor_with_sampling()) {
    Tried* lag = nullptr;
    const Tried* stribeck = nullptr;
    for (auto& t : out) {
      if (t.fit.effect == Effect::frictional_lag) lag = &t;
      if (t.fit.effect == Effect::stribeck && t.result.ok &&
          t.fit.verdict.passes_estimation_rules() &&
          t.fit.verdict.nested == Verdict::Nested::none)
        stribeck = &t;
    }
    if (lag && stribeck) {
      Tried on = lag_on_stribeck(c, s, *stribeck);
      const auto lag_bic = [&](const Tried& t) {
        return bic(t.fit.estimation_rss, c.n, t.fit.extra_parameters);
      };
      if (on.result.ok && (!lag->result.ok || lag_bic(on) < lag_bic(*lag))) {
        on.fit.seconds += lag->fit.seconds;
        *lag = std::move(on);
        check_nested(c, s, out);
      }
    }
  }
  return out;
}

Chain forward_pass(const Context& c, const State& start, const std::vector<Effect>& pool,
                   std::vector<CandidateFit>& first_round) {
  Chain chain;
  chain.states.push_back(start);
  std::vector<Effect> live = pool;
  for (;;) {
    while (chain.states.back().order.size() < c.options.max_findings) {
      // A round on a model at the estimation record's floor turns every candidate down (rule b),
      // whatever its fit: only the first round's fits are shown, so a later one is not fitted.
      // (On the discovery study's records the last round after the last finding often is one.)
      const bool shown = chain.rounds.empty() && first_round.empty();
      if (!shown && c.estimation_at_floor(chain.states.back().rss)) break;
      std::vector<Tried> tried = fit_candidates(c, chain.states.back(), live);
      if (shown)
        for (const auto& t : tried) first_round.push_back(t.fit);
      // Among those that earn their place, the largest gain (the lowest validation error); one
      // with a parameter on an edge only when no other earns its place.
      const Tried* best = nullptr;
      for (const bool edge_allowed : {false, true}) {
        for (const auto& t : tried)
          if ((edge_allowed ? t.fit.verdict.earns_place_but_for_an_edge() : t.fit.earns_place) &&
              (!best || t.fit.validation_percent < best->fit.validation_percent))
            best = &t;
        if (best) break;
      }
      if (!best) break;
      chain.states.push_back(accepted(c, chain.states.back(), *best));
      chain.rounds.push_back(std::move(tried));
    }
    // A piece accepted on an edge that the later findings left there goes, and the search goes on
    // without it.
    const State& last = chain.states.back();
    std::optional<std::pair<Effect, std::string>> edge;
    for (const auto& ab : last.at_bound)
      if (std::find(last.order.begin(), last.order.end(), ab.first) != last.order.end()) edge = ab;
    if (!edge) break;
    State reduced = last;
    const ExtensionParameters<double> without = without_piece(last, edge->first);
    const ExtendedSlipFit f = fit_extended_slip(
        c.est, last.base,
        carried_state(c.est, last.base, last.ext, last.rho, last.base, without, &c.windows),
        without, false, c.options.max_iterations);
    if (!f.ok) {
      chain.warnings.push_back("kept " + std::string(effect_name(edge->first)) + " with its " +
                               edge->second +
                               " on the edge of its range: the model without it could not be "
                               "fitted (the finding is doubtful)");
      break;
    }
    take_fit(reduced, f, extended_validation_percent(f.base, f.ext, c.val));
    reduced.order.erase(std::find(reduced.order.begin(), reduced.order.end(), edge->first));
    chain.warnings.push_back("removed " + std::string(effect_name(edge->first)) + ": its " +
                             edge->second +
                             " stayed at the edge of its range with the other findings in the "
                             "model (the effect as defined does not describe this record)");
    chain.removed = true;
    chain.states = rebuild_chain(c, chain.states.front(), reduced);
    live.erase(std::find(live.begin(), live.end(), edge->first));
  }
  return chain;
}

double residual_phi(const Context& c, const MaxwellSlipParameters<double>& base,
                    const ExtensionParameters<double>& ext, const std::vector<double>& rho) {
  const ExtendedSlipRun run =
      run_extended_slip(base, ext, deflections_from_relative(base, rho, ext), c.est);
  std::vector<double> e(c.est.size());
  for (std::size_t k = 0; k < e.size(); ++k) e[k] = c.est.force[k] - run.force[k];
  return residual_colour(e).phi;
}

// The restarts of the forward pass run without the global stage and without growth: they run once
// per accepted finding, and each growth step costs an NLR fit.  The final model gets both, once:
// with a varying normal force (a discovery-study record) the accepted model kept the baseline's 5
// operators and validated at 5.9 times the floor; polished, 6 operators and 1.00.
void polish_final(const Context& c, Chain& chain) {
  if (chain.states.size() < 2) return;
  State& last = chain.states.back();
  // A model within three standard deviations of the noise floor's chi-square (N sigma^2, sd
  // sqrt(2N) sigma^2) has nothing left that another minimum could explain.
  const double n = static_cast<double>(c.est.size());
  if (c.floor_rss > 0 && last.rss <= c.floor_rss * (1.0 + 3.0 * std::sqrt(2.0 / n))) return;
  ExtensionFitOptions o;
  o.max_iterations = c.options.max_iterations;
  o.max_operators = c.options.method.max_operators;
  o.global_stage = c.options.method.global_stage;
  o.grow_operators = true;
  o.base_under_level = kDiagnoseBaseUnderLevel;
  o.threads = c.options.threads;  // nothing else runs beside the final polish
  bool restarted = false;
  const ExtendedSlipFit g = extension_detail::restart_base(
      c.est, ExtendedSlipFit{last.base, last.rho, last.ext, last.rss, true, last.at_bound}, o,
      restarted, true, c.joint_fits);
  if (restarted) take_fit(last, g, extended_validation_percent(g.base, g.ext, c.val));
}

Chain backward_pass(const Context& c, Chain chain) {
  if (!c.options.backward_pass || chain.states.back().order.size() < 2) return chain;
  State full = chain.states.back();
  struct Without {
    ExtendedSlipFit fit;
    double validation = 0;
    std::exception_ptr error;  // of a fit made ahead: thrown only when the loop reaches it
  };
  auto fit_without = [&](const State& from, Effect e) {
    const ExtensionParameters<double> without = without_piece(from, e);
    Without w;
    w.fit = fit_extended_slip(
        c.est, from.base,
        carried_state(c.est, from.base, from.ext, from.rho, from.base, without, &c.windows),
        without, false, c.options.max_iterations);
    w.validation = extended_validation_percent(w.fit.base, w.fit.ext, c.val);
    return w;
  };
  // The fits without each piece of the model as the forward pass left it are independent: made
  // concurrently, each into its own slot, and used for as long as the model has not changed (it
  // nearly never does); after a change they are fitted again from the changed model, one by one
  // as before.  The same result on any number of threads.
  std::vector<Without> ahead(full.order.size());
  detail::parallel_for(ahead.size(), c.options.threads, [&](std::size_t i) {
    try {
      ahead[i] = fit_without(full, full.order[i]);
    } catch (...) {
      ahead[i].error = std::current_exception();
    }
  });
  bool changed = false;
  for (std::size_t i = 0; i < full.order.size();) {
    const Effect e = full.order[i];
    const ExtensionParameters<double> without = without_piece(full, e);
    const Without w = changed ? fit_without(full, e) : ahead[i];
    if (w.error) std::rethrow_exception(w.error);
    const ExtendedSlipFit& f = w.fit;
    const double v_without = w.validation;
    if (f.ok && f.rss < full.rss) {
      // The model without the piece fits better than the model with it, which nests it: the full
      // model is not at its minimum (on the tribometer, position-dependence + normal-load ended
      // 7 N^2 above position-dependence alone).  Refitted from the reduced solution with the
      // piece as it was, it is judged at the better of the two.
      ExtensionParameters<double> start = full.ext;
      std::vector<double> reduced;
      f.ext.for_each_parameter(
          [&](Effect, std::string_view, const double& x) { reduced.push_back(x); });
      std::size_t j = 0;
      start.for_each_parameter([&](Effect pe, std::string_view, double& x) {
        if (without.has(pe)) x = reduced[j++];
      });
      const ExtendedSlipFit g = fit_extended_slip(
          c.est, f.base, carried_state(c.est, f.base, f.ext, f.rho, f.base, start, &c.windows),
          start, false, c.options.max_iterations);
      if (g.ok && g.rss < full.rss) {
        take_fit(full, g, extended_validation_percent(g.base, g.ext, c.val));
        chain.removed = true;  // the chain is recomputed for the refitted model
        changed = true;
      }
    }
    if (f.ok) {
      const Verdict v = accept(c, f.rss, full.rss, extra_parameters(full.ext, without), v_without,
                               full.validation, residual_phi(c, full.base, full.ext, full.rho));
      if (!v.earns_place()) {
        // The rules judge on the estimation record; what the validation record said is reported
        // beside them, since a user may have a record that would decide (the tribometer's
        // normal-load term, removed here, takes its validation error from 3.6 % to 0.39 %).
        char figures[160];
        std::snprintf(figures, sizeof figures,
                      " (validation RSS/SSS %.4g %% with it, %.4g %% without; `identify "
                      "--extension` fits it on request)",
                      full.validation, v_without);
        chain.warnings.push_back("backward pass removed " + std::string(effect_name(e)) + ": " +
                                 v.to_text() + figures);
        take_fit(full, f, v_without);
        full.order.erase(full.order.begin() + static_cast<std::ptrdiff_t>(i));
        chain.removed = true;
        changed = true;
        i = 0;
        continue;
      }
    }
    ++i;
  }
  if (chain.removed) chain.states = rebuild_chain(c, chain.states.front(), full);
  return chain;
}

}  // namespace friction::diagnose_detail
