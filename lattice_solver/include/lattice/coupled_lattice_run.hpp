#pragma once
// The lattice's coupled adapter (cosim/coupled_solver.hpp), driven by libcosim's window loop: it owns
// the model, its solver and the CoupledLattice of a participant run. Every face of the scene's
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

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "cosim/coupled_solver.hpp"
#include "lattice/coupled_lattice.hpp"
#include "lattice/scene.hpp"

namespace common {
class H5Writer;
class StateArchive;
class Summary;
}  // namespace common

namespace lattice {

class CoupledLatticeRun : public cosim::CoupledSolver {
 public:
  /// The participant of `scene` (its `interface` faces coupled), writing lattice.h5 into `h5`.
  CoupledLatticeRun(const Scene& scene, common::H5Writer& h5);
  void declare(cosim::InterfaceDeclaration& io) override;
  void save() override { lattice_.save(); }
  void restore() override { lattice_.restore(); }
  void step(const cosim::Window& w, const cosim::Substep& s, cosim::WindowIo& io) override;
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
  const Scene& scene_;
  common::H5Writer& h5_;
  Model model_;
  std::unique_ptr<EquilibriumSolver> solver_;
  CoupledLattice lattice_;
  LatticeOutput out_;
  int axis_ = 2;
  Nominal nominal_;
  std::vector<std::string> meshes_;
  // The last iterate of the current window, written when the window is committed.
  struct Pending {
    bool any = false;
    std::uint64_t window = 0;
    std::vector<double> row;
  } pending_;
  Results results_;
  std::int64_t committed_ = 0;
  std::size_t removedBefore_ = 0;
};

}  // namespace lattice
