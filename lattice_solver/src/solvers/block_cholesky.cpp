#include "block_cholesky.hpp"

#include <algorithm>

#include <Eigen/Cholesky>
#include <Eigen/OrderingMethods>

#include "common/errors.hpp"
#include "common/state_archive.hpp"

namespace lattice {

void BlockCholesky::analyze(const std::vector<std::vector<int>>& neighbours) {
  const auto nb = static_cast<int>(neighbours.size());
  // AMD on the block graph: its permutation gives, for each place in the factor, the block of A
  // (as Eigen's simplicial factorisations use it).
  {
    std::vector<Eigen::Triplet<double, int>> t;
    for (int i = 0; i < nb; ++i) {
      t.emplace_back(i, i, 1.0);
      for (int j : neighbours[static_cast<std::size_t>(i)]) t.emplace_back(i, j, 1.0);
    }
    Eigen::SparseMatrix<double, Eigen::ColMajor, int> graph(nb, nb);
    graph.setFromTriplets(t.begin(), t.end());
    Eigen::AMDOrdering<int> amd;
    Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> order;
    amd(graph.selfadjointView<Eigen::Lower>(), order);
    perm_.assign(order.indices().data(), order.indices().data() + nb);
  }
  inv_.assign(static_cast<std::size_t>(nb), 0);
  for (int k = 0; k < nb; ++k) inv_[static_cast<std::size_t>(perm_[static_cast<std::size_t>(k)])] = k;
  // Symbolic factorisation: column j of L holds A's rows below j in column j and those of its children
  // in the elimination tree (each child's column without j itself).
  std::vector<std::vector<int>> column(static_cast<std::size_t>(nb)), children(static_cast<std::size_t>(nb));
  for (int j = 0; j < nb; ++j) {
    auto& s = column[static_cast<std::size_t>(j)];
    for (int n : neighbours[static_cast<std::size_t>(perm_[static_cast<std::size_t>(j)])])
      if (const int i = inv_[static_cast<std::size_t>(n)]; i > j) s.push_back(i);
    for (int c : children[static_cast<std::size_t>(j)])
      for (int i : column[static_cast<std::size_t>(c)])
        if (i > j) s.push_back(i);
    std::sort(s.begin(), s.end());
    s.erase(std::unique(s.begin(), s.end()), s.end());
    if (!s.empty()) children[static_cast<std::size_t>(s.front())].push_back(j);
  }
  colStart_.assign(1, 0);
  rowOf_.clear();
  for (const auto& s : column) {
    rowOf_.insert(rowOf_.end(), s.begin(), s.end());
    colStart_.push_back(static_cast<int>(rowOf_.size()));
  }
  L_.resize(rowOf_.size());
  Lf_.resize(rowOf_.size());
  D_.resize(static_cast<std::size_t>(nb));
  diagInv_.resize(static_cast<std::size_t>(nb));
  diagInvF_.resize(static_cast<std::size_t>(nb));
  pos_.assign(static_cast<std::size_t>(nb), -1);
  y_.resize(6 * nb);
}

bool BlockCholesky::factorize(const Eigen::SparseMatrix<double>& A) {
  const auto nb = static_cast<int>(perm_.size());
  for (auto& b : D_) b.setZero();
  for (auto& b : L_) b.setZero();
  // The lower half of A, in the factor's order, into the blocks.
  for (Eigen::Index c = 0; c < A.outerSize(); ++c) {
    const int j = inv_[static_cast<std::size_t>(c / 6)];
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, c); it; ++it) {
      const int i = inv_[static_cast<std::size_t>(it.row() / 6)];
      if (i == j) {
        D_[static_cast<std::size_t>(j)](it.row() % 6, c % 6) = it.value();
      } else if (i > j) {
        const auto first = rowOf_.begin() + colStart_[static_cast<std::size_t>(j)];
        const auto last = rowOf_.begin() + colStart_[static_cast<std::size_t>(j) + 1];
        const auto p = std::lower_bound(first, last, i);
        COSIM_ASSERT(p != last && *p == i, "entry ({}, {}) of A outside the analysed block pattern", it.row(), c);
        L_[static_cast<std::size_t>(p - rowOf_.begin())](it.row() % 6, c % 6) = it.value();
      }
    }
  }
  // Right-looking: column j final, then its outer products subtracted from the columns to its right
  // (column j's rows below k all lie in column k: the symbolic factorisation's fill).
  for (int j = 0; j < nb; ++j) {
    const Eigen::LLT<Block> llt(D_[static_cast<std::size_t>(j)]);
    if (llt.info() != Eigen::Success) return false;
    const Block Ljj = llt.matrixL();
    Block inv = Block::Identity();
    Ljj.triangularView<Eigen::Lower>().solveInPlace(inv);
    diagInv_[static_cast<std::size_t>(j)] = inv;
    const int begin = colStart_[static_cast<std::size_t>(j)], end = colStart_[static_cast<std::size_t>(j) + 1];
    for (int p = begin; p < end; ++p) L_[static_cast<std::size_t>(p)] = (L_[static_cast<std::size_t>(p)] * inv.transpose()).eval();
    for (int q = begin; q < end; ++q) {
      const int k = rowOf_[static_cast<std::size_t>(q)];
      const Block& Lkj = L_[static_cast<std::size_t>(q)];
      D_[static_cast<std::size_t>(k)].noalias() -= Lkj * Lkj.transpose();
      if (q + 1 == end) break;
      const int kBegin = colStart_[static_cast<std::size_t>(k)], kEnd = colStart_[static_cast<std::size_t>(k) + 1];
      for (int r = kBegin; r < kEnd; ++r) pos_[static_cast<std::size_t>(rowOf_[static_cast<std::size_t>(r)])] = r;
      for (int p = q + 1; p < end; ++p)
        L_[static_cast<std::size_t>(pos_[static_cast<std::size_t>(rowOf_[static_cast<std::size_t>(p)])])].noalias() -=
            L_[static_cast<std::size_t>(p)] * Lkj.transpose();
      for (int r = kBegin; r < kEnd; ++r) pos_[static_cast<std::size_t>(rowOf_[static_cast<std::size_t>(r)])] = -1;
    }
  }
  for (std::size_t p = 0; p < L_.size(); ++p) Lf_[p] = L_[p].cast<float>();
  for (std::size_t j = 0; j < diagInv_.size(); ++j) diagInvF_[j] = diagInv_[j].cast<float>();
  return true;
}

template <typename T>
void BlockCholesky::solveWith(const std::vector<Eigen::Matrix<T, 6, 6>>& L, const std::vector<Eigen::Matrix<T, 6, 6>>& diagInv,
                              Eigen::VectorXd& x) const {
  using Vec6 = Eigen::Matrix<double, 6, 1>;
  const auto nb = static_cast<int>(perm_.size());
  for (int j = 0; j < nb; ++j) y_.segment<6>(6 * j) = x.segment<6>(6 * perm_[static_cast<std::size_t>(j)]);
  // L y = x, column by column.
  for (int j = 0; j < nb; ++j) {
    // The inverses are lower triangular with exact zeros above: the full 6 × 6 product is the same.
    const Vec6 yj = diagInv[static_cast<std::size_t>(j)].template cast<double>() * y_.segment<6>(6 * j);
    y_.segment<6>(6 * j) = yj;
    for (int p = colStart_[static_cast<std::size_t>(j)]; p < colStart_[static_cast<std::size_t>(j) + 1]; ++p)
      y_.segment<6>(6 * rowOf_[static_cast<std::size_t>(p)]).noalias() -= L[static_cast<std::size_t>(p)].template cast<double>() * yj;
  }
  // Lᵀ y = y, row of Lᵀ by row: each a sum over the column's blocks.
  for (int j = nb - 1; j >= 0; --j) {
    Vec6 s = y_.segment<6>(6 * j);
    for (int p = colStart_[static_cast<std::size_t>(j)]; p < colStart_[static_cast<std::size_t>(j) + 1]; ++p)
      s.noalias() -= L[static_cast<std::size_t>(p)].template cast<double>().transpose() * y_.segment<6>(6 * rowOf_[static_cast<std::size_t>(p)]);
    y_.segment<6>(6 * j) = diagInv[static_cast<std::size_t>(j)].template cast<double>().transpose() * s;
  }
  for (int j = 0; j < nb; ++j) x.segment<6>(6 * perm_[static_cast<std::size_t>(j)]) = y_.segment<6>(6 * j);
}

void BlockCholesky::solve(Eigen::VectorXd& x) const { solveWith(L_, diagInv_, x); }

void BlockCholesky::solveSingle(Eigen::VectorXd& x) const { solveWith(Lf_, diagInvF_, x); }

void BlockCholesky::archive(common::StateArchive& a) {
  a.io("perm", perm_), a.io("inv", inv_), a.io("col_start", colStart_), a.io("row_of", rowOf_), a.io("l", L_);
  a.io("diag_inv", diagInv_), a.io("l_single", Lf_), a.io("diag_inv_single", diagInvF_);
}

}  // namespace lattice
