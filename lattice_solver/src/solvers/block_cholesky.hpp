#pragma once
// Sparse Cholesky factorisation A = L Lᵀ of a symmetric positive definite matrix made of 6 × 6 blocks
// (the coarse stiffness: one block row per cell of the coarse space), in a fill-reducing order of the
// blocks (Eigen's AMD on the block graph). Every operation is on whole 6 × 6 blocks, so the factorisation
// runs dense fixed-size products instead of a scalar sparse loop with an index per value, and the
// triangular solves read one row index per 36 values (lattice_solver/README.md "Coarse level").
//
// analyze() once per block pattern, factorize() after every change of the values; solve() in double,
// solveSingle() on a copy of the factor rounded to float (the inner solves' preconditioner).
// Not thread safe; serial.
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace common {
class StateArchive;
}

namespace lattice {

class BlockCholesky {
 public:
  using Block = Eigen::Matrix<double, 6, 6>;
  using BlockF = Eigen::Matrix<float, 6, 6>;
  /// The block pattern of A: for each block row, the other blocks rows it couples to (symmetric).
  void analyze(const std::vector<std::vector<int>>& neighbours);
  /// The values of A (6 × blocks square, column major, its entries within the analysed block pattern).
  /// Returns false when A is not positive definite (a pivot block without a Cholesky factor).
  bool factorize(const Eigen::SparseMatrix<double>& A);
  /// x ← A⁻¹ x.
  void solve(Eigen::VectorXd& x) const;
  /// x ← A⁻¹ x with the factor rounded to float (sums in double).
  void solveSingle(Eigen::VectorXd& x) const;
  /// The ordering and the factor (double and float), to or from disk.
  void archive(common::StateArchive& a);
  /// Off-diagonal blocks of L.
  std::size_t offDiagonalBlocks() const { return rowOf_.size(); }

 private:
  template <typename T>
  void solveWith(const std::vector<Eigen::Matrix<T, 6, 6>>& L, const std::vector<Eigen::Matrix<T, 6, 6>>& diagInv,
                 Eigen::VectorXd& x) const;
  std::vector<int> perm_, inv_;  // block in the factor's order → block of A, and back
  // L below the diagonal, block column by block column in the factor's order, rows ascending.
  std::vector<int> colStart_, rowOf_;
  std::vector<Block> L_, diagInv_;  // diagInv_: the inverse of each diagonal block of L (lower triangular)
  std::vector<BlockF> Lf_, diagInvF_;
  std::vector<Block> D_;            // scratch of factorize: the diagonal blocks as they are updated
  std::vector<int> pos_;            // scratch of factorize: per block row, its place in one column, or −1
  mutable Eigen::VectorXd y_;       // scratch of the solves
};

}  // namespace lattice
