#include "cg.hpp"

#include <fmt/format.h>

#include "common/errors.hpp"

namespace lattice {

void Cg::update(const Model& model) {
  K_.attach(model);
  blocks_.update(model);
  if (settings_.coarseCells != 0) {
    // A restored model has rods back and nodes released: rebuild the coarse space (P included, it
    // dropped the rows of held nodes).
    if (model.restores() != restoresSeen_) coarseBuilt_ = false;
    restoresSeen_ = model.restores();
    if (!coarseBuilt_) {
      // Auto: cells of 4 mean rod lengths, at most 8 along the longest side (the factorisation of A_c
      // is redone after every removal round, so it must stay small).
      const double longest = model.box().size.maxCoeff();
      double mean = 0.0;
      for (std::size_t r = 0; r < model.rods(); ++r) mean += model.rodLength(r);
      mean /= static_cast<double>(std::max<std::size_t>(1, model.rods()));
      const double cell = settings_.coarseCells > 0 ? longest / settings_.coarseCells : std::max(4 * mean, longest / 8);
      coarse_.build(model, cell);
      coarseBuilt_ = true;
    } else {
      coarse_.update(model);
    }
  }
  cg_.preconditioner().bind(&blocks_, settings_.coarseCells != 0 ? &coarse_ : nullptr);
  cg_.compute(K_);
  cg_.setTolerance(settings_.tolerance);
  cg_.setMaxIterations(settings_.maxIterations > 0 ? settings_.maxIterations : static_cast<int>(10 * K_.rows()));
  ready_ = true;
}

SolveReport Cg::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  COSIM_ASSERT(ready_, "Cg::solve before update()");
  x = cg_.solveWithGuess(b, x);
  SolveReport rep{static_cast<int>(cg_.iterations()), cg_.error()};
  if (!(rep.residual <= settings_.tolerance))
    throw common::SimulationError(fmt::format("cg did not reach the relative residual {:.3g} in {} iterations (it is {:.3g}); "
                                              "raise solver.max_iterations or the tolerance",
                                              settings_.tolerance, rep.iterations, rep.residual));
  return rep;
}

}  // namespace lattice
