#pragma once
// Participant mode (lattice_solver/README.md "Participant mode"): the lattice as one side of a
// quasi-static Dirichlet–Neumann coupling. The coupler drives the faces of Supports::coupled:
//   dirichlet face  input: displacement of its nodes (3 per node, m); output: the force the lattice exerts
//                   on them (3 per node, N) — minus the support force, so a stretched lattice pulls back;
//   neumann face    input: force on its nodes (3 per node, N); output: their displacement (3 per node, m).
// Rotations of face nodes are free: the other side (solid FEM) has none to prescribe, and the moment of
// the interface forces about any point is carried by the forces alone.
//
// Each window is one quasi-static load state; the coupler iterates it. When rods are removed is the
// CoupledRemoval choice (README "Participant mode", measured in docs/validation/lattice.md):
//   settled  (default) rods are checked only in an iterate whose input has settled: it moved by at most
//            settleTolerance × its change since the window start. There the removal rounds run at that
//            fixed input (BrittleEquilibrium, as the standalone test at a fixed strain), and the rods
//            removed stay removed for the rest of the window, which the coupler then re-converges with
//            the weakened lattice. A rejected (unsettled) iterate never removes anything, so there is
//            nothing to undo; rods still over their limit when the coupler commits the window anyway
//            (its iteration limit) are removed at the commit ("late").
//   iterate  every iterate runs the removal rounds from the window-start state (restore() brings back
//            the rods a rejected iterate removed). Exact in principle, but the interface map then jumps
//            whenever a rod breaks in one iterate and not in the next, and the quasi-Newton coupling
//            stalls on those jumps.
// Without checkpoints (explicit coupling) every advance is final and removes.
//
// Call order: construct → save() → setInput(face, …) for every face → advance() → output(face) …;
// restore() goes back to the last save() (iterate mode); commit(window) makes the window final (its
// removals are recorded). The model and solver are borrowed. Not thread safe; OpenMP inside.

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "lattice/brittle_equilibrium.hpp"
#include "lattice/model.hpp"
#include "lattice/solver.hpp"

namespace common {
class StateArchive;
}

namespace lattice {

enum class CoupledRemoval { kSettled, kIterate };

class CoupledLattice {
 public:
  CoupledLattice(Model& model, EquilibriumSolver& solver, RemovalStrategy removal, int maxRounds,
                 CoupledRemoval when = CoupledRemoval::kSettled, double settleTolerance = 1e-3);

  std::size_t faces() const { return model_.supports().coupled.size(); }
  const CoupledFace& face(std::size_t i) const { return model_.supports().coupled[i]; }
  /// Face i's input: 3 values per node of model.faceNodes(i) (displacement for Dirichlet, force for
  /// Neumann). std::invalid_argument for a wrong length or a non-finite value.
  void setInput(std::size_t face, std::span<const double> values);
  /// Equilibrium at the current inputs, with removal as above (`final`: an iterate without checkpoints,
  /// always removes). `where` names the call in warnings.
  BrittleEquilibrium::Report advance(const std::string& where, bool final = false);
  /// Face i's output: 3 values per node (force the lattice exerts for Dirichlet, displacement for Neumann).
  std::vector<double> output(std::size_t face) const;
  /// Σ over face i of the force the lattice exerts on it [N], and the mean displacement of its nodes [m].
  Eigen::Vector3d resultant(std::size_t face) const;
  Eigen::Vector3d meanDisplacement(std::size_t face) const;

  void save();
  void restore();
  /// The window is final: its removals are recorded with `window`, `nominalStrain` (settled mode: rods
  /// still over their limit are removed first). Returns the rods removed late.
  std::size_t commit(int window, double nominalStrain);

  struct Record {
    std::uint32_t rod;
    int window;
    double nominalStrain;  ///< the lattice's nominal strain when it broke
    double rodStrain;      ///< its own strain then
  };
  const std::vector<Record>& removals() const { return removals_; }
  /// Per rod: the window it was removed in, −1 while intact.
  const std::vector<int>& removedAt() const { return removedAt_; }
  /// Full displacement (6 per node) of the last advance.
  const std::vector<double>& displacement() const { return u_; }
  const BrittleEquilibrium& equilibrium() const { return brittle_; }
  /// The state between committed windows (the current solution and inputs, the removals recorded so
  /// far, the counters), to or from disk; the model is archived on its own (Model::archive).
  void archive(common::StateArchive& a);

 private:
  Model& model_;
  EquilibriumSolver& solver_;
  BrittleEquilibrium brittle_;
  RemovalStrategy strategy_;
  CoupledRemoval when_;
  double settleTolerance_;
  Eigen::VectorXd x_;
  std::vector<double> prescribed_, force_, u_;  // 6 per node
  std::vector<double> windowStart_, lastInput_;  // inputs (prescribed_ then force_) at the window start, last iterate
  Model::Checkpoint saved_;
  std::vector<BrittleEquilibrium::Removal> pending_;
  std::vector<Record> removals_;
  std::vector<int> removedAt_;
};

/// Crack localisation (docs/validation/lattice.md): the plane normal to `axis` with the most removed
/// rods (by midpoint) within ± halfWidth, and the fraction of all removed rods that lie there.
struct CrackBand {
  double plane = 0.0;     ///< position along the axis [m]
  double fraction = 0.0;  ///< removed rods in the band / removed rods (0 when none)
};
CrackBand crackBand(const Model& model, std::span<const std::uint32_t> removed, int axis, double halfWidth);

}  // namespace lattice
