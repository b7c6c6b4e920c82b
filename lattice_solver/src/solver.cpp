#include "lattice/solver.hpp"

#include <stdexcept>

#include "common/config.hpp"
#include "common/registry.hpp"
#include "solvers/averaging.hpp"
#include "solvers/cg.hpp"

namespace lattice {

namespace {
using common::Interval;
struct Entry {
  const char* name;
  std::unique_ptr<EquilibriumSolver> (*make)(const SolverSettings&);
  void (*readKeys)(const common::Config&, bool matrixFree, SolverSettings&);
};
const Entry kSolvers[] = {
    {"cg", [](const SolverSettings& s) -> std::unique_ptr<EquilibriumSolver> { return std::make_unique<Cg>(s); },
     [](const common::Config& so, bool matrixFree, SolverSettings& s) {
       s.coarseCells = static_cast<int>(so.get("coarse_cells", -1.0, Interval::closed(-1, 22)));
       // Single-precision inner solves halve the memory traffic of an iteration (docs/performance.md):
       // the default where they apply.
       s.mixed = so.choice("precision", {"double", "mixed"}, matrixFree ? "mixed" : "double") == "mixed";
       if (s.mixed && !matrixFree) so.failAt("precision", "`mixed` needs solver.type cg with solver.operator matrix_free");
     }},
    {"averaging",
     [](const SolverSettings& s) -> std::unique_ptr<EquilibriumSolver> { return std::make_unique<Averaging>(s); },
     [](const common::Config& so, bool, SolverSettings& s) {
       s.relaxation = so.get("relaxation", 1.0, Interval::open(0, 2));
       s.mixed = false;
     }},
};
constexpr common::Registry<Entry> kRegistry{kSolvers, "lattice solver"};
}  // namespace

std::unique_ptr<EquilibriumSolver> makeSolver(const std::string& name, const SolverSettings& settings) {
  return kRegistry.at(name).make(settings);
}

void readSolverKeys(const std::string& name, const common::Config& solver, bool matrixFree, SolverSettings& settings) {
  kRegistry.at(name).readKeys(solver, matrixFree, settings);
}

const std::vector<std::string>& solverNames() {
  static const std::vector<std::string> names = kRegistry.names();
  return names;
}

}  // namespace lattice
