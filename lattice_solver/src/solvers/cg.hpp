#pragma once
#include <vector>

#include <Eigen/IterativeLinearSolvers>

#include "coarse_space.hpp"
#include "stiffness_operator.hpp"
#include "lattice/solver.hpp"

namespace lattice {

/// Its keys of `solver:`.
struct CgKeys {
  int coarseCells = -1;  ///< coarse cells along the longest side (−1 auto, 0 no coarse level)
  bool mixed = false;    ///< inner solves in single precision, refined in double (matrix-free K)
};
SolverMake readCg(const common::Config& solver, bool matrixFree);

/// Eigen's ConjugateGradient on K (assembled or matrix-free, through StiffnessOperator) with the
/// node-block Jacobi preconditioner, plus (coarseCells ≠ 0) the additive coarse correction of
/// CoarseSpace: M⁻¹ = D⁻¹ + P A_c⁻¹ Pᵀ.
class Cg : public EquilibriumSolver {
 public:
  Cg(const SolverSettings& s, const CgKeys& keys) : settings_(s), keys_(keys) {}
  std::string name() const override { return "cg"; }
  void update(const Model& model) override;
  SolveReport solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) override;
  /// The coarse space (its A_c and factor follow the removals incrementally) and, in mixed precision,
  /// the last solve's residual, x and b (the next residual is updated from them when x has not moved).
  void archive(common::StateArchive& a) override;

  /// Eigen's preconditioner concept over NodeBlocks (the blocks are computed by update()).
  class Preconditioner {
   public:
    template <class M>
    Preconditioner& analyzePattern(const M&) { return *this; }
    template <class M>
    Preconditioner& factorize(const M&) { return *this; }
    template <class M>
    Preconditioner& compute(const M&) { return *this; }
    template <class Rhs>
    Eigen::VectorXd solve(const Eigen::MatrixBase<Rhs>& r) const {
      Eigen::VectorXd z;
      const Eigen::VectorXd& rr = r;
      blocks_->apply(rr, z);
      if (coarse_) coarse_->addCorrection(rr, z);
      return z;
    }
    Eigen::ComputationInfo info() const { return Eigen::Success; }
    void bind(const NodeBlocks* blocks, const CoarseSpace* coarse) {
      blocks_ = blocks;
      coarse_ = coarse;
    }

   private:
    const NodeBlocks* blocks_ = nullptr;
    const CoarseSpace* coarse_ = nullptr;
  };

 private:
  // Mixed precision: x += K̃⁻¹ r solved in float (pcgSingle) while the double residual b − K x is above
  // the tolerance (iterative refinement).
  SolveReport solveMixed(const Eigen::VectorXd& b, Eigen::VectorXd& x);
  // d ≈ K̃⁻¹ rhs by preconditioned cg in float from d = 0, to ‖rhs − K̃ d‖ ≤ reduction ‖rhs‖ or
  // maxIterations, in the model's padded space (Model::applySingle); returns the iterations.
  int pcgSingle(const Eigen::VectorXf& rhs, Eigen::VectorXf& d, double reduction, int maxIterations);
  // b − K x for the x and b of the last mixed solve, updated instead of recomputed when only rods went
  // since (x unchanged: a re-solve after a removal round): b − K' x = (b' − b) + (b − K x) + Σ_removed K_r x.
  bool residualFromLast(const Eigen::VectorXd& b, const Eigen::VectorXd& x);
  SolverSettings settings_;
  CgKeys keys_;
  Eigen::VectorXd residual_, rc_, rcRhs_;
  const Model* lastModel_ = nullptr;
  Eigen::VectorXd lastX_, lastB_;
  std::size_t lastRemovals_ = 0, lastHeld_ = 0, lastRestores_ = 0;
  bool haveLast_ = false;
  std::vector<double> chunkDot_;
  Eigen::VectorXf rhsF_, dF_, rF_, zF_, pF_, qF_;
  NodeBlocks blocks_;
  CoarseSpace coarse_;
  bool coarseBuilt_ = false;
  std::size_t restoresSeen_ = 0;
  StiffnessOperator K_;
  Eigen::ConjugateGradient<StiffnessOperator, Eigen::Lower | Eigen::Upper, Preconditioner> cg_;
  bool ready_ = false;
};

}  // namespace lattice
