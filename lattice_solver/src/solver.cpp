#include "lattice/solver.hpp"

#include <stdexcept>

#include "solvers/averaging.hpp"
#include "solvers/cg.hpp"

namespace lattice {

std::unique_ptr<EquilibriumSolver> makeSolver(const std::string& name, const SolverSettings& settings) {
  if (name == "cg") return std::make_unique<Cg>(settings);
  if (name == "averaging") return std::make_unique<Averaging>(settings);
  throw std::invalid_argument("unknown solver \"" + name + "\"");
}

const std::vector<std::string>& solverNames() {
  static const std::vector<std::string> names{"cg", "averaging"};
  return names;
}

}  // namespace lattice
