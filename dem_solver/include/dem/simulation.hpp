#pragma once
// The DEM model and its time step. Bodies are rigid: a single sphere, or a rigid cluster of spheres.
// Contacts are found by a cell list with a Verlet skin, computed by the
// contact law of their material pair in batches, and summed per sphere and per body in a fixed order,
// so results are deterministic for a given thread count.
//
// Time integration: leapfrog (velocities at half steps, positions at whole steps). Contact dashpots see
// the half-step velocities. A scene's velocities are those at t = 0: the first step kicks by half a step.
//
// Call order: interactions() (materials, laws) / add bodies and walls / settings() → initialize() → step()
// repeatedly.
// Not thread safe; step() uses OpenMP inside. Units SI.
//
// Inside, Simulation orchestrates components that each own their arrays and state — interactions,
// neighbour list, sphere pairs, plane walls, mesh walls, integrator (dem_solver/src; dem_solver/README.md
// "Code structure") — and its Checkpoint is their values. What the public surface alone can express is a free
// function, not a method (addSphere and bodyVelocity below, dem/contact_queries.hpp).

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/bridging_zone.hpp"
#include "dem/contact_law.hpp"
#include "dem/interactions.hpp"
#include "dem/material.hpp"
#include "dem/mesh_wall.hpp"
#include "dem/model.hpp"
#include "dem/walls.hpp"

namespace dem {

/// Contacts of one body right now (for probes).
struct BodyContacts {
  int count = 0;                 ///< contacts with overlap > 0
  double maxOverlap = -std::numeric_limits<double>::infinity();  ///< largest signed overlap of its candidates [m]
  Vec3 force = Vec3::Zero();     ///< total contact force on the body [N]
  const ContactLaw* law = nullptr;  ///< law of the candidate with the largest overlap
  double effRadius = 0, effMass = 0;  ///< R*, m* of that candidate
};

class Integrator;
class MeshWalls;
class NeighbourList;
class PlaneWalls;
class SpherePairs;
struct StepContext;

class Simulation {
 public:
  using Settings = SimulationSettings;

  Simulation();
  ~Simulation();

  /// The materials and the law of each pair of them: filled while the scene is built.
  Interactions& interactions() { return interactions_; }
  const Interactions& interactions() const { return interactions_; }

  /// A rigid cluster: member sphere centres `local` are relative to the centre of mass in the principal
  /// frame, `inertia` the principal moments, `orientation` principal frame → world. Returns the body id.
  std::uint32_t addCluster(const std::vector<Vec3>& local, const std::vector<double>& radii, std::uint32_t material,
                           double mass, const Vec3& inertia, const Vec3& position, const Quat& orientation,
                           const Vec3& velocity, const Vec3& angularVelocity, bool fixed);
  /// A constant force on the body's centre of mass (besides gravity and contacts) [N].
  void setExternalForce(std::uint32_t body, const Vec3& force) {
    bodies_.externalForce.at(body) = force;
    // Even −0 counts: the loop without external forces adds +0 (the same bits only for +0).
    for (int c = 0; c < 3; ++c) externalForces_ = externalForces_ || force[c] != 0.0 || std::signbit(force[c]);
  }

  /// A torque on top of the contacts' over the next finishStep() only, given after prepareStep() (a
  /// bridging domain's multipliers on the spin) [N m]; its work is booked as external work. Ignored where
  /// the bodies do not rotate (physics() "rotation" off).
  void addStepTorque(std::uint32_t body, const Vec3& torque);

  /// The plane and triangle-mesh walls (dem/walls.hpp): added with the scene, moved between steps (a
  /// servo sets a plane's velocity, a coupled run a mesh's nodes), read with the forces of the last step.
  PlaneWallSet& planeWalls();
  const PlaneWallSet& planeWalls() const;
  MeshWallSet& meshWalls();
  const MeshWallSet& meshWalls() const;

  Settings& settings() { return settings_; }
  const Settings& settings() const { return settings_; }

  /// Prepares neighbour search and energies. Call once after building, before step().
  void initialize();
  void step();
  /// step() in its two halves: the forces at the current positions (contacts, bonds, their energies),
  /// then the move under them. A state saved between the two and restored repeats only the move: a
  /// bridging domain's corrected step, whose forces are the trial step's.
  void prepareStep();
  void finishStep();
  /// Forms the bonds of the laws that bond between the spheres as they are now (a sample cemented after
  /// its consolidation), replacing any. A touching pair's shear force carries over into its bond, which
  /// starts from its compression: no force jumps.
  void formBonds();

  /// The complete dynamic state — bodies, walls, contacts with their histories, time, energy ledger —
  /// to repeat a coupling window. Restoring gives bit-identical continuations. `Keep::kMotion` holds
  /// only what finishStep() changes (the bodies, the walls, the clock, the ledger): saved between
  /// prepareStep() and finishStep() and restored there, it repeats the move under the same forces.
  struct Checkpoint;
  enum class Keep { kAll, kMotion };
  std::shared_ptr<const Checkpoint> saveCheckpoint(Keep keep = Keep::kAll) const;
  void restoreCheckpoint(const Checkpoint& c);
  /// The same state on disk (a restart): written into `a`, or, if `a` is reading, read from it and
  /// restored. The simulation must be built from the same scene and initialize()d.
  void archive(common::StateArchive& a);

  double time() const;
  std::int64_t steps() const;
  const Bodies& bodies() const { return bodies_; }
  /// The spheres, every centre at the current time. (Between neighbour rebuilds a step moves only the
  /// spheres that are near something; the others are placed here, on demand.)
  const Spheres& spheres() const;
  /// The contact components as they stand after the last step (dem_solver/src), for what reads them
  /// between steps inside libdem (dem/contact_queries.hpp).
  struct Components {
    const SpherePairs& pairs;
    const PlaneWalls& planes;
    const MeshWalls& meshes;
  };
  Components components() const { return {*pairs_, *planeWalls_, *meshWalls_}; }
  const EnergyLedger& energy() const { return energy_; }
  /// The cohesive bonds (formed at initialize() by the laws that bond; empty otherwise).
  const BondSet& bonds() const { return bonds_; }
  double initialEnergy() const { return initialEnergy_; }
  /// Where a run's time goes: wall-clock seconds in each phase of step(), summed over the run (as
  /// LIGGGHTS' Pair/Neigh/Modify breakdown), how evenly the threads share the sphere pairs, and how often
  /// the neighbour list was built.
  struct Profile {
    double neighbour = 0.0;       ///< rebuild checks and candidate rebuilds
    double sphereContacts = 0.0;  ///< sphere pairs: geometry, law, sums to the spheres
    double wallContacts = 0.0;    ///< planes and meshes: geometry, law, sums
    double integrate = 0.0;       ///< bodies moved, kinetic and potential energy
    double other = 0.0;           ///< the rest of step(): sums cleared, energy sums
    /// Sphere pairs on several threads: per pass, the slowest thread's time minus the threads' mean (the
    /// time the others wait), summed.
    double sphereContactsWait = 0.0;
    std::int64_t neighbourRebuilds = 0;
  };
  Profile profile() const;
  /// What the simulation holds on the heap now, by structure [bytes]: bodies (with the integrator's and
  /// the clusters' per-body arrays), spheres (with their force sums), sphere_contacts (candidates, their
  /// histories and the next rebuild's arrays), wall_contacts (planes and meshes, mesh nodes included),
  /// neighbour_list (poses at the last builds, cell lists, per-thread candidate lists), bonds, other.
  std::vector<std::pair<std::string, std::size_t>> memoryUse() const;
  /// The physics the step computes, each off when nothing in the scene needs it (after initialize()):
  /// (name, on) for rotation (friction, spin or a cluster's off-centre contacts), Coulomb friction,
  /// rolling resistance, sphere pairs (more than one body), plane walls, mesh walls, Cundall damping, and
  /// the lone-sphere fast path (every body one sphere at its centre).
  std::vector<std::pair<std::string, bool>> physics() const;
  /// What a checkpoint must match to be this simulation's: its bodies, spheres, walls (mesh walls with
  /// their nodes and triangles), materials and laws, in words.
  std::string shape() const;
  BodyContacts bodyContacts(std::uint32_t body) const;

 private:
  // A run on several ranks (dem_solver/src/ranked_simulation.hpp) holds its share of the bodies and ghosts
  // here: it sends the ghosts' states and forces between steps and moves bodies between ranks.
  friend class RankedSimulation;
  /// archive() without the scene's dimensions: a rank's share, which the dimensions of the scene do not
  /// describe.
  void archiveState(common::StateArchive& a);
  /// A contact's history by its two sides as this simulation numbers them: sphere pair (a, b), a < b, or
  /// (sphere, plane wall).
  using HistoryOf = std::function<ContactHistory(std::uint32_t, std::uint32_t)>;
  /// Replaces the bodies by `bodies` and `spheres` (a rank's share and its ghosts, each body with its
  /// member spheres; no bonds), `owner` each sphere's rank and `rank` this one's. Before the first step it
  /// initializes again: the share's forces, energies and initial energy. After it, the contacts are built
  /// again with the histories `pairHistory` and `planeHistory` give; the clock, the walls and the ledger's
  /// sums stay.
  void replaceBodies(Bodies bodies, Spheres spheres, std::vector<int> owner, int rank, const HistoryOf& pairHistory,
                     const HistoryOf& planeHistory);
  /// Frees the bodies, spheres and their contacts; replaceBodies() follows (a rank frees its share before
  /// the next one arrives, so that a cut holds one share at a time).
  void releaseBodies();
  /// The skins left at 0 (automatic), from the spheres and meshes: initialize()'s first step.
  void resolveSkins();
  void updateSpherePositions(bool all);
  /// The sphere centres a step reads: the bodies' for lone spheres (spheres_.position is then refreshed
  /// only on demand), else spheres_.position of the active spheres.
  const std::vector<Vec3>& centres() const { return loneSpheres_ ? bodies_.position : spheres_.position; }
  void applyRollingResistance();
  BondSet::View bondView() const;
  void createBonds(const BondSet::ShearOf& shearOf = {});
  const BondingLaw* bondingLaw(std::uint32_t s, std::uint32_t t) const {
    return interactions_.bonding(spheres_.material[s], spheres_.material[t]);
  }
  /// Builds the candidates of the kinds asked for again, then the active spheres.
  void rebuildContacts(bool pairs, bool planeWalls, bool meshWalls);
  void rebuildReferences() const;
  void computeGeometry();
  void computeForces();
  void integrate();
  /// The model and switches the components read in one call (dem_solver/src/step_context.hpp).
  StepContext context();
  /// Each contact kind's per-contact forces (sphere pairs, plane walls, mesh walls), in the order their
  /// energies are summed.
  std::array<const std::vector<ContactForce>*, 3> contactForces() const;
  /// The last force pass's contact energies (elastic, damping, friction) [J]: what the passes summed
  /// themselves, else their stored forces' in contact order, kind after kind as contactForces() lists them.
  std::array<double, 3> contactEnergies() const;

  Settings settings_;
  Interactions interactions_;
  Bodies bodies_;
  Spheres spheres_;
  BondSet bonds_;
  void weighBridgingZone();  // at initialize(), once the bonds formed
  // The components (dem_solver/src), each owning its arrays and state; step() calls them in order.
  std::unique_ptr<NeighbourList> neighbours_;
  std::unique_ptr<SpherePairs> pairs_;
  std::unique_ptr<PlaneWalls> planeWalls_;
  std::unique_ptr<MeshWalls> meshWalls_;
  std::unique_ptr<Integrator> integrator_;
  // Sphere → contacts: for sphere s, refs_[refStart_[s] .. refStart_[s+1]) with the sign of its side. Only
  // bodyContacts() reads them (a probe, the participant): built there when a rebuild made them stale.
  struct Ref {
    std::uint32_t index;
    std::uint8_t wall;  // 0: pairs_, 1: planeWalls_
    std::int8_t sign;   // +1: sphere is side a; −1: side b
  };
  mutable std::vector<std::uint32_t> refStart_;
  mutable std::vector<Ref> refs_;
  mutable bool refsStale_ = true;
  std::vector<Eigen::Matrix3d> bodyRotation_;  // per body, refreshed by updateSpherePositions()
  std::vector<Vec3> sphereForce_, sphereTorque_;
  // What the contacts add their forces and torques to, per sphere: for lone spheres the bodies' own.
  std::vector<Vec3>& forceSums() { return loneSpheres_ ? bodies_.force : sphereForce_; }
  std::vector<Vec3>& torqueSums() { return loneSpheres_ ? bodies_.torque : sphereTorque_; }
  // Only the active spheres (NeighbourList::active()) are moved each step; the others keep a stale
  // position until a rebuild or spheres().
  mutable bool positionsStale_ = false;
  bool rotation_ = false;
  bool rolling_ = false;  // some interaction has rolling resistance
  // Every body is one sphere at its centre with isotropic inertia (a granular sample): sphere i belongs to
  // body i, its force is its body's force, and orientations need no update.
  bool loneSpheres_ = false;
  // False where the whole scene is not all lone spheres though this simulation's bodies are (a rank's
  // share, RankedSimulation): every share of a run then takes the same path.
  bool loneScene_ = true;
  bool externalForces_ = false;      // some body was given a non-zero external force
  std::vector<std::pair<std::uint32_t, Vec3>> stepTorques_;  // addStepTorque()'s bodies, their contacts' torque
  bool initialized_ = false;
  Profile profile_;  // its neighbourRebuilds is the neighbour list's, filled by profile()
  EnergyLedger energy_;
  double initialEnergy_ = 0.0;
  double initialApproach_ = 0.0;  // approachSpeedEstimate() at initialize() (dem/time_steps.hpp), for diagnoses [m/s]
};

/// A body made of one sphere (a cluster of one at its centre), its mass and inertia from the material's
/// density. Returns the body id.
std::uint32_t addSphere(Simulation& sim, const Vec3& position, double radius, std::uint32_t material,
                        const Vec3& velocity, const Vec3& angularVelocity, bool fixed);

/// A body's velocity at sim.time() (the half-step velocity advanced by half a step) [m/s].
Vec3 bodyVelocity(const Simulation& sim, std::uint32_t body);

}  // namespace dem
