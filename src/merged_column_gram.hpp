// The Gram matrix A^T A of a tall matrix whose columns become equal to one another as the rows go
// on, accumulated from blocks of rows that hold only the columns not yet merged (not installed).
//
// NLR's dictionary (nlr.cpp, dictionary_operators) has three columns per grid threshold: the
// operator's trajectory from the virgin state and from either bound.  Once the record's range has
// covered twice the threshold the three sit at the same bound, and from then on they are the same
// recursion on the same input, equal to the bit.  A block of rows then needs only one of them: its
// Gram matrix over the columns it holds is spread over the full one, entry (a, b) of the full
// matrix taking entry (held(a), held(b)) of the block's, where held maps a merged column to the
// column it equals.  On a record whose range soon covers most of the grid that is a third of the
// columns and a ninth of the products.
//
// The caller decides what is merged, before the block whose rows make it true; a merge is for
// good (the rows of every later block must carry the equality), and a column can only be merged
// into one that is itself held.
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <vector>

#include "friction/error.hpp"

namespace friction::detail {

class MergedColumnGram {
 public:
  explicit MergedColumnGram(Eigen::Index columns)
      : gram_(Eigen::MatrixXd::Zero(columns, columns)),
        into_(static_cast<std::size_t>(columns), -1),
        slot_(static_cast<std::size_t>(columns)) {
    index_held();
  }

  Eigen::Index columns() const { return gram_.cols(); }

  /// From the next block on, `column` equals `into` (a held column) on every row.  A column
  /// already merged stays where it was merged.
  void merge(Eigen::Index column, Eigen::Index into) {
    FRICTION_CHECK(column >= 0 && column < columns() && into >= 0 && into < columns() &&
                       column != into && !merged(into),
                   "MergedColumnGram::merge: a column can only be merged into a held one");
    if (merged(column)) return;
    // A column merged before into `column` follows it.
    for (Eigen::Index& target : into_)
      if (target == column) target = into;
    into_[static_cast<std::size_t>(column)] = into;
    index_held();
  }

  bool merged(Eigen::Index column) const { return into_[static_cast<std::size_t>(column)] >= 0; }

  /// The columns a block holds, in increasing order: its column u is column held()[u] of A.
  const std::vector<Eigen::Index>& held() const { return held_; }

  /// Adds the products of a block of rows, rows x held().size(), its columns as held() says.
  void add(const Eigen::Ref<const Eigen::MatrixXd>& block) {
    const Eigen::Index nu = static_cast<Eigen::Index>(held_.size());
    FRICTION_CHECK(block.cols() == nu, "MergedColumnGram::add: the block must hold held() columns");
    block_gram_.setZero(nu, nu);
    block_gram_.selfadjointView<Eigen::Lower>().rankUpdate(block.transpose());
    for (Eigen::Index a = 0; a < columns(); ++a) {
      const Eigen::Index ua = slot_[static_cast<std::size_t>(a)];
      for (Eigen::Index b = 0; b <= a; ++b) {
        const Eigen::Index ub = slot_[static_cast<std::size_t>(b)];
        gram_(a, b) += ua >= ub ? block_gram_(ua, ub) : block_gram_(ub, ua);
      }
    }
  }

  /// A^T A over the rows added; its lower triangle (the upper is not written).
  const Eigen::MatrixXd& gram() const { return gram_; }

 private:
  void index_held() {
    held_.clear();
    for (Eigen::Index c = 0; c < columns(); ++c)
      if (!merged(c)) {
        slot_[static_cast<std::size_t>(c)] = static_cast<Eigen::Index>(held_.size());
        held_.push_back(c);
      }
    for (Eigen::Index c = 0; c < columns(); ++c)
      if (merged(c))
        slot_[static_cast<std::size_t>(c)] =
            slot_[static_cast<std::size_t>(into_[static_cast<std::size_t>(c)])];
  }

  Eigen::MatrixXd gram_, block_gram_;
  std::vector<Eigen::Index> into_;  ///< the held column a merged one equals; -1 when held
  std::vector<Eigen::Index> slot_;  ///< a column's place in a block
  std::vector<Eigen::Index> held_;
};

}  // namespace friction::detail
