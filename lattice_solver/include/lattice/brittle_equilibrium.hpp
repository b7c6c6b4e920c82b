#pragma once
// Equilibrium with brittle rod removal at fixed boundary values (lattice_solver/README.md "Fracture"):
// solve K x = rhs, list the rods whose strain passes their phase's critical value, remove them, re-solve,
// and repeat until no rod is over its limit. Which rods go per round is the removal strategy:
//   all  every rod over its limit at once (the LGM: "each element was removed … if the critical strain
//        was exceeded", Kozicki & Donzé 2008 §2.2);
//   one  only the most critical rod (largest ε/ε_crit), as in sequentially linear analysis (Rots &
//        Invernizzi 2004): slower, and insensitive to how many rods happened to cross in one increment.
// Shared by the strain-controlled test (FractureTest) and participant mode (CoupledLattice), which
// differ only in how the boundary values enter the right-hand side and the full displacement.
//
// The model and solver are borrowed and must outlive this object. Throws common::SimulationError when a
// solve fails. Not thread safe; OpenMP inside.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "lattice/model.hpp"
#include "lattice/solver.hpp"

namespace common {
class StateArchive;
}

namespace lattice {

enum class RemovalStrategy { kAll, kOne };

class BrittleEquilibrium {
 public:
  BrittleEquilibrium(Model& model, EquilibriumSolver& solver, RemovalStrategy removal, int maxRounds);

  struct Removal {
    std::uint32_t rod;
    double strain;  ///< its strain when it went
  };
  struct Report {
    int rounds = 0;      ///< equilibria solved (1 + removal rounds)
    long iterations = 0; ///< solver iterations
    std::vector<Removal> removed;  ///< in the order of removal
  };
  /// The right-hand side of the current model (it changes as rods go and fragments are held).
  using Rhs = std::function<Eigen::VectorXd()>;
  /// The full displacement (6 per node) of the free dofs x.
  using Full = std::function<void(const Eigen::VectorXd& x, std::vector<double>& u)>;
  /// Called once with the first (elastic) solution, before any removal.
  using Inspect = std::function<void(const std::vector<double>& u)>;

  /// From the guess in x: x and u end at the equilibrium of the model with no rod over its limit (or
  /// after maxRounds removal rounds, with a warning naming `where`). With `remove` false: the equilibrium
  /// only, no rod checked.
  Report run(const Rhs& rhs, const Full& full, Eigen::VectorXd& x, std::vector<double>& u, const std::string& where,
             const Inspect& elastic = {}, bool remove = true);

  /// Rods over their limit in u, with the ratio ε/ε_crit of each, in rod order.
  void overLimit(const std::vector<double>& u, std::vector<std::uint32_t>& rods, std::vector<double>& ratio) const;
  /// max over rods of ε/ε_crit (intact rods included; 0 for none).
  double worstRatio(const std::vector<double>& u) const;

  long solves() const { return solves_; }
  long iterations() const { return iterations_; }
  /// Wall time in solves, in rod removal (K update, fragment search), in solver updates (preconditioner),
  /// and in the strain checks [s].
  double solveSeconds() const { return solveSeconds_; }
  double removalSeconds() const { return removalSeconds_; }
  double updateSeconds() const { return updateSeconds_; }
  double checkSeconds() const { return checkSeconds_; }
  /// The counters, to or from disk.
  void archive(common::StateArchive& a);

 private:
  Model& model_;
  EquilibriumSolver& solver_;
  RemovalStrategy removal_;
  int maxRounds_;
  long iterations_ = 0, solves_ = 0;
  double solveSeconds_ = 0.0, removalSeconds_ = 0.0, updateSeconds_ = 0.0, checkSeconds_ = 0.0;
};

}  // namespace lattice
