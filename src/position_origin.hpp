// Position dependence fitted about a reference position, reported about the origin.
//
// The position piece's level sin(2 pi x / lambda + phi) is the only part of any model that sees
// the absolute position x.  Study and machine records lie far from x = 0 (x near 0.08 m, travel
// 1e-5 m, lambda 4e-6 m: 2 pi x / lambda ~ 1e5 rad), where the phase at the origin moves by
// radians for a relative change of lambda of 1e-5: the two are correlated to 1 - 1e-10, and
// Levenberg-Marquardt could not move lambda (it stopped 3 % off, validating at 4x the floor, with
// a phase standard error of 846 rad).  So fits run on the record shifted to start at x = 0 (every
// other part of a model sees increments, derivatives or time, which the shift leaves alone), and
// the phase phi_0 fitted about x_ref is carried back to the origin afterwards:
//     sin(2 pi (x - x_ref) / lambda + phi_0) = sin(2 pi x / lambda + phi),
//     phi = phi_0 - 2 pi x_ref / lambda  (in [0, 2 pi)),
// its standard error and correlations through the linear map d phi = d phi_0 + a d lambda,
// a = 2 pi x_ref / lambda^2 (the phase at the origin is as uncertain as the wavelength makes it).
#pragma once

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "friction/extension_fit.hpp"
#include "friction/extensions.hpp"
#include "friction/record.hpp"

namespace friction::detail {

/// The record with x_ref subtracted from its displacement.
inline Record shifted_record(const Record& r, double x_ref) {
  Record s = r;
  for (double& v : s.displacement) v -= x_ref;
  return s;
}

/// The position piece's phase (fitted about x_ref) carried to the origin; nothing without one.
inline void phase_to_origin(ExtensionParameters<double>& ext, double x_ref) {
  if (!ext.position_dependence || x_ref == 0.0) return;
  auto& pd = *ext.position_dependence;
  pd.phase -= 2.0 * M_PI * x_ref / pd.wavelength;
  pd.phase -= 2.0 * M_PI * std::floor(pd.phase / (2.0 * M_PI));
}

/// The phase's estimate among `pieces` carried to the origin, at the value `phase_at_origin`
/// (phase_to_origin of the fitted pieces).  `correlation` is over [base, pieces] with the base's
/// standard errors `base_se` first (empty when the base was held); its phase row and column are
/// carried too.  Without a standard error for both phase and wavelength only the value and the
/// interval move.
inline void phase_estimate_to_origin(std::vector<ExtensionEstimate>& pieces,
                                     const std::vector<double>& base_se,
                                     Eigen::MatrixXd& correlation, double x_ref,
                                     double phase_at_origin) {
  std::ptrdiff_t ip = -1, iw = -1;
  for (std::size_t i = 0; i < pieces.size(); ++i)
    if (pieces[i].effect == Effect::position_dependence) {
      if (pieces[i].name == "phase") ip = static_cast<std::ptrdiff_t>(i);
      if (pieces[i].name == "wavelength") iw = static_cast<std::ptrdiff_t>(i);
    }
  if (ip < 0 || x_ref == 0.0) return;
  ExtensionEstimate& ph = pieces[static_cast<std::size_t>(ip)];
  const double shift = phase_at_origin - ph.value;
  ph.value = phase_at_origin;
  if (!ph.available || iw < 0 || !pieces[static_cast<std::size_t>(iw)].available) {
    ph.lower95 += shift, ph.upper95 += shift;
    return;
  }
  const double lambda = pieces[static_cast<std::size_t>(iw)].value;
  const double a = 2.0 * M_PI * x_ref / (lambda * lambda);
  const std::size_t nb = base_se.size();
  Eigen::MatrixXd& r = correlation;
  const Eigen::Index n = r.rows(), p = static_cast<Eigen::Index>(nb) + ip,
                     w = static_cast<Eigen::Index>(nb) + iw;
  if (p >= n || w >= n) {
    ph.available = false, ph.standard_error = 0, ph.lower95 = ph.upper95 = ph.value;
    return;
  }
  // Standard errors of every parameter of the matrix (0 where unknown).
  Eigen::VectorXd se = Eigen::VectorXd::Zero(n);
  for (std::size_t i = 0; i < nb && static_cast<Eigen::Index>(i) < n; ++i)
    se(static_cast<Eigen::Index>(i)) = base_se[i];
  for (std::size_t i = 0; i < pieces.size() && static_cast<Eigen::Index>(nb + i) < n; ++i)
    se(static_cast<Eigen::Index>(nb + i)) = pieces[i].available ? pieces[i].standard_error : 0.0;
  const Eigen::MatrixXd cov = se.asDiagonal() * r * se.asDiagonal();
  Eigen::VectorXd row = cov.row(p).transpose() + a * cov.row(w).transpose();
  const double var = cov(p, p) + 2.0 * a * cov(p, w) + a * a * cov(w, w);
  row(p) = var;
  const double sp = std::sqrt(std::max(var, 0.0));
  ph.standard_error = sp;
  ph.lower95 = ph.value - 1.96 * sp;
  ph.upper95 = ph.value + 1.96 * sp;
  for (Eigen::Index j = 0; j < n; ++j) {
    const double c = j == p ? 1.0 : (sp > 0 && se(j) > 0 ? row(j) / (sp * se(j)) : 0.0);
    r(p, j) = r(j, p) = c;
  }
}

}  // namespace friction::detail
