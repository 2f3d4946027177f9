// The out-of-line parts of compressed_cost.hpp.
#include "compressed_cost.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>

#include "friction/error.hpp"

namespace friction::detail {

void normal_factor(Eigen::MatrixXd& gram, Eigen::MatrixXd& factor) {
  const Eigen::Index p = gram.rows();
  Eigen::VectorXd scale(p);
  for (Eigen::Index j = 0; j < p; ++j) scale(j) = gram(j, j) > 0.0 ? std::sqrt(gram(j, j)) : 1.0;
  for (Eigen::Index j = 0; j < p; ++j)
    for (Eigen::Index i = j; i < p; ++i) gram(i, j) /= scale(i) * scale(j);
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(gram);
  const Eigen::MatrixXd perm = ldlt.transpositionsP() * Eigen::MatrixXd::Identity(p, p);
  factor.noalias() = ldlt.matrixU() * perm;
  for (Eigen::Index i = 0; i < p; ++i)
    factor.row(i) *= std::sqrt(std::max(0.0, ldlt.vectorD()(i)));
  factor = factor * scale.asDiagonal();
}

GramAccumulator::GramAccumulator(Eigen::MatrixXd& gram)
    : gram_(gram), rows_(kRows, gram.rows()) {}

void GramAccumulator::add(const double* const* blocks, const std::vector<int>& sizes, double r) {
  Eigen::Index c = 0;
  for (std::size_t k = 0; k < sizes.size(); ++k) {
    if (!blocks[k]) continue;
    for (int j = 0; j < sizes[k]; ++j) rows_(used_, c + j) = blocks[k][j];
    c += sizes[k];
  }
  rows_(used_, c) = r;
  if (++used_ == kRows) flush();
}

void GramAccumulator::flush() {
  if (used_ == 0) return;
  // Columns that are zero on every gathered row add nothing; they are common (an operator's
  // initial deflection is forgotten for good once it slips, so its column is zero from there on).
  // The products of the others are formed alone and added where they belong: per entry the same
  // terms as the full product's, summed by Eigen's kernel for the smaller matrix in another order
  // (the numbers move at rounding; README, "Where a diagnosis of data/ spends its time").
  const Eigen::Index p = rows_.cols();
  live_.clear();
  for (Eigen::Index c = 0; c < p; ++c)
    if (!(rows_.col(c).head(used_).array() == 0.0).all()) live_.push_back(c);
  const Eigen::Index nl = static_cast<Eigen::Index>(live_.size());
  if (nl == p) {
    gram_.selfadjointView<Eigen::Lower>().rankUpdate(rows_.topRows(used_).transpose());
  } else if (nl > 0) {
    live_rows_.resize(used_, nl);
    for (Eigen::Index u = 0; u < nl; ++u)
      live_rows_.col(u) = rows_.col(live_[static_cast<std::size_t>(u)]).head(used_);
    live_gram_.setZero(nl, nl);
    live_gram_.selfadjointView<Eigen::Lower>().rankUpdate(live_rows_.transpose());
    for (Eigen::Index b = 0; b < nl; ++b)
      for (Eigen::Index a = b; a < nl; ++a)
        gram_(live_[static_cast<std::size_t>(a)], live_[static_cast<std::size_t>(b)]) +=
            live_gram_(a, b);
  }
  used_ = 0;
}

void accumulate_gram(const std::vector<const double*>& blocks, const std::vector<int>& sizes,
                     const double* residuals, Eigen::Index n, Eigen::MatrixXd& gram) {
  GramAccumulator acc(gram);
  std::vector<const double*> row(blocks.size());
  for (Eigen::Index t = 0; t < n; ++t) {
    for (std::size_t k = 0; k < blocks.size(); ++k)
      row[k] = blocks[k] ? blocks[k] + t * sizes[k] : nullptr;
    acc.add(row.data(), sizes, residuals[t]);
  }
  acc.flush();
}

RowCompressor::RowCompressor(Eigen::Index cols) : cols_(cols), stack_(0, cols) {}

void RowCompressor::add(const Eigen::Ref<const Eigen::MatrixXd>& rows) {
  FRICTION_CHECK(rows.cols() == cols_, "RowCompressor: ", rows.cols(), " columns for ", cols_);
  if (rows.rows() == 0) return;
  const Eigen::Index top = stack_.rows();
  stack_.conservativeResize(top + rows.rows(), cols_);
  stack_.bottomRows(rows.rows()) = rows;
  {
    Eigen::HouseholderQR<Eigen::Ref<Eigen::MatrixXd>> qr(stack_);  // in place
  }
  stack_.conservativeResize(std::min(stack_.rows(), cols_), cols_);
  stack_.triangularView<Eigen::StrictlyLower>().setZero();
}

Eigen::MatrixXd RowCompressor::factor() const {
  Eigen::MatrixXd r = Eigen::MatrixXd::Zero(cols_, cols_);
  r.topRows(stack_.rows()) = stack_;
  return r;
}

CompressedCost::CompressedCost(ceres::CostFunction* inner)
    : inner_(inner), streaming_(dynamic_cast<const RowStreamingCost*>(inner)) {
  *mutable_parameter_block_sizes() = inner_->parameter_block_sizes();
  int p = 0;
  for (int s : inner_->parameter_block_sizes()) p += s;
  set_num_residuals(p + 1);
}

bool CompressedCost::Evaluate(double const* const* parameters, double* residuals,
                              double** jacobians) const {
  const Eigen::Index n = inner_->num_residuals();
  const Eigen::Index rows = num_residuals();
  residuals_.resize(static_cast<std::size_t>(n));
  Eigen::Map<Eigen::VectorXd> out(residuals, rows);
  if (!jacobians) {
    out.setZero();
    if (!same_as_last_value_point(parameters)) {
      // Forgotten first: an evaluation that throws leaves no answer behind for its point.
      last_value_point_.clear();
      last_value_ok_ = inner_->Evaluate(parameters, residuals_.data(), nullptr);
      last_value_norm_ =
          last_value_ok_ ? Eigen::Map<const Eigen::VectorXd>(residuals_.data(), n).norm() : 0.0;
      const auto& sizes = inner_->parameter_block_sizes();
      for (std::size_t b = 0; b < sizes.size(); ++b)
        last_value_point_.insert(last_value_point_.end(), parameters[b], parameters[b] + sizes[b]);
    }
    out(rows - 1) = last_value_norm_;
    return last_value_ok_ && std::isfinite(last_value_norm_);
  }
  const auto& sizes = inner_->parameter_block_sizes();
  Eigen::Index p = 0;  // the requested columns
  for (std::size_t b = 0; b < sizes.size(); ++b)
    if (jacobians[b]) p += sizes[b];
  gram_.setZero(p + 1, p + 1);
  const bool ok = streaming_ && streaming_->streams() ? add_rows_streamed(parameters, jacobians)
                                                      : add_rows_whole(parameters, jacobians);
  if (!ok) return false;
  normal_factor(gram_, factor_);
  if (!factor_.allFinite()) return false;
  // Rows beyond P + 1 of the requested columns (blocks held constant) are zero.
  out.setZero();
  out.head(p + 1) = factor_.col(p);
  Eigen::Index c = 0;
  for (std::size_t b = 0; b < sizes.size(); ++b) {
    if (!jacobians[b]) continue;
    using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    Eigen::Map<RowMajor> j(jacobians[b], rows, sizes[b]);
    j.setZero();
    j.topRows(p + 1) = factor_.middleCols(c, sizes[b]);
    c += sizes[b];
  }
  return true;
}

bool CompressedCost::same_as_last_value_point(double const* const* parameters) const {
  if (last_value_point_.empty()) return false;
  const auto& sizes = inner_->parameter_block_sizes();
  std::size_t k = 0;
  for (std::size_t b = 0; b < sizes.size(); ++b)
    for (int i = 0; i < sizes[b]; ++i, ++k)
      if (std::bit_cast<std::uint64_t>(last_value_point_[k]) !=
          std::bit_cast<std::uint64_t>(parameters[b][i]))
        return false;
  return true;
}

bool CompressedCost::add_rows_streamed(double const* const* parameters,
                                       double** jacobians) const {
  const auto& sizes = inner_->parameter_block_sizes();
  const std::unique_ptr<bool[]> requested(new bool[sizes.size()]);
  for (std::size_t b = 0; b < sizes.size(); ++b) requested[b] = jacobians[b] != nullptr;
  GramAccumulator acc(gram_);
  // rows[b] is null for a block not requested (RowStreamingCost): the accumulator skips it.
  if (!streaming_->EvaluateRows(parameters, residuals_.data(), requested.get(),
                                [&](std::size_t k, const double* const* rows) {
                                  acc.add(rows, sizes, residuals_[k]);
                                }))
    return false;
  acc.flush();
  return true;
}

bool CompressedCost::add_rows_whole(double const* const* parameters, double** jacobians) const {
  const Eigen::Index n = inner_->num_residuals();
  const auto& sizes = inner_->parameter_block_sizes();
  jacobians_.resize(sizes.size());
  std::vector<double*> inner_jacobians(sizes.size(), nullptr);
  for (std::size_t b = 0; b < sizes.size(); ++b) {
    if (!jacobians[b]) continue;
    jacobians_[b].resize(static_cast<std::size_t>(n * sizes[b]));
    inner_jacobians[b] = jacobians_[b].data();
  }
  if (!inner_->Evaluate(parameters, residuals_.data(), inner_jacobians.data())) return false;
  const std::vector<const double*> blocks(inner_jacobians.begin(), inner_jacobians.end());
  accumulate_gram(blocks, sizes, residuals_.data(), n, gram_);
  return true;
}

}  // namespace friction::detail
