#pragma once
// The FEM's coupled adapter (cosim/coupled_solver.hpp), driven by libcosim's window loop. The interface
// is the scene's `interface.group`; mode dirichlet reads its displacement and writes the force the
// structure exerts on it, mode neumann reads the force on it and writes its displacement and velocity.
// Static scenes solve each window to equilibrium (one substep); explicit scenes advance the window in
// the loop's substeps (at most the scene's dt) and checkpoint at window starts. A Dirichlet interface's
// displacement is interpolated linearly over the window and prescribed at each substep's end; its force
// is the window mean of the substeps' dynamic support forces.
// With `bridging:` (fem/bridging.hpp) it also declares the overlap as mesh `bridge` (its elements as
// cells): it writes the nodes' velocity, weighted mass and weight α at the window end, reads the
// multiplier force held over the window, and writes its energy on the one-node mesh `bridge_energy`.

#include <optional>
#include <vector>

#include "cosim/coupled_solver.hpp"
#include "fem/bridging.hpp"
#include "fem/scene.hpp"

namespace common {
class H5Writer;
class StateArchive;
class Summary;
}  // namespace common

namespace fem {

class CoupledFem : public cosim::CoupledSolver {
 public:
  /// Fixes a Dirichlet interface, declares the records in `h5` and, for an explicit scene, solves the
  /// initial static state (before the handshake: it is setup, not window work). Throws ConfigError if
  /// the scene names no interface.
  CoupledFem(Scene& scene, common::H5Writer& h5);
  void declare(cosim::InterfaceDeclaration& io) override;
  void save() override;
  void restore() override;
  /// A bridging domain's window is one common step (the coupler checks it against stableStep()).
  double maxSubstep() const override { return explicit_ && !scene_.bridging ? scene_.dt : 0.0; }
  void beginWindow(const cosim::Window& w, const cosim::Substeps& sub, cosim::WindowIo& io) override;
  void step(const cosim::Window& w, const cosim::Substep& s, cosim::WindowIo& io) override;
  void endWindow(const cosim::Window& w, cosim::WindowIo& io) override;
  void commit() override;
  double stableStep() const override { return critical_; }
  /// The state at a window start: written (with the extent of `h5`) or read (a restart; `h5` was
  /// reopened at the extent the executable read first, common/results_file.hpp).
  void archive(common::StateArchive& a);
  static constexpr const char* kKind = "fem_solver";
  static std::string shape(const Scene& scene) { return scene.model.shape(); }
  void report(common::Summary& summary) const;

 private:
  Scene& scene_;
  Model& model_;
  common::H5Writer& h5_;
  const Mesh::Group& group_;
  bool interface_ = false, dirichlet_ = false, explicit_ = false;
  std::optional<BridgeCells> bridge_;
  std::vector<double> bridgeOut_;  // a bridge output's values, per overlap node
  void writeBridge(cosim::WindowIo& io);
  std::optional<bool> staticReused_;
  double critical_ = 0.0;
  Model::State checkpoint_;
  std::vector<double> out_;  // an output's values, per interface dof
  // out_ = sign × `field` (per model dof) at the interface nodes, node-major.
  const std::vector<double>& gather(const std::vector<double>& field, double sign = 1.0);
  SeriesRecorder series_;
  double initialEnergy_ = 0.0;  // the energy balance's start (explicit: after the initial static state)
  // A window's record is kept once the window is final (the next one starts, or the run ends).
  SeriesRecorder::Row pending_;
  // Field snapshots at the scene's output.interval, of final windows only (the model at the window's end).
  double nextSnapshot_ = 0.0;
  std::int64_t committed_ = 0;
};

}  // namespace fem
