#pragma once
#include "lattice/solver.hpp"

namespace lattice {

/// The LGM's node-displacement averaging as block Gauss–Seidel (see solver.hpp and README "Solvers").
class Averaging : public EquilibriumSolver {
 public:
  explicit Averaging(const SolverSettings& s) : settings_(s) {}
  std::string name() const override { return "averaging"; }
  void update(const Model& model) override;
  SolveReport solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) override;

 private:
  void sweep(const Eigen::VectorXd& b, Eigen::VectorXd& x, bool forward) const;

  SolverSettings settings_;
  NodeBlocks blocks_;
  const Model* model_ = nullptr;
};

}  // namespace lattice
