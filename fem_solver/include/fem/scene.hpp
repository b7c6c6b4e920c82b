#pragma once
// An FEM scene: reading it from YAML (keys in fem_solver/README.md) and running it with outputs
// (fem.h5 + fem.xdmf, summary results).

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "fem/mesh.hpp"
#include "common/bridging_zone.hpp"
#include "fem/initial_motion.hpp"
#include "fem/model.hpp"

namespace common {
class H5Writer;
class Config;
class Summary;
}  // namespace common

namespace fem {

struct Probe {
  std::string name;
  std::uint32_t node;
};

struct ReactionGroup {
  std::string name;
  std::vector<std::uint32_t> nodes;
};

struct Scene {
  Mesh mesh;
  Model model;
  std::vector<std::string> blockGroups;  ///< the mesh group of each element block
  std::vector<ReactionGroup> reactionGroups;
  std::vector<Probe> probes;
  std::string analysis;  ///< "static" or "explicit"
  StaticSettings staticSettings;
  /// Coupled static runs: loads and prescribed displacements grow with the coupling time,
  /// load factor min(t / rampTime, 1) at each window end t (0: full load in every window).
  double rampTime = 0.0;
  bool initialStatic = false;  ///< explicit: start from the static state
  std::filesystem::path initialStateFile;  ///< explicit: start from /state/displacement of this fem.h5
  double dt = 0.0, endTime = 0.0;
  bool bySteps = false;  ///< explicit.steps given: end_time follows dt (else a dt must reach it in whole steps)
  /// explicit.dt_fraction when dt is not given: the step follows fraction × the current stable step.
  double dtFraction = 0.0;
  double dtSafety = 0.9;           ///< explicit.dt_safety: largest dt / stable step [-]
  bool dtWarnOnly = false;         ///< explicit.dt_check: warn — a dt above the stable step only warns
  double energyTolerance = 0.1;    ///< largest energy-balance residual / energy scale before exit 3 [-]
  double outputInterval = 0.0, seriesInterval = 0.0;
  double checkpointInterval = 0.0;  ///< explicit: on-disk checkpoints (restart) every … [s]; 0: none
  /// Coupled runs: the interface group and how it couples ("dirichlet": reads displacement, writes the
  /// force the structure exerts there; "neumann": reads force, writes displacement and velocity).
  std::string interfaceGroup, interfaceMode;
  /// Coupled runs: the overlap of a bridging domain (`bridging:`), whose elements carry the weighted share
  /// of their energy and whose nodes the coupler ties to the particles there.
  std::optional<common::BridgingZone> bridging;
  /// explicit.initial_wave: a travelling pulse as the initial state.
  std::optional<InitialWave> initialWave;
  /// explicit.initial_velocity: a translation or a uniform stretching as the initial velocity.
  std::optional<InitialVelocity> initialVelocity;
};

/// Support forces summed per boundary-condition group.
std::vector<Vec3> groupReactions(const Scene& scene);
/// Puts probe displacements (NAME_sag, NAME_displacement) and reactions (reaction_GROUP) with `suffix`
/// into the summary.
void reportProbesAndReactions(const Scene& scene, common::Summary& summary, const std::string& suffix);

/// Builds the scene; every error is a common::ConfigError naming the key, file and line.
Scene loadScene(const common::Config& cfg);
/// Runs it, writing `outDir`/fem.h5 (+ .xdmf) and filling `summary`.
/// `restart`: continue an explicit run from this checkpoint (output.checkpoint_interval writes
/// OUT/checkpoint/fem.h5), appending to OUT's results; empty: from the start.
void runScene(Scene& scene, const std::filesystem::path& outDir, common::Summary& summary, bool progress,
              const std::filesystem::path& restart = {});

/// The element blocks as meshes of `h5` (one per block, named after its group), and a snapshot of them
/// at `time`: current positions, displacement, velocity, stress per element, and — coupled runs that
/// read a force (Neumann) — the coupled force on the nodes. Standalone and coupled runs write the same layout with these.
void addMeshes(common::H5Writer& h5, const Scene& scene);
void writeSnapshot(common::H5Writer& h5, const Scene& scene, double time, bool coupled);

/// The time series of fem.h5, one layout standalone and coupled: `reactions` (per reaction group),
/// `probes` (displacement per probe) and `energy` (kinetic, strain, external_work, damping, coupled_work,
/// residual = kinetic + strain + damping − external_work − the initial energy).
class SeriesRecorder {
 public:
  SeriesRecorder(common::H5Writer& h5, const Scene& scene);
  struct Row {
    double time = -1.0;  ///< < 0: no row
    std::vector<double> reactions, probes, energy;
  };
  /// The current state's row at time `t`; `initialEnergy`: the energy the residual starts from.
  Row sample(double t, double initialEnergy) const;
  void write(const Row& row);

 private:
  common::H5Writer& h5_;
  const Scene& scene_;
  bool reactions_ = false, probes_ = false;
};

}  // namespace fem
