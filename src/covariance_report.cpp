// Standard errors, intervals, correlations and identifiability warnings from a covariance
// (covariance_report.hpp).
#include "friction/covariance_report.hpp"

#include <algorithm>
#include <cmath>

#include "friction/error.hpp"

namespace friction {

namespace {

// Standard error and 95 % interval of one parameter with a covariance column.
ParameterUncertainty uncertainty(const CovarianceParameter& p, double variance,
                                 const CovarianceOptions& o) {
  ParameterUncertainty u;
  u.available = true;
  u.fitted_standard_error = std::sqrt(std::max(0.0, variance));
  const double s = u.fitted_standard_error;
  double lo = 0, hi = 0;
  if (p.fitted == Parametrisation::log) {
    const double se = p.value * s;
    u.standard_error = std::isfinite(se) ? se : 0.0;
    lo = p.value * std::exp(-1.96 * s);
    hi = p.value * std::exp(1.96 * s);
  } else {
    u.standard_error = s * p.scale;
    lo = p.value - 1.96 * u.standard_error;
    hi = p.value + 1.96 * u.standard_error;
  }
  if (o.clip_to_limits) {
    u.clipped = !(lo >= p.lower_limit) || !(hi <= p.upper_limit);
    u.lower95 = lo >= p.lower_limit ? lo : std::min(p.lower_limit, p.value);
    u.upper95 = hi <= p.upper_limit ? hi : std::max(p.upper_limit, p.value);
  } else {
    u.lower95 = lo;
    u.upper95 = hi;
  }
  return u;
}

}  // namespace

CovarianceReport covariance_report(const Eigen::MatrixXd* covariance,
                                   const std::vector<CovarianceParameter>& parameters,
                                   const CovarianceOptions& o) {
  const std::size_t n = parameters.size();
  const auto ni = static_cast<Eigen::Index>(n);
  CovarianceReport r;
  r.computed = covariance != nullptr;
  r.correlation = Eigen::MatrixXd::Identity(ni, ni);
  r.parameters.resize(n);
  for (std::size_t a = 0; a < n; ++a)
    r.parameters[a].lower95 = r.parameters[a].upper95 = parameters[a].value;
  if (!covariance) {
    r.warnings.push_back({IdentifiabilityIssue::covariance_unavailable, 0, 0, 0.0});
    return r;
  }
  const Eigen::MatrixXd& c = *covariance;
  for (std::size_t a = 0; a < n; ++a) {
    const CovarianceParameter& p = parameters[a];
    FRICTION_CHECK(p.column < c.rows(), "covariance_report: column ", p.column, " of ", p.name,
                   " outside a ", c.rows(), "-row covariance");
    if (p.column < 0) {
      r.warnings.push_back(
          {p.at_bound ? IdentifiabilityIssue::at_bound : IdentifiabilityIssue::no_standard_error, a,
           0, 0.0});
      continue;
    }
    ParameterUncertainty& u = r.parameters[a];
    u = uncertainty(p, c(p.column, p.column), o);
    if (p.fitted == Parametrisation::log && u.upper95 > o.span_limit * u.lower95)
      r.warnings.push_back({IdentifiabilityIssue::wide_interval, a, 0, 0.0});
    if (p.fitted == Parametrisation::linear && o.zero_test &&
        std::abs(p.value) < 1.96 * u.standard_error)
      r.warnings.push_back({IdentifiabilityIssue::not_significant, a, 0, 0.0});
  }
  for (std::size_t a = 0; a < n; ++a)
    for (std::size_t b = 0; b < n; ++b) {
      const std::ptrdiff_t ca = parameters[a].column, cb = parameters[b].column;
      if (a == b || ca < 0 || cb < 0) continue;
      const double den = std::sqrt(c(ca, ca) * c(cb, cb));
      r.correlation(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) =
          den > 0.0 ? c(ca, cb) / den : 0.0;
    }
  for (std::size_t a = 0; a < n; ++a)
    for (std::size_t b = a + 1; b < n; ++b) {
      const double v = r.correlation(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b));
      if (std::abs(v) > o.correlation_limit)
        r.warnings.push_back({IdentifiabilityIssue::correlated, a, b, v});
    }
  return r;
}

void CovarianceReport::apply(std::vector<ParameterEstimate>& estimates) const {
  FRICTION_CHECK(estimates.size() == parameters.size(),
                 "CovarianceReport::apply: ", estimates.size(), " estimates for ",
                 parameters.size(), " parameters");
  for (std::size_t a = 0; a < parameters.size(); ++a) {
    estimates[a].standard_error = parameters[a].standard_error;
    estimates[a].lower95 = parameters[a].lower95;
    estimates[a].upper95 = parameters[a].upper95;
  }
}

}  // namespace friction
