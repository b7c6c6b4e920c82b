#include "lattice/solver.hpp"

#include "common/config.hpp"
#include "common/registry.hpp"
#include "solvers/averaging.hpp"
#include "solvers/cg.hpp"

namespace lattice {

namespace {
struct Entry {
  const char* name;
  /// Reads its own keys of `solver:` into its make.
  SolverMake (*read)(const common::Config& solver, bool matrixFree);
};
const Entry kSolvers[] = {
    {"cg", readCg},
    {"averaging", readAveraging},
};
constexpr common::Registry<Entry> kRegistry{kSolvers, "lattice solver"};
}  // namespace

SolverMake readSolverKeys(const std::string& type, const common::Config& solver, bool matrixFree) {
  return kRegistry.at(type).read(solver, matrixFree);
}

std::unique_ptr<EquilibriumSolver> makeSolver(const std::string& type, const SolverSettings& settings, bool matrixFree,
                                              const std::string& keys) {
  const common::Config c = keys.empty() ? common::Config{} : common::Config::parse(keys);
  return readSolverKeys(type, c, matrixFree)(settings);
}

const std::vector<std::string>& solverNames() {
  static const std::vector<std::string> names = kRegistry.names();
  return names;
}

}  // namespace lattice
