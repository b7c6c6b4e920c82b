#pragma once
// The coarse level of cg's two-level preconditioner: the rigid-body motions (3 translations, 3 rotations)
// of cubic cells of nodes, P (free dofs × 6 cells), and the coarse stiffness A_c = Pᵀ K P = Σ_rods
// P_rᵀ K_rod P_r, factorised and updated rod by rod as rods are removed (−P_rᵀ K_rod P_r each).
// Block Jacobi alone only smooths: the long-range response needs O(n_side) iterations to travel; the
// coarse correction carries it in one step (plain-aggregation two-level method, e.g. Vaněk, Mandel &
// Brezina 1996 without the smoothing of P).
#include <omp.h>

#include <Eigen/Geometry>
#include <Eigen/SparseCore>

#include "block_cholesky.hpp"

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
  /// The single-precision inner solves apply the correction in three steps in the model's padded space
  /// (Model::applySingle), P node by node (each node's cell and its offset from the cell's centroid,
  /// rounded to float): rc = Pᵀ r (threaded), rc ← A_c⁻¹ rc (serial, so cg overlaps it with block
  /// Jacobi), P rc added into cg's new direction (threaded, direction()). before(first, end) is called
  /// on each node block's 6 entries [first, end) just before they are read and returns a share of a sum;
  /// the shares are added per thread and then in thread order (deterministic per thread count) and the
  /// total returned. cg uses it to update r in the same pass.
  template <class Before>
  double coarseResidual(const Eigen::VectorXf& r, Eigen::VectorXd& rc, const Before& before) const;
  void solve(Eigen::VectorXd& rc) const;
  /// cg's new direction p ← z + β p + P yc, node block by node block (one pass instead of two); the
  /// entries of nodes without free dofs are left as they are (0).
  void direction(const Eigen::VectorXd& yc, const Eigen::VectorXf& z, float beta, Eigen::VectorXf& p) const;
  Eigen::Index size() const { return Ac_.rows(); }
  /// A_c as maintained (for tests: incremental updates = rebuilding).
  const Eigen::SparseMatrix<double>& matrix() const { return Ac_; }
  /// A_c as updated rod by rod, its factor (refreshed only every so many removals) and the counts of
  /// what it has seen: to or from disk. Read into a space build() made for the same model.
  void archive(common::StateArchive& a);

 private:
  void assemble(const Model& model);
  // P_rᵀ K_rod P_r of one rod over the coarse columns `cols` (whole cells) it touches.
  Eigen::MatrixXd rodCoarse(const Model& model, std::size_t r, std::vector<Eigen::Index>& cols) const;

  Eigen::SparseMatrix<double, Eigen::RowMajor> P_;
  // P per node block: its cell (−1: held, no rows in P), offset from the cell's centroid, free dofs
  // (bit k: dof k), and the node's first entry in the padded space.
  struct BlockRows {
    std::int32_t cell;
    float d[3];
    std::uint32_t first;
    std::uint8_t mask;
  };
  std::vector<BlockRows> rows_;
  mutable std::vector<Eigen::VectorXd> rcThread_;
  mutable std::vector<double> sumThread_;
  Eigen::SparseMatrix<double> Ac_;
  BlockCholesky factor_;  // of Ac_, block by block (cells)
  std::size_t removalsSeen_ = 0, heldSeen_ = 0, pending_ = 0;
};

template <class Before>
double CoarseSpace::coarseResidual(const Eigen::VectorXf& r, Eigen::VectorXd& rc, const Before& before) const {
  const auto nt = static_cast<std::size_t>(omp_get_max_threads());
  rcThread_.resize(nt);
  sumThread_.assign(nt, 0.0);
  for (auto& part : rcThread_) part.setZero(Ac_.rows());  // all of them: the team may come out smaller
#pragma omp parallel num_threads(static_cast<int>(nt))
  {
    const auto t = static_cast<std::size_t>(omp_get_thread_num());
    const auto team = static_cast<std::size_t>(omp_get_num_threads());
    Eigen::VectorXd& part = rcThread_[t];
    double sum = 0.0;
    const std::size_t begin = rows_.size() * t / team, end = rows_.size() * (t + 1) / team;
    for (std::size_t b = begin; b < end; ++b) {
      const BlockRows& row = rows_[b];
      sum += before(static_cast<Eigen::Index>(row.first), static_cast<Eigen::Index>(row.first) + 6);
      if (row.cell < 0) continue;
      const float* v = r.data() + row.first;  // 0 at the dofs that are not free
      // Pᵀ of a node: translations sum u, rotations sum θ + d × u.
      double* c = part.data() + 6 * row.cell;
      c[0] += v[0];
      c[1] += v[1];
      c[2] += v[2];
      c[3] += v[3] + (row.d[1] * v[2] - row.d[2] * v[1]);
      c[4] += v[4] + (row.d[2] * v[0] - row.d[0] * v[2]);
      c[5] += v[5] + (row.d[0] * v[1] - row.d[1] * v[0]);
    }
    sumThread_[t] = sum;
  }
  rc = rcThread_[0];
  double total = sumThread_[0];
  for (std::size_t t = 1; t < nt; ++t) {  // in thread order: deterministic per thread count
    rc += rcThread_[t];
    total += sumThread_[t];
  }
  return total;
}

}  // namespace lattice
