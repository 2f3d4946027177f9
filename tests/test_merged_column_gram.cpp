// MergedColumnGram (src/merged_column_gram.hpp), the Gram matrix of NLR's dictionary: blocks of
// rows hold only the columns not yet merged into an equal one, and their products are spread over
// the full matrix.  Checked against A^T A summed here sample by sample, on random matrices whose
// columns become equal to others from random rows on, in random blocks.
#include <gtest/gtest.h>

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "../src/merged_column_gram.hpp"
#include "friction/error.hpp"

namespace test_merged_column_gram {
namespace {

using friction::detail::MergedColumnGram;

// A matrix of `rows` x `columns` random values in which column c, from row from[c] on, is a copy
// of column into[c] (into[c] < 0: never).  into[] may chain (c -> b -> a): b's copy of a then
// starts no later than c's copy of b.
struct Merging {
  Eigen::MatrixXd a;
  std::vector<Eigen::Index> into, from;
};

Merging random_merging(std::mt19937_64& rng, Eigen::Index rows, Eigen::Index columns) {
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> unit;
  Merging m;
  m.a.resize(rows, columns);
  for (Eigen::Index c = 0; c < columns; ++c)
    for (Eigen::Index t = 0; t < rows; ++t) m.a(t, c) = normal(rng) * std::pow(10.0, c % 3);
  m.into.assign(static_cast<std::size_t>(columns), -1);
  m.from.assign(static_cast<std::size_t>(columns), rows);
  for (Eigen::Index c = 1; c < columns; ++c) {
    if (unit(rng) < 0.3) continue;  // never merged
    const Eigen::Index target = static_cast<Eigen::Index>(unit(rng) * static_cast<double>(c));
    Eigen::Index start = static_cast<Eigen::Index>(unit(rng) * static_cast<double>(rows));
    // A chain: the target's own copy must already hold where this one starts.
    start = std::max(start, m.from[static_cast<std::size_t>(target)] == rows
                                ? Eigen::Index{0}
                                : m.from[static_cast<std::size_t>(target)]);
    m.into[static_cast<std::size_t>(c)] = target;
    m.from[static_cast<std::size_t>(c)] = start;
  }
  // Copies in column order, so that a chain copies values already copied.
  for (Eigen::Index c = 0; c < columns; ++c) {
    const Eigen::Index target = m.into[static_cast<std::size_t>(c)];
    if (target < 0) continue;
    const Eigen::Index start = m.from[static_cast<std::size_t>(c)];
    m.a.col(c).tail(rows - start) = m.a.col(target).tail(rows - start);
  }
  return m;
}

// A^T A by plain sums over the samples, in long double.
Eigen::MatrixXd plain_gram(const Eigen::MatrixXd& a) {
  const Eigen::Index p = a.cols();
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(p, p);
  for (Eigen::Index i = 0; i < p; ++i)
    for (Eigen::Index j = 0; j <= i; ++j) {
      long double s = 0;
      for (Eigen::Index t = 0; t < a.rows(); ++t)
        s += static_cast<long double>(a(t, i)) * static_cast<long double>(a(t, j));
      g(i, j) = static_cast<double>(s);
    }
  return g;
}

// Accumulates `m.a` in random blocks, merging a column before the first block that lies wholly
// in its copied rows (`honest`); otherwise (a defect on purpose) before the first block of all.
Eigen::MatrixXd merged_gram(const Merging& m, std::mt19937_64& rng, bool honest = true) {
  const Eigen::Index rows = m.a.rows(), columns = m.a.cols();
  MergedColumnGram gram(columns);
  std::uniform_int_distribution<Eigen::Index> length(1, 300);
  for (Eigen::Index t0 = 0; t0 < rows;) {
    // Merging in column order: a chain's target is merged (into its own target) first, and a
    // merge into a column merged in the same pass goes to the column that one follows.
    for (Eigen::Index c = 0; c < columns; ++c) {
      const Eigen::Index target = m.into[static_cast<std::size_t>(c)];
      if (target < 0 || gram.merged(c)) continue;
      if (honest && m.from[static_cast<std::size_t>(c)] > t0) continue;
      Eigen::Index held = target;
      while (gram.merged(held)) held = m.into[static_cast<std::size_t>(held)];
      gram.merge(c, held);
    }
    const Eigen::Index n = std::min(length(rng), rows - t0);
    const std::vector<Eigen::Index>& held = gram.held();
    Eigen::MatrixXd block(n, static_cast<Eigen::Index>(held.size()));
    for (std::size_t u = 0; u < held.size(); ++u)
      block.col(static_cast<Eigen::Index>(u)) = m.a.col(held[u]).segment(t0, n);
    gram.add(block);
    t0 += n;
  }
  return gram.gram();
}

// The largest difference of the lower triangles, relative to sqrt(G_ii G_jj).
double largest_relative_difference(const Eigen::MatrixXd& g, const Eigen::MatrixXd& reference) {
  double worst = 0;
  for (Eigen::Index i = 0; i < g.cols(); ++i)
    for (Eigen::Index j = 0; j <= i; ++j) {
      const double s = std::sqrt(reference(i, i) * reference(j, j));
      worst = std::max(worst, std::abs(g(i, j) - reference(i, j)) / s);
    }
  return worst;
}

TEST(MergedColumnGram, EqualsTheWholeGramMatrixOnRandomMergings) {
  std::mt19937_64 rng(0x51a7c0de2026ULL);
  int merged_columns = 0, chains = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const Eigen::Index rows = 200 + static_cast<Eigen::Index>(rng() % 3000);
    const Eigen::Index columns = 2 + static_cast<Eigen::Index>(rng() % 30);
    const Merging m = random_merging(rng, rows, columns);
    for (std::size_t c = 0; c < m.into.size(); ++c) {
      merged_columns += m.into[c] >= 0;
      chains += m.into[c] >= 0 && m.into[static_cast<std::size_t>(m.into[c])] >= 0;
    }
    const Eigen::MatrixXd reference = plain_gram(m.a);
    EXPECT_LT(largest_relative_difference(merged_gram(m, rng), reference), 1e-13)
        << "trial " << trial << ": " << rows << " x " << columns;
  }
  // The random mergings did exercise what they are meant to.
  EXPECT_GT(merged_columns, 200);
  EXPECT_GT(chains, 50);
}

// The comparison sees merges made before the columns are equal: the products of the rows before
// the copy are then those of the wrong column.
TEST(MergedColumnGram, AMergeBeforeTheColumnsAreEqualIsSeen) {
  std::mt19937_64 rng(0x0dd5eedULL);
  int seen = 0, trials = 0;
  for (int trial = 0; trial < 20; ++trial) {
    const Merging m = random_merging(rng, 2000, 12);
    const bool late_copy = std::any_of(m.from.begin(), m.from.end(),
                                       [](Eigen::Index f) { return f > 300 && f < 2000; });
    if (!late_copy) continue;
    ++trials;
    seen += largest_relative_difference(merged_gram(m, rng, false), plain_gram(m.a)) > 1e-6;
  }
  ASSERT_GT(trials, 10);
  EXPECT_EQ(seen, trials);
}

// Adds one row holding `held_values` (the held columns') to a Gram matrix with nothing added yet:
// its lower triangle must then be that of the whole row's outer product, exactly.
void expect_gram_of_one_row(MergedColumnGram& gram, const Eigen::VectorXd& held_values,
                            const Eigen::VectorXd& whole_row) {
  gram.add(held_values.transpose());
  const Eigen::MatrixXd expected = whole_row * whole_row.transpose();
  for (Eigen::Index i = 0; i < whole_row.size(); ++i)
    for (Eigen::Index j = 0; j <= i; ++j) EXPECT_EQ(gram.gram()(i, j), expected(i, j));
}

TEST(MergedColumnGram, HeldColumnsAndTheirOrder) {
  MergedColumnGram gram(5);
  EXPECT_EQ(gram.held(), (std::vector<Eigen::Index>{0, 1, 2, 3, 4}));
  gram.merge(3, 1);
  EXPECT_EQ(gram.held(), (std::vector<Eigen::Index>{0, 1, 2, 4}));
  gram.merge(1, 0);  // 3 follows 1 into 0
  EXPECT_TRUE(gram.merged(3));
  EXPECT_EQ(gram.held(), (std::vector<Eigen::Index>{0, 2, 4}));
  // Only into a held column, never into itself; the block must hold held() columns.
  EXPECT_THROW(gram.merge(4, 3), friction::InvalidParameter);
  EXPECT_THROW(gram.merge(2, 2), friction::InvalidParameter);
  EXPECT_THROW(gram.add(Eigen::MatrixXd::Ones(4, 5)), friction::InvalidParameter);
  // One row after those merges: every merged column equal to the one it follows.
  expect_gram_of_one_row(gram, (Eigen::VectorXd(3) << 1.0, 3.0, 5.0).finished(),
                         (Eigen::VectorXd(5) << 1.0, 1.0, 3.0, 1.0, 5.0).finished());
  // A chain through a column of higher index: 1 into 3, then 3 into 0.
  MergedColumnGram chain(5);
  chain.merge(1, 3);
  chain.merge(3, 0);
  EXPECT_EQ(chain.held(), (std::vector<Eigen::Index>{0, 2, 4}));
  expect_gram_of_one_row(chain, (Eigen::VectorXd(3) << 7.0, 8.0, 9.0).finished(),
                         (Eigen::VectorXd(5) << 7.0, 7.0, 8.0, 7.0, 9.0).finished());
}

}  // namespace
}  // namespace test_merged_column_gram
