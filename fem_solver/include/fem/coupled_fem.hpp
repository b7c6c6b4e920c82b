#pragma once
// The FEM's coupled adapter (cosim/coupled_solver.hpp), driven by libcosim's window loop. The interface
// is the scene's `interface.group`; mode dirichlet reads its displacement and writes the force the
// structure exerts on it, mode neumann reads the force on it and writes its displacement and velocity.
// Static scenes solve each window to equilibrium; explicit scenes advance the window with their own
// (sub)steps and checkpoint at window starts.

#include <optional>
#include <vector>

#include "cosim/coupled_solver.hpp"
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
  void declare(cosim::InterfaceIo& io) override;
  void save() override;
  void restore() override;
  void advance(const cosim::Window& w, cosim::InterfaceIo& io) override;
  void commit() override;
  double stableStep() const override { return critical_; }
  bool checkpoints() const override { return true; }
  void writeCheckpoint(const std::string& path) override;
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
  bool dirichlet_ = false, explicit_ = false;
  std::optional<bool> staticReused_;
  double critical_ = 0.0;
  Model::State checkpoint_;
  std::vector<double> impulse_;  // Dirichlet, explicit: window-mean support force per interface dof
  SeriesRecorder series_;
  double initialEnergy_ = 0.0;  // the energy balance's start (explicit: after the initial static state)
  // A window's record is kept once the window is final (the next one starts, or the run ends).
  SeriesRecorder::Row pending_;
  // Field snapshots at the scene's output.interval, of final windows only (the model at the window's end).
  double nextSnapshot_ = 0.0;
  std::int64_t committed_ = 0;
};

}  // namespace fem
