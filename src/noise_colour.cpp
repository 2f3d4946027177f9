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

std::size_t score_block_length(std::size_t n, const ResidualColour& c) {
  const auto root = static_cast<std::size_t>(std::floor(std::sqrt(static_cast<double>(n))));
  const auto colour = static_cast<std::size_t>(std::ceil(5.0 * c.slow_inflation()));
  return std::max<std::size_t>({root, colour, 1});
}

BlockScores::BlockScores(std::size_t parameters, std::size_t block_length)
    : length_(block_length), score_(Eigen::VectorXd::Zero(static_cast<Eigen::Index>(parameters))) {
  FRICTION_CHECK(block_length > 0, "BlockScores: a block of 0 samples");
}

void BlockScores::add(std::span<const double> row, double residual) {
  FRICTION_CHECK(row.size() == static_cast<std::size_t>(score_.size()), "BlockScores: row of ",
                 row.size(), " values, expected ", score_.size());
  score_ += residual * Eigen::Map<const Eigen::VectorXd>(row.data(), score_.size());
  if (++in_block_ == length_) {
    done_.push_back(score_);
    score_.setZero();
    in_block_ = 0;
  }
}

Eigen::MatrixXd BlockScores::meat(std::size_t merge) const {
  FRICTION_CHECK(merge > 0, "BlockScores: blocks of 0 base blocks");
  const auto p = score_.size();
  Eigen::MatrixXd meat = Eigen::MatrixXd::Zero(p, p);
  Eigen::VectorXd s = Eigen::VectorXd::Zero(p);
  std::size_t in = 0;
  for (const Eigen::VectorXd& b : done_) {
    s += b;
    if (++in == merge) {
      meat.noalias() += s * s.transpose();
      s.setZero();
      in = 0;
    }
  }
  if (in_block_ > 0) s += score_, ++in;
  if (in > 0) meat.noalias() += s * s.transpose();
  return meat;
}

BlockScores BlockScores::selected(const std::vector<Eigen::Index>& columns,
                                  const Eigen::VectorXd& scale) const {
  FRICTION_CHECK(scale.size() == static_cast<Eigen::Index>(columns.size()), "BlockScores: ",
                 scale.size(), " scales for ", columns.size(), " columns");
  const auto pick = [&](const Eigen::VectorXd& s) {
    Eigen::VectorXd out(scale.size());
    for (Eigen::Index q = 0; q < scale.size(); ++q) {
      const Eigen::Index c = columns[static_cast<std::size_t>(q)];
      FRICTION_CHECK(c >= 0 && c < score_.size(), "BlockScores: column ", c, " of ", score_.size());
      out(q) = scale(q) * s(c);
    }
    return out;
  };
  BlockScores out(columns.size(), length_);
  out.in_block_ = in_block_;
  out.score_ = pick(score_);
  out.done_.reserve(done_.size());
  for (const Eigen::VectorXd& b : done_) out.done_.push_back(pick(b));
  return out;
}

std::size_t BlockScores::blocks(std::size_t merge) const {
  FRICTION_CHECK(merge > 0, "BlockScores: blocks of 0 base blocks");
  const std::size_t base = done_.size() + (in_block_ > 0 ? 1 : 0);
  return (base + merge - 1) / merge;
}

Eigen::MatrixXd block_sandwich_covariance(const Eigen::MatrixXd& gram_inverse,
                                          const BlockScores& scores, std::size_t n,
                                          std::size_t rank) {
  FRICTION_CHECK(scores.blocks() >= 2 && n > rank, "block_sandwich_covariance: ", scores.blocks(),
                 " blocks, ", n, " samples, rank ", rank);
  Eigen::MatrixXd out;
  for (std::size_t merge = 1; merge == 1 || scores.blocks(merge) >= kMinimumScoreBlocks;
       merge *= 2) {
    const auto b = static_cast<double>(scores.blocks(merge));
    const double factor = b / (b - 1) * static_cast<double>(n - 1) / static_cast<double>(n - rank);
    const Eigen::MatrixXd c = factor * gram_inverse * scores.meat(merge) * gram_inverse;
    out = merge == 1 ? c : larger_variances(out, c);
  }
  return out;
}

Eigen::MatrixXd larger_variances(const Eigen::MatrixXd& model, const Eigen::MatrixXd& robust) {
  FRICTION_CHECK(model.rows() == robust.rows() && model.cols() == robust.cols() &&
                     model.rows() == model.cols(),
                 "larger_variances: ", model.rows(), "x", model.cols(), " and ", robust.rows(), "x",
                 robust.cols());
  const Eigen::Index p = model.rows();
  Eigen::VectorXd s(p), m(p);
  for (Eigen::Index q = 0; q < p; ++q) {
    m(q) = std::sqrt(std::max(model(q, q), 0.0));
    s(q) = std::sqrt(std::max({model(q, q), robust(q, q), 0.0}));
  }
  Eigen::MatrixXd out(p, p);
  for (Eigen::Index j = 0; j < p; ++j)
    for (Eigen::Index i = 0; i < p; ++i) {
      if (i == j) {
        out(i, j) = s(i) * s(i);
      } else {
        const double c = m(i) > 0 && m(j) > 0 ? model(i, j) / (m(i) * m(j)) : 0.0;
        out(i, j) = s(i) * s(j) * c;
      }
    }
  return out;
}

}  // namespace friction
