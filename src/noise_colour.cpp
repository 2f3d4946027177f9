// Sandwich covariance for AR(1) residuals (see noise_colour.hpp).
#include "friction/noise_colour.hpp"

#include <algorithm>
#include <cmath>

#include "friction/error.hpp"

namespace friction {

ResidualColour residual_colour(std::span<const double> e) {
  ResidualColour c;
  const std::size_t n = e.size();
  if (n < 8) return c;
  double mean = 0;
  for (double v : e) mean += v;
  mean /= static_cast<double>(n);
  double c0 = 0, c1 = 0, c2 = 0;
  for (std::size_t t = 0; t < n; ++t) {
    const double a = e[t] - mean;
    c0 += a * a;
    if (t >= 1) c1 += a * (e[t - 1] - mean);
    if (t >= 2) c2 += a * (e[t - 2] - mean);
  }
  if (!(c0 > 0)) return c;
  c.lag_one = c1 / c0;
  c.lag_two = c2 / c0;
  c.phi = std::clamp(c.lag_one, 0.0, 0.99);
  // The sampling error of an autocorrelation estimate is about sqrt(1/N) for white noise and
  // grows with the colour (Bartlett); judged against 3 such errors with the AR(1) long-run factor.
  const double scale = std::sqrt(c.slow_inflation() / static_cast<double>(n));
  c.ar1_adequate = std::abs(c.lag_two - c.phi * c.phi) <= 3 * scale;
  return c;
}

ColouredGram::ColouredGram(std::size_t parameters, double phi)
    : phi_(phi),
      g_(Eigen::VectorXd::Zero(static_cast<Eigen::Index>(parameters))),
      gram_(Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(parameters),
                                  static_cast<Eigen::Index>(parameters))),
      cross_(gram_) {
  FRICTION_CHECK(phi >= 0 && phi < 1, "ColouredGram: phi = ", phi, " must lie in [0, 1)");
}

void ColouredGram::add(std::span<const double> row) {
  FRICTION_CHECK(row.size() == static_cast<std::size_t>(g_.size()), "ColouredGram: row of ",
                 row.size(), " values, expected ", g_.size());
  const Eigen::Map<const Eigen::VectorXd> j(row.data(), static_cast<Eigen::Index>(row.size()));
  g_ = j + phi_ * g_;
  gram_.noalias() += j * j.transpose();
  cross_.noalias() += j * g_.transpose();
}

Eigen::MatrixXd ColouredGram::coloured() const {
  return cross_ + cross_.transpose() - gram_;
}

Eigen::MatrixXd sandwich_covariance(const Eigen::MatrixXd& gram_inverse,
                                    const Eigen::MatrixXd& coloured, double residual_variance) {
  return residual_variance * gram_inverse * coloured * gram_inverse;
}

}  // namespace friction
