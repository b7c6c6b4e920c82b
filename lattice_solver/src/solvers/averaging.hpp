#pragma once
#include "lattice/solver.hpp"

namespace lattice {

/// Its keys of `solver:`.
struct AveragingKeys {
  double relaxation = 1.0;  ///< ω of the block update x_j += ω D_j⁻¹ r_j, in (0, 2)
  int checkEvery = 4;       ///< sweeps between residual evaluations
};
SolverMake readAveraging(const common::Config& solver, bool matrixFree);

/// The LGM's node-displacement averaging as block Gauss–Seidel (see solver.hpp and README "Solvers").
class Averaging : public EquilibriumSolver {
 public:
  Averaging(const SolverSettings& s, const AveragingKeys& keys) : settings_(s), keys_(keys) {}
  std::string name() const override { return "averaging"; }
  void update(const Model& model) override;
  SolveReport solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) override;

 private:
  void sweep(const Eigen::VectorXd& b, Eigen::VectorXd& x, bool forward) const;

  SolverSettings settings_;
  AveragingKeys keys_;
  NodeBlocks blocks_;
  const Model* model_ = nullptr;
};

}  // namespace lattice
