#pragma once
// The coarse level of cg's two-level preconditioner: the rigid-body motions (3 translations, 3 rotations)
// of cubic cells of nodes, P (free dofs × 6 cells), and the coarse stiffness A_c = Pᵀ K P = Σ_rods
// P_rᵀ K_rod P_r, factorised and updated rod by rod as rods are removed (−P_rᵀ K_rod P_r each).
// Block Jacobi alone only smooths: the long-range response needs O(n_side) iterations to travel; the
// coarse correction carries it in one step (plain-aggregation two-level method, e.g. Vaněk, Mandel &
// Brezina 1996 without the smoothing of P).
#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "lattice/model.hpp"

namespace lattice {

class CoarseSpace {
 public:
  /// Cells of edge `cellSize` [m] over the model's box.
  void build(const Model& model, double cellSize);
  /// Subtracts the rods removed since the last call (refactorising once enough have gone); rebuilds
  /// A_c when nodes were held.
  void update(const Model& model);
  /// z += P A_c⁻¹ Pᵀ r.
  void addCorrection(const Eigen::VectorXd& r, Eigen::VectorXd& z) const;
  /// The single-precision inner solves apply the correction in three steps, P node by node (each
  /// node's cell and its offset from the cell's centroid, rounded to float): rc = Pᵀ r (threaded),
  /// rc ← A_c⁻¹ rc (serial, so cg overlaps it with block Jacobi), z += P rc (threaded).
  void coarseResidual(const Eigen::VectorXf& r, Eigen::VectorXd& rc) const;
  void solve(Eigen::VectorXd& rc) const;
  void prolongAdd(const Eigen::VectorXd& yc, Eigen::VectorXf& z) const;
  Eigen::Index size() const { return Ac_.rows(); }
  /// A_c as maintained (for tests: incremental updates = rebuilding).
  const Eigen::SparseMatrix<double>& matrix() const { return Ac_; }

 private:
  void assemble(const Model& model);
  // P_rᵀ K_rod P_r of one rod over the coarse columns `cols` (whole cells) it touches.
  Eigen::MatrixXd rodCoarse(const Model& model, std::size_t r, std::vector<Eigen::Index>& cols) const;

  Eigen::SparseMatrix<double, Eigen::RowMajor> P_;
  // P per node block: its cell (−1: held, no rows in P), offset from the cell's centroid, free dofs
  // (bit k: dof k), and the first of them in the unknowns.
  struct BlockRows {
    std::int32_t cell;
    float d[3];
    std::uint32_t first;
    std::uint8_t mask;
  };
  std::vector<BlockRows> rows_;
  mutable std::vector<Eigen::VectorXd> rcThread_;
  Eigen::SparseMatrix<double> Ac_;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt_;
  std::size_t removalsSeen_ = 0, heldSeen_ = 0, pending_ = 0;
};

}  // namespace lattice
