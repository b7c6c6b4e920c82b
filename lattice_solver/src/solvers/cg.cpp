#include "cg.hpp"

#include <fmt/format.h>

#include "common/errors.hpp"

namespace lattice {

void Cg::update(const Model& model) {
  K_ = &model.stiffness();
  blocks_.compute(*K_, model.blockStart());
  cg_.preconditioner().bind(&blocks_);
  cg_.compute(*K_);
  cg_.setTolerance(settings_.tolerance);
  cg_.setMaxIterations(settings_.maxIterations > 0 ? settings_.maxIterations : static_cast<int>(10 * K_->rows()));
}

SolveReport Cg::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  COSIM_ASSERT(K_ != nullptr, "Cg::solve before update()");
  x = cg_.solveWithGuess(b, x);
  SolveReport rep{static_cast<int>(cg_.iterations()), cg_.error()};
  if (!(rep.residual <= settings_.tolerance))
    throw common::SimulationError(fmt::format("cg did not reach the relative residual {:.3g} in {} iterations (it is {:.3g}); "
                                              "raise solver.max_iterations or the tolerance",
                                              settings_.tolerance, rep.iterations, rep.residual));
  return rep;
}

}  // namespace lattice
