// Forward-mode derivatives of a record-long model run, handed over a sample at a time (not
// installed).
//
// ceres::DynamicAutoDiffCostFunction evaluates a functor of N residuals on Jets of a fixed stride
// (16 lanes), in as many passes as the parameters need, and keeps what each pass produces: N
// output Jets (8 (stride + 1) bytes each) and the N x P Jacobian it returns.  At 10^6 samples
// and P = 30 that is 136 + 240 bytes a sample per evaluation, which the diagnosis paid for every
// fit and every covariance of a family without the structured Jacobian (extension_fit.cpp).
//
// Here the functor visits its residuals in sample order, visit(k, residual_k), and all
// parameters are carried in one pass on Jets of 16, 32 or 64 lanes (the fewest that hold the
// requested columns), so each Jacobian row is complete when its sample is: RowStreamingCost hands
// it on and nothing of length N is kept but the residuals.  Each lane's arithmetic is the one of
// a pass of the stride-16 evaluation (a Jet's lanes never mix), so rows and residuals are those
// of ceres::DynamicAutoDiffCostFunction to the bit; a value-only evaluation runs the functor on
// doubles.  More than 64 requested columns (a DNLRX base with long filters) take passes of 64
// lanes into the caller's N x P blocks, as Ceres did, and do not stream.
#pragma once

#include <ceres/cost_function.h>
#include <ceres/jet.h>

#include <algorithm>
#include <cstddef>
#include <memory>
#include <vector>

#include "compressed_cost.hpp"

namespace friction::detail {

/// Functor: `template <typename T, class Visit> bool operator()(T const* const* p, Visit&& visit)
/// const`, calling visit(k, residual_k) for k = 0, ..., N - 1 in order (false: outside the
/// model's domain, as for Ceres' autodiff functors).
template <class Functor>
class StreamedAutoDiffCost final : public ceres::CostFunction, public RowStreamingCost {
 public:
  static constexpr int kMaxLanes = 64;

  StreamedAutoDiffCost(std::unique_ptr<Functor> functor, const std::vector<int>& block_sizes,
                       int residuals)
      : functor_(std::move(functor)) {
    *mutable_parameter_block_sizes() = block_sizes;
    set_num_residuals(residuals);
  }

  const Functor& functor() const { return *functor_; }

  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    if (!jacobians)
      return (*functor_)(p, [&](std::size_t k, double r) { residuals[k] = r; });
    const auto& sizes = parameter_block_sizes();
    const std::unique_ptr<bool[]> requested(new bool[sizes.size()]);
    for (std::size_t b = 0; b < sizes.size(); ++b) requested[b] = jacobians[b] != nullptr;
    const int columns = requested_columns(requested.get());
    // Column c of the requested ones is entry c - first[b] of block b.
    for (int first = 0; first == 0 || first < columns; first += kMaxLanes) {
      const int lanes = std::min(columns - first, kMaxLanes);
      const bool ok = dispatch(lanes, p, residuals, requested.get(), first,
                               [&](std::size_t k, const double* row) {
                                 int c = 0;
                                 for (std::size_t b = 0; b < sizes.size(); ++b) {
                                   if (!requested[b]) continue;
                                   for (int i = 0; i < sizes[b]; ++i, ++c)
                                     if (c >= first && c < first + lanes)
                                       jacobians[b][k * static_cast<std::size_t>(sizes[b]) +
                                                    static_cast<std::size_t>(i)] = row[c - first];
                                 }
                               });
      if (!ok) return false;
    }
    return true;
  }

  /// Whether every parameter fits in one pass (with every block requested).
  bool streams() const override {
    int total = 0;
    for (int s : parameter_block_sizes()) total += s;
    return total <= kMaxLanes;
  }

  bool EvaluateRows(double const* const* p, double* residuals, const bool* requested,
                    const RowVisitor& visit) const override {
    const int columns = requested_columns(requested);
    if (columns > kMaxLanes) return false;
    const auto& sizes = parameter_block_sizes();
    std::vector<const double*> rows(sizes.size(), nullptr);
    return dispatch(columns, p, residuals, requested, 0, [&](std::size_t k, const double* row) {
      int c = 0;
      for (std::size_t b = 0; b < sizes.size(); ++b) {
        rows[b] = requested[b] ? row + c : nullptr;
        if (requested[b]) c += sizes[b];
      }
      visit(k, rows.data());
    });
  }

 private:
  int requested_columns(const bool* requested) const {
    int columns = 0;
    const auto& sizes = parameter_block_sizes();
    for (std::size_t b = 0; b < sizes.size(); ++b)
      if (requested[b]) columns += sizes[b];
    return columns;
  }

  template <class Row>
  bool dispatch(int lanes, double const* const* p, double* residuals, const bool* requested,
                int first, Row&& row) const {
    if (lanes <= 16) return pass<16>(p, residuals, requested, first, row);
    if (lanes <= 32) return pass<32>(p, residuals, requested, first, row);
    return pass<64>(p, residuals, requested, first, row);
  }

  // One run of the functor on Jets whose lane l is requested column first + l; row(k, lanes) gets
  // the derivatives of residual k (L values, those beyond the columns zero).
  template <int L, class Row>
  bool pass(double const* const* p, double* residuals, const bool* requested, int first,
            Row& row) const {
    using J = ceres::Jet<double, L>;
    const auto& sizes = parameter_block_sizes();
    std::vector<std::vector<J>> blocks(sizes.size());
    std::vector<const J*> pointers(sizes.size());
    int c = 0;
    for (std::size_t b = 0; b < sizes.size(); ++b) {
      for (int i = 0; i < sizes[b]; ++i) {
        J v(p[b][i]);
        if (requested[b]) {
          if (c >= first && c < first + L) v.v[c - first] = 1.0;
          ++c;
        }
        blocks[b].push_back(v);
      }
      pointers[b] = blocks[b].data();
    }
    return (*functor_)(pointers.data(), [&](std::size_t k, const J& r) {
      residuals[k] = r.a;
      row(k, r.v.data());
    });
  }

  std::unique_ptr<Functor> functor_;
};

}  // namespace friction::detail
