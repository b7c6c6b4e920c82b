#pragma once
// Equilibrium solvers for K x = b of a lattice Model (lattice_solver/README.md "Solvers"), chosen by
// the scene key `solver.type` with the solver's file name:
//   cg         Eigen's conjugate gradient, preconditioned by the inverses of the 6×6 node blocks of K plus
//              a coarse correction on the rigid motions of cells of nodes, started from the guess in x
//              (the previous increment's state, scaled to the new strain).
//   averaging  the LGM's iterative node-displacement averaging (Kozicki & Donzé 2008 eq. 7): every
//              node in turn moves to the stiffness-weighted average of the positions its rods ask for,
//              i.e. block Gauss–Seidel, swept forward then backward, optionally over-relaxed.
// Both stop on the same test, ‖b − K x‖ ≤ tolerance · ‖b‖, so they reach the same state.
//
// Call order: construct → update(model) → solve(b, x) …; call update(model) again after every change of
// K (rod removals, Model::restore). Not thread safe; OpenMP inside.

#include <functional>
#include <memory>
#include <string>
#include <type_traits>
#include <vector>

#include <Eigen/Core>

#include "lattice/model.hpp"

namespace common {
class Config;
class StateArchive;
}

namespace lattice {

/// What every solver takes; a solver's own keys are its file's (solvers/NAME.hpp).
struct SolverSettings {
  double tolerance = 1e-6;  ///< relative residual ‖b − K x‖/‖b‖
  int maxIterations = 0;    ///< 0: 10 × the free dofs (cg) or 20 × that (averaging)
};

struct SolveReport {
  int iterations = 0;     ///< CG iterations or averaging sweeps (each about one product with K)
  double residual = 0.0;  ///< final ‖b − K x‖/‖b‖
};

class EquilibriumSolver {
 public:
  virtual ~EquilibriumSolver() = default;
  virtual std::string name() const = 0;
  /// Re-reads K and its node blocks (cheap: block inverses only).
  virtual void update(const Model& model) = 0;
  /// Solves from the guess in x. Throws common::SimulationError (exit 3) when the tolerance is not
  /// reached within the iteration limit.
  virtual SolveReport solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) = 0;
  /// What the solver carries from solve to solve beyond what update() derives from the model, to or
  /// from disk (restart); read it after update(model). The default: nothing.
  virtual void archive(common::StateArchive& a) { (void)a; }
};

/// A solver's make once its own keys are read.
using SolverMake = std::function<std::unique_ptr<EquilibriumSolver>(const SolverSettings&)>;

/// `solver:` as read with the scene: the type, what every solver takes, and the type's make holding its
/// own keys.
struct SolverSpec {
  std::string type = "cg";
  SolverSettings settings;
  SolverMake make;
  std::unique_ptr<EquilibriumSolver> build() const { return make(settings); }
};

const std::vector<std::string>& solverNames();
/// Reads solver `type`'s own keys from the scene's `solver:` (an invalid Config: its defaults; another
/// solver's key stays unread: an unknown-key error). `matrixFree`: the operator is matrix-free.
SolverMake readSolverKeys(const std::string& type, const common::Config& solver, bool matrixFree);
/// `type` with `settings` and, in YAML, its own `keys` (empty: its defaults) for a `matrixFree` operator
/// or an assembled one.
std::unique_ptr<EquilibriumSolver> makeSolver(const std::string& type, const SolverSettings& settings = {},
                                              bool matrixFree = false, const std::string& keys = {});

/// Inverses of the diagonal node blocks of K (≤ 6×6, stored padded to 6×6). Shared by both solvers:
/// the preconditioner of cg and the averaging weights.
class NodeBlocks {
 public:
  /// All blocks the first time; afterwards only those of the nodes of rods removed since the last call
  /// (all again when fragments were held or the model was restored to a checkpoint).
  void update(const Model& model);
  /// z = D⁻¹ r, block by block.
  void apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const;
  /// The same in single precision in the model's padded space (Model::applySingle), with the inverse
  /// rounded to float and padded with zeros (so z is 0 at the dofs that are not free): the inner solves
  /// of mixed-precision cg. Only after keepSingle(). Returns r·z over the block, summed in double.
  double applySingleBlock(std::size_t b, const Eigen::VectorXf& r6, Eigen::VectorXf& z6) const {
    const auto base = static_cast<Eigen::Index>(base_[b]);
    z6.segment<6>(base) = inverseSingle_[b] * r6.segment<6>(base);
    double dot = 0.0;
    for (Eigen::Index k = base; k < base + 6; ++k) dot += static_cast<double>(r6[k]) * static_cast<double>(z6[k]);
    return dot;
  }
  std::size_t blocks() const { return start_->size() - 1; }
  void keepSingle() { single_ = true; }
  const Eigen::Matrix<double, 6, 6>& inverse(std::size_t block) const { return inverse_[block]; }

 private:
  void invert(const Model& model, std::size_t block);
  std::vector<Eigen::Matrix<double, 6, 6>> inverse_;
  std::vector<Eigen::Matrix<float, 6, 6>> inverseSingle_;  // padded: rows and columns of the node's 6 dofs
  std::vector<std::uint32_t> base_;                         // per block: Model::paddedBase of its node
  bool single_ = false;
  const std::vector<std::uint32_t>* start_ = nullptr;
  std::size_t removalsSeen_ = 0, heldSeen_ = 0, restoresSeen_ = 0;
};

}  // namespace lattice
