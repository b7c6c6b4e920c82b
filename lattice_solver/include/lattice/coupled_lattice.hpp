#pragma once
// The lattice's coupled adapter (cosim/coupled_solver.hpp), driven by libcosim's window loop: it owns
// the model and its solver of a participant run. Every face of the scene's
// `interface` is one interface mesh named after the face (x_min … z_max): its nodes, and the 2-D
// Delaunay triangles of their in-plane coordinates (so either side may use nearest_projection). A
// dirichlet face reads `displacement` and writes `force` (what the lattice exerts on it); a neumann face
// reads `force` and writes `displacement`.
//
// Each ADVANCE is one load state: the coupler's time is only a load parameter. Checkpoints: the lattice
// state (K, removed rods, held fragments) is saved at a window start and restored when the coupler
// repeats the window, so rods that broke in a rejected iterate come back; a window is committed (its
// removals recorded, its row written) when the next window starts or the run ends. On-disk checkpoints
// (coupling.checkpoint_interval) hold the model, the solver's history, the coupled lattice and what the
// committed windows showed (README "Restart").
//
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

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "cosim/coupled_solver.hpp"
#include "lattice/brittle_equilibrium.hpp"
#include "lattice/model.hpp"
#include "lattice/scene.hpp"
#include "lattice/solver.hpp"

namespace common {
class H5Writer;
class StateArchive;
class Summary;
}  // namespace common

namespace lattice {

class CoupledLattice : public cosim::CoupledSolver {
 public:
  /// The participant of `scene` (its `interface` faces coupled), writing lattice.h5 into `h5`.
  CoupledLattice(const Scene& scene, common::H5Writer& h5);
  void declare(cosim::InterfaceDeclaration& io) override;
  /// The window start, kept in iterate mode (settled mode removes only what it keeps).
  void save() override;
  void restore() override;
  void step(const cosim::Window& w, const cosim::Substep& s, cosim::WindowIo& io) override;
  /// The window is final: its removals are recorded (settled mode: rods still over their limit are
  /// removed first, "late"), its row written.
  void commit() override;
  /// Everything a restart needs, to or from disk (the results file's extent is read by openResults).
  void archive(common::StateArchive& a);
  static constexpr const char* kKind = "lattice_solver";
  /// What a checkpoint must have been written by: the specimen's nodes and rods, the operator and the
  /// coupled faces (the model checks the sizes it derives from them).
  static std::string shape(const Scene& scene);
  /// The final snapshot, the cracks and the summary of the run.
  void report(common::Summary& summary);

 private:
  const CoupledFace& face(std::size_t i) const { return model_.supports().coupled[i]; }
  std::size_t faces() const { return model_.supports().coupled.size(); }
  bool dirichlet(std::size_t i) const { return face(i).mode == FaceMode::kDirichlet; }
  // Face i's input: 3 values per node of model.faceNodes(i) (displacement for Dirichlet, force for
  // Neumann). std::invalid_argument for a wrong length or a non-finite value.
  void setInput(std::size_t face, std::span<const double> values);
  // Equilibrium at the current inputs, with removal as above (`final`: an iterate without checkpoints,
  // always removes). `where` names the call in warnings.
  BrittleEquilibrium::Report advance(const std::string& where, bool final);
  // Face i's output: 3 values per node (force the lattice exerts for Dirichlet, displacement for Neumann).
  std::vector<double> output(std::size_t face) const;
  // Σ over face i of the force the lattice exerts on it [N], and the mean displacement of its nodes [m].
  Eigen::Vector3d resultant(std::size_t face) const;
  Eigen::Vector3d meanDisplacement(std::size_t face) const;
  // Settled mode: the rods still over their limit in the committed state, removed. Returns how many.
  std::size_t removeLate();

  // The nominal strain and stress of the lattice zone along the loading axis, when both of its faces
  // normal to it are coupled: ε = (ū_max − ū_min)/H, σ = (F_min − F_max)/(2A) with F the axial force the
  // lattice exerts on each face (positive in tension). Otherwise 0, 0.
  struct Nominal {
    int lo = -1, hi = -1;
    double height = 0.0, area = 0.0;
    bool valid() const { return lo >= 0 && hi >= 0; }
  };
  // What the committed windows showed.
  struct Results {
    double peakStress = 0.0, strainAtPeak = 0.0, youngsModulus = 0.0;
    int peakWindow = -1;
    std::int64_t lateRemovals = 0, windows = 0;
    double time = 0.0, strain = 0.0, stress = 0.0;  // of the last window advanced
  };
  // The last iterate of the current window, its row of `windows` written when the window is committed.
  struct Pending {
    bool any = false;
    std::uint64_t window = 0;
    std::vector<double> faces;  // per face: its resultant and mean displacement
    double rounds = 0, iterations = 0, couplingIterations = 0;
  };
  struct Record {
    std::uint32_t rod;
    int window;
    double nominalStrain;  ///< the lattice's nominal strain when it broke
    double rodStrain;      ///< its own strain then
  };
  // The removal state between committed windows, to or from disk.
  void archiveRemovals(common::StateArchive& a);

  const Scene& scene_;
  common::H5Writer& h5_;
  Model model_;
  std::unique_ptr<EquilibriumSolver> solver_;
  BrittleEquilibrium brittle_;
  LatticeOutput out_;
  int axis_ = 2;
  Nominal nominal_;
  std::vector<std::string> meshes_;
  Eigen::VectorXd x_;
  std::vector<double> prescribed_, force_, u_;  // 6 per node
  std::vector<double> windowStart_, lastInput_;  // inputs (prescribed_ then force_) at the window start, last iterate
  Model::Checkpoint saved_;
  std::vector<BrittleEquilibrium::Removal> removedInWindow_;  // removed in the window's iterates kept
  std::vector<Record> removals_;
  std::vector<int> removedAt_;  // per rod: the window it was removed in, −1 while intact
  Pending pending_;
  Results results_;
  std::int64_t committed_ = 0;
  std::size_t removedBefore_ = 0;
};

}  // namespace lattice
