#pragma once
// The DEM's coupled adapter (cosim/coupled_solver.hpp), driven by libcosim's window loop. The interface
// is the mesh wall named by `interface.wall` (motion: external). It reads the wall's node displacement
// (from the wall's reference nodes), interpolated linearly over the window by the loop: each substep
// places the nodes where the displacement is at the substep's start, with the window's constant
// velocity (consistent with that motion). It writes the nodal contact force, the loop's window mean of
// the substeps' forces (the impulse divided by the window: momentum is passed on exactly).
// With `bridging:` (dem/bridging.cpp) it declares the spheres in the overlap as the point mesh `bridge`
// (their centres at the start): it writes their velocity, weighted mass and weight β at the window end,
// reads the multiplier force held over the window (an external force on each sphere), and writes its
// energy on the one-node mesh `bridge_energy`. A scene may have both, or either.

#include <memory>
#include <vector>

#include "cosim/coupled_solver.hpp"
#include "dem/mesh_wall.hpp"
#include "dem/scene.hpp"
#include "dem/stability_monitor.hpp"

namespace common {
class H5Writer;
class StateArchive;
class Summary;
}  // namespace common

namespace dem {

class CoupledDem : public cosim::CoupledSolver {
 public:
  /// Writes the run's records to `h5` (the mesh walls, body_0, energy, snapshots). Throws ConfigError if
  /// the scene names no interface wall.
  CoupledDem(Scene& scene, common::H5Writer& h5);
  void declare(cosim::InterfaceDeclaration& io) override;
  void save() override;
  void restore() override;
  /// A bridging domain's window is one common step (the coupler checks it against stableStep()).
  double maxSubstep() const override { return sim_.settings().bridging ? 0.0 : dt_; }
  void beginWindow(const cosim::Window& w, const cosim::Substeps& sub, cosim::WindowIo& io) override;
  void step(const cosim::Window& w, const cosim::Substep& s, cosim::WindowIo& io) override;
  void endWindow(const cosim::Window& w, cosim::WindowIo& io) override;
  void commit() override;
  double stableStep() const override { return critical_; }
  /// The state at a window start: written (with the extent of `h5`) or read (a restart; `h5` was
  /// reopened at the extent the executable read first, common/results_file.hpp).
  void archive(common::StateArchive& a);
  static constexpr const char* kKind = "dem_solver";
  static std::string shape(const Scene& scene) { return scene.sim->shape(); }
  /// The interface: the mesh wall `wall` at its reference nodes, its displacement read (linear in time)
  /// and its node forces written (window means).
  static void declareInterface(cosim::InterfaceDeclaration& io, const MeshWall& wall);
  /// The bodies whose series a coupled run records: the scene's output.track and its probe body.
  static std::vector<std::uint32_t> recordedBodies(const Scene& scene);
  /// After the run: the summary's results and cost.
  void report(common::Summary& summary) const;

 private:
  Scene& scene_;
  Simulation& sim_;
  common::H5Writer& h5_;
  static constexpr std::uint32_t kNoWall = ~std::uint32_t{0};
  std::uint32_t wall_ = kNoWall;
  std::vector<std::uint32_t> bridge_;  // the bodies in the overlap
  std::vector<double> weights_;        // and their β at the start
  // and their centres at the start (x, y, z): the constraint's places X_J, declared as such after a restart too
  std::vector<double> centres_;
  bool spins_ = false;                 // they rotate: the coupler may constrain their spin
  void applyTorques(cosim::WindowIo& io);
  std::vector<double> bridgeOut_;
  void writeBridge(cosim::WindowIo& io);
  MeshWall reference_;
  double dt_ = 0.0, critical_ = 0.0;
  // The state at the window's start; in a bridging domain, after the trial step's forces (coupled_dem.cpp).
  std::shared_ptr<const Simulation::Checkpoint> checkpoint_;
  bool saveAfterForces_ = false, restoreAfterForces_ = false;
  bool reusesForces() const;
  void applyMultipliers(cosim::WindowIo& io);
  // The run's own energy ledger, checked on final windows only (a repeated window's iterations are
  // discarded with their ledger).
  StabilityMonitor monitor_;
  SeriesRecorder series_;
  // The last iteration's record, kept only if its window turns out final.
  SeriesRecorder::Row pending_;
  // Snapshots at the scene's output.interval, of final windows only (the state at the window's end).
  // None at t = 0: the interface wall is not yet where the structure put it (the net's static sag
  // arrives with the first window).
  double nextSnapshot_ = 0.0;
  std::int64_t committed_ = 0;
  // The interface wall's nodes where the displacement is at `at` of the window, at the window's velocity.
  void placeWall(cosim::WindowIo& io, double at);
  std::vector<Vec3> positions_, velocity_;
};

}  // namespace dem
