#pragma once
// A DEM scene: reading it from YAML (keys documented in dem_solver/README.md) and running it with
// outputs (dem.h5 + dem.xdmf, summary results).

#include <filesystem>
#include <map>
#include <string>
#include <memory>
#include <vector>

#include "dem/simulation.hpp"

namespace common {
class H5Writer;
class Config;
class Summary;
}  // namespace common

namespace dem {

struct OutputSettings {
  double interval = 0.0;        ///< particle snapshots every … [s]; 0: none
  double seriesInterval = 0.0;  ///< time-series rows every … [s]
  std::vector<std::uint32_t> track;  ///< bodies whose trajectories are written
  double checkpointInterval = 0.0;   ///< on-disk checkpoints (restart) every … [s]; 0: none
};

/// Measures a scene's key result while it runs.
struct ProbeSettings {
  enum class Kind { kNone, kImpact, kAcceleration, kPacking };
  Kind kind = Kind::kNone;
  std::uint32_t body = 0;
  Vec3 direction = Vec3::UnitX();  ///< kAcceleration: axis of the measured acceleration
  double from = 0.0;               ///< kAcceleration: start of the fitted window [s]
  Vec3 regionMin = Vec3::Zero(), regionMax = Vec3::Zero();  ///< kPacking: measured box [m]
};

struct Scene {
  std::unique_ptr<Simulation> sim;
  double endTime = 0.0;
  double energyTolerance = 0.1;  ///< largest energy-balance residual / energy scale before exit 3 [-]
  OutputSettings output;
  ProbeSettings probe;
  std::string interfaceWall;  ///< coupled runs: the externally driven mesh wall that is the interface
};

/// The scene's `materials` into `sim`, by name.
std::map<std::string, std::uint32_t> loadMaterials(const common::Config& cfg, Simulation& sim);
/// The scene's `interactions` into `sim` (each law with `change` applied).
void loadInteractions(const common::Config& cfg, Simulation& sim, const std::map<std::string, std::uint32_t>& materials,
                      const LawOverride& change = {});

/// Builds the scene. Every error is a common::ConfigError naming the key, file and line; unknown keys
/// are errors. The time step is checked against the critical one here. `initialize` false: the
/// simulation is left to be initialized by its user, and overlapping bodies to be found then (a run on
/// several ranks initializes each rank's share, dem/ranked_run.hpp).
Scene loadScene(const common::Config& cfg, bool initialize = true);

/// Runs to the end time, writing `outDir`/dem.h5 (+ .xdmf) and filling `summary`.
/// `restart`: continue from this checkpoint (output.checkpoint_interval writes OUT/checkpoint/dem.h5),
/// appending to OUT's results; empty: from the start.
void runScene(Scene& scene, const std::filesystem::path& outDir, common::Summary& summary, bool progress,
              const std::filesystem::path& restart = {});
/// One-sided sheets: NAME_max_depth_radii (deepest centre behind the sheet) and NAME_lost_contact_steps
/// (contacts dropped because a centre went deeper than `depth`), with a warning when any were lost.
void reportSheets(const Simulation& sim, common::Summary& summary);
/// The mesh walls as meshes of `h5`, and a snapshot at `time`: spheres as points (radius, velocity, their
/// body's contact force, body id) and the mesh walls' nodes with their contact forces. Standalone and
/// coupled runs write the same layout with these.
void addMeshWalls(common::H5Writer& h5, const Simulation& sim);
void writeParticleSnapshot(common::H5Writer& h5, const Simulation& sim, double time);
/// A snapshot's spheres and force network as written: per sphere (xyz interleaved) its centre, its body's
/// velocity and contact force, its radius and body id; per touching pair its two centres and normal force.
struct ParticleSnapshot {
  std::vector<double> position, velocity, bodyForce, radius, body;
  std::vector<double> lineEnds, normalForce;
};
ParticleSnapshot particleSnapshot(const Simulation& sim);
void writeParticleSnapshot(common::H5Writer& h5, double time, const ParticleSnapshot& snapshot);
/// The mesh walls' part of a snapshot: nodes and node forces.
void writeMeshSnapshots(common::H5Writer& h5, const std::vector<MeshWall>& meshes, double time);
/// The time series of dem.h5, one layout standalone and coupled: `energy` (the ledger: kinetic,
/// potential, elastic, damping, friction, cundall, [bond_fracture,] wall_work, external_work, residual), `body_N` for each
/// recorded body (position, velocity, angular velocity, force, contacts) and `walls` (force per plane;
/// force and moment per mesh wall).
class SeriesRecorder {
 public:
  SeriesRecorder(common::H5Writer& h5, const Simulation& sim, std::vector<std::uint32_t> bodies);
  struct Row {
    double time = -1.0;  ///< < 0: no row
    std::vector<double> energy, walls;
    std::vector<std::vector<double>> bodies;
  };
  Row sample() const;  ///< the simulation's current state
  void write(const Row& row);
  /// A row's parts, for a run that sums them over ranks (dem/ranked_run.hpp): the ledger's columns with
  /// `initialEnergy` for the residual; a body's columns with its contact count; every wall's force (and a
  /// mesh's moment), as this simulation holds them.
  std::vector<double> energyRow(const EnergyLedger& e, double initialEnergy) const;
  static std::vector<double> bodyRow(const Simulation& sim, std::uint32_t body, double contacts);
  static std::vector<double> wallRow(const Simulation& sim);

 private:
  common::H5Writer& h5_;
  const Simulation& sim_;
  std::vector<std::uint32_t> bodies_;
  bool walls_ = false;
  bool bonds_ = false;
};

/// summary.yaml results of the bonds, if any formed: bonds_created, broken_bonds, bond_fracture_energy,
/// fragments, largest_fragment_mass_fraction (standalone and coupled).
void reportBonds(const Simulation& sim, common::Summary& summary);
/// Of those, `fragments` and `largest_fragment_mass_fraction` from the pieces' masses, largest first
/// (pieceMasses, dem/bonds.hpp); nothing if there are none.
void reportPieces(const std::vector<double>& pieces, common::Summary& summary);
/// summary.yaml `cost:`: the physics the step computed and left out, time per step and per phase.
void reportCost(const Simulation& sim, common::Summary& summary, double loopSeconds);

}  // namespace dem
