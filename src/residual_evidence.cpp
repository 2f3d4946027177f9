// The evidence stage of diagnose (diagnose.hpp, section 2): what a model's free run gets wrong on
// a record, by regime, against velocity, across time shifts, and as each effect's signature
// (effect_table.hpp); and the starts of the fits that evidence gives.
#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <span>
#include <utility>

#include "compressed_cost.hpp"
#include "diagnose_stages.hpp"
#include "friction/diagnose.hpp"
#include "friction/extension_fit.hpp"
#include "friction/identification.hpp"
#include "friction/metrics.hpp"
#include "number_format.hpp"

namespace friction {

namespace {

// Least-squares share of the residual explained by an effect's regressors beyond the nuisance
// regressors (a Coulomb level change the threshold refit absorbs anyway).
struct Explained {
  double share = 0;
  Eigen::VectorXd coefficients;  // of the effect's regressors
};

Explained explain(const std::vector<double>& e, const std::vector<std::vector<double>>& nuisance,
                  const std::vector<std::vector<double>>& effect) {
  const std::size_t n = e.size();
  const std::size_t q = nuisance.size(), p = effect.size();
  const auto as_vector = [n](const std::vector<double>& v) {
    return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(n));
  };
  const double total = as_vector(e).squaredNorm();
  Explained out;
  out.coefficients = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(p));
  if (total <= 0) return out;
  // A signature that is zero on the whole record (a sliding-only signature on a run that never
  // slides) explains nothing and has no coefficient: a least-squares solve of zero columns gave
  // an infinite one on a study record, and a start built from it failed every grid point.
  for (const std::vector<double>& x : effect)
    if (!(as_vector(x).squaredNorm() > 0)) return out;
  // [nuisance effect e] goes in blocks of rows into its triangular factor R (A = Q R): for every
  // c, ||e - A c|| = ||R_e - R_A c|| on R's columns, so both fits below are problems of q + p + 1
  // rows, and no N x (q + p) matrix or QR of it is kept (three record-long columns per call, with
  // the QR's copy, were a tenth of a diagnosis' peak memory).
  const Eigen::Index cols = static_cast<Eigen::Index>(q + p + 1);
  detail::RowCompressor compressor(cols);
  {
    constexpr std::size_t kRows = 1024;
    Eigen::MatrixXd block(static_cast<Eigen::Index>(std::min(kRows, n)), cols);
    for (std::size_t k0 = 0; k0 < n; k0 += kRows) {
      const std::size_t rows = std::min(kRows, n - k0);
      for (std::size_t k = 0; k < rows; ++k) {
        const Eigen::Index row = static_cast<Eigen::Index>(k);
        for (std::size_t j = 0; j < q; ++j)
          block(row, static_cast<Eigen::Index>(j)) = nuisance[j][k0 + k];
        for (std::size_t j = 0; j < p; ++j)
          block(row, static_cast<Eigen::Index>(q + j)) = effect[j][k0 + k];
        block(row, cols - 1) = e[k0 + k];
      }
      compressor.add(block.topRows(static_cast<Eigen::Index>(rows)));
    }
  }
  const Eigen::MatrixXd r = compressor.factor();
  const auto rb = r.col(cols - 1);
  auto rss_of = [&](Eigen::Index m, Eigen::VectorXd* coef) {
    if (m == 0) return total;
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(r.leftCols(m));
    const Eigen::VectorXd c = qr.solve(rb);
    if (coef) *coef = c;
    return (rb - r.leftCols(m) * c).squaredNorm();
  };
  const double r0 = rss_of(static_cast<Eigen::Index>(q), nullptr);
  Eigen::VectorXd c;
  const double r1 = rss_of(cols - 1, &c);
  if (!c.allFinite() || !std::isfinite(r1)) return out;
  out.share = std::max(0.0, (r0 - r1) / total);
  out.coefficients = c.tail(static_cast<Eigen::Index>(p));
  return out;
}

// The per-sample signals of a free run: residual, simulated force, motion and regime.
struct Signals {
  std::vector<double> e, fhat, v, a, t, sliding, dir;
  std::span<const double> x;  // the record's displacement
  double f0 = 0;
};

Signals signals_of(const MaxwellSlipParameters<double>& base,
                   const ExtensionParameters<double>& ext, const Record& r,
                   const std::vector<double>& rho) {
  const std::size_t n = r.size();
  ExtendedSlipRun run = run_extended_slip(base, ext, deflections_from_relative(base, rho, ext), r);
  Signals s;
  s.f0 = ext.reference_force > 0 ? ext.reference_force : base.sliding_force();
  s.e.resize(n);
  s.v = std::move(run.velocity);
  s.a = std::move(run.acceleration);
  s.x = r.displacement;
  s.t.resize(n);
  s.sliding.resize(n);
  s.dir.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    s.e[k] = r.force[k] - run.force[k];
    s.t[k] = r.time[k] - r.time.front();
    s.sliding[k] = run.sliding[k] ? 1.0 : 0.0;
    s.dir[k] = run.sliding[k] ? (run.force[k] >= 0 ? 1.0 : -1.0) : 0.0;
  }
  s.fhat = std::move(run.force);
  return s;
}

// Mean and RMS of the residual per regime; returns the sliding speeds.
std::vector<double> regime_statistics(const Signals& s, ResidualEvidence& ev) {
  double ss_s = 0, ss_p = 0, m_s = 0, m_p = 0;
  std::vector<double> speeds;
  for (std::size_t k = 0; k < s.e.size(); ++k) {
    if (s.sliding[k] > 0) {
      ++ev.sliding_samples;
      ss_s += s.e[k] * s.e[k];
      m_s += s.e[k];
      speeds.push_back(std::abs(s.v[k]));
    } else {
      ++ev.presliding_samples;
      ss_p += s.e[k] * s.e[k];
      m_p += s.e[k];
    }
  }
  if (ev.sliding_samples) {
    ev.sliding_rms = std::sqrt(ss_s / static_cast<double>(ev.sliding_samples));
    ev.sliding_mean = m_s / static_cast<double>(ev.sliding_samples);
    ev.sliding_speed_min = nearest_rank_quantile(speeds, 0.05);
    ev.sliding_speed_max = nearest_rank_quantile(speeds, 0.95);
  }
  if (ev.presliding_samples) {
    ev.presliding_rms = std::sqrt(ss_p / static_cast<double>(ev.presliding_samples));
    ev.presliding_mean = m_p / static_cast<double>(ev.presliding_samples);
  }
  return speeds;
}

// Sliding samples, quantile bins of |v| per direction: mean residual per bin.
// An encoder's record has few distinct speeds (its velocity estimates are sums of whole steps), so
// a bin's edge usually falls inside a group of equal speeds.  Such a group is split in time order:
// split by residual (a sort of (|v|, e) pairs) it gave the lower bin the group's lowest residuals,
// and equal speeds that rounding left an ulp apart were split by the rounding, so that a change in
// the last digit of the velocity's regression factor moved bin means by 3 %.  Speeds are compared
// on a grid of 1e-12 of the largest.
void velocity_bins(const Signals& s, ResidualEvidence& ev) {
  double fastest = 0;
  for (std::size_t k = 0; k < s.e.size(); ++k)
    if (s.sliding[k] > 0) fastest = std::max(fastest, std::abs(s.v[k]));
  const double grid = fastest > 0 ? 1e-12 * fastest : 1.0;
  for (int d : {1, -1}) {
    std::vector<std::pair<double, std::size_t>> pts;  // (speed on the grid, sample)
    for (std::size_t k = 0; k < s.e.size(); ++k)
      if (s.sliding[k] > 0 && s.dir[k] == d)
        pts.emplace_back(std::round(std::abs(s.v[k]) / grid), k);
    if (pts.size() < 16) continue;
    std::sort(pts.begin(), pts.end());
    const std::size_t bins = 6;
    for (std::size_t b = 0; b < bins; ++b) {
      const std::size_t lo = b * pts.size() / bins, hi = (b + 1) * pts.size() / bins;
      ResidualEvidence::Bin bin;
      bin.direction = d;
      bin.speed_low = std::abs(s.v[pts[lo].second]);
      bin.speed_high = std::abs(s.v[pts[hi - 1].second]);
      for (std::size_t k = lo; k < hi; ++k) bin.mean_residual += s.e[pts[k].second];
      bin.samples = hi - lo;
      bin.mean_residual /= static_cast<double>(bin.samples);
      ev.velocity_bins.push_back(bin);
    }
  }
}

// Cross-correlation of e with the displacement increments, and the best shift of Fhat.
void time_shifts(const Signals& s, const Record& r, ResidualEvidence& ev) {
  const std::size_t n = r.size();
  const double ts = n > 1 ? (r.time.back() - r.time.front()) / static_cast<double>(n - 1) : 1.0;
  const long lmax = static_cast<long>(std::min<std::size_t>(40, n / 20));
  std::vector<double> dx(n, 0.0);
  for (std::size_t k = 1; k < n; ++k) dx[k] = r.displacement[k] - r.displacement[k - 1];
  const double se = std::sqrt(sum_of_squares(s.e)), sd = std::sqrt(sum_of_squares(dx));
  double best_rss = std::numeric_limits<double>::infinity();
  long best = 0;
  std::vector<double> shift_rss;
  for (long lag = -lmax; lag <= lmax; ++lag) {
    double c = 0, rs = 0;
    for (long k = lmax; k < static_cast<long>(n) - lmax; ++k) {
      c += s.e[static_cast<std::size_t>(k)] * dx[static_cast<std::size_t>(k - lag)];
      const double g =
          r.force[static_cast<std::size_t>(k)] - s.fhat[static_cast<std::size_t>(k - lag)];
      rs += g * g;
    }
    ev.xcorr_lags.push_back(static_cast<double>(lag) * ts);
    ev.xcorr_values.push_back(se > 0 && sd > 0 ? c / (se * sd) : 0.0);
    shift_rss.push_back(rs);
    if (rs < best_rss) best_rss = rs, best = lag;
  }
  // Parabolic refinement of the best shift.
  double frac = 0;
  const std::size_t bi = static_cast<std::size_t>(best + lmax);
  if (bi > 0 && bi + 1 < shift_rss.size()) {
    const double y0 = shift_rss[bi - 1], y1 = shift_rss[bi], y2 = shift_rss[bi + 1];
    const double den = y0 - 2 * y1 + y2;
    if (den > 0) frac = std::clamp(0.5 * (y0 - y2) / den, -0.5, 0.5);
  }
  ev.best_shift = (static_cast<double>(best) + frac) * ts;
}

// Each effect's signature at the best point of its grid (effect_table.hpp), ranked.
void signatures(const Signals& s, const Record& r, const std::vector<double>& speeds,
                ResidualEvidence& ev) {
  const EvidenceSignals signals{s.e,    s.fhat,    s.v,   s.a,      s.x, s.t,
                                r.time, s.sliding, s.dir, r.normal, s.f0};
  const double travel = 2.0 * largest_travel(r.displacement);
  for (Effect eff : kEvidenceOrder) {
    if (effect_info(eff).needs_normal_force && !r.has_normal()) continue;
    const SignatureGrid grid = evidence_grid(eff, speeds, travel);
    if (grid.skip) continue;
    Explained best;
    double best_grid = 0;
    if (!grid.gridded) {
      const SignatureRegressors x = evidence_signature(eff, signals, 0.0);
      best = explain(s.e, x.nuisance, x.effect);
    }
    for (double g : grid.values) {
      const SignatureRegressors x = evidence_signature(eff, signals, g);
      Explained e = explain(s.e, x.nuisance, x.effect);
      if (e.share > best.share || best_grid == 0) best = std::move(e), best_grid = g;
    }
    const std::span<const double> coefficients(best.coefficients.data(),
                                               static_cast<std::size_t>(best.coefficients.size()));
    const EffectStart start = evidence_start(eff, coefficients, best_grid, ev.best_shift);
    ev.effects.push_back({eff, best.share, start.coefficient, start});
  }
  std::stable_sort(
      ev.effects.begin(), ev.effects.end(),
      [](const EffectEvidence& a, const EffectEvidence& b) { return a.explained > b.explained; });
}

const EffectEvidence* find_evidence(const ResidualEvidence& ev, Effect e) {
  for (const auto& x : ev.effects)
    if (x.effect == e) return &x;
  return nullptr;
}

// The grid point a start came from, as the evidence reports it.
std::string start_detail_text(const EffectEvidence& w) {
  switch (effect_info(w.effect).detail) {
    case StartDetail::velocity:
      return format_number(w.start.velocity, 6);
    case StartDetail::wavelength_phase:
      return format_number(w.start.wavelength, 6) + " " + format_number(w.start.phase, 6);
    case StartDetail::shift:
      return "shift " + format_number(w.start.shift, 3) + " s";
    case StartDetail::none:
      return "";
  }
  return "";
}

}  // namespace

namespace diagnose_detail {

ResidualEvidence gather_evidence(const MaxwellSlipParameters<double>& base,
                                 const ExtensionParameters<double>& ext, const Record& r,
                                 const std::vector<double>& rho) {
  const Signals s = signals_of(base, ext, r, rho);
  ResidualEvidence ev;
  ev.rss_sss_percent = 100.0 * sum_of_squares(s.e) / sum_of_squares(r.force);
  ev.noise_sigma = estimate_white_noise_sigma(r.force);
  ev.noise_floor_percent = noise_floor_rss_sss_percent(r.force, ev.noise_sigma);
  const std::vector<double> speeds = regime_statistics(s, ev);
  velocity_bins(s, ev);
  time_shifts(s, r, ev);
  signatures(s, r, speeds, ev);
  return ev;
}

}  // namespace diagnose_detail

ResidualEvidence analyse_residual(const MaxwellSlipParameters<double>& base,
                                  const ExtensionParameters<double>& extensions,
                                  const Record& record) {
  const std::vector<double> rho = estimate_relative_deflections(base, extensions, record, nullptr);
  return diagnose_detail::gather_evidence(base, extensions, record, rho);
}

ExtensionParameters<double> extension_start(Effect e, const ExtensionParameters<double>& current,
                                            const ResidualEvidence& ev, const Record& r,
                                            double f0) {
  ExtensionParameters<double> x = current;
  const EffectEvidence* w = find_evidence(ev, e);
  const EffectEvidence* viscous = find_evidence(ev, Effect::viscous);
  EvidenceStartContext c;
  c.reference_force = f0;
  c.duration = record_duration(r);
  c.sample_period = c.duration / static_cast<double>(r.size() - 1);
  if (effect_info(e).needs_normal_force) {
    double sum = 0;
    for (double v : r.normal) sum += v;
    c.mean_normal_force = sum / static_cast<double>(r.normal.size());
  }
  c.sliding_speed_max = ev.sliding_speed_max;
  c.has_velocity_piece = x.viscous || x.stribeck;
  c.current_viscous = x.viscous ? x.viscous->viscous : 0.0;
  c.viscous_coefficient = viscous ? viscous->coefficient : 0.0;
  const PieceStart start = start_from_evidence(e, w ? &w->start : nullptr, c);
  x.enable(e);
  if (start.viscous_companion) {
    x.enable(Effect::viscous);
    x.viscous->viscous = *start.viscous_companion;
  }
  x.assign(e, start.values);
  x.reference_force = f0;
  return x;
}

double extended_validation_percent(const MaxwellSlipParameters<double>& base,
                                   const ExtensionParameters<double>& extensions,
                                   const Record& record, std::vector<double>* simulated) {
  const std::vector<double> rho = estimate_relative_deflections(base, extensions, record, nullptr);
  const ExtendedSlipRun run =
      run_extended_slip(base, extensions, deflections_from_relative(base, rho, extensions), record);
  double rss = 0;
  for (std::size_t k = 0; k < record.size(); ++k)
    rss += (record.force[k] - run.force[k]) * (record.force[k] - run.force[k]);
  if (simulated) *simulated = run.force;
  return 100.0 * rss / sum_of_squares(record.force);
}

Json ResidualEvidence::to_json() const {
  Json j;
  j["rss_sss_percent"] = rss_sss_percent;
  j["noise"] = {{"sigma", noise_sigma}, {"floor_percent", noise_floor_percent}};
  j["regime"] = {
      {"sliding", {{"samples", sliding_samples}, {"rms", sliding_rms}, {"mean", sliding_mean}}},
      {"presliding",
       {{"samples", presliding_samples}, {"rms", presliding_rms}, {"mean", presliding_mean}}}};
  j["sliding_speed"] = {{"q05", sliding_speed_min}, {"q95", sliding_speed_max}};
  Json bins = Json::array();
  for (const auto& b : velocity_bins)
    bins.push_back({{"direction", b.direction},
                    {"speed_low", b.speed_low},
                    {"speed_high", b.speed_high},
                    {"mean_residual", b.mean_residual},
                    {"samples", b.samples}});
  j["velocity_bins"] = bins;
  j["best_shift"] = best_shift;
  std::size_t imax = 0;
  for (std::size_t i = 0; i < xcorr_values.size(); ++i)
    if (std::abs(xcorr_values[i]) > std::abs(xcorr_values[imax])) imax = i;
  if (!xcorr_values.empty())
    j["cross_correlation"] = {{"lags", xcorr_lags},
                              {"values", xcorr_values},
                              {"peak_lag", xcorr_lags[imax]},
                              {"peak_value", xcorr_values[imax]}};
  Json eff = Json::array();
  for (const auto& e : effects)
    eff.push_back({{"effect", std::string(effect_name(e.effect))},
                   {"explained", e.explained},
                   {"coefficient", e.coefficient},
                   {"detail", start_detail_text(e)}});
  j["signatures"] = eff;
  return j;
}

}  // namespace friction
